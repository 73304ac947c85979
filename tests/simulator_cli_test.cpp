// Command-line tests of `eco` for the simulator module (split from simulator_test.cpp, issue 23):
// they run the eco binary (ECO_BINARY) and live in eco_cli_tests, apart from the unit tests.
#include <catch2/catch.hpp>
#include <omp.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <fstream>
#include <limits>
#include <map>
#include <random>
#include <sstream>

#include "canopy_file.h"
#include "h5_compare.h"
#include "atomic_file.h"
#include "demo_scene.h"
#include "batch_math.h"
#include "error.h"
#include "footprint.h"
#include "paint.h"
#include "processes.h"
#include "sim_config.h"
#include "sim_run.h"
#include "sim_file.h"
#include "sim_scene_fixture.h"
#include "simulator.h"
#include "test_util.h"

using namespace eco;
using namespace eco::sim;

namespace {

using test::smallDemoScene;

using eco::test::writeText;

// Scene files for the command line: abiotics.h5 and canopy.h5.
void writeSceneFiles(const test::TempDir& dir) {
    const SimInputs in = smallDemoScene();
    writeAbiotics(dir.file("abiotics.h5"), in.abiotics, in.biome, AbioticParams{});
    auto f = h5::File::create(dir.file("canopy.h5"));
    setCanopyFormat(f);
    writePlants(f, "/canopy", in.canopy, in.biome);
    f.ensureGroup("/chm");
    f.writeGrid("/chm/height", in.chmM, "m");
}

using eco::test::readAll;

}  // namespace

TEST_CASE("eco simulate: bad configs and inputs give one clear line and a non-zero exit", "[sim][cli]") {
    test::TempDir dir("simcli");
    writeText(dir.file("typo.toml"), "[model]\ncell_sise_m = 0.2\n");
    auto r = test::runEco("simulate --config " + dir.file("typo.toml"));
    CHECK(r.exitCode != 0);
    CHECK_THAT(r.output, Catch::Contains("cell_sise_m") && Catch::Contains("typo.toml"));

    r = test::runEco("simulate --abiotics " + dir.file("none.h5") + " --canopy " + dir.file("none2.h5") + " --out " +
                     dir.file("o.h5"));
    CHECK(r.exitCode != 0);
    CHECK_THAT(r.output, Catch::Contains("none.h5") && Catch::Contains("not found"));

    writeSceneFiles(dir);
    // A canopy file without a CHM.
    {
        const SimInputs in = smallDemoScene();
        auto f = h5::File::create(dir.file("nochm.h5"));
        setCanopyFormat(f);
        writePlants(f, "/canopy", in.canopy, in.biome);
    }
    r = test::runEco("simulate --abiotics " + dir.file("abiotics.h5") + " --canopy " + dir.file("nochm.h5") + " --out " +
                     dir.file("o.h5"));
    CHECK(r.exitCode != 0);
    CHECK_THAT(r.output, Catch::Contains("/chm/height"));
    // A crop outside the terrain.
    r = test::runEco("simulate --abiotics " + dir.file("abiotics.h5") + " --canopy " + dir.file("canopy.h5") +
                     " --crop 100,100,120,120 --years 1 --out " + dir.file("o.h5"));
    CHECK(r.exitCode != 0);
    CHECK_THAT(r.output, Catch::Contains("not inside the abiotics extent"));
    r = test::runEco("simulate --abiotics " + dir.file("abiotics.h5") + " --canopy " + dir.file("canopy.h5") +
                     " --crop 1,2,x,4 --out " + dir.file("o.h5"));
    CHECK(r.exitCode != 0);
    CHECK_THAT(r.output, Catch::Contains("--crop"));
    // Initial plants with an unknown species, and with a missing column.
    writeText(dir.file("bad.csv"), "species,x_m,y_m,height_m\nNot A Plant,11,11,0.1\n");
    r = test::runEco("simulate --abiotics " + dir.file("abiotics.h5") + " --canopy " + dir.file("canopy.h5") +
                     " --crop 10,10,20,20 --years 1 --initial " + dir.file("bad.csv") + " --out " + dir.file("o.h5"));
    CHECK(r.exitCode != 0);
    CHECK_THAT(r.output, Catch::Contains("bad.csv:2") && Catch::Contains("Not A Plant"));
    writeText(dir.file("nocol.csv"), "species,x_m,y_m\nToyon,11,11\n");
    r = test::runEco("simulate --abiotics " + dir.file("abiotics.h5") + " --canopy " + dir.file("canopy.h5") +
                     " --crop 10,10,20,20 --years 1 --initial " + dir.file("nocol.csv") + " --out " + dir.file("o.h5"));
    CHECK(r.exitCode != 0);
    CHECK_THAT(r.output, Catch::Contains("height_m"));
    // A misspelt model choice on the command line.
    r = test::runEco("simulate --abiotics " + dir.file("abiotics.h5") + " --canopy " + dir.file("canopy.h5") +
                     " --crop 10,10,20,20 --years 1 --competition deusen --out " + dir.file("o.h5"));
    CHECK(r.exitCode != 0);
    CHECK_THAT(r.output, Catch::Contains("--competition") && Catch::Contains("deusen") && Catch::Contains("\"deussen\""));
    CHECK_FALSE(std::ifstream(dir.file("o.h5")).good());
}

TEST_CASE("eco simulate: disturbance settings that cannot strike in the run are said", "[sim][cli][disturbance]") {
    test::TempDir dir("simcli_never");
    writeSceneFiles(dir);
    const std::string inputs = "[inputs]\nabiotics = \"" + dir.file("abiotics.h5") + "\"\ncanopy = \"\"\n" +
                               "[model]\nkind = \"ecomod\"\n[run]\nyears = 3\n[outputs]\nhdf5 = \"" + dir.file("o.h5") + "\"\n";
    // A forced year beyond the run and no probability: no fire can happen.
    writeText(dir.file("late.toml"), inputs + "[disturbance.fire]\nyears = [1, 3, 500]\n[disturbance.storm]\nyears = [7]\n");
    auto r = test::runEco("simulate --config " + dir.file("late.toml"));
    INFO(r.output);
    CHECK(r.exitCode == 0);
    CHECK_THAT(r.output, Catch::Contains("fire forced in years beyond the 3 simulated years (0 = the first) never happens: 3, 500"));
    CHECK_THAT(r.output, Catch::Contains("no storm can happen in this run"));
    CHECK_THAT(r.output, !Catch::Contains("no fire can happen"));  // year 1 is within the run
    // A table with neither a probability nor years; the probability rounded, not cut.
    writeText(dir.file("empty.toml"), inputs + "[disturbance.fire]\n[disturbance.storm]\nreturn_interval_years = 15\n");
    r = test::runEco("simulate --config " + dir.file("empty.toml"));
    CHECK(r.exitCode == 0);
    CHECK_THAT(r.output, Catch::Contains("no fire can happen in this run") && Catch::Contains("storms (probability 0.06667/year)"));
    CHECK_THAT(r.output, !Catch::Contains("no storm can happen"));
}

TEST_CASE("eco config describe disturbance-fire / -storm: the keys eco simulate reads, and a bad value exits 1", "[sim][cli][disturbance]") {
    // The describe tables list exactly the descriptors' keys, which are the keys the reader
    // accepts (tests/disturbance_test.cpp checks the reader against the same tables).
    auto describedKeys = [](const std::string& table) {
        const auto r = test::runEco("config describe " + table);
        REQUIRE(r.exitCode == 0);
        std::vector<std::string> keys;
        std::istringstream lines(r.output);
        for (std::string line; std::getline(lines, line);) {
            if (line.rfind(table + "\t", 0) != 0) continue;
            const std::size_t a = line.find('\t') + 1;
            keys.push_back(line.substr(a, line.find('\t', a) - a));
        }
        return keys;
    };
    std::vector<std::string> fire, storm;
    for (const auto& f : sim::fireFields()) fire.push_back(f.key());
    for (const auto& f : sim::stormFields()) storm.push_back(f.key());
    CHECK(describedKeys("disturbance-fire") == fire);
    CHECK(describedKeys("disturbance-storm") == storm);
    const auto index = test::runEco("config describe --index");
    CHECK_THAT(index.output, Catch::Contains("| `disturbance-fire` | `sim::FireSettings` | `fireFields()` | 12 |") &&
                                 Catch::Contains("| `disturbance-storm` | `sim::StormSettings` | `stormFields()` | 9 |"));
    // eco simulate refuses a bad value with the file, line, table, key and value, exit code 1.
    test::TempDir dir("simcli_badfire");
    writeSceneFiles(dir);
    const std::string inputs = "[inputs]\nabiotics = \"" + dir.file("abiotics.h5") + "\"\ncanopy = \"" + dir.file("canopy.h5") +
                               "\"\n[run]\nyears = 1\n[outputs]\nhdf5 = \"" + dir.file("o.h5") + "\"\n";
    writeText(dir.file("bad.toml"), inputs + "[disturbance.fire]\nyears = [1]\nspread_probability = 1.5\n");
    auto r = test::runEco("simulate --config " + dir.file("bad.toml"));
    INFO(r.output);
    CHECK(r.exitCode == 1);
    CHECK_THAT(r.output, Catch::Contains("bad.toml:10: [disturbance.fire]: field 'spread_probability': value 1.5: must lie in [0, 1]"));
    writeText(dir.file("bad2.toml"), inputs + "[disturbance.storm]\nmonth = 12\n");
    r = test::runEco("simulate --config " + dir.file("bad2.toml"));
    CHECK(r.exitCode == 1);
    CHECK_THAT(r.output, Catch::Contains("bad2.toml:9: [disturbance.storm]: field 'month': value 12: must lie in 0..11 (0 = January)"));
    CHECK_FALSE(std::ifstream(dir.file("o.h5")).good());
}

TEST_CASE("eco simulate: outputs, and a resumed run equals an uninterrupted one", "[sim][cli][checkpoint]") {
    test::TempDir dir("simrun");
    writeSceneFiles(dir);
    const std::string common = "simulate --abiotics " + dir.file("abiotics.h5") + " --canopy " + dir.file("canopy.h5") +
                               " --crop 10,10,26,26 --seed 4 ";
    auto r = test::runEco(common + "--years 8 --snapshot-years 4 --out " + dir.file("full.h5") + " --csv " +
                          dir.file("full.csv") + " --png " + dir.file("png"));
    INFO(r.output);
    REQUIRE(r.exitCode == 0);
    // First 5 years with checkpoints, then resume to 8.
    r = test::runEco(common + "--years 5 --checkpoint-every 2 --out " + dir.file("part.h5"));
    REQUIRE(r.exitCode == 0);
    r = test::runEco(common + "--years 8 --snapshot-years 4 --checkpoint-every 2 --resume --out " + dir.file("part.h5") +
                     " --csv " + dir.file("resumed.csv"));
    INFO(r.output);
    REQUIRE(r.exitCode == 0);
    CHECK_THAT(r.output, Catch::Contains("resumed"));
    const std::string a = readAll(dir.file("full.csv")), b = readAll(dir.file("resumed.csv"));
    CHECK(a.size() > 200);
    CHECK(a == b);
    // The thread count changes nothing.
    r = test::runEco("--threads 1 " + common + "--years 8 --out " + dir.file("one.h5") + " --csv " + dir.file("one.csv"));
    REQUIRE(r.exitCode == 0);
    CHECK(readAll(dir.file("one.csv")) == a);

    auto f = h5::File::openRead(dir.file("full.h5"));
    CHECK(f.attrString("/", "format") == "eco-simulation");
    CHECK(f.attrInt("/", "schema_version") == kSimulationSchemaVersion);  // 2 since issue 31
    CHECK(f.attrDouble("/", "seeding_probability") == 0.003);
    CHECK(f.hasAttr("/", "biome_toml"));
    CHECK(f.exists("/snapshots/year_0004"));
    CHECK(f.exists("/snapshots/year_0008"));
    std::vector<hsize_t> dims;
    f.readI32("/timeseries/count", &dims);
    CHECK(dims[0] == 9);
    const auto snap = readSnapshot(f, "/snapshots/year_0008", defaultBiome());
    CHECK(!snap.empty());
    const auto back = readInitialPlants(dir.file("full.csv"), defaultBiome());
    CHECK(back.size() == snap.size());
    CHECK(std::ifstream(dir.file("png/species_counts.png")).good());
    CHECK(std::ifstream(dir.file("png/plants_year_0008.png")).good());
    // The final state restarts a simulation.
    SimInputs in = smallDemoScene();
    in.area = SimArea{10, 10, 26, 26};
    Simulation again(in, SimParams{}, 1, readInitialPlants(dir.file("full.h5"), defaultBiome()));
    CHECK(again.plantCount() == snap.size());
}

TEST_CASE("eco simulate --model ecomod: outputs the analyser reads, resume and thread count change no byte",
          "[sim][cli][checkpoint][ecomod]") {
    test::TempDir dir("simecomod");
    writeSceneFiles(dir);
    const std::string common = "--no-provenance simulate --model ecomod --abiotics " + dir.file("abiotics.h5") + " --canopy " +
                               dir.file("canopy.h5") + " --seed 4 ";
    auto r = test::runEco(common + "--years 30 --snapshot-years 10,20 --out " + dir.file("full.h5") + " --csv " + dir.file("full.csv"));
    INFO(r.output);
    REQUIRE(r.exitCode == 0);
    CHECK_THAT(r.output, Catch::Contains("model ecomod"));
    // 20 years with checkpoints (a run killed after its checkpoint of year 20, in effect), then
    // resumed to 30: the same snapshots, so the same file, byte for byte.
    r = test::runEco(common + "--years 20 --snapshot-years 10,20 --checkpoint-every 5 --out " + dir.file("part.h5"));
    REQUIRE(r.exitCode == 0);
    r = test::runEco(common + "--years 30 --snapshot-years 10,20 --checkpoint-every 5 --resume --out " + dir.file("part.h5") +
                     " --csv " + dir.file("resumed.csv"));
    INFO(r.output);
    REQUIRE(r.exitCode == 0);
    CHECK_THAT(r.output, Catch::Contains("resumed"));
    const std::string a = readAll(dir.file("full.csv"));
    CHECK(a.size() > 2000);
    CHECK(readAll(dir.file("resumed.csv")) == a);
    {
        const auto diffs = test::outputFileDifferences(dir.file("full.h5"), dir.file("part.h5"));
        for (const auto& d : diffs) UNSCOPED_INFO(d);
        CHECK(diffs.empty());  // the simulation files too (no provenance: the same bytes)
    }
    r = test::runEco("--threads 1 " + common + "--years 30 --snapshot-years 10,20 --out " + dir.file("one.h5") + " --csv " +
                     dir.file("one.csv"));
    REQUIRE(r.exitCode == 0);
    CHECK(readAll(dir.file("one.csv")) == a);
    CHECK(test::outputFileDifferences(dir.file("full.h5"), dir.file("one.h5")).empty());
    {
        auto f = h5::File::openRead(dir.file("full.h5"));
        CHECK(f.exists("/snapshots"));
    }
    // The simulation file is an ordinary one: the analyser reads it.
    r = test::runEco("analyse " + dir.file("full.h5") + " --out " + dir.file("db.h5"));
    INFO(r.output);
    CHECK(r.exitCode == 0);
    // The monthly model's checkpoint is refused by an ecomod run and the reverse.
    r = test::runEco("simulate --abiotics " + dir.file("abiotics.h5") + " --canopy " + dir.file("canopy.h5") +
                     " --seed 4 --crop 10,10,20,20 --years 20 --resume --out " + dir.file("part.h5"));
    CHECK(r.exitCode != 0);
    // A misspelt model.
    r = test::runEco(common + "--years 1 --model ecomodd --out " + dir.file("o.h5"));
    CHECK(r.exitCode != 0);
    CHECK_THAT(r.output, Catch::Contains("--model") && Catch::Contains("ecomodd") && Catch::Contains("\"ecomod\""));
}
