// The canopy file format (core/canopy_file.h): round trip, parts, and refused files.
#include <catch2/catch.hpp>

#include "canopy_file.h"
#include "error.h"
#include "provenance.h"
#include "test_util.h"

using namespace eco;

namespace {

CanopyFileContents smallCanopy(const Biome& biome) {
    CanopyFileContents c;
    c.trees = {{biome.speciesIndex("Redwood"), 10.5, 20.25, 100.0, 60.0, 5.5}};
    c.speciesMap = Grid<std::int32_t>(4, 3, 1.0, 0, 0, -1);
    c.chmM = Grid<float>(4, 3, 1.0, 0, 0, 12.f);
    c.terrainM = Grid<float>(4, 3, 1.0, 0, 0, 100.f);
    c.iterations = {{0, 1, 0, 1, 0.5, 2.0, 0.01}, {-1, 1, 0, 0, 0.5, 2.0, 0.02}};
    c.seed = 42;
    c.realParameters = {{"canopy_threshold_m", 3.0}};
    c.integerParameters = {{"target_sweeps", 2}};
    c.speciesWeights.assign(biome.species.size(), 1.0);
    return c;
}

}  // namespace

TEST_CASE("canopy file: written and read back, the simulator's parts alone", "[canopy_file]") {
    test::TempDir dir("canopy_file");
    const Biome biome = defaultBiome();
    const std::string path = dir.file("c.h5");
    writeCanopyFile(path, smallCanopy(biome), biome);
    {
        const h5::File f = h5::File::openRead(path);
        CHECK(f.attrString("/", "format") == kCanopyFormat);
        CHECK(f.attrInt("/", "schema_version") == kCanopySchemaVersion);
        CHECK(f.attrInt("/", "target_sweeps") == 2);
    }
    const CanopyFileData all = readCanopyFile(path, biome);
    REQUIRE(all.trees.size() == 1);
    CHECK(all.trees[0].crownRadiusM == 5.5);
    CHECK(all.seed == 42);
    REQUIRE(all.iterations.size() == 2);
    CHECK(all.iterations[1].iteration == -1);
    CHECK(all.terrainM(1, 1) == 100.f);
    const CanopyFileData some = readCanopyFile(path, biome, CanopyFileParts::TreesAndChm);
    CHECK(some.trees.size() == 1);
    CHECK(some.chmM(2, 1) == 12.f);
    CHECK(some.terrainM.empty());
}

TEST_CASE("canopy file: other files, versions and missing datasets are refused by name", "[canopy_file][errors]") {
    test::TempDir dir("canopy_file");
    const Biome biome = defaultBiome();
    const CanopyFileContents c = smallCanopy(biome);
    {
        auto f = h5::File::create(dir.file("plain.h5"));
        writePlants(f, "/canopy", c.trees, biome);
        f.ensureGroup("/chm");
        f.writeGrid("/chm/height", c.chmM, "m");
    }
    CHECK_THROWS_WITH(readCanopyFile(dir.file("plain.h5"), biome, CanopyFileParts::TreesAndChm),
                      Catch::Contains("plain.h5") && Catch::Contains("not an eco-canopy file"));
    {
        auto f = h5::File::create(dir.file("v9.h5"));
        f.setAttr("/", "format", std::string(kCanopyFormat));
        f.setAttr("/", "schema_version", std::int64_t{9});
    }
    CHECK_THROWS_WITH(readCanopyFile(dir.file("v9.h5"), biome), Catch::Contains("v9.h5") && Catch::Contains("version 9"));
    {
        auto f = h5::File::create(dir.file("nochm.h5"));
        setCanopyFormat(f);
        writePlants(f, "/canopy", c.trees, biome);
    }
    CHECK_THROWS_WITH(readCanopyFile(dir.file("nochm.h5"), biome, CanopyFileParts::TreesAndChm),
                      Catch::Contains("nochm.h5") && Catch::Contains("/chm/height"));
}

TEST_CASE("canopy file: wall times in /provenance, or none with provenance off, or in /iterations in version 1",
          "[canopy_file][provenance]") {
    test::TempDir dir("canopy_file");
    const Biome biome = defaultBiome();
    writeCanopyFile(dir.file("c.h5"), smallCanopy(biome), biome);
    CHECK(readCanopyFile(dir.file("c.h5"), biome).iterations[1].seconds == 0.02);
    {
        const h5::File f = h5::File::openRead(dir.file("c.h5"));
        CHECK(f.attrDoubles(kProvenanceGroup, "iteration_seconds") == std::vector<double>{0.01, 0.02});
        CHECK_FALSE(f.exists("/iterations/seconds"));
    }

    setProvenanceRecorded(false);
    writeCanopyFile(dir.file("v1.h5"), smallCanopy(biome), biome);
    setProvenanceRecorded(true);
    CHECK(readCanopyFile(dir.file("v1.h5"), biome).iterations[1].seconds == 0.0);
    // Make it a version 1 file: the wall times in /iterations/seconds.
    {
        const hid_t file = H5Fopen(dir.file("v1.h5").c_str(), H5F_ACC_RDWR, H5P_DEFAULT);
        REQUIRE(file >= 0);
        const hsize_t n = 2;
        const double seconds[2] = {0.5, 0.75};
        const hid_t space = H5Screate_simple(1, &n, nullptr);
        const hid_t ds = H5Dcreate2(file, "/iterations/seconds", H5T_IEEE_F64LE, space, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
        H5Dwrite(ds, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, seconds);
        const std::int64_t one = 1;
        const hid_t version = H5Aopen(file, "schema_version", H5P_DEFAULT);
        H5Awrite(version, H5T_NATIVE_INT64, &one);
        H5Aclose(version);
        H5Dclose(ds);
        H5Sclose(space);
        H5Fclose(file);
    }
    REQUIRE(h5::File::openRead(dir.file("v1.h5")).attrInt("/", "schema_version") == 1);
    const CanopyFileData old = readCanopyFile(dir.file("v1.h5"), biome);
    REQUIRE(old.iterations.size() == 2);
    CHECK(old.iterations[0].seconds == 0.5);
    CHECK(old.iterations[1].seconds == 0.75);
}
