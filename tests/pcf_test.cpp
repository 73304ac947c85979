// The pair-correlation estimator of core/point_pattern: agreement with spatstat (fixtures
// made by tests/data/pcf/make_fixtures.R), g = 1 for Poisson, exact values on hand-made
// patterns, edge-correction weights against brute force, determinism (`eco pcf`:
// pcf_cli_test.cpp).
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

constexpr double kPi = 3.14159265358979323846;

/// The window of every fixture (see make_fixtures.R).
const RectWindow kFixtureWindow{10, 20, 110, 80};

struct RefRow {
    std::string from, to;
    double rLo, rHi, gTrans, gIso;
};

std::vector<RefRow> readReference(const std::string& path) {
    std::ifstream in(path);
    REQUIRE(in.good());
    std::string line;
    std::getline(in, line);  // header
    std::vector<RefRow> rows;
    while (std::getline(in, line)) {
        std::stringstream ss(line);
        std::string f[8];
        for (auto& s : f) std::getline(ss, s, ',');
        rows.push_back({f[0], f[1], std::stod(f[2]), std::stod(f[3]), std::stod(f[6]), std::stod(f[7])});
    }
    return rows;
}

std::string fixture(const std::string& name) { return eco::test::sourcePath("tests/data/pcf/" + name); }

/// Compare our estimator with spatstat's on one fixture. Both compute the same formula on
/// the same numbers, so they agree to rounding: tolerance 1e-9 relative (absolute near 0).
void compareWithSpatstat(const std::string& name) {
    const PointPattern p = readPointPatternCsv(fixture(name + "_points.csv"), &kFixtureWindow);
    const auto ref = readReference(fixture(name + "_spatstat.csv"));
    REQUIRE(!ref.empty());
    PcfOptions opt;
    opt.bins = DistanceBins{15.0, 30};
    const PairSums sums = countPairs(p, kFixtureWindow, opt);
    const PairSums all = sums.merged();
    std::map<std::string, int> typeOf;
    for (std::size_t t = 0; t < p.typeNames.size(); ++t) typeOf[p.typeNames[t]] = static_cast<int>(t);
    int compared = 0;
    for (const RefRow& r : ref) {
        const int k = static_cast<int>(std::lround(r.rLo / opt.bins.widthM()));
        REQUIRE(opt.bins.loM(k) == Approx(r.rLo).margin(1e-12));
        REQUIRE(opt.bins.hiM(k) == Approx(r.rHi).margin(1e-12));
        double gt, gi;
        if (r.from == "all" && typeOf.count("all") == 0) {
            gt = all.gTranslate(0, 0, k);
            gi = all.gIsotropic(0, 0, k);
        } else {
            REQUIRE(typeOf.count(r.from) == 1);
            REQUIRE(typeOf.count(r.to) == 1);
            gt = sums.gTranslate(typeOf[r.from], typeOf[r.to], k);
            gi = sums.gIsotropic(typeOf[r.from], typeOf[r.to], k);
        }
        INFO(name << " " << r.from << " -> " << r.to << " bin [" << r.rLo << ", " << r.rHi << ")");
        CHECK(gt == Approx(r.gTrans).epsilon(1e-9).margin(1e-12));
        CHECK(gi == Approx(r.gIso).epsilon(1e-9).margin(1e-12));
        ++compared;
    }
    CHECK(compared == static_cast<int>(ref.size()));
}

}  // namespace

TEST_CASE("g(r) agrees with spatstat (translate and isotropic) on Poisson, Thomas and hard-core patterns", "[pcf]") {
    compareWithSpatstat("poisson");
    compareWithSpatstat("thomas");
    compareWithSpatstat("hardcore");
}

TEST_CASE("cross-type g_ij agrees with spatstat Kcross on a two-type pattern", "[pcf]") {
    compareWithSpatstat("bivariate");
}

TEST_CASE("the fixtures show the expected shapes: clustered > 1, hard core = 0 below 2 m", "[pcf]") {
    PcfOptions opt;
    opt.bins = DistanceBins{15.0, 30};
    const auto thomas = countPairs(readPointPatternCsv(fixture("thomas_points.csv")), kFixtureWindow, opt);
    CHECK(thomas.gTranslate(0, 0, 1) > 3.0);  // 0.5-1 m: strongly clustered
    const auto hard = countPairs(readPointPatternCsv(fixture("hardcore_points.csv")), kFixtureWindow, opt);
    for (int k = 0; k < 4; ++k) CHECK(hard.pairCount[hard.index(0, 0, k)] == 0);
}

TEST_CASE("Poisson pattern: g(r) = 1 within 5 standard deviations in every bin", "[pcf][statistical]") {
    // 24,000 points of intensity 1 per m^2 in 200 x 120 m. For a Poisson process the count U
    // of unordered pairs in an annulus of area A has mean |W| A / 2 and variance about
    // |W| A / 2 + |W| A^2 (pairs sharing a point); each bin's g is tested at 5 sigma
    // (two-sided p ~ 6e-7 per bin, ~1e-5 over the 20 bins), on a fixed seed.
    const RectWindow w{0, 0, 200, 120};
    PointPattern p;
    p.typeNames = {"all"};
    RandomStream rng(12345, 1);
    const int n = 24000;
    for (int i = 0; i < n; ++i) {
        p.x.push_back(rng.uniform(w.x0, w.x1));
        p.y.push_back(rng.uniform(w.y0, w.y1));
        p.type.push_back(0);
    }
    PcfOptions opt;
    opt.bins = DistanceBins{10.0, 20};
    const PairSums s = countPairs(p, w, opt);
    for (int k = 0; k < opt.bins.count; ++k) {
        const double a = opt.bins.annulusAreaM2(k);
        const double mean = w.areaM2() * a / 2.0;
        const double sd = std::sqrt(w.areaM2() * a / 2.0 + w.areaM2() * a * a);
        INFO("bin " << k << " g_trans " << s.gTranslate(0, 0, k) << " g_iso " << s.gIsotropic(0, 0, k));
        CHECK(std::abs(s.gTranslate(0, 0, k) - 1.0) < 5.0 * sd / mean);
        CHECK(std::abs(s.gIsotropic(0, 0, k) - 1.0) < 5.0 * sd / mean);
    }
}

TEST_CASE("exact sums on a hand-made pattern in a small window (edge correction)", "[pcf]") {
    // Window 4 x 3 m; points (0.5, 1) and (1.5, 1) are 1 m apart; (0.5, 2.8) is >= 1.5 m from
    // both, outside rmax. Translation weight |W| / ((4 - 1)(3 - 0)) = 12 / 9 for both orders.
    // Isotropic: the circle of radius 1 around (0.5, 1) is cut by the left side at 0.5 m:
    // weight 2 pi / (2 pi - 2 acos(0.5)) = 1.5; around (1.5, 1) it lies inside: weight 1.
    const RectWindow w{0, 0, 4, 3};
    PointPattern p;
    p.typeNames = {"all"};
    p.x = {0.5, 1.5, 0.5};
    p.y = {1.0, 1.0, 2.8};
    p.type = {0, 0, 0};
    PcfOptions opt;
    opt.bins = DistanceBins{1.5, 3};
    const PairSums s = countPairs(p, w, opt);
    CHECK(s.pairCount[s.index(0, 0, 2)] == 2);
    CHECK(s.pairCount[s.index(0, 0, 0)] == 0);
    CHECK(s.pairCount[s.index(0, 0, 1)] == 0);
    CHECK(s.translateSum[s.index(0, 0, 2)] == Approx(2.0 * 12.0 / 9.0).epsilon(1e-14));
    CHECK(s.isotropicSum[s.index(0, 0, 2)] == Approx(2.5).epsilon(1e-14));
    const double norm = 3.0 * 2.0 / 12.0;  // n (n - 1) / |W|
    CHECK(s.normalisation(0, 0) == Approx(norm));
    const double annulus = kPi * (1.5 * 1.5 - 1.0);
    CHECK(s.gTranslate(0, 0, 2) == Approx((24.0 / 9.0) / (annulus * norm)).epsilon(1e-14));
    CHECK(s.gIsotropic(0, 0, 2) == Approx(2.5 / (annulus * norm)).epsilon(1e-14));
    // Typed: a -> b only.
    p.typeNames = {"a", "b"};
    p.type = {0, 1, 1};
    const PairSums t = countPairs(p, w, opt);
    CHECK(t.pairCount[t.index(0, 1, 2)] == 1);
    CHECK(t.pairCount[t.index(1, 0, 2)] == 1);
    CHECK(t.pairCount[t.index(0, 0, 2)] == 0);
    CHECK(t.isotropicSum[t.index(0, 1, 2)] == Approx(1.5));
    CHECK(t.isotropicSum[t.index(1, 0, 2)] == Approx(1.0));
    CHECK(t.normalisation(0, 1) == Approx(1.0 * 2.0 / 12.0));  // n_a n_b / |W|
    CHECK(t.normalisation(1, 1) == Approx(2.0 * 1.0 / 12.0));  // n_b (n_b - 1) / |W|
}

TEST_CASE("isotropic weight matches the fraction of the circle inside the window", "[pcf]") {
    const RectWindow w{0, 0, 10, 6};
    struct Case {
        double x, y, r;
    };
    // Interior, one side, two sides with the corner outside, corner inside the circle.
    for (const Case c : {Case{5, 3, 2}, Case{1, 3, 2}, Case{1.5, 1.5, 2}, Case{0.5, 0.7, 2.5}, Case{9.9, 5.8, 3}}) {
        const int steps = 2000000;
        int inside = 0;
        for (int i = 0; i < steps; ++i) {
            const double th = 2 * kPi * (i + 0.5) / steps;
            inside += w.contains(c.x + c.r * std::cos(th), c.y + c.r * std::sin(th));
        }
        INFO("point " << c.x << ", " << c.y << " r " << c.r);
        CHECK(isotropicWeight(w, c.x, c.y, c.r) == Approx(static_cast<double>(steps) / inside).epsilon(1e-5));
    }
}

TEST_CASE("set covariance of a cell window is exact: rectangle closed form and an L shape by brute force", "[pcf]") {
    const double cs = 0.5;
    Grid<std::int32_t> labels(12, 9, cs, 100.0, 200.0, -1);
    // Label 0: the 8 x 6 rectangle of cells at (2..9, 1..6); label 1: an L shape.
    for (int iy = 1; iy <= 6; ++iy)
        for (int ix = 2; ix <= 9; ++ix) labels(ix, iy) = 0;
    std::vector<std::pair<int, int>> lCells;
    for (int iy = 0; iy < 9; ++iy)
        for (int ix = 0; ix < 12; ++ix)
            if (labels(ix, iy) < 0 && (ix < 2 || iy == 8)) {
                labels(ix, iy) = 1;
                lCells.emplace_back(ix, iy);
            }
    const auto windows = CellWindow::fromLabels(labels, 2, 3.0);
    REQUIRE(windows.size() == 2);
    CHECK(windows[0].areaM2() == Approx(48 * cs * cs));
    CHECK(windows[1].areaM2() == Approx(static_cast<double>(lCells.size()) * cs * cs));
    RandomStream rng(7, 7);
    for (int trial = 0; trial < 200; ++trial) {
        const double dx = rng.uniform(-3.0, 3.0), dy = rng.uniform(-3.0, 3.0);
        // Rectangle: (w - |dx|)(h - |dy|).
        const double rect = std::max(0.0, 4.0 - std::abs(dx)) * std::max(0.0, 3.0 - std::abs(dy));
        CHECK(windows[0].overlapM2(dx, dy) == Approx(rect).margin(1e-12));
        // L shape: sum over cell pairs of the overlap of square a with square b shifted by u.
        double brute = 0;
        for (const auto& a : lCells)
            for (const auto& b : lCells) {
                const double ox = std::max(0.0, cs - std::abs((b.first - a.first) * cs + dx));
                const double oy = std::max(0.0, cs - std::abs((b.second - a.second) * cs + dy));
                brute += ox * oy;
            }
        CHECK(windows[1].overlapM2(dx, dy) == Approx(brute).margin(1e-12));
    }
}

TEST_CASE("PointGrid finds exactly the neighbours brute force finds", "[pcf]") {
    RandomStream rng(3, 3);
    std::vector<double> x, y;
    for (int i = 0; i < 3000; ++i) {
        x.push_back(rng.uniform(-50, 50));
        y.push_back(rng.uniform(0, 30));
    }
    const PointGrid grid(x, y, 1.7);
    for (int q = 0; q < 50; ++q) {
        const double qx = rng.uniform(-60, 60), qy = rng.uniform(-10, 40), r = rng.uniform(0.1, 6.0);
        std::vector<std::uint32_t> found;
        grid.forEachWithin(qx, qy, r, [&](std::size_t s, double, double, double) { found.push_back(grid.order()[s]); });
        std::sort(found.begin(), found.end());
        std::vector<std::uint32_t> expect;
        for (std::size_t i = 0; i < x.size(); ++i)
            if ((x[i] - qx) * (x[i] - qx) + (y[i] - qy) * (y[i] - qy) < r * r) expect.push_back(static_cast<std::uint32_t>(i));
        CHECK(found == expect);
    }
}

TEST_CASE("pair sums are bit-identical with 1 and 2 threads", "[pcf]") {
    const PointPattern p = readPointPatternCsv(fixture("bivariate_points.csv"));
    PcfOptions opt;
    opt.bins = DistanceBins{15.0, 30};
    const int before = omp_get_max_threads();
    omp_set_num_threads(1);
    const PairSums a = countPairs(p, kFixtureWindow, opt);
    omp_set_num_threads(2);
    const PairSums b = countPairs(p, kFixtureWindow, opt);
    omp_set_num_threads(before);
    CHECK(a.pairCount == b.pairCount);
    CHECK(a.translateSum == b.translateSum);  // exact, not approximate
    CHECK(a.isotropicSum == b.isotropicSum);
}

TEST_CASE("nearest-neighbour distances (FLANN kd-tree) equal brute force, for any thread count", "[pcf][nn]") {
    RandomStream rng(7, 3);
    std::vector<double> x, y;
    for (int i = 0; i < 3000; ++i) {
        x.push_back(50.0 * rng.uniform());
        y.push_back(20.0 * rng.uniform());
    }
    x.push_back(x[10]);  // a coincident pair: distance 0 for both
    y.push_back(y[10]);
    const auto d = nearestNeighbourDistances(x, y);
    REQUIRE(d.size() == x.size());
    for (std::size_t i = 0; i < x.size(); i += 7) {
        double best = std::numeric_limits<double>::infinity();
        for (std::size_t j = 0; j < x.size(); ++j)
            if (j != i) best = std::min(best, std::hypot(x[i] - x[j], y[i] - y[j]));
        INFO(i);
        CHECK(d[i] == Approx(best).margin(1e-12));
    }
    CHECK(d[10] == 0.0);
    CHECK(d.back() == 0.0);
    const int threads = omp_get_max_threads();
    omp_set_num_threads(1);
    const auto d1 = nearestNeighbourDistances(x, y);
    omp_set_num_threads(threads);
    CHECK(d1 == d);
    CHECK(std::isinf(nearestNeighbourDistances({1.0}, {2.0})[0]));
}

TEST_CASE("Clark-Evans index with Donnelly's correction agrees with spatstat's clarkevans", "[pcf][nn]") {
    // tests/data/pcf/clark_evans_spatstat.csv, written by tests/data/pcf/clark_evans.R.
    std::ifstream in(fixture("clark_evans_spatstat.csv"));
    REQUIRE(in.good());
    std::string line;
    std::getline(in, line);
    int rows = 0;
    while (std::getline(in, line)) {
        std::stringstream ss(line);
        std::string name, n, meanNn, index;
        std::getline(ss, name, ',');
        std::getline(ss, n, ',');
        std::getline(ss, meanNn, ',');
        std::getline(ss, index, ',');
        const PointPattern p = readPointPatternCsv(fixture(name + "_points.csv"), &kFixtureWindow);
        const ClarkEvans ce = clarkEvans(p.x, p.y, kFixtureWindow);
        INFO(name);
        CHECK(ce.n == std::stoul(n));
        CHECK(ce.meanNearestM == Approx(std::stod(meanNn)).epsilon(1e-12));
        CHECK(ce.index == Approx(std::stod(index)).epsilon(1e-12));
        ++rows;
    }
    CHECK(rows == 4);
    // The shapes: clustered < 1 < regular.
    const auto index = [&](const std::string& name) {
        const PointPattern p = readPointPatternCsv(fixture(name + "_points.csv"), &kFixtureWindow);
        return clarkEvans(p.x, p.y, kFixtureWindow).index;
    };
    CHECK(index("thomas") < 0.8);
    CHECK(index("hardcore") > 1.1);
    CHECK(std::isnan(clarkEvans({1.0}, {1.0}, kFixtureWindow).index));
}

TEST_CASE("bad input to the estimator: clear errors", "[pcf][errors]") {
    PointPattern p;
    p.typeNames = {"all"};
    p.x = {1, 2};
    p.y = {1, 2};
    p.type = {0, 0};
    PcfOptions opt;
    opt.bins = DistanceBins{2.5, 10};
    const RectWindow w{0, 0, 10, 4};
    CHECK_THROWS_WITH(countPairs(p, w, opt), Catch::Contains("rmax 2.5") && Catch::Contains("half the window's shorter side (2 m)"));
    opt.bins = DistanceBins{1.0, 10};
    p.x[1] = 11;
    CHECK_THROWS_WITH(countPairs(p, w, opt), Catch::Contains("point 1") && Catch::Contains("outside the window"));
    CHECK_THROWS_AS(countPairs(p, RectWindow{0, 0, -1, 1}, opt), ValidationError);
}

TEST_CASE("point CSV: species column, quoted fields, and errors naming file and line", "[pcf][errors]") {
    eco::test::TempDir dir("pcf");
    const std::string good = dir.file("good.csv");
    std::ofstream(good) << "id,x_m,y_m,species\n1,1.5,2.5,\"Toyon\"\n\n# comment\n2,3,4,Redwood Sorrel\n3,5,6,\"Toyon\"\n";
    const PointPattern p = readPointPatternCsv(good);
    REQUIRE(p.size() == 3);
    CHECK(p.typeNames == std::vector<std::string>{"Redwood Sorrel", "Toyon"});
    CHECK(p.type == std::vector<int>{1, 0, 1});
    CHECK(p.x[1] == 3.0);

    const std::string bad = dir.file("bad.csv");
    std::ofstream(bad) << "x,y\n1,2\n3,abc\n";
    CHECK_THROWS_WITH(readPointPatternCsv(bad), Catch::Contains("bad.csv:3:") && Catch::Contains("'abc'"));
    std::ofstream(bad) << "x,y\n1,2\n3,4,5\n";
    CHECK_THROWS_WITH(readPointPatternCsv(bad), Catch::Contains("bad.csv:3:") && Catch::Contains("expected 2 fields"));
    std::ofstream(bad) << "a,b\n1,2\n";
    CHECK_THROWS_WITH(readPointPatternCsv(bad), Catch::Contains("bad.csv:1:") && Catch::Contains("x and y"));
    std::ofstream(bad) << "x,y\n1,2\n50,2\n";
    const RectWindow w{0, 0, 10, 10};
    CHECK_THROWS_WITH(readPointPatternCsv(bad, &w), Catch::Contains("bad.csv:3:") && Catch::Contains("outside the window"));
    CHECK_THROWS_AS(readPointPatternCsv(dir.file("missing.csv")), IoError);
}
