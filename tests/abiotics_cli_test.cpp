// Command-line tests of `eco` for the abiotics module (split from abiotics_test.cpp, issue 23):
// they run the eco binary (ECO_BINARY) and live in eco_cli_tests, apart from the unit tests.
#include <omp.h>

#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <string>
#include <vector>

#include "abiotics.h"
#include "error.h"
#include "h5io.h"
#include "terrain_io.h"
#include "test_util.h"

using namespace eco;

namespace {

/// A grid filled from a function of world (x, y) at the cell centres.
template <class F>
Grid<float> makeTerrain(int w, int h, double cell, F f, double ox = 0, double oy = 0) {
    Grid<float> g(w, h, cell, ox, oy);
    for (int iy = 0; iy < h; ++iy)
        for (int ix = 0; ix < w; ++ix) g(ix, iy) = static_cast<float>(f(g.cellCentreX(ix), g.cellCentreY(iy)));
    return g;
}

/// Rough hills with pits and a ridge: exercises every code path of the sweeps and routing.
Grid<float> roughTerrain(int w, int h, double cell) {
    return makeTerrain(w, h, cell, [](double x, double y) {
        return 40 + 12 * std::sin(0.11 * x) * std::cos(0.07 * y) + 6 * std::sin(0.31 * x + 0.17 * y) +
               3 * std::cos(0.53 * y - 0.2 * x) - 15 * std::exp(-((x - 50) * (x - 50) + (y - 30) * (y - 30)) / 40.0);
    });
}

/// Restores the OpenMP thread count at scope exit.
struct ThreadCountGuard {
    int saved = omp_get_max_threads();
    ~ThreadCountGuard() { omp_set_num_threads(saved); }
};

}  // namespace

TEST_CASE("abiotics: the eco abiotics command writes the maps and pictures", "[abiotics][cli]") {
    test::TempDir dir("abiotics_cli");
    const std::string terrain = dir.file("terrain.asc");
    writeAsc(terrain, roughTerrain(31, 22, 2.0));
    const std::string out = dir.file("abiotics.h5");
    const std::string png = dir.file("png");
    const auto r = test::runEco("--threads 2 abiotics --terrain '" + terrain + "' --out '" + out + "' --png '" + png +
                                "' --sun-step 30");
    INFO(r.output);
    REQUIRE(r.exitCode == 0);
    REQUIRE(r.output.find(out) != std::string::npos);
    const Abiotics a = readAbiotics(out);
    REQUIRE(a.sunHours[0].width() == 31);
    REQUIRE(a.sunHours[0].height() == 22);
    for (const char* name : {"elevation.png", "slope.png", "sun_01_jan.png", "sun_12_dec.png", "moisture_07_jul.png",
                             "temperature_06_jun.png"})
        REQUIRE(std::filesystem::exists(png + "/" + name));
    REQUIRE(h5::File::openRead(out).attrDouble("/", "sun_step_minutes") == 30.0);
}

TEST_CASE("abiotics: the eco abiotics command rejects bad input with one clear line", "[abiotics][cli]") {
    test::TempDir dir("abiotics_cli_bad");
    const std::string tiny = dir.file("tiny.asc");
    writeAsc(tiny, Grid<float>(2, 2, 1.0, 0, 0, 5.f));
    auto r = test::runEco("abiotics --terrain '" + tiny + "' --out '" + dir.file("a.h5") + "'");
    REQUIRE(r.exitCode == 1);
    REQUIRE(r.output.find("at least 3 x 3") != std::string::npos);
    REQUIRE(r.output.find(tiny) != std::string::npos);
    REQUIRE(!std::filesystem::exists(dir.file("a.h5")));

    r = test::runEco("abiotics --terrain '" + dir.file("nope.asc") + "' --out '" + dir.file("a.h5") + "'");
    REQUIRE(r.exitCode == 1);
    REQUIRE(r.output.find("nope.asc") != std::string::npos);

    r = test::runEco("abiotics --out '" + dir.file("a.h5") + "'");
    REQUIRE(r.exitCode != 0);
    REQUIRE(r.output.find("--terrain") != std::string::npos);

    const std::string ok = dir.file("ok.asc");
    writeAsc(ok, roughTerrain(8, 6, 1.0));
    r = test::runEco("abiotics --terrain '" + ok + "' --out '" + dir.file("a.h5") + "' --sun-step 0");
    REQUIRE(r.exitCode != 0);
    r = test::runEco("abiotics --terrain '" + ok + "' --out '" + dir.file("missing_dir/a.h5") + "'");
    REQUIRE(r.exitCode == 1);
    REQUIRE(r.output.find("missing_dir") != std::string::npos);
}
