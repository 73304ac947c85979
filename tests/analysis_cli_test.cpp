// Command-line tests of `eco` for the analysis module (split from analysis_test.cpp, issue 23):
// they run the eco binary (ECO_BINARY) and live in eco_cli_tests, apart from the unit tests.
#include <catch2/catch.hpp>
#include <omp.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <numeric>
#include <fstream>

#include "abiotics.h"
#include "analysis.h"
#include "biome_db.h"
#include "error.h"
#include "h5io.h"
#include "plants.h"
#include "rng.h"
#include "sim_input.h"
#include "sim_file_fixture.h"
#include "test_util.h"

using namespace eco;

using test::writeFakeSimulation;

namespace {

using eco::test::lineCount;

}  // namespace

TEST_CASE("eco analyse and eco inspect on a small simulation file", "[analysis][cli]") {
    eco::test::TempDir dir("cli");
    const std::string sim = dir.file("sim.h5");
    writeFakeSimulation(sim, dir.file("abiotics.h5"));
    const std::string db = dir.file("out/db.h5");
    const auto r = eco::test::runEco("analyse " + sim + " --out " + db + " --kmax 3");
    INFO(r.output);
    REQUIRE(r.exitCode == 0);
    CHECK_THAT(r.output, Catch::Contains("wrote biome database"));
    const BiomeDatabase d = readBiomeDatabase(db);
    CHECK(d.inputs.size() == 1);
    CHECK(d.inputs[0].seed == 42);
    CHECK(d.inputs[0].year == 10);
    CHECK(d.inputs[0].parameters.find("cell_size_m") != std::string::npos);
    CHECK(d.combinations.size() == 3);  // redwood disc, oak disc, and their overlap
    const auto ins = eco::test::runEco("inspect " + db + " --png " + dir.file("png"));
    INFO(ins.output);
    REQUIRE(ins.exitCode == 0);
    CHECK_THAT(ins.output, Catch::Contains("k = ") && Catch::Contains("leading species") && Catch::Contains("plants/m2"));
    CHECK(std::filesystem::exists(dir.file("png/region_0000_pcf.png")));
    CHECK(std::filesystem::exists(dir.file("png/region_0000_heights.png")));
}

TEST_CASE("eco analyse: bad input gives one clear line, a non-zero exit and no output", "[analysis][cli][errors]") {
    eco::test::TempDir dir("cli");
    const std::string ab = dir.file("abiotics.h5");
    writeFakeSimulation(dir.file("nox.h5"), ab, "x");
    const std::string db = dir.file("db.h5");
    auto r = eco::test::runEco("analyse " + dir.file("nox.h5") + " --year 20 --out " + db);
    CHECK(r.exitCode == 1);
    CHECK_THAT(r.output, Catch::Contains("eco: error: ") && Catch::Contains("nox.h5") && Catch::Contains("year_0020/x"));
    CHECK_FALSE(std::filesystem::exists(db));
    r = eco::test::runEco("analyse " + ab + " --out " + db);
    CHECK(r.exitCode == 1);
    CHECK_THAT(r.output, Catch::StartsWith("eco: error: ") && Catch::Contains("not a simulation file"));
    CHECK(lineCount(r.output) == 1);
    CHECK_FALSE(std::filesystem::exists(db));
    r = eco::test::runEco("inspect " + ab);
    CHECK(r.exitCode == 1);
    CHECK_THAT(r.output, Catch::Contains("not a biome database"));
    // A seeding disc so small that no cell is in a region: refused, nothing written (it wrote
    // a database of 0 regions).
    writeFakeSimulation(dir.file("sim0.h5"), dir.file("abiotics0.h5"));
    r = eco::test::runEco("analyse " + dir.file("sim0.h5") + " --out " + db + " --seeding-radius-factor 1e-9");
    CHECK(r.exitCode == 1);
    CHECK_THAT(r.output, Catch::Contains("no region") && Catch::Contains("nothing written"));
    CHECK_FALSE(std::filesystem::exists(db));
    // A pair-correlation range beyond the window (issue 26: 1e12 gave g = 0 everywhere and
    // exit 0; 1e6 ran out of memory) is refused with the largest usable value.
    writeFakeSimulation(dir.file("sim.h5"), dir.file("abiotics2.h5"));
    for (const char* rmax : {"1e12", "1e6", "500"}) {
        r = eco::test::runEco("analyse " + dir.file("sim.h5") + " --out " + db + " --rmax " + rmax);
        INFO(r.output);
        CHECK(r.exitCode == 1);
        CHECK_THAT(r.output, Catch::Contains("more than half the shorter side") && Catch::Contains("use at most"));
        // the input's summary line, then the error as one line; no progress: refused before any work
        CHECK(lineCount(r.output) == 2);
        CHECK_THAT(r.output, Catch::Contains("\neco: error: analyse: input 0"));
        CHECK_FALSE(std::filesystem::exists(db));
    }
}

TEST_CASE("eco analyse: one simulation file named twice is refused", "[analysis][cli][errors]") {
    // Given as "sim.h5 ./sim.h5" it counted twice: the database said twice the area and
    // plants (and two replicates) of one simulation, with exit 0.
    eco::test::TempDir dir("cli_twice");
    const std::string sim = dir.file("sim.h5");
    writeFakeSimulation(sim, dir.file("abiotics.h5"));
    const std::string other = (dir.path() / "." / "sim.h5").string();
    const std::string db = dir.file("db.h5");
    const auto r = eco::test::runEco("analyse " + sim + " " + other + " --out " + db + " --kmax 3");
    INFO(r.output);
    CHECK(r.exitCode == 1);
    CHECK_THAT(r.output, Catch::StartsWith("eco: error: ") && Catch::Contains("is given twice") && Catch::Contains(other));
    CHECK_FALSE(std::filesystem::exists(db));
    // Two different files are two simulations, as before.
    std::filesystem::copy_file(sim, dir.file("copy.h5"));
    const auto two = eco::test::runEco("--quiet analyse " + sim + " " + dir.file("copy.h5") + " --out " + db + " --kmax 3");
    INFO(two.output);
    CHECK(two.exitCode == 0);
}
