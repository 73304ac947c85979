// The analyser (analysis/): canopy masks and combination labels, k-means and the choice of
// k, exact counts / proportions / histograms / pair sums on hand-made patterns, pooling of
// several inputs, determinism across thread counts, simulation files (the CLI:
// analysis_cli_test.cpp).
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
#include "param_table_check.h"
#include "plants.h"
#include "rng.h"
#include "sim_file.h"
#include "sim_input.h"
#include "sim_file_fixture.h"
#include "test_util.h"

using namespace eco;

namespace {

const Biome& sonoma() {
    static const Biome b = defaultBiome();
    return b;
}

int sp(const std::string& name) { return sonoma().speciesIndex(name); }

Plant plant(const std::string& species, double x, double y, double h, double r) {
    Plant p;
    p.speciesId = sp(species);
    p.xM = x;
    p.yM = y;
    p.heightM = h;
    p.crownRadiusM = r;
    return p;
}

/// An input on a w x h grid of 1 m cells at the origin, constant abiotics, window = grid.
analysis::AnalysisInput flatInput(int w, int h) {
    analysis::AnalysisInput in;
    in.biome = &sonoma();
    in.features = FactorGrids::uniform(Grid<float>(w, h, 1.0), {10, 100, 15, 5});
    in.window = RectWindow{0, 0, static_cast<double>(w), static_cast<double>(h)};
    in.provenance.path = "memory";
    return in;
}

/// Well-separated Gaussian blobs in 4-D (sd 0.15, centres >= 4 apart).
std::vector<Features> blobs(int nBlobs, int perBlob, std::uint64_t seed, std::vector<Features>* centres = nullptr) {
    RandomStream rng(seed, 1);
    std::vector<Features> pts, cs;
    for (int b = 0; b < nBlobs; ++b) {
        Features c{};
        for (std::size_t f = 0; f < kFactorCount; ++f) c[f] = 4.0 * ((b >> f) & 1) + (f == 0 ? 4.0 * (b >> 2) : 0.0);
        cs.push_back(c);
        for (int i = 0; i < perBlob; ++i) {
            Features p = c;
            for (double& v : p) v += 0.15 * rng.normal();
            pts.push_back(p);
        }
    }
    if (centres) *centres = cs;
    return pts;
}

/// Every numeric field of two databases, exactly.
void requireIdentical(const BiomeDatabase& a, const BiomeDatabase& b) {
    REQUIRE(a.combinations.size() == b.combinations.size());
    for (std::size_t c = 0; c < a.combinations.size(); ++c) {
        CHECK(a.combinations[c].mask == b.combinations[c].mask);
        CHECK(a.combinations[c].k == b.combinations[c].k);
        CHECK(a.combinations[c].featureMean == b.combinations[c].featureMean);
        CHECK(a.combinations[c].featureStd == b.combinations[c].featureStd);
    }
    REQUIRE(a.regions.size() == b.regions.size());
    for (std::size_t r = 0; r < a.regions.size(); ++r) {
        const DbRegion& x = a.regions[r];
        const DbRegion& y = b.regions[r];
        CHECK(x.centroidNormalised == y.centroidNormalised);
        CHECK(x.areaM2 == y.areaM2);
        CHECK(x.speciesCount == y.speciesCount);
        REQUIRE(x.pairs.size() == y.pairs.size());
        for (std::size_t p = 0; p < x.pairs.size(); ++p) {
            CHECK(x.pairs[p].pairCount == y.pairs[p].pairCount);
            CHECK(x.pairs[p].translateWeighted == y.pairs[p].translateWeighted);
            CHECK(x.pairs[p].normalisation == y.pairs[p].normalisation);
            CHECK(x.pairs[p].g == y.pairs[p].g);
            CHECK(x.pairs[p].separationCount == y.pairs[p].separationCount);
            CHECK(x.pairs[p].separationSources == y.pairs[p].separationSources);
        }
    }
}

/// A random input: 60 x 50 m, a wet west and a dry east half, a few canopy trees, and
/// undergrowth of three species.
analysis::AnalysisInput randomInput(std::uint64_t seed) {
    analysis::AnalysisInput in = flatInput(60, 50);
    RandomStream rng(seed, 9);
    for (int iy = 0; iy < 50; ++iy)
        for (int ix = 0; ix < 60; ++ix) {
            in.features[Factor::Moisture](ix, iy) = static_cast<float>((ix < 30 ? 150.0 : 40.0) + rng.normal());
        }
    // Both seeding discs (60 m and 48 m) cover the whole input: one combination, 1+2.
    in.canopy = {plant("Redwood", 15, 25, 60, 5), plant("Coast Live Oak", 30, 25, 20, 4)};
    const char* names[] = {"Redwood Sorrel", "Western Swordfern", "Toyon"};
    for (int i = 0; i < 3000; ++i) {
        const std::string s = names[rng.below(3)];
        in.undergrowth.push_back(plant(s, rng.uniform(0, 60), rng.uniform(0, 50), rng.uniform(0.05, 0.25),
                                       rng.uniform(0.05, 0.6)));
    }
    return in;
}

}  // namespace

// ---------------------------------------------------------------------------------------
// Labels

TEST_CASE("canopy sub-biome masks follow the sub-biomes' canopy lists (as the simulator's seed packages)", "[analysis]") {
    const auto m = analysis::canopySubBiomeMasks(sonoma(), analysis::CanopyMembership::SubBiomeCanopyLists);
    CHECK(m[static_cast<std::size_t>(sp("Redwood"))] == 0b0001);
    CHECK(m[static_cast<std::size_t>(sp("Douglas-Fir"))] == 0b0001);
    CHECK(m[static_cast<std::size_t>(sp("Coast Live Oak"))] == 0b0010);
    CHECK(m[static_cast<std::size_t>(sp("Gray Pine"))] == 0b0100);
    CHECK(m[static_cast<std::size_t>(sp("Pacific Madrone"))] == 0b1000);
    CHECK(m[static_cast<std::size_t>(sp("Toyon"))] == 0);
    const auto own = analysis::canopySubBiomeMasks(sonoma(), analysis::CanopyMembership::SpeciesSubBiomes);
    CHECK(own[static_cast<std::size_t>(sp("Douglas-Fir"))] == 0b1001);  // Table 3: 1, 4
    CHECK(own[static_cast<std::size_t>(sp("Toyon"))] == 0);             // not canopy-capable
}

TEST_CASE("combination labels: cells within factor x crown radius of each tree get its sub-biomes", "[analysis]") {
    const Grid<float> geo(20, 10, 1.0, 100.0, 50.0);
    const std::vector<Plant> canopy = {plant("Redwood", 105, 55, 50, 0.5), plant("Coast Live Oak", 108, 55, 20, 0.5)};
    const auto masks = analysis::canopySubBiomeMasks(sonoma(), analysis::CanopyMembership::SubBiomeCanopyLists);
    const auto labels = seedingLabels(geo, canopy, masks, 4.0);  // discs of 2 m
    for (int iy = 0; iy < 10; ++iy)
        for (int ix = 0; ix < 20; ++ix) {
            const double cx = geo.cellCentreX(ix), cy = geo.cellCentreY(iy);
            int expect = 0;
            if (std::hypot(cx - 105, cy - 55) <= 2.0) expect |= 1;
            if (std::hypot(cx - 108, cy - 55) <= 2.0) expect |= 2;
            INFO("cell " << ix << ", " << iy);
            CHECK(labels(ix, iy) == expect);
        }
    CHECK(labels(4, 4) == 1);    // centre (104.5, 54.5)
    CHECK(labels(7, 5) == 2);    // centre (107.5, 55.5): 2.55 m from the redwood
    CHECK(labels(0, 0) == 0);
}

// ---------------------------------------------------------------------------------------
// k-means and k

TEST_CASE("k-means recovers well-separated clusters", "[analysis][kmeans]") {
    std::vector<Features> centres;
    const auto pts = blobs(3, 200, 11, &centres);
    const analysis::KMeansResult r = analysis::kmeans(pts, 3, 1, 1, 4, 100);
    REQUIRE(r.centroids.size() == 3);
    for (const Features& c : centres) {
        double best = 1e9;
        for (const Features& k : r.centroids) {
            double d = 0;
            for (std::size_t f = 0; f < kFactorCount; ++f) d += (c[f] - k[f]) * (c[f] - k[f]);
            best = std::min(best, std::sqrt(d));
        }
        CHECK(best < 0.05);  // sd 0.15 / sqrt(200) per coordinate: 5 sigma is ~0.05 in 4-D
    }
    // Every blob is one cluster.
    for (int b = 0; b < 3; ++b)
        for (int i = 1; i < 200; ++i) CHECK(r.assignment[static_cast<std::size_t>(b * 200 + i)] == r.assignment[static_cast<std::size_t>(b * 200)]);
}

TEST_CASE("the silhouette criterion picks the number of well-separated clusters, and k = 1 without structure", "[analysis][kmeans]") {
    analysis::AnalysisParams params;
    params.kMax = 6;
    for (int n : {2, 3, 4, 5}) {
        const analysis::KSelection s = analysis::selectK(blobs(n, 150, 20 + static_cast<std::uint64_t>(n)), 6, params, 7);
        INFO(n << " blobs");
        CHECK(s.k == n);
        CHECK(s.centroids.size() == static_cast<std::size_t>(n));
        CHECK(std::isnan(s.silhouette[0]));
        CHECK(s.silhouette[static_cast<std::size_t>(n - 1)] > 0.8);
    }
    // One Gaussian blob: no k >= 2 reaches the threshold.
    const analysis::KSelection one = analysis::selectK(blobs(1, 600, 5), 6, params, 7);
    CHECK(one.k == 1);
    // The area bound caps k.
    CHECK(analysis::selectK(blobs(4, 100, 3), 2, params, 7).k == 2);
}

TEST_CASE("mean silhouette on a hand-made partition", "[analysis][kmeans]") {
    const std::vector<Features> pts = {{0, 0, 0, 0}, {1, 0, 0, 0}, {10, 0, 0, 0}};
    // Point 0: a = 1, b = 10 -> 0.9; point 1: a = 1, b = 9 -> 8/9; point 2 alone -> 0.
    CHECK(analysis::meanSilhouette(pts, {0, 0, 1}, 2) == Approx((0.9 + 8.0 / 9.0) / 3.0));
}

// ---------------------------------------------------------------------------------------
// Statistics on hand-made patterns

TEST_CASE("hand-made pattern: area, density, proportions and size histograms are exact", "[analysis]") {
    analysis::AnalysisInput in = flatInput(40, 40);
    in.canopy = {plant("Redwood", 20, 20, 60, 3)};  // seeds 36 m: every cell is combination 1
    for (int i = 0; i < 10; ++i) in.undergrowth.push_back(plant("Redwood Sorrel", 5 + i, 10, i < 5 ? 0.0625 : 0.25, 0.2));
    for (int i = 0; i < 6; ++i) in.undergrowth.push_back(plant("Western Swordfern", 5 + i, 30, 0.65, 0.5));
    in.undergrowth.push_back(plant("Western Swordfern", 30, 30, 1.3, 9.0));  // the tallest and widest fern
    analysis::AnalysisParams params;
    const BiomeDatabase db = analysis::analyse({in}, params);
    REQUIRE(db.combinations.size() == 1);
    CHECK(db.combinations[0].mask == 1);
    CHECK(db.combinations[0].k == 1);  // constant abiotics
    REQUIRE(db.regions.size() == 1);
    const DbRegion& r = db.regions[0];
    CHECK(r.areaM2 == 1600.0);
    CHECK(r.cellCount == 1600);
    CHECK(r.undergrowthCount == 17);
    CHECK(r.canopyCount == 1);
    CHECK(r.densityPerM2 == 17.0 / 1600.0);
    CHECK(r.speciesCount[static_cast<std::size_t>(sp("Redwood Sorrel"))] == 10);
    CHECK(r.speciesProportion[static_cast<std::size_t>(sp("Redwood Sorrel"))] == 10.0 / 17.0);
    CHECK(r.speciesProportion[static_cast<std::size_t>(sp("Western Swordfern"))] == 7.0 / 17.0);
    CHECK(r.canopySpeciesCount[static_cast<std::size_t>(sp("Redwood"))] == 1);
    // Edges per species: 0 .. its tallest plant in 20 bins. Sorrel: 0.25 m, bins of 0.0125 m;
    // 0.0625 m is the lower edge of bin 5; 0.25 m, the top, belongs to the last bin.
    const DbHistogram& hs = r.height[static_cast<std::size_t>(sp("Redwood Sorrel"))];
    REQUIRE(hs.edges.size() == 21);
    CHECK(hs.edges.front() == 0.0);
    CHECK(hs.edges.back() == 0.25);
    CHECK(hs.counts[5] == 5);
    CHECK(hs.counts[19] == 5);
    CHECK(std::accumulate(hs.counts.begin(), hs.counts.end(), 0.0) == 10);
    // Swordfern: 0 .. 1.3 m; 0.65 m is exactly half: bin 10. Radius 0 .. 9 m: 0.5 m -> bin 1.
    const DbHistogram& hf = r.height[static_cast<std::size_t>(sp("Western Swordfern"))];
    CHECK(hf.edges.back() == 1.3);
    CHECK(hf.counts[10] == 6);
    CHECK(hf.counts[19] == 1);
    CHECK(hf.overflow == 0);
    const DbHistogram& rf = r.crownRadius[static_cast<std::size_t>(sp("Western Swordfern"))];
    CHECK(rf.edges.back() == 9.0);
    CHECK(rf.counts[1] == 6);
    CHECK(rf.counts[19] == 1);
    // A species absent everywhere keeps its maximum height as the range.
    CHECK(r.height[static_cast<std::size_t>(sp("Toyon"))].edges.back() == 9.0);
    CHECK(db.inputs[0].undergrowthPlants == 17);
    CHECK(db.inputs[0].canopyTrees == 1);
    CHECK(db.inputs[0].unlabelledPlants == 0);
}

TEST_CASE("region pair correlation equals the rectangle estimator when the region is the whole window", "[analysis][pcf]") {
    analysis::AnalysisInput in = flatInput(40, 30);
    in.canopy = {plant("Redwood", 20, 15, 60, 3)};
    RandomStream rng(4, 4);
    for (int i = 0; i < 400; ++i)
        in.undergrowth.push_back(plant(i % 3 ? "Redwood Sorrel" : "Western Swordfern", rng.uniform(0, 40), rng.uniform(0, 30),
                                       0.1, 0.2));
    analysis::AnalysisParams params;
    params.pcfBins = DistanceBins{10.0, 20};
    const BiomeDatabase db = analysis::analyse({in}, params);
    REQUIRE(db.regions.size() == 1);
    // The same points through core's rectangle estimator: undergrowth types + the canopy tree.
    PointPattern p;
    p.typeNames = {"sorrel", "fern", "redwood"};
    for (const Plant& pl : in.undergrowth) {
        p.x.push_back(pl.xM);
        p.y.push_back(pl.yM);
        p.type.push_back(pl.speciesId == sp("Redwood Sorrel") ? 0 : 1);
    }
    p.x.push_back(20);
    p.y.push_back(15);
    p.type.push_back(2);
    PcfOptions opt;
    opt.bins = params.pcfBins;
    opt.isotropic = false;
    const PairSums ref = countPairs(p, in.window, opt);
    const int ns = sonoma().species.size();
    const int cat[3] = {sp("Redwood Sorrel"), sp("Western Swordfern"), ns + sp("Redwood")};
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) {
            if (i == 2 && j == 2) continue;  // a single tree has no pairs with itself
            const DbPairStats* ps = db.regions[0].pair(cat[i], cat[j]);
            REQUIRE(ps != nullptr);
            CHECK(ps->normalisation == Approx(ref.normalisation(i, j)).epsilon(1e-12));
            for (int k = 0; k < opt.bins.count; ++k) {
                INFO(i << " -> " << j << " bin " << k);
                CHECK(ps->pairCount[static_cast<std::size_t>(k)] == static_cast<double>(ref.pairCount[ref.index(i, j, k)]));
                CHECK(ps->translateWeighted[static_cast<std::size_t>(k)] == Approx(ref.translateSum[ref.index(i, j, k)]).epsilon(1e-11));
                CHECK(ps->g[static_cast<std::size_t>(k)] == Approx(ref.gTranslate(i, j, k)).epsilon(1e-11));
            }
        }
}

TEST_CASE("disk separation histograms: exact counts per source, sources near the edge left out", "[analysis]") {
    analysis::AnalysisInput in = flatInput(40, 40);
    in.canopy = {plant("Redwood", 20, 20, 60, 3)};
    in.undergrowth = {
        plant("Redwood Sorrel", 10, 10, 0.1, 0.4),       // 0
        plant("Redwood Sorrel", 11, 10, 0.1, 0.4),       // 1: 1 m from 0, separation 0.2 m
        plant("Western Swordfern", 10, 10.5, 0.6, 0.5),  // 2: 0.5 m from 0: overlap -0.4 m
        plant("Redwood Sorrel", 2, 30, 0.1, 0.4),        // 3: 2 m from the west edge
        plant("Redwood Sorrel", 3, 30, 0.1, 0.4),        // 4
    };
    analysis::AnalysisParams params;
    params.separationBins = SeparationBins{-2.0, 2.0, 16};  // 0.25 m bins
    const BiomeDatabase db = analysis::analyse({in}, params);
    REQUIRE(db.regions.size() == 1);
    const DbRegion& r = db.regions[0];
    const int sorrel = sp("Redwood Sorrel"), fern = sp("Western Swordfern");
    const DbPairStats* ss = r.pair(sorrel, sorrel);
    REQUIRE(ss != nullptr);
    // Interior sorrel sources need 2 + 0.4 + 0.4 = 2.8 m to the edge: 0 and 1, not 3 (2 m) nor 4 (3 m? yes: 3 >= 2.8).
    CHECK(ss->separationSources == 3);
    // Sorrel pairs with separation 0.2 m (bin 8 = [0, 0.25)): 0->1, 1->0; 4->3 (1 m apart) also 0.2 m.
    CHECK(ss->separationCount[8] == 3);
    CHECK(std::accumulate(ss->separationCount.begin(), ss->separationCount.end(), 0.0) == 3);
    const DbPairStats* sf = r.pair(sorrel, fern);
    REQUIRE(sf != nullptr);
    // Sorrel -> fern needs 2 + 0.4 + 0.5 = 2.9 m: sources 0 and 1 (4 is 3 m from the edge).
    CHECK(sf->separationSources == 3);
    // 0 -> 2: separation 0.5 - 0.9 = -0.4 (bin 6 = [-0.5, -0.25)); 1 -> 2: 1.118 - 0.9 = 0.218 (bin 8).
    CHECK(sf->separationCount[6] == 1);
    CHECK(sf->separationCount[8] == 1);
    CHECK(sf->separationPerSource(6) == Approx(1.0 / 3.0));
    // Canopy -> sorrel: the tree (3 m crown) is 20 m from the edge; sorrel at (10, 10) is
    // 14.1 m away: separation 10.7 m, beyond 2 m: no count, but the tree is a source.
    const DbPairStats* cs = r.pair(static_cast<int>(sonoma().species.size()) + sp("Redwood"), sorrel);
    REQUIRE(cs != nullptr);
    CHECK(cs->separationSources == 1);
    CHECK(std::accumulate(cs->separationCount.begin(), cs->separationCount.end(), 0.0) == 0);
}

TEST_CASE("abiotic zones become k-means regions and nearestRegion finds them", "[analysis][kmeans]") {
    const analysis::AnalysisInput in = randomInput(1);
    analysis::AnalysisParams params;
    params.minClusterAreaM2 = 100;
    const BiomeDatabase db = analysis::analyse({in}, params);
    REQUIRE(db.combinations.size() == 1);
    CHECK(db.combinations[0].mask == 3);
    for (const DbCombination& c : db.combinations) {
        INFO("combination " << c.mask);
        CHECK(c.k == 2);  // wet west, dry east (moisture 150 vs 40 mm, noise 1 mm)
        const DbRegion& a = db.regions[static_cast<std::size_t>(c.firstRegion)];
        const DbRegion& b = db.regions[static_cast<std::size_t>(c.firstRegion + 1)];
        CHECK(std::min(a.centroidRaw[1], b.centroidRaw[1]) == Approx(40).margin(1));
        CHECK(std::max(a.centroidRaw[1], b.centroidRaw[1]) == Approx(150).margin(1));
        const int wet = a.centroidRaw[1] > b.centroidRaw[1] ? c.firstRegion : c.firstRegion + 1;
        CHECK(db.nearestRegion(c.mask, {10, 140, 15, 5}) == wet);
        CHECK(db.nearestRegion(c.mask, {10, 45, 15, 5}) != wet);
    }
}

TEST_CASE("two inputs pool: areas and counts add, ratios and g stay", "[analysis]") {
    const analysis::AnalysisInput in = randomInput(2);
    analysis::AnalysisParams params;
    params.minClusterAreaM2 = 100;  // the same k for one and two copies
    const BiomeDatabase one = analysis::analyse({in}, params);
    const BiomeDatabase two = analysis::analyse({in, in}, params);
    REQUIRE(one.regions.size() == two.regions.size());
    CHECK(two.inputs.size() == 2);
    for (std::size_t r = 0; r < one.regions.size(); ++r) {
        CHECK(two.regions[r].areaM2 == 2 * one.regions[r].areaM2);
        CHECK(two.regions[r].undergrowthCount == 2 * one.regions[r].undergrowthCount);
        CHECK(two.regions[r].densityPerM2 == Approx(one.regions[r].densityPerM2));
        REQUIRE(two.regions[r].pairs.size() == one.regions[r].pairs.size());
        for (std::size_t p = 0; p < one.regions[r].pairs.size(); ++p)
            for (std::size_t k = 0; k < one.regions[r].pairs[p].g.size(); ++k)
                CHECK(two.regions[r].pairs[p].g[k] == Approx(one.regions[r].pairs[p].g[k]));
    }
}

TEST_CASE("the database is bit-identical with 1 and 2 threads", "[analysis]") {
    const analysis::AnalysisInput in = randomInput(3);
    analysis::AnalysisParams params;
    params.minClusterAreaM2 = 100;
    const int before = omp_get_max_threads();
    omp_set_num_threads(1);
    const BiomeDatabase a = analysis::analyse({in}, params);
    omp_set_num_threads(2);
    const BiomeDatabase b = analysis::analyse({in}, params);
    omp_set_num_threads(before);
    requireIdentical(a, b);
}

TEST_CASE("analysis parameters: one description drives validation, the database record and the docs", "[analysis]") {
    test::checkParamTable(
        analysis::analysisParamFields(), "docs/analysis.md", [](const analysis::AnalysisParams& p) { p.validate(); },
        [](const analysis::AnalysisParams& p) { return p.asParameters(); }, 12);
    // The record keeps the order the databases have (each name once).
    const auto rec = analysis::AnalysisParams{}.asParameters();
    REQUIRE(rec.size() == 24);
    CHECK(rec[1].first == "canopy_membership");
    CHECK(rec[3].first == "k_criterion");
    CHECK(rec[11].first == "feature_normalisation");
    CHECK(rec[21].first == "context_edges_m");
    CHECK(rec[23].first == "context_pair_sample_cells");
}

TEST_CASE("inconsistent inputs and parameters are ValidationErrors naming the problem", "[analysis][errors]") {
    analysis::AnalysisInput in = flatInput(10, 10);
    analysis::AnalysisParams params;
    params.kMax = 0;
    CHECK_THROWS_WITH(analysis::analyse({in}, params), Catch::Contains("'kmax' must lie in [1, 64], got 0"));
    params = analysis::AnalysisParams{};
    in.features[Factor::Moisture] = Grid<float>(9, 10, 1.0);
    CHECK_THROWS_WITH(analysis::analyse({in}, params), Catch::Contains("moisture grid differs"));
    in = flatInput(10, 10);
    in.undergrowth.push_back(Plant{99, 1, 1, 0, 1, 1});
    CHECK_THROWS_WITH(analysis::analyse({in}, params), Catch::Contains("species id 99"));
    CHECK_THROWS_AS(analysis::analyse({}, params), ValidationError);
}

// ---------------------------------------------------------------------------------------
// Simulation files (the command, eco analyse / inspect, is tested in analysis_cli_test.cpp)

using test::writeFakeSimulation;

TEST_CASE("readSimulation: last snapshot, chosen year, abiotics beside the file, provenance", "[analysis][io]") {
    eco::test::TempDir dir("sim");
    const std::string sim = dir.file("sim.h5");
    writeFakeSimulation(sim, dir.file("abiotics.h5"));
    const analysis::LoadedSimulation last = analysis::readSimulation(sim, {});
    CHECK(last.years == std::vector<int>{1, 10});
    CHECK(last.input.provenance.year == 10);
    CHECK(last.input.undergrowth.size() == 1500);
    CHECK(last.input.canopy.size() == 2);
    CHECK(last.input.provenance.seed == 42);
    CHECK(last.input.window.x1 == 1050.0);
    CHECK(last.seedOuterRadiusFactor == 12.0);
    CHECK(last.input.features[Factor::Sun](0, 0) == Approx(9.0));  // annual mean of 8, 9, 10
    analysis::SimulationReadOptions opt;
    opt.year = 1;
    CHECK(analysis::readSimulation(sim, opt).input.undergrowth.size() == 100);
    opt.year = 5;
    CHECK_THROWS_WITH(analysis::readSimulation(sim, opt), Catch::Contains("no snapshot of year 5") && Catch::Contains("1, 10"));
}

TEST_CASE("readSimulation: missing datasets and wrong files are IoErrors naming file and dataset", "[analysis][io][errors]") {
    eco::test::TempDir dir("sim");
    const std::string ab = dir.file("abiotics.h5");
    writeFakeSimulation(dir.file("nosnap.h5"), ab, "/snapshots");
    CHECK_THROWS_WITH(analysis::readSimulation(dir.file("nosnap.h5"), {}), Catch::Contains("nosnap.h5") && Catch::Contains("/snapshots"));
    writeFakeSimulation(dir.file("nocanopy.h5"), ab, "/canopy");
    CHECK_THROWS_WITH(analysis::readSimulation(dir.file("nocanopy.h5"), {}), Catch::Contains("nocanopy.h5") && Catch::Contains("/canopy"));
    writeFakeSimulation(dir.file("nox.h5"), ab, "x");
    CHECK_THROWS_WITH(analysis::readSimulation(dir.file("nox.h5"), {}), Catch::Contains("nox.h5") && Catch::Contains("year_0020/x"));
    CHECK_THROWS_WITH(analysis::readSimulation(ab, {}), Catch::Contains("abiotics.h5") && Catch::Contains("not a simulation file"));
    writeFakeSimulation(dir.file("good.h5"), ab);
    analysis::SimulationReadOptions opt;
    opt.abioticsPath = dir.file("missing-abiotics.h5");
    CHECK_THROWS_WITH(analysis::readSimulation(dir.file("good.h5"), opt), Catch::Contains("missing-abiotics.h5"));
}

// ---------------------------------------------------------------------------------------
// A factor no species responds to (wind in the Sonoma biome)

TEST_CASE("a factor no species responds to is left out of the clustering and of nearestRegion", "[analysis][kmeans][wind]") {
    // The same input twice: once calm everywhere, once with a strong north-south split of
    // the wind (0 vs 12 m/s, with noise), which k-means would separate if it counted.
    const analysis::AnalysisInput calm = randomInput(4);
    analysis::AnalysisInput windy = calm;
    RandomStream rng(4, 10);
    for (int iy = 0; iy < 50; ++iy)
        for (int ix = 0; ix < 60; ++ix)
            windy.features[Factor::Wind](ix, iy) = static_cast<float>((iy < 25 ? 0.0 : 12.0) + 0.1 * rng.normal());
    analysis::AnalysisParams params;
    params.minClusterAreaM2 = 100;
    const BiomeDatabase a = analysis::analyse({calm}, params);
    const BiomeDatabase b = analysis::analyse({windy}, params);
    CHECK(analysis::clusteringWeights(sonoma())[factorIndex(Factor::Wind)] == 0.0);
    CHECK(analysis::clusteringWeights(sonoma())[factorIndex(Factor::Sun)] == 1.0);
    CHECK(b.featureWeights[factorIndex(Factor::Wind)] == 0.0);
    REQUIRE(a.combinations.size() == b.combinations.size());
    for (std::size_t c = 0; c < a.combinations.size(); ++c) CHECK(a.combinations[c].k == b.combinations[c].k);
    REQUIRE(a.regions.size() == b.regions.size());
    for (std::size_t r = 0; r < a.regions.size(); ++r) {
        CHECK(a.regions[r].centroidNormalised == b.regions[r].centroidNormalised);  // wind: 0 in both
        CHECK(a.regions[r].areaM2 == b.regions[r].areaM2);
        CHECK(a.regions[r].speciesCount == b.regions[r].speciesCount);
    }
    // The wind's statistics are still recorded (its column in the database), ...
    CHECK(b.combinations[0].featureMean[factorIndex(Factor::Wind)] == Approx(6.0).margin(0.1));
    // ... and nearestRegion ignores it.
    const int mask = b.combinations[0].mask;
    for (double wind : {0.0, 6.0, 12.0, 1000.0}) {
        CHECK(b.nearestRegion(mask, {10, 140, 15, 5, wind}) == a.nearestRegion(mask, {10, 140, 15, 5, 0}));
        CHECK(b.nearestRegion(mask, {10, 45, 15, 5, wind}) == a.nearestRegion(mask, {10, 45, 15, 5, 0}));
    }
    // The weights survive the file.
    test::TempDir dir("analysis_wind");
    writeBiomeDatabase(dir.file("db.h5"), b);
    CHECK(readBiomeDatabase(dir.file("db.h5")).featureWeights == b.featureWeights);

    // Control: when one species responds to wind, the wind counts and splits the regions.
    Biome responding = sonoma();
    responding.species[static_cast<std::size_t>(sp("Toyon"))].response(Factor::Wind) = Response{2.0, 5.0};
    analysis::AnalysisInput windyResponding = windy;
    windyResponding.biome = &responding;
    const BiomeDatabase c = analysis::analyse({windyResponding}, params);
    CHECK(c.featureWeights[factorIndex(Factor::Wind)] == 1.0);
    CHECK(c.combinations[0].k > b.combinations[0].k);  // wet / dry, and calm / windy
    const int calmRegion = c.nearestRegion(mask, {10, 140, 15, 5, 0});
    CHECK(c.nearestRegion(mask, {10, 140, 15, 5, 12}) != calmRegion);
}
