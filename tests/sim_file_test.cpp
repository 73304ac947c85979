// The simulation file format (core/sim_file.h): written and read back.
#include <catch2/catch.hpp>

#include "error.h"
#include "sim_file.h"
#include "test_util.h"

using namespace eco;

TEST_CASE("simulation file: snapshots, canopy and context read back, years listed", "[sim_file]") {
    test::TempDir dir("sim_file");
    const Biome biome = defaultBiome();
    SimulationFileInfo info;
    info.seed = 7;
    info.years = 10;
    info.x0 = 1;
    info.y0 = 2;
    info.x1 = 11;
    info.y1 = 12;
    info.abioticsPath = "abiotics.h5";
    info.parameters = {{"seed_outer_radius_factor", 12.0}};
    UndergrowthPlant u;
    u.id = 5;
    u.speciesId = 3;
    u.xM = 4;
    u.yM = 5;
    u.heightM = 0.5;
    u.crownRadiusM = 0.25;
    u.pool = 0.75;
    const SnapshotList snapshots = {{0, {}}, {10, {u}}};
    YearRecord r;
    r.year = 10;
    r.count.assign(biome.species.size(), 1);
    r.meanHeightM.assign(biome.species.size(), 0.5);
    r.meanVigour.assign(biome.species.size(), 0.25);
    r.crownAreaM2.assign(biome.species.size(), 2.0);
    const std::vector<Plant> canopy = {{0, 6, 7, 8, 30, 3}};
    const std::string path = dir.file("out/sim.h5");
    writeSimulationFile(path, info, biome, snapshots, {r}, canopy);

    const SimulationFileData last = readSimulationFile(path);
    CHECK(last.years == std::vector<int>{0, 10});
    CHECK(last.year == 10);
    REQUIRE(last.undergrowth.size() == 1);
    CHECK(last.undergrowth[0].crownRadiusM == 0.25);
    REQUIRE(last.canopy.size() == 1);
    REQUIRE(last.area);
    CHECK((*last.area)[3] == 12);
    CHECK(last.abioticsPath == "abiotics.h5");
    CHECK(last.seed == 7);
    CHECK(last.seedOuterRadiusFactor == 12.0);
    CHECK(readSimulationFile(path, 0).undergrowth.empty());
    CHECK_THROWS_WITH(readSimulationFile(path, 5), Catch::Contains("no snapshot of year 5") && Catch::Contains("0, 10"));

    const h5::File f = h5::File::openRead(path);
    CHECK(f.attrString("/", "format") == kSimulationFormat);
    CHECK(lastSnapshotGroup(f) == "/snapshots/year_0010");
    const auto snap = readSnapshot(f, lastSnapshotGroup(f), biome);
    REQUIRE(snap.size() == 1);
    CHECK(snap[0].id == 5);
    CHECK(snap[0].pool == 0.75);
    const auto ts = readTimeseries(f, "/timeseries", biome.species.size());
    REQUIRE(ts.size() == 1);
    CHECK(ts[0].crownAreaM2.back() == 2.0);
}

TEST_CASE("simulation file: another format or schema version is refused by name", "[sim_file][errors]") {
    test::TempDir dir("sim_file");
    {
        auto f = h5::File::create(dir.file("other.h5"));
        f.setAttr("/", "format", std::string("eco-canopy"));
    }
    CHECK_THROWS_WITH(readSimulationFile(dir.file("other.h5")),
                      Catch::Contains("other.h5") && Catch::Contains("not a simulation file"));
    {
        auto f = h5::File::create(dir.file("v3.h5"));
        f.setAttr("/", "format", std::string(kSimulationFormat));
        f.setAttr("/", "schema_version", kSimulationSchemaVersion + 1);
    }
    CHECK_THROWS_WITH(readSimulationFile(dir.file("v3.h5")), Catch::Contains("v3.h5") && Catch::Contains("schema_version 3"));
}
