// Procedural terrain, density sketch and CHM: determinism, thread independence and the
// properties the rest of the pipeline relies on.
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

namespace {

/// Same 468 m domain as the default at half the resolution, to keep tests quick.
eco::TerrainGenParams smallTerrain(std::uint64_t seed) {
    eco::TerrainGenParams p;
    p.width = 256;
    p.height = 200;  // non-square on purpose
    p.cellSizeM = 1.828;
    p.seed = seed;
    return p;
}

/// Runs f with exactly n OpenMP threads, restoring the previous setting.
template <typename F>
auto withThreads(int n, F f) {
    const int before = omp_get_max_threads();
    omp_set_num_threads(n);
    auto r = f();
    omp_set_num_threads(before);
    return r;
}

std::size_t countDifferent(const std::vector<float>& a, const std::vector<float>& b) {
    std::size_t n = 0;
    for (std::size_t i = 0; i < a.size(); ++i) n += a[i] != b[i];
    return n;
}

}  // namespace

// ---------------------------------------------------------------------------- terrain

TEST_CASE("generate: terrain is deterministic for a seed", "[generate]") {
    const Grid<float> a = eco::generateTerrain(smallTerrain(5));
    const Grid<float> b = eco::generateTerrain(smallTerrain(5));
    CHECK(a.data() == b.data());
    const Grid<float> c = eco::generateTerrain(smallTerrain(6));
    CHECK(countDifferent(a.data(), c.data()) > a.size() * 9 / 10);
}

TEST_CASE("generate: terrain, sketch and CHM do not depend on the thread count", "[generate]") {
    const auto p = smallTerrain(3);
    const Grid<float> t1 = withThreads(1, [&] { return eco::generateTerrain(p); });
    const Grid<float> t2 = withThreads(2, [&] { return eco::generateTerrain(p); });
    const Grid<float> t4 = withThreads(4, [&] { return eco::generateTerrain(p); });
    CHECK(t1.data() == t2.data());
    CHECK(t1.data() == t4.data());

    eco::SketchParams sp;
    sp.seed = 9;
    const auto s1 = withThreads(1, [&] { return eco::generateDensitySketch(t1, sp); });
    const auto s2 = withThreads(2, [&] { return eco::generateDensitySketch(t1, sp); });
    CHECK(s1.data() == s2.data());

    eco::ChmGenParams cp;
    cp.seed = 4;
    std::vector<eco::GeneratedTree> trees1, trees2;
    const auto c1 = withThreads(1, [&] { return eco::generateChm(s1, cp, trees1); });
    const auto c2 = withThreads(2, [&] { return eco::generateChm(s1, cp, trees2); });
    CHECK(c1.data() == c2.data());
    REQUIRE(trees1.size() == trees2.size());
    for (std::size_t i = 0; i < trees1.size(); ++i) {
        CHECK(trees1[i].x == trees2[i].x);
        CHECK(trees1[i].heightM == trees2[i].heightM);
    }
}

TEST_CASE("generate: default terrain has coastal-hill elevations at real scale", "[generate]") {
    const eco::TerrainGenParams p;  // 512 x 512 cells of 0.914 m
    const Grid<float> g = eco::generateTerrain(p);
    CHECK(g.width() == 512);
    CHECK(g.height() == 512);
    CHECK(g.cellSizeM() == 0.914);
    CHECK(g.extentX() == Approx(468.0).margin(0.1));
    CHECK(g.minValue() >= 40.0f);
    CHECK(g.maxValue() <= 320.0f);
    CHECK(g.maxValue() - g.minValue() >= 80.0f);  // hills, not a plain
    for (float v : g.data()) REQUIRE(std::isfinite(v));
}

TEST_CASE("generate: the creek lies below the ridges and drains out of the domain", "[generate]") {
    for (std::uint64_t seed : {1ull, 2ull, 3ull, 17ull}) {
        INFO("seed " << seed);
        const auto p = smallTerrain(seed);
        eco::TerrainFeatures features;
        const Grid<float> g = eco::generateTerrain(p, features);
        REQUIRE(features.creekPath.size() > 100);
        REQUIRE(features.creekPath.size() == features.creekBedM.size());

        // Both ends of the path lie outside the grid: the creek crosses the whole domain.
        auto insideBy = [&](const std::array<double, 2>& q, double marginM) {
            return q[0] >= g.originX() + marginM && q[0] <= g.originX() + g.extentX() - marginM &&
                   q[1] >= g.originY() + marginM && q[1] <= g.originY() + g.extentY() - marginM;
        };
        CHECK_FALSE(insideBy(features.creekPath.front(), 0.0));
        CHECK_FALSE(insideBy(features.creekPath.back(), 0.0));

        // Along the path the terrain equals the bed and descends monotonically.
        std::vector<double> along;
        double previous = std::numeric_limits<double>::infinity();
        for (std::size_t i = 0; i < features.creekPath.size(); ++i) {
            const auto& q = features.creekPath[i];
            if (!insideBy(q, 1.5 * p.cellSizeM)) continue;
            const double z = g.sampleBilinear(q[0], q[1]);
            REQUIRE(z == Approx(features.creekBedM[i]).margin(0.01));
            REQUIRE(z <= previous + 1e-3);
            previous = z;
            along.push_back(z);
        }
        REQUIRE(along.size() > 100);
        CHECK(along.front() - along.back() > 0.5 * p.creekDropM);
        for (std::size_t i = 1; i < features.creekBedM.size(); ++i)
            REQUIRE(features.creekBedM[i] < features.creekBedM[i - 1]);

        // The creek is below the ridges: ridge tops stand well above the highest bed.
        std::vector<float> sorted = g.data();
        std::sort(sorted.begin(), sorted.end());
        const double p90 = sorted[sorted.size() * 9 / 10];
        const double p50 = sorted[sorted.size() / 2];
        CHECK(p90 > along.front() + p.valleyDepthM);
        // Even where it enters (the bed falls creekDropM across the domain), the creek lies
        // below the median elevation.
        CHECK(along.front() < p50);
        CHECK(g.minValue() >= features.creekBedM.back() - 1e-3);

        // Steepest descent (D8) from the first creek cell inside the grid reaches an edge.
        const auto& start = *std::find_if(features.creekPath.begin(), features.creekPath.end(),
                                          [&](const auto& q) { return insideBy(q, 2.0 * p.cellSizeM); });
        int x = g.cellX(start[0]), y = g.cellY(start[1]);
        int steps = 0;
        while (x > 0 && y > 0 && x < g.width() - 1 && y < g.height() - 1 && steps < 100000) {
            int bx = x, by = y;
            double best = 0;
            for (int dy = -1; dy <= 1; ++dy)
                for (int dx = -1; dx <= 1; ++dx) {
                    if (!dx && !dy) continue;
                    const double drop = (g(x, y) - g(x + dx, y + dy)) / std::hypot(dx, dy);
                    if (drop > best) {
                        best = drop;
                        bx = x + dx;
                        by = y + dy;
                    }
                }
            if (bx == x && by == y) break;  // a pit: the creek would not drain
            x = bx;
            y = by;
            ++steps;
        }
        INFO("descent stopped at (" << x << ", " << y << ") after " << steps << " steps");
        CHECK((x == 0 || y == 0 || x == g.width() - 1 || y == g.height() - 1));
        CHECK(steps > g.width() / 4);
    }
}

TEST_CASE("generate: slopes face all four quadrants of aspect", "[generate]") {
    const auto p = smallTerrain(11);
    const Grid<float> g = eco::generateTerrain(p);
    std::array<long, 4> quadrant{};  // downslope towards NE, NW, SW, SE
    long sloped = 0;
    for (int iy = 1; iy < g.height() - 1; ++iy)
        for (int ix = 1; ix < g.width() - 1; ++ix) {
            const double dzdx = (g(ix + 1, iy) - g(ix - 1, iy)) / (2 * g.cellSizeM());
            const double dzdy = (g(ix, iy + 1) - g(ix, iy - 1)) / (2 * g.cellSizeM());
            if (std::hypot(dzdx, dzdy) < std::tan(2.0 * 3.141592653589793 / 180.0)) continue;
            ++sloped;
            const bool east = dzdx < 0, north = dzdy < 0;  // downslope direction
            quadrant[north ? (east ? 0 : 1) : (east ? 3 : 2)]++;
        }
    REQUIRE(sloped > static_cast<long>(g.size()) / 2);
    for (int q = 0; q < 4; ++q) {
        INFO("quadrant " << q << ": " << quadrant[q] << " of " << sloped);
        CHECK(quadrant[q] > sloped / 10);
    }
}

TEST_CASE("generate: invalid terrain parameters are refused by name", "[generate]") {
    auto p = smallTerrain(1);
    p.cellSizeM = 0;
    CHECK_THROWS_WITH(eco::generateTerrain(p), Catch::Contains("cellSizeM"));
    p = smallTerrain(1);
    p.width = 1;
    CHECK_THROWS_AS(eco::generateTerrain(p), eco::ValidationError);
    p = smallTerrain(1);
    p.creekDropM = 0;
    CHECK_THROWS_WITH(eco::generateTerrain(p), Catch::Contains("creekDropM"));
}

// ---------------------------------------------------------------------------- sketch

TEST_CASE("generate: density sketch meets its fractions", "[generate]") {
    struct Case {
        double empty, dense;
    };
    for (const Case c : {Case{0.2, 0.5}, Case{0.0, 1.0}, Case{0.33, 0.33}, Case{0.6, 0.1}, Case{0.0, 0.0}}) {
        INFO("empty " << c.empty << " dense " << c.dense);
        eco::SketchParams sp;
        sp.seed = 21;
        sp.emptyFraction = c.empty;
        sp.denseFraction = c.dense;
        const auto s = eco::generateDensitySketch(300, 170, 0.914, sp);
        REQUIRE(s.width() == 300);
        REQUIRE(s.height() == 170);
        std::array<double, 3> share{};
        for (auto v : s.data()) {
            REQUIRE((v == eco::Empty || v == eco::Sparse || v == eco::Dense));
            share[static_cast<std::size_t>(v)] += 1.0 / static_cast<double>(s.size());
        }
        const double tol = 1.5 / static_cast<double>(s.size());
        CHECK(share[eco::Empty] == Approx(c.empty).margin(tol));
        CHECK(share[eco::Dense] == Approx(c.dense).margin(tol));
        CHECK(share[eco::Sparse] == Approx(1.0 - c.empty - c.dense).margin(2 * tol));
    }
    eco::SketchParams bad;
    bad.emptyFraction = 0.7;
    bad.denseFraction = 0.5;
    CHECK_THROWS_WITH(eco::generateDensitySketch(10, 10, 1.0, bad), Catch::Contains("emptyFraction + denseFraction"));
}

TEST_CASE("generate: density sketch is smooth patches, deterministic, origin-independent", "[generate]") {
    eco::SketchParams sp;
    sp.seed = 2;
    const auto a = eco::generateDensitySketch(200, 200, 0.914, sp);
    const auto b = eco::generateDensitySketch(Grid<float>(200, 200, 0.914, 5000.0, -300.0), sp);
    CHECK(a.data() == b.data());
    CHECK(b.originX() == 5000.0);
    sp.seed = 3;
    const auto c = eco::generateDensitySketch(200, 200, 0.914, sp);
    CHECK(a.data() != c.data());
    // Patches, not salt-and-pepper: most horizontal neighbours share a level.
    long same = 0, pairs = 0;
    for (int iy = 0; iy < a.height(); ++iy)
        for (int ix = 0; ix + 1 < a.width(); ++ix) {
            same += a(ix, iy) == a(ix + 1, iy);
            ++pairs;
        }
    CHECK(same > pairs * 9 / 10);
}

TEST_CASE("generate: density sketch image round trip, grey levels and size check", "[generate]") {
    eco::test::TempDir dir("gen_sketch");
    eco::SketchParams sp;
    const Grid<float> like(90, 40, 2.0, 10.0, 20.0);
    const auto s = eco::generateDensitySketch(like, sp);
    const std::string path = dir.file("sketch.png");
    eco::writeDensitySketch(path, s);
    const auto r = eco::readDensitySketch(path, like);
    CHECK(r.data() == s.data());
    CHECK(r.sameGeometry(like));

    // A painted RGB(A) image: grey level = mean of the colour channels, row 0 = north.
    const std::string rgb = dir.file("painted.png");
    {
        const int w = 3, h = 2;
        // Top row: black, dark grey (0.3), mid grey (0.5); bottom row: 0.7 grey, white, red (mean 1/3).
        const float px[h][w][4] = {{{0, 0, 0, 1}, {0.3f, 0.3f, 0.3f, 1}, {0.5f, 0.5f, 0.5f, 1}},
                                   {{0.7f, 0.7f, 0.7f, 1}, {1, 1, 1, 0}, {1, 0, 0.01f, 1}}};
        REQUIRE(eco::test::writeImage(rgb, w, h, 4, eco::SampleType::UInt8, eco::SampleType::Float, &px[0][0][0]));
    }
    const auto painted = eco::readDensitySketch(rgb, Grid<float>(3, 2, 1.0));
    CHECK(painted(0, 1) == eco::Empty);   // NW black
    CHECK(painted(1, 1) == eco::Empty);   // 0.3
    CHECK(painted(2, 1) == eco::Sparse);  // 0.5
    CHECK(painted(0, 0) == eco::Dense);   // 0.7
    CHECK(painted(1, 0) == eco::Dense);   // white, alpha ignored
    CHECK(painted(2, 0) == eco::Sparse);  // red: mean just above 1/3

    // Wrong size: refused, never resampled.
    CHECK_THROWS_AS(eco::readDensitySketch(path, Grid<float>(91, 40, 2.0)), eco::ValidationError);
    CHECK_THROWS_WITH(eco::readDensitySketch(path, Grid<float>(40, 90, 2.0)),
                      Catch::Contains(path) && Catch::Contains("90 x 40") && Catch::Contains("40 x 90"));
    CHECK_THROWS_WITH(eco::readDensitySketch(dir.file("none.png"), like), Catch::Contains("none.png"));
}

// ---------------------------------------------------------------------------- CHM

namespace {

struct ChmFixture {
    Grid<std::int32_t> sketch;
    eco::ChmGenParams params;
    std::vector<eco::GeneratedTree> trees;
    Grid<float> chm;
    ChmFixture() {
        eco::SketchParams sp;
        sp.seed = 8;
        sketch = eco::generateDensitySketch(Grid<float>(400, 300, 0.914, 1000.0, 2000.0), sp);
        params.seed = 12;
        chm = eco::generateChm(sketch, params, trees);
    }
};

}  // namespace

TEST_CASE("generate: CHM is empty in Empty cells and denser in Dense than Sparse", "[generate]") {
    const ChmFixture f;
    REQUIRE(f.chm.sameGeometry(f.sketch));
    std::array<long, 3> cells{}, covered{}, treesPer{};
    for (int iy = 0; iy < f.chm.height(); ++iy)
        for (int ix = 0; ix < f.chm.width(); ++ix) {
            const auto level = f.sketch(ix, iy);
            cells[level]++;
            covered[level] += f.chm(ix, iy) > 0;
            if (level == eco::Empty) REQUIRE(f.chm(ix, iy) == 0.0f);
        }
    for (const auto& t : f.trees) {
        const int ix = f.sketch.cellX(t.x), iy = f.sketch.cellY(t.y);
        REQUIRE(f.sketch.inside(ix, iy));
        treesPer[f.sketch(ix, iy)]++;
    }
    const double area = f.chm.cellSizeM() * f.chm.cellSizeM();
    const double denseDensity = treesPer[eco::Dense] / (cells[eco::Dense] * area);
    const double sparseDensity = treesPer[eco::Sparse] / (cells[eco::Sparse] * area);
    INFO("trees per m2: dense " << denseDensity << ", sparse " << sparseDensity);
    CHECK(treesPer[eco::Empty] == 0);
    CHECK(covered[eco::Empty] == 0);
    CHECK(treesPer[eco::Dense] > 100);
    CHECK(treesPer[eco::Sparse] > 10);
    CHECK(denseDensity > 3.0 * sparseDensity);
    // About one tree per spacing^2 (dart throwing at 0.8 x spacing).
    CHECK(denseDensity == Approx(1.0 / (7.0 * 7.0)).epsilon(0.5));
    // Crown patches: most of the Dense area is under canopy, much less of the Sparse area.
    CHECK(static_cast<double>(covered[eco::Dense]) / cells[eco::Dense] > 0.6);
    CHECK(static_cast<double>(covered[eco::Sparse]) / cells[eco::Sparse] < 0.5);
}

TEST_CASE("generate: CHM trees follow the allometry, heights and spacing", "[generate]") {
    const ChmFixture f;
    REQUIRE(!f.trees.empty());
    double lo = 1e9, hi = 0;
    for (const auto& t : f.trees) {
        REQUIRE(t.heightM >= f.params.minHeightM);
        REQUIRE(t.heightM <= f.params.maxHeightM);
        REQUIRE(t.crownRadiusM == Approx(std::exp(-0.72 + 0.65 * std::log(t.heightM))));
        lo = std::min(lo, t.heightM);
        hi = std::max(hi, t.heightM);
        // The CHM under the trunk is close to the apex (within half a cell of it).
        const float z = f.chm(f.chm.cellX(t.x), f.chm.cellY(t.y));
        REQUIRE(z >= t.heightM - t.crownRadiusM);
        REQUIRE(z <= f.params.maxHeightM + 1e-3);
    }
    CHECK(hi - lo > 10.0);  // heights vary
    CHECK(f.chm.maxValue() <= f.params.maxHeightM + 1e-3f);
    // Lowest point of any crown: its rim, h - r(h), smallest for the shortest tree.
    const double lowestRim = f.params.minHeightM - eco::chmCrownRadiusM(f.params, f.params.minHeightM);
    for (float v : f.chm.data()) REQUIRE((v == 0.0f || v >= lowestRim - 1e-4));
    // Minimum trunk distance of the dart throwing.
    const double minDist = 0.8 * f.params.denseSpacingM;
    for (std::size_t i = 0; i < f.trees.size(); ++i)
        for (std::size_t j = i + 1; j < f.trees.size(); ++j) {
            const double d = std::hypot(f.trees[i].x - f.trees[j].x, f.trees[i].y - f.trees[j].y);
            REQUIRE(d >= minDist - 1e-9);
        }
}

TEST_CASE("generate: CHM is the max over sphere caps of its trees", "[generate]") {
    const ChmFixture f;
    // Brute force on a window.
    for (int iy = 100; iy < 130; ++iy)
        for (int ix = 200; ix < 230; ++ix) {
            double best = 0;
            const double x = f.chm.cellCentreX(ix), y = f.chm.cellCentreY(iy);
            for (const auto& t : f.trees) {
                const double d2 = (x - t.x) * (x - t.x) + (y - t.y) * (y - t.y);
                const double r = t.crownRadiusM;
                if (d2 < r * r) best = std::max(best, t.heightM - r + std::sqrt(r * r - d2));
            }
            REQUIRE(f.chm(ix, iy) == Approx(best).margin(1e-4));
        }
    // Determinism and seed dependence.
    std::vector<eco::GeneratedTree> again;
    CHECK(eco::generateChm(f.sketch, f.params, again).data() == f.chm.data());
    auto other = f.params;
    other.seed = 13;
    CHECK(eco::generateChm(f.sketch, other).data() != f.chm.data());
}

TEST_CASE("generate: CHM parameters are validated", "[generate]") {
    const Grid<std::int32_t> sketch(10, 10, 1.0, 0.0, 0.0, eco::Dense);
    eco::ChmGenParams p;
    p.minHeightM = 60;
    CHECK_THROWS_WITH(eco::generateChm(sketch, p), Catch::Contains("minHeightM"));
    p = {};
    p.denseSpacingM = -1;
    CHECK_THROWS_WITH(eco::generateChm(sketch, p), Catch::Contains("denseSpacingM"));
    Grid<std::int32_t> bad = sketch;
    bad(3, 4) = 7;
    CHECK_THROWS_WITH(eco::generateChm(bad, eco::ChmGenParams{}), Catch::Contains("(3, 4)"));
}
