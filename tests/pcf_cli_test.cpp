// Command-line tests of `eco` for the pcf module (split from pcf_test.cpp, issue 23):
// they run the eco binary (ECO_BINARY) and live in eco_cli_tests, apart from the unit tests.
#include <catch2/catch.hpp>
#include <omp.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <sstream>

#include "error.h"
#include "point_pattern.h"
#include "rng.h"
#include "test_util.h"

using namespace eco;

namespace {

std::string fixture(const std::string& name) { return eco::test::sourcePath("tests/data/pcf/" + name); }

}  // namespace

TEST_CASE("eco pcf writes CSV and PNG that match the library", "[pcf][cli]") {
    eco::test::TempDir dir("pcfcli");
    const std::string out = dir.file("g.csv");
    const auto r = eco::test::runEco("pcf " + fixture("bivariate_points.csv") + " --window 10,20,110,80 --rmax 15 --bins 30 --out " + out);
    INFO(r.output);
    REQUIRE(r.exitCode == 0);
    REQUIRE(std::filesystem::exists(out));
    REQUIRE(std::filesystem::exists(dir.file("g.png")));
    std::ifstream in(out);
    std::string line;
    // One header line (a leading comment line broke R's read.csv and pandas), the window in
    // every row.
    std::getline(in, line);
    CHECK(line == "from,to,r_lo,r_hi,r_mid,pair_count,translate_weighted,normalisation_per_m2,g_trans,g_iso,"
                  "window_x0,window_y0,window_x1,window_y1");
    in.close();
    const auto rows = eco::test::readCsvRows(out);
    CHECK(rows.size() == 5 * 30);  // 4 ordered type pairs + the unmarked pattern
    for (const auto& row : rows) {
        REQUIRE(row.count("<fields>") == 0);
        CHECK(row.at("window_x0") == "10");
        CHECK(row.at("window_y1") == "80");
        CHECK(!row.at("g_trans").empty());
    }
}

TEST_CASE("eco pcf: bad input gives one clear error line and a non-zero exit", "[pcf][cli][errors]") {
    eco::test::TempDir dir("pcfcli");
    const std::string csv = dir.file("pts.csv");
    const std::string out = dir.file("g.csv");
    std::ofstream(csv) << "x,y\n1,1\n2,2\n3,x3\n";
    auto r = eco::test::runEco("pcf " + csv + " --window 0,0,10,10 --rmax 2 --out " + out);
    CHECK(r.exitCode == 1);
    CHECK_THAT(r.output, Catch::StartsWith("eco: error: ") && Catch::Contains("pts.csv:4:"));
    CHECK_FALSE(std::filesystem::exists(out));

    std::ofstream(csv) << "x,y\n1,1\n2,2\n30,3\n";
    r = eco::test::runEco("pcf " + csv + " --window 0,0,10,10 --rmax 2 --out " + out);
    CHECK(r.exitCode == 1);
    CHECK_THAT(r.output, Catch::Contains("pts.csv:4:") && Catch::Contains("outside the window"));

    std::ofstream(csv) << "x,y\n1,1\n2,2\n";
    r = eco::test::runEco("pcf " + csv + " --window 0,0,10,4 --rmax 3 --out " + out);
    CHECK(r.exitCode == 1);
    CHECK_THAT(r.output, Catch::Contains("rmax 3") && Catch::Contains("half the window's shorter side"));
    CHECK_FALSE(std::filesystem::exists(out));

    r = eco::test::runEco("pcf " + csv + " --window 0,0,10 --out " + out);
    CHECK(r.exitCode != 0);
    CHECK_THAT(r.output, Catch::Contains("window"));
}
