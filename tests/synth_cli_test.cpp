// Command-line tests of `eco` for the synth module (split from synth_test.cpp, issue 23):
// they run the eco binary (ECO_BINARY) and live in eco_cli_tests, apart from the unit tests.
#include <hdf5.h>
#include <omp.h>

#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>

#include "abiotics.h"
#include "biome.h"
#include "biome_db.h"
#include "canopy_placer.h"
#include "error.h"
#include "forest_floor.h"
#include "h5io.h"
#include "scene.h"
#include "synth_world_fixture.h"
#include "terrain_io.h"
#include "test_util.h"
#include "undergrowth.h"

using namespace eco;

namespace {

// ------------------------------------------------------------------ the test world (synth_world_fixture.h)

using test::kCell;
using test::kSide;
using test::makeWorld;
using test::World;

/// Files of the world for the command-line tests.
struct WorldFiles {
    std::string terrain, canopy, abiotics, db;
};

WorldFiles writeWorld(const World& w, const test::TempDir& dir) {
    WorldFiles f{dir.file("terrain.h5"), dir.file("canopy.h5"), dir.file("abiotics.h5"), dir.file("db.h5")};
    writeTerrainH5(f.terrain, w.terrain);
    synth::CanopyRecord rec;
    rec.result.trees = w.canopy;
    rec.speciesMap = Grid<std::int32_t>::like(w.terrain, -1);
    rec.chmM = Grid<float>::like(w.terrain, 0.0f);
    rec.terrainM = w.terrain;
    rec.terrainSource = f.terrain;
    synth::writeCanopyFile(f.canopy, rec, w.biome);
    Abiotics ab;
    for (int m = 0; m < 12; ++m) {
        ab.sunHours.months.push_back(w.features[Factor::Sun]);
        ab.moistureMm.months.push_back(w.features[Factor::Moisture]);
        ab.temperatureC.months.push_back(w.features[Factor::Temperature]);
    }
    ab.slopeDeg = w.features[Factor::Slope];
    ab.elevationM = w.terrain;
    writeAbiotics(f.abiotics, ab, w.biome, AbioticParams{});
    writeBiomeDatabase(f.db, w.db);
    return f;
}

}  // namespace

// ======================================================================== cluster map

TEST_CASE("eco synth and eco compare write a scene and report it", "[synth][cli]") {
    const World w = makeWorld();
    test::TempDir dir("synth_cli");
    const WorldFiles f = writeWorld(w, dir);
    const auto r = test::runEco("synth --terrain " + f.terrain + " --canopy " + f.canopy + " --database " + f.db +
                                " --abiotics " + f.abiotics + " --out " + dir.file("out/scene.h5") + " --png " +
                                dir.file("png") + " --csv " + dir.file("plants.csv") + " --pdb " + dir.file("plants.pdb") +
                                " --refine --refine-sweeps 1 --refine-window 80,80,120,120");
    INFO(r.output);
    REQUIRE(r.exitCode == 0);
    CHECK_THAT(r.output, Catch::Contains("refinement: pair-correlation distance"));
    for (const char* name : {"out/scene.h5", "plants.csv", "plants.pdb", "png/scene.png", "png/scene_zoom.png",
                             "png/grass.png", "png/litter.png", "png/cluster_map.png"})
        CHECK(std::filesystem::exists(dir.file(name)));
    const auto c = test::runEco("compare " + dir.file("out/scene.h5") + " " + f.db + " --png " + dir.file("compare.png"));
    INFO(c.output);
    REQUIRE(c.exitCode == 0);
    CHECK_THAT(c.output, Catch::Contains("| region |") && Catch::Contains("pair-correlation distance"));
    CHECK(std::filesystem::exists(dir.file("compare.png")));
}

TEST_CASE("eco synth refuses bad inputs with one clear line and no output", "[synth][cli]") {
    const World w = makeWorld();
    test::TempDir dir("synth_bad");
    const WorldFiles f = writeWorld(w, dir);
    const std::string out = dir.file("scene.h5");
    auto synth = [&](const std::string& terrain, const std::string& canopy, const std::string& db) {
        return test::runEco("synth --terrain " + terrain + " --canopy " + canopy + " --database " + db + " --abiotics " +
                            f.abiotics + " --out " + out);
    };

    SECTION("a database of another schema version") {
        const std::string bad = dir.file("db_old.h5");
        std::filesystem::copy_file(f.db, bad);
        const hid_t file = H5Fopen(bad.c_str(), H5F_ACC_RDWR, H5P_DEFAULT);
        REQUIRE(file >= 0);
        REQUIRE(H5Adelete(file, "schema_version") >= 0);
        const hid_t space = H5Screate(H5S_SCALAR);
        const hid_t attr = H5Acreate2(file, "schema_version", H5T_STD_I64LE, space, H5P_DEFAULT, H5P_DEFAULT);
        const long long older = kBiomeDbOldestReadableVersion - 1;
        H5Awrite(attr, H5T_NATIVE_LLONG, &older);
        H5Aclose(attr);
        H5Sclose(space);
        H5Fclose(file);
        const auto r = synth(f.terrain, f.canopy, bad);
        INFO(r.output);
        CHECK(r.exitCode != 0);
        CHECK_THAT(r.output, Catch::Contains("db_old.h5") && Catch::Contains("schema_version") && Catch::Contains("eco: error"));
    }
    SECTION("a canopy tree outside the terrain") {
        std::vector<Plant> trees = w.canopy;
        trees[3].xM = kSide * kCell + 25.0;
        synth::CanopyRecord rec;
        rec.result.trees = trees;
        rec.speciesMap = Grid<std::int32_t>::like(w.terrain, -1);
        rec.chmM = Grid<float>::like(w.terrain, 0.0f);
        rec.terrainM = w.terrain;
        synth::writeCanopyFile(dir.file("outside.h5"), rec, w.biome);
        const auto r = synth(f.terrain, dir.file("outside.h5"), f.db);
        INFO(r.output);
        CHECK(r.exitCode != 0);
        CHECK_THAT(r.output, Catch::Contains("outside.h5") && Catch::Contains("canopy tree 3") &&
                                 Catch::Contains("outside the terrain"));
    }
    SECTION("a canopy placed on another terrain") {
        Grid<float> other(kSide / 2, kSide, kCell, 0, 0, 50.0f);
        writeTerrainH5(dir.file("other.h5"), other);
        const auto r = synth(dir.file("other.h5"), f.canopy, f.db);
        INFO(r.output);
        CHECK(r.exitCode != 0);
        CHECK_THAT(r.output, Catch::Contains("canopy.h5") && Catch::Contains("other.h5") &&
                                 Catch::Contains("was placed on a terrain of"));
    }
    SECTION("a missing file") {
        const auto r = synth(f.terrain, f.canopy, dir.file("nothing.h5"));
        INFO(r.output);
        CHECK(r.exitCode != 0);
        CHECK_THAT(r.output, Catch::Contains("nothing.h5"));
    }
    CHECK_FALSE(std::filesystem::exists(out));
    // No temporary files left beside the output either.
    for (const auto& e : std::filesystem::directory_iterator(dir.path()))
        CHECK(e.path().filename().string().find("scene") == std::string::npos);
}

TEST_CASE("eco compare refuses a scene from another database", "[synth][cli]") {
    const World w = makeWorld();
    test::TempDir dir("synth_cmp");
    const WorldFiles f = writeWorld(w, dir);
    REQUIRE(test::runEco("synth --terrain " + f.terrain + " --canopy " + f.canopy + " --database " + f.db +
                         " --abiotics " + f.abiotics + " --out " + dir.file("scene.h5"))
                .exitCode == 0);
    BiomeDatabase small = w.db;
    small.regions.resize(1);
    small.combinations.resize(1);
    small.combinations[0].k = 1;
    writeBiomeDatabase(dir.file("small.h5"), small);
    const auto r = test::runEco("compare " + dir.file("scene.h5") + " " + dir.file("small.h5"));
    INFO(r.output);
    CHECK(r.exitCode != 0);
    CHECK_THAT(r.output, Catch::Contains("another database"));
}
