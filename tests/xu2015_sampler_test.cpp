// Tests of the Xu et al. 2015 sampler (synth/xu2015_sampler.cpp, SynthMethod::Xu2015) and of
// its evaluation (validate/xu_evaluation.h): exemplars made here (a regular jittered grid,
// aggregated Thomas clusters, a random Poisson pattern) are synthesized over larger areas and
// compared with the paper's indices (density and Ripley's aggregation index, PCT.DEV) and with
// their pair correlation at short range, against a CSR pattern of the same density; the canopy
// and the cluster map on a terrain; thread identity; refusals. `eco synth --method xu2015` is
// tested in synth_cli_test.cpp.
#include <omp.h>

#include <catch2/catch.hpp>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <vector>

#include "param_table_check.h"
#include "point_pattern.h"
#include "rng.h"
#include "canopy_context.h"
#include "error.h"
#include "fidelity.h"
#include "synth_world_fixture.h"
#include "test_util.h"
#include "undergrowth.h"
#include "xu_evaluation.h"

using namespace eco;

namespace {

constexpr double kExemplarSide = 20.0;  // exemplar window 20 m x 20 m
const RectWindow kExemplarWindow{0, 0, kExemplarSide, kExemplarSide};

/// About 196 points: a 14 x 14 grid, each point jittered uniformly by +-jitter x the spacing.
PointPattern jitteredGrid(std::uint64_t seed, double jitter = 0.2) {
    PointPattern p;
    p.typeNames = {"a"};
    const int n = 14;
    const double s = kExemplarSide / n;
    RandomStream rs(seed, 11, 0);
    for (int j = 0; j < n; ++j)
        for (int i = 0; i < n; ++i) {
            p.x.push_back((i + 0.5) * s + rs.uniform(-jitter, jitter) * s);
            p.y.push_back((j + 0.5) * s + rs.uniform(-jitter, jitter) * s);
            p.type.push_back(0);
        }
    return p;
}

/// Thomas process: parents at `kappa` per m^2 (drawn in the window grown by 4 sigma), mu
/// children each, normal offsets of sd sigma; children outside the window dropped.
PointPattern thomas(std::uint64_t seed, double kappa = 0.05, double mu = 10, double sigma = 0.6) {
    PointPattern p;
    p.typeNames = {"a"};
    RandomStream rs(seed, 12, 0);
    const double m = 4 * sigma, a = (kExemplarSide + 2 * m) * (kExemplarSide + 2 * m);
    const int parents = static_cast<int>(std::lround(kappa * a));
    for (int k = 0; k < parents; ++k) {
        const double px = rs.uniform(-m, kExemplarSide + m), py = rs.uniform(-m, kExemplarSide + m);
        const int c = static_cast<int>(std::lround(mu * (0.5 + rs.uniform())));
        for (int i = 0; i < c; ++i) {
            const double x = px + sigma * rs.normal(), y = py + sigma * rs.normal();
            if (kExemplarWindow.contains(x, y)) {
                p.x.push_back(x);
                p.y.push_back(y);
                p.type.push_back(0);
            }
        }
    }
    return p;
}

/// n uniform points in `w`.
PointPattern poisson(std::uint64_t seed, std::size_t n, const RectWindow& w = kExemplarWindow) {
    PointPattern p;
    p.typeNames = {"a"};
    RandomStream rs(seed, 13, 0);
    for (std::size_t i = 0; i < n; ++i) {
        p.x.push_back(rs.uniform(w.x0, w.x1));
        p.y.push_back(rs.uniform(w.y0, w.y1));
        p.type.push_back(0);
    }
    return p;
}

RectWindow enlargement(int k) { return RectWindow{0, 0, k * kExemplarSide, k * kExemplarSide}; }

/// Pooled g(r) (translation correction) of the points in a window.
std::vector<double> pcf(const std::vector<double>& x, const std::vector<double>& y, const RectWindow& w, const DistanceBins& bins) {
    PointPattern p;
    p.typeNames = {"a"};
    for (std::size_t i = 0; i < x.size(); ++i)
        if (w.contains(x[i], y[i])) {
            p.x.push_back(x[i]);
            p.y.push_back(y[i]);
            p.type.push_back(0);
        }
    PcfOptions o;
    o.bins = bins;
    o.isotropic = false;
    const PairSums s = countPairs(p, w, o);
    std::vector<double> g;
    for (int k = 0; k < bins.count; ++k) g.push_back(s.gTranslate(0, 0, k));
    return g;
}

double rms(const std::vector<double>& a, const std::vector<double>& b) {
    double s = 0;
    for (std::size_t k = 0; k < a.size(); ++k) s += (a[k] - b[k]) * (a[k] - b[k]);
    return std::sqrt(s / static_cast<double>(a.size()));
}

}  // namespace


namespace {

synth::XuPattern grow(const PointPattern& ex, int k, std::uint64_t seed = 5, const synth::XuParams& params = {}) {
    return synth::synthesizeXuPattern(ex, kExemplarWindow, enlargement(k), params, seed);
}

struct Kind {
    const char* name;
    PointPattern pattern;
};
std::vector<Kind> kinds() { return {{"regular", jitteredGrid(1)}, {"aggregated", thomas(2)}, {"random", poisson(3, 200)}}; }

}  // namespace

// The paper's claim (PCT.DEV under 5 %) on its kinds of input, on the synthesized 3 x 3
// enlargement as a whole. Measured (seed 5): density 1.1 / 0.2 / 1.7 % and Ripley's index
// 3.5 / 11.9 / - % (regular / aggregated / random); the random exemplar's index is near 0
// (-0.09 m), where a PCT.DEV means nothing, so its synthesis is held to |index| < 0.1 m
// (measured 0.009 m). The bounds leave room for the 2-56 % seen over other exemplar seeds.
TEST_CASE("xu2015: a 3x3 enlargement keeps the density and Ripley's index of a regular, an aggregated and a random exemplar",
          "[xu2015]") {
    const DistanceBins bins{5.0, 20};
    for (const Kind& kd : kinds()) {
        const synth::XuPattern out = grow(kd.pattern, 3);
        const validate::XuIndices e = validate::xuIndices(kd.pattern.x, kd.pattern.y, kExemplarWindow, bins);
        const validate::XuIndices s = validate::xuIndices(out.x, out.y, enlargement(3), bins);
        const double devDensity = validate::pctDev(s.densityPerM2, e.densityPerM2);
        const double devRipley = validate::pctDev(s.ripleyIndexM, e.ripleyIndexM);
        INFO(kd.name << ": density " << e.densityPerM2 << " -> " << s.densityPerM2 << " (" << devDensity << " %), Ripley index "
                     << e.ripleyIndexM << " -> " << s.ripleyIndexM << " m (" << devRipley << " %)");
        CHECK(devDensity < 5.0);
        if (std::string(kd.name) == "regular") CHECK(devRipley < 10.0);
        if (std::string(kd.name) == "aggregated") {
            CHECK(devRipley < 45.0);
            CHECK(s.ripleyIndexM > 0.3);  // clearly aggregated (CSR: 0)
        }
        if (std::string(kd.name) == "random") CHECK(std::abs(s.ripleyIndexM) < 0.1);
    }
}

// g(r) to 2 m in 0.25 m bins, RMS against the exemplar's. Measured (seed 5): regular 0.19
// (CSR 0.70), aggregated 0.73 (CSR 2.72).
TEST_CASE("xu2015: the synthesis reproduces a clustered and a regular exemplar's g(r) at short range, CSR does not",
          "[xu2015]") {
    const DistanceBins gb{2.0, 8};
    struct Case {
        PointPattern pattern;
        double bound;
    };
    for (const Case& c : {Case{jitteredGrid(1), 0.35}, Case{thomas(2), 1.2}}) {
        const synth::XuPattern out = grow(c.pattern, 3);
        const auto gE = pcf(c.pattern.x, c.pattern.y, kExemplarWindow, gb);
        const auto gS = pcf(out.x, out.y, enlargement(3), gb);
        const PointPattern csr = poisson(9, out.x.size(), enlargement(3));
        const auto gC = pcf(csr.x, csr.y, enlargement(3), gb);
        INFO("RMS g synthesis " << rms(gS, gE) << ", CSR " << rms(gC, gE) << ", bound " << c.bound);
        CHECK(rms(gS, gE) < c.bound);
        CHECK(rms(gC, gE) > c.bound);
        // The regular exemplar's hard core (no pair below 0.975 m) holds in the synthesis.
        if (c.bound < 1) CHECK(gS[0] + gS[1] + gS[2] == 0.0);
    }
}

TEST_CASE("xu2015: the same bytes with 1 and 2 threads, tiles or not", "[xu2015]") {
    const PointPattern ex = thomas(2);
    for (double tile : {0.0, 20.0}) {
        synth::XuParams params;
        params.tileM = tile;
        std::vector<synth::XuPattern> runs;
        const int before = omp_get_max_threads();
        for (int threads : {1, 2}) {
            omp_set_num_threads(threads);
            runs.push_back(grow(ex, 3, 11, params));
        }
        omp_set_num_threads(before);
        INFO("tile " << tile << " m: " << runs[0].x.size() << " plants in " << runs[0].tiles << " tiles");
        REQUIRE(runs[0].x.size() == runs[1].x.size());
        REQUIRE(!runs[0].x.empty());
        CHECK(std::memcmp(runs[0].x.data(), runs[1].x.data(), runs[0].x.size() * sizeof(double)) == 0);
        CHECK(std::memcmp(runs[0].y.data(), runs[1].y.data(), runs[0].y.size() * sizeof(double)) == 0);
        CHECK(runs[0].source == runs[1].source);
        CHECK(runs[0].tiles == (tile > 0 ? 9 : 1));
        // Another seed, another pattern.
        CHECK(grow(ex, 3, 12, params).x != runs[0].x);
    }
}

TEST_CASE("xu2015: on a terrain, no plant where the cluster map has no region, on a trunk, or as tall as the crown above",
          "[xu2015]") {
    const test::World w = test::makeWorld();
    const Biome& b = w.biome;
    // The western half of the plot has no region; the rest is region 0 (combination 1).
    synth::ClusterMap map;
    map.combination = Grid<std::int32_t>::like(w.terrain, 1);
    map.region = Grid<std::int32_t>::like(w.terrain, 0);
    map.seedWeight = Grid<float>::like(w.terrain, 1.0f);
    for (int iy = 0; iy < w.terrain.height(); ++iy)
        for (int ix = 0; ix < w.terrain.width() / 2; ++ix) map.region(ix, iy) = -1;
    // Exemplar: a jittered grid of Western Swordferns, all 50 m tall (taller than every crown).
    synth::XuExemplar ex;
    ex.window = kExemplarWindow;
    ex.source = "test exemplar";
    const PointPattern grid = jitteredGrid(4);
    for (std::size_t i = 0; i < grid.size(); ++i) {
        Plant p;
        p.speciesId = b.speciesIndex("Western Swordfern");
        p.xM = grid.x[i];
        p.yM = grid.y[i];
        p.heightM = 50.0;
        p.crownRadiusM = 0.5;
        ex.plants.push_back(p);
    }
    synth::SynthParams params;
    params.method = synth::SynthMethod::Xu2015;
    params.seed = 3;
    params.trunkExclusionFactor = 0.5;
    const synth::UndergrowthSample s = synth::sampleUndergrowth(w.db, b, w.canopy, map, w.terrain, params, nullptr, &ex);
    REQUIRE(s.plants.size() > 1000);
    INFO(s.plants.size() << " plants; dropped " << s.xuDroppedOutsideRegion << " outside a region, " << s.xuDroppedOnTrunk
                         << " on trunks; " << s.heightsLimitedByCrown << " heights drawn below a crown");
    CHECK(s.xuDroppedOutsideRegion > 0);
    CHECK(s.xuDroppedOnTrunk > 0);
    CHECK(s.heightsLimitedByCrown > 0);
    const CanopyCover cover(w.canopy);
    std::size_t west = 0, onTrunk = 0, tooTall = 0, copied = 0;
    for (const Plant& p : s.plants) {
        if (map.region(w.terrain.cellX(p.xM), w.terrain.cellY(p.yM)) < 0) ++west;
        for (const Plant& t : w.canopy)
            if (std::hypot(p.xM - t.xM, p.yM - t.yM) < params.trunkExclusionFactor * t.crownRadiusM) ++onTrunk;
        const double limit = cover.lowestCrownAboveM(p.xM, p.yM);
        if (!(p.heightM < limit)) ++tooTall;
        if (p.heightM == 50.0) ++copied;
    }
    CHECK(west == 0);
    CHECK(onTrunk == 0);
    CHECK(tooTall == 0);
    // In the open the exemplar's sizes are kept; under a crown they are drawn below it.
    CHECK(copied > 0);
    CHECK(copied + static_cast<std::size_t>(s.heightsLimitedByCrown) == s.plants.size());
}

TEST_CASE("xu2015: bad exemplars and parameters are refused with the exemplar and the value named", "[xu2015][errors]") {
    auto refused = [](const PointPattern& p, const RectWindow& w, const std::string& what) {
        try {
            synth::synthesizeXuPattern(p, w, enlargement(3), synth::XuParams{}, 1, "exemplar 'stand.csv'");
        } catch (const ValidationError& e) {
            INFO(e.what());
            CHECK_THAT(e.what(), Catch::Contains("stand.csv") && Catch::Contains(what));
            return;
        }
        FAIL("not refused: " << what);
    };
    refused(poisson(1, 1), kExemplarWindow, "1 plants");
    PointPattern outside = poisson(1, 50);
    outside.x[7] = 25.0;
    refused(outside, kExemplarWindow, "outside its window");
    // 200 plants on 20 m x 2 m: the neighbourhood disc fits nowhere inside.
    refused(poisson(1, 200, RectWindow{0, 0, 20, 2}), RectWindow{0, 0, 20, 2}, "too small");
    synth::XuParams bad;
    bad.shells = 0;
    CHECK_THROWS_WITH(bad.validate(), Catch::Contains("xu_shells"));
    const test::World w = test::makeWorld();
    synth::ClusterMap map;
    map.combination = Grid<std::int32_t>::like(w.terrain, 1);
    map.region = Grid<std::int32_t>::like(w.terrain, 0);
    map.seedWeight = Grid<float>::like(w.terrain, 1.0f);
    synth::SynthParams params;
    params.method = synth::SynthMethod::Xu2015;
    CHECK_THROWS_WITH(synth::sampleUndergrowth(w.db, w.biome, w.canopy, map, w.terrain, params),
                      Catch::Contains("needs an exemplar"));
    synth::XuExemplar ex;
    params.method = synth::SynthMethod::Structured;
    CHECK_THROWS_WITH(synth::sampleUndergrowth(w.db, w.biome, w.canopy, map, w.terrain, params, nullptr, &ex),
                      Catch::Contains("'xu2015' method only"));
}

TEST_CASE("xu2015: parameters documented and recorded, the method's name", "[xu2015]") {
    test::checkParamTable(
        synth::xuParamFields(), "docs/synth.md", [](const synth::XuParams& d) { d.validate(); },
        [](const synth::XuParams& d) { return d.asParameters(); }, 10);
    CHECK(synth::parseSynthMethod("xu2015") == synth::SynthMethod::Xu2015);
    CHECK(std::string(synth::toString(synth::SynthMethod::Xu2015)) == "xu2015");
    // Recorded only with the Xu 2015 method, so the other methods' scene files stay as they were.
    synth::SynthParams params;
    auto hasKey = [](const synth::SynthParams& q) {
        for (const auto& [k, v] : q.asParameters())
            if (k == "xu_sigma") return true;
        return false;
    };
    CHECK_FALSE(hasKey(params));
    params.method = synth::SynthMethod::Xu2015;
    CHECK(hasKey(params));
}

// The docs' table (docs/synth.md 2d): M = 15 x 15 exemplar areas synthesized, 10 patches
// of 3 x 3, 6 x 6 and 10 x 10 drawn from it, as the paper does. About 5 s.
TEST_CASE("xu2015: PCT.DEV table of the paper's evaluation", "[.xu-table]") {
    const DistanceBins bins{5.0, 20};
    for (const Kind& kd : kinds()) {
        const auto t0 = std::chrono::steady_clock::now();
        const synth::XuPattern out = grow(kd.pattern, 15);
        const double secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
        const validate::XuEvaluation ev = validate::evaluateXu(kd.pattern.x, kd.pattern.y, kExemplarWindow, out.x, out.y, enlargement(15), bins);
        std::printf("%s: exemplar %zu plants, density %.4f, Ripley %.4f m; M %zu plants in %.2f s (R %.3f m, %lld extensions, %lld from empty spots, %lld conflicts)\n",
                    kd.name, kd.pattern.size(), ev.exemplar.densityPerM2, ev.exemplar.ripleyIndexM, out.x.size(), secs, out.radiusM,
                    static_cast<long long>(out.extensions), static_cast<long long>(out.holeSeeds), static_cast<long long>(out.conflicts));
        for (const auto& e : ev.enlargements)
            std::printf("  %dx%d: density %.4f (PCT.DEV %.2f %%), Ripley %.4f m (PCT.DEV %.2f %%)\n", e.factor, e.factor,
                        e.mean.densityPerM2, e.pctDevDensity, e.mean.ripleyIndexM, e.pctDevRipley);
        std::printf("  mean over the three: density %.2f %%, Ripley %.2f %%\n", ev.meanPctDevDensity, ev.meanPctDevRipley);
    }
}
