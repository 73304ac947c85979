// Command-line tests of `eco` for the pcf module (split from pcf_test.cpp, issue 23):
// they run the eco binary (ECO_BINARY) and live in eco_cli_tests, apart from the unit tests.
#include <catch2/catch.hpp>
#include <omp.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <limits>
#include <map>
#include <sstream>

#include "error.h"
#include "image_out.h"
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

TEST_CASE("eco pcf plots every type pair, beyond twelve", "[pcf][cli]") {
    // Five types: 15 unordered pairs (the plot used to stop at the first 12 alphabetically).
    eco::test::TempDir dir("pcfcli");
    const std::string csv = dir.file("five.csv");
    {
        std::ofstream f(csv);
        f << "x,y,species\n";
        const char* names[] = {"alder", "birch", "cedar", "dogwood", "elm"};
        std::uint64_t state = 12345;
        for (int i = 0; i < 500; ++i) {
            state = state * 6364136223846793005ULL + 1442695040888963407ULL;
            const double x = static_cast<double>(state >> 11) / 9007199254740992.0 * 50;
            state = state * 6364136223846793005ULL + 1442695040888963407ULL;
            const double y = static_cast<double>(state >> 11) / 9007199254740992.0 * 50;
            f << x << "," << y << "," << names[i % 5] << "\n";
        }
    }
    const auto r = eco::test::runEco("pcf " + csv + " --window 0,0,50,50 --rmax 8 --bins 16 --out " + dir.file("g.csv"));
    INFO(r.output);
    REQUIRE(r.exitCode == 0);
    int w = 0, h = 0;
    const auto px = eco::test::readPngRgb(dir.file("g.png"), w, h);
    // Each pair's curve is drawn in its own categoryColour (0..14) without blending: all 15
    // are in the picture, and so is the pooled curve's black.
    for (int i = 0; i < 15; ++i) {
        const Rgb c = categoryColour(i);
        const int cr = static_cast<int>(std::lround(c[0] * 255)), cg = static_cast<int>(std::lround(c[1] * 255)),
                  cb = static_cast<int>(std::lround(c[2] * 255));
        int count = 0;
        for (std::size_t k = 0; k + 2 < px.size(); k += 3)
            count += px[k] == cr && px[k + 1] == cg && px[k + 2] == cb;
        INFO("pair " << i);
        CHECK(count > 20);
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

TEST_CASE("eco pcf: a window in UTM coordinates is printed in full", "[pcf][cli]") {
    // It printed "in window 5.451e+05,4.26e+06,5.452e+05,4.26e+06": four digits of a northing.
    eco::test::TempDir dir("pcfutm");
    const std::string csv = dir.file("utm.csv");
    {
        std::ofstream f(csv);
        f << "x,y\n" << std::setprecision(10);
        eco::RandomStream rng(3, 0);
        for (int i = 0; i < 200; ++i) f << 545100.0 + 120.0 * rng.uniform() << "," << 4260060.0 + 120.0 * rng.uniform() << "\n";
    }
    const auto r = eco::test::runEco("pcf " + csv + " --window 545100,4260060,545220,4260180 --out " + dir.file("g.csv"));
    INFO(r.output);
    REQUIRE(r.exitCode == 0);
    CHECK_THAT(r.output, Catch::Contains("in window 545100,4260060,545220,4260180 (1.44e+04 m2)"));
}
