// Command-line tests of `eco` for the generate module (split from generate_test.cpp, issue 23):
// they run the eco binary (ECO_BINARY) and live in eco_cli_tests, apart from the unit tests.
#include <omp.h>

#include <catch2/catch.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <filesystem>
#include <limits>
#include <vector>

#include "error.h"
#include "generate.h"
#include "test_util.h"

using eco::Grid;

// ---------------------------------------------------------------------------- terrain

TEST_CASE("generate: CLI terrain generate and chm generate", "[generate]") {
    eco::test::TempDir dir("gen_cli");
    const std::string terrain = dir.file("t.h5");
    auto r = eco::test::runEco("terrain generate --out " + terrain + " --width 128 --height 96 --cell-size 2 --seed 4");
    INFO(r.output);
    REQUIRE(r.exitCode == 0);
    CHECK(r.output.find(terrain) != std::string::npos);
    const std::string chm = dir.file("chm.h5");
    r = eco::test::runEco("chm generate --terrain " + terrain + " --out " + chm + " --sketch-seed 3 --seed 2");
    INFO(r.output);
    REQUIRE(r.exitCode == 0);
    CHECK(r.output.find(chm) != std::string::npos);
    CHECK(std::filesystem::exists(chm));

    // Image output: the printed vertical scale reads it back.
    const std::string png = dir.file("t.png");
    r = eco::test::runEco("terrain generate --out " + png + " --width 64 --height 48 --cell-size 4");
    REQUIRE(r.exitCode == 0);
    CHECK(r.output.find("--vertical-scale") != std::string::npos);

    // Mutually exclusive sketch options.
    r = eco::test::runEco("chm generate --terrain " + terrain + " --out " + dir.file("x.h5") +
                          " --sketch a.png --sketch-seed 3");
    CHECK(r.exitCode != 0);
    CHECK_FALSE(std::filesystem::exists(dir.file("x.h5")));
}
