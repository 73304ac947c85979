// Canopy placer (paper §5.2, Algorithm 1): recovery of known trees from a synthetic CHM,
// determinism across thread counts, species fallback, duplicates and files (the eco canopy
// command's outputs and error paths: canopy_placer_cli_test.cpp).
#include <catch2/catch.hpp>
#include <omp.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <limits>
#include <sstream>

#include "biome.h"
#include "canopy_placer.h"
#include "error.h"
#include "generate.h"
#include "h5io.h"
#include "rng.h"
#include "species_map.h"
#include "terrain_io.h"
#include "test_util.h"

using namespace eco;

namespace {

/// A CHM built from known spheres: isolated trees on a jittered lattice, and clusters of two
/// or three overlapping crowns whose apexes all stay visible. Crown radii follow the
/// allometry of `species`, so the placer's crowns can match the CHM exactly.
struct SyntheticForest {
    Grid<float> chm;
    std::vector<GeneratedTree> trees;
    std::vector<bool> isolated;
};

SyntheticForest syntheticForest(const Biome& b, int species, std::uint64_t seed = 3) {
    SyntheticForest f;
    const double cell = 0.914, slot = 18.0;
    const int n = 240;
    f.chm = Grid<float>(n, n, cell, 500.0, 1000.0, 0.f);  // a non-zero origin on purpose
    const Allometry& allo = b.species[static_cast<std::size_t>(species)].allometry;
    const int slots = static_cast<int>((n * cell - slot / 2) / slot);
    for (int sy = 0; sy < slots; ++sy)
        for (int sx = 0; sx < slots; ++sx) {
            RandomStream rng(seed, static_cast<std::uint64_t>(sy * slots + sx));
            const double cx = f.chm.originX() + slot * (sx + 0.5), cy = f.chm.originY() + slot * (sy + 0.5);
            const double kind = rng.uniform();
            const double base = rng.uniform(15.0, 35.0);
            if (kind < 0.65) {  // isolated
                const double h = base;
                f.trees.push_back({cx + rng.uniform(-2, 2), cy + rng.uniform(-2, 2), h, allo.crownRadiusM(h)});
                f.isolated.push_back(true);
                continue;
            }
            const int count = kind < 0.9 ? 2 : 3;
            const double r = allo.crownRadiusM(base);
            const double d = rng.uniform(0.9, 1.4) * r;  // trunk distance: crowns overlap
            const double rho = count == 2 ? d / 2 : d / std::sqrt(3.0);
            const double phase = rng.uniform(0, 6.283185307179586);
            for (int k = 0; k < count; ++k) {
                const double a = phase + 6.283185307179586 * k / count;
                const double h = base + rng.uniform(-1.5, 1.5);
                f.trees.push_back({cx + rho * std::cos(a), cy + rho * std::sin(a), h, allo.crownRadiusM(h)});
                f.isolated.push_back(false);
            }
        }
    rasterizeCrowns(f.trees, f.chm);
    return f;
}

Grid<std::int32_t> uniformMap(const Grid<float>& like, int species) { return Grid<std::int32_t>::like(like, species); }

double nearestDistance(const std::vector<Plant>& plants, double x, double y) {
    double best = std::numeric_limits<double>::infinity();
    for (const auto& p : plants) best = std::min(best, std::hypot(p.xM - x, p.yM - y));
    return best;
}

bool sameTrees(const std::vector<Plant>& a, const std::vector<Plant>& b) {
    if (a.size() != b.size()) return false;
    for (std::size_t i = 0; i < a.size(); ++i)
        if (a[i].speciesId != b[i].speciesId || a[i].xM != b[i].xM || a[i].yM != b[i].yM ||
            a[i].groundZM != b[i].groundZM || a[i].heightM != b[i].heightM || a[i].crownRadiusM != b[i].crownRadiusM)
            return false;
    return true;
}

/// Two Douglas-Firs of 30 and 27 m, trunks 4.35 m apart inside the taller crown, on cells of
/// 0.5 m: the lower tree's apex stands 0.6 m above the taller crown's surface, but a cell
/// toward the taller trunk that surface is higher than the apex, so it is no strict maximum.
struct FlankPair {
    Biome biome = defaultBiome();
    int df = biome.speciesIndex("Douglas-Fir");
    std::vector<GeneratedTree> trees;
    Grid<float> chm;
    Grid<float> terrain;

    synth::CanopyResult place(const synth::CanopyParams& p) const {
        return synth::placeCanopy(chm, terrain, uniformMap(chm, df), biome, p);
    }
};

/// Two Douglas-Firs, 30 m and 27 m tall, 4.35 m apart on flat ground: the lower one's top
/// lies on the taller one's flank and is no CHM maximum.
FlankPair flankPair() {
    FlankPair f;
    const Allometry& a = f.biome.species[static_cast<std::size_t>(f.df)].allometry;
    f.trees = {{20.25, 20.25, 30.0, a.crownRadiusM(30)}, {20.25 + 4.35, 20.25, 27.0, a.crownRadiusM(27)}};
    f.chm = Grid<float>(80, 80, 0.5, 0, 0, 0.f);
    rasterizeCrowns(f.trees, f.chm);
    f.terrain = Grid<float>::like(f.chm, 0.f);
    return f;
}

}  // namespace

TEST_CASE("placer recovers known trees from a synthetic CHM", "[canopy]") {
    const Biome b = defaultBiome();
    const int fir = b.speciesIndex("Douglas-Fir");
    const SyntheticForest f = syntheticForest(b, fir);
    const Grid<float> terrain = Grid<float>::like(f.chm, 100.f);
    const synth::CanopyResult r = synth::placeCanopy(f.chm, terrain, uniformMap(f.chm, fir), b, synth::CanopyParams{});
    const double truth = static_cast<double>(f.trees.size());
    INFO("truth " << truth << " placed " << r.trees.size() << " initial " << r.initialSeeds << " final coverage "
                  << r.final.coverage << " rmse " << r.final.rmseM << " stop " << r.stopReason);
    REQUIRE(f.trees.size() > 150);
    CHECK(std::abs(static_cast<double>(r.trees.size()) - truth) <= 0.05 * truth);
    std::size_t isolated = 0;
    double worst = 0;
    for (std::size_t i = 0; i < f.trees.size(); ++i) {
        if (!f.isolated[i]) continue;
        ++isolated;
        worst = std::max(worst, nearestDistance(r.trees, f.trees[i].x, f.trees[i].y));
    }
    INFO("isolated trees " << isolated << ", worst position error " << worst << " m");
    CHECK(isolated > 60);
    CHECK(worst <= 1.0);
    CHECK(r.final.coverage > 0.95);
    for (const auto& p : r.trees) {
        CHECK(p.speciesId == fir);
        CHECK(p.groundZM == Approx(100.0));
        CHECK(p.heightM >= 3.0);
        CHECK(p.crownRadiusM == Approx(b.species[static_cast<std::size_t>(fir)].allometry.crownRadiusM(p.heightM)));
    }
    REQUIRE(!r.iterations.empty());
    CHECK(r.iterations.front().iteration == 0);
    CHECK(r.final.trees == r.trees.size());
}

TEST_CASE("placer output is identical with 1 and 2 threads", "[canopy]") {
    const Biome b = defaultBiome();
    // A dense generated canopy (ring seeding, removals and moves all happen) with two
    // species and a patch where no species can grow (fallback).
    const Grid<std::int32_t> sketch = generateDensitySketch(160, 140, 0.914, SketchParams{});
    ChmGenParams cp;
    cp.denseSpacingM = 3.5;
    cp.minHeightM = 5;
    cp.maxHeightM = 20;
    const Grid<float> chm = generateChm(sketch, cp);
    Grid<std::int32_t> map = uniformMap(chm, b.speciesIndex("Douglas-Fir"));
    for (int iy = 0; iy < chm.height(); ++iy)
        for (int ix = 0; ix < chm.width(); ++ix) {
            if (ix > 100) map(ix, iy) = b.speciesIndex("Redwood");
            if (ix < 30 && iy < 40) map(ix, iy) = -1;
        }
    Grid<float> terrain = Grid<float>::like(chm);
    for (int iy = 0; iy < chm.height(); ++iy)
        for (int ix = 0; ix < chm.width(); ++ix) terrain(ix, iy) = static_cast<float>(50 + 0.3 * ix + 0.1 * iy);
    synth::CanopyParams p;
    p.seed = 11;
    omp_set_num_threads(1);
    const synth::CanopyResult one = synth::placeCanopy(chm, terrain, map, b, p);
    omp_set_num_threads(2);
    const synth::CanopyResult two = synth::placeCanopy(chm, terrain, map, b, p);
    CHECK(one.iterations.size() >= 2);
    CHECK(sameTrees(one.trees, two.trees));
    REQUIRE(one.iterations.size() == two.iterations.size());
    for (std::size_t i = 0; i < one.iterations.size(); ++i) {
        CHECK(one.iterations[i].trees == two.iterations[i].trees);
        CHECK(one.iterations[i].coverage == two.iterations[i].coverage);
        CHECK(one.iterations[i].rmseM == two.iterations[i].rmseM);
    }
    CHECK(one.final.rmseM == two.final.rmseM);
    CHECK(one.stopReason == two.stopReason);
    // A different seed changes the ring sampling.
    p.seed = 12;
    const synth::CanopyResult other = synth::placeCanopy(chm, terrain, map, b, p);
    CHECK_FALSE(sameTrees(one.trees, other.trees));
}

TEST_CASE("trees where no species can grow take the nearest mapped species", "[canopy]") {
    const Biome b = defaultBiome();
    const int fir = b.speciesIndex("Douglas-Fir"), redwood = b.speciesIndex("Redwood");
    const SyntheticForest f = syntheticForest(b, fir);
    Grid<std::int32_t> map = uniformMap(f.chm, fir);
    const int w = f.chm.width();
    for (int iy = 0; iy < f.chm.height(); ++iy)
        for (int ix = 0; ix < w; ++ix) map(ix, iy) = ix < w / 3 ? -1 : (ix < 2 * w / 3 ? fir : redwood);
    const synth::CanopyResult r = synth::placeCanopy(f.chm, Grid<float>::like(f.chm, 0.f), map, b, synth::CanopyParams{});
    std::size_t west = 0;
    for (const auto& p : r.trees) {
        const int ix = f.chm.cellX(p.xM);
        if (ix < w / 3) {
            ++west;
            CHECK(p.speciesId == fir);  // nearest mapped cells are the fir band
        } else {
            CHECK(p.speciesId == map(ix, f.chm.cellY(p.yM)));
        }
    }
    CHECK(west > 20);
    CHECK(r.fallbackTrees == west);
    // Nothing mapped at all: the tallest canopy species (Redwood, 110 m).
    const synth::CanopyResult none = synth::placeCanopy(f.chm, Grid<float>::like(f.chm, 0.f), uniformMap(f.chm, -1), b, synth::CanopyParams{});
    REQUIRE(!none.trees.empty());
    for (const auto& p : none.trees) CHECK(p.speciesId == redwood);
    CHECK(none.fallbackTrees == none.trees.size());
}

TEST_CASE("seeds are strict local maxima at or above the seed height, a plateau gives one", "[canopy]") {
    Grid<float> chm(12, 10, 1.0, 0, 0, 0.f);
    chm(3, 3) = 10.f;           // a peak
    chm(8, 6) = chm(9, 6) = 7.f;  // a two-cell plateau
    chm(5, 8) = 2.5f;           // below 3 m
    chm(0, 0) = 4.f;            // a corner counts
    const auto seeds = synth::chmLocalMaxima(chm, 3.0, 1);
    REQUIRE(seeds.size() == 3);
    CHECK(seeds[0] == chm.index(0, 0));
    CHECK(seeds[1] == chm.index(3, 3));
    CHECK(seeds[2] == chm.index(8, 6));
    // A wider window merges nearby peaks.
    chm(5, 3) = 9.f;
    CHECK(synth::chmLocalMaxima(chm, 3.0, 1).size() == 4);
    CHECK(synth::chmLocalMaxima(chm, 3.0, 2).size() == 3);
}

TEST_CASE("crowns render as spheres with depth ties to the lower index", "[canopy]") {
    const Grid<float> like(40, 40, 0.5, 10.0, 20.0);
    std::vector<Plant> plants = {{0, 20.0, 30.0, 0, 12.0, 4.0}, {1, 20.0, 30.0, 0, 12.0, 4.0}};
    const synth::CrownRender r = synth::renderCrowns(plants, like);
    for (int iy = 0; iy < like.height(); ++iy)
        for (int ix = 0; ix < like.width(); ++ix) {
            const double d = std::hypot(like.cellCentreX(ix) - 20.0, like.cellCentreY(iy) - 30.0);
            if (d < 4.0 - 1e-6) {
                REQUIRE(r.treeIndex(ix, iy) == 0);
                REQUIRE(r.surfaceM(ix, iy) == Approx(12.0 - 4.0 + std::sqrt(16.0 - d * d)).epsilon(1e-5));
            } else if (d > 4.0 + 1e-6) {
                REQUIRE(r.treeIndex(ix, iy) == -1);
                REQUIRE(r.surfaceM(ix, iy) == 0.f);
            }
        }
    // A taller crown wins where it is higher.
    plants.push_back({2, 22.0, 30.0, 0, 14.0, 3.0});
    const synth::CrownRender r2 = synth::renderCrowns(plants, like);
    CHECK(r2.treeIndex(like.cellX(22.1), like.cellY(30.1)) == 2);
}

TEST_CASE("duplicate removal in parallel equals the one-by-one greedy rule, for 1 and 2 threads", "[canopy]") {
    // Clustered random crowns (many chains of conflicts), with tied heights and radii.
    std::vector<Plant> plants;
    RandomStream rng(5, 77);
    for (int c = 0; c < 300; ++c) {
        const double cx = rng.uniform(0, 200), cy = rng.uniform(0, 150);
        for (int k = 0; k < 8; ++k) {
            const double h = std::round(rng.uniform(5, 25) * 2) / 2;  // ties on purpose
            plants.push_back({0, cx + rng.uniform(-3, 3), cy + rng.uniform(-3, 3), 0, h, std::round(h / 5) / 2 + 0.5});
        }
    }
    // Reference: tallest first (ties: larger crown, lower index), each against every kept one.
    std::vector<std::size_t> order(plants.size());
    for (std::size_t i = 0; i < order.size(); ++i) order[i] = i;
    std::sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
        if (plants[a].heightM != plants[b].heightM) return plants[a].heightM > plants[b].heightM;
        if (plants[a].crownRadiusM != plants[b].crownRadiusM) return plants[a].crownRadiusM > plants[b].crownRadiusM;
        return a < b;
    });
    const double minD = 1.2;
    std::vector<char> keep(plants.size(), 0);
    std::vector<std::size_t> kept;
    for (const std::size_t i : order) {
        const Plant& a = plants[i];
        bool dup = false;
        for (const std::size_t j : kept) {
            const Plant& b = plants[j];
            const double d2 = (a.xM - b.xM) * (a.xM - b.xM) + (a.yM - b.yM) * (a.yM - b.yM);
            const double dz = (b.heightM - b.crownRadiusM) - (a.heightM - a.crownRadiusM);
            if (d2 < minD * minD || std::sqrt(d2 + dz * dz) + a.crownRadiusM <= b.crownRadiusM) {
                dup = true;
                break;
            }
        }
        if (dup) continue;
        keep[i] = 1;
        kept.push_back(i);
    }
    std::vector<Plant> expected;
    for (std::size_t i = 0; i < plants.size(); ++i)
        if (keep[i]) expected.push_back(plants[i]);
    REQUIRE(expected.size() < plants.size() * 3 / 4);  // many removed: the order matters
    for (const int threads : {1, 2}) {
        omp_set_num_threads(threads);
        std::vector<Plant> got = plants;
        CHECK(synth::removeDuplicateTrees(got, minD) == plants.size() - expected.size());
        CHECK(sameTrees(got, expected));
    }
    omp_set_num_threads(2);
}

TEST_CASE("duplicates: close trunks and crowns inside larger crowns are removed", "[canopy]") {
    std::vector<Plant> plants = {
        {0, 0.0, 0.0, 0, 20.0, 4.0},   // kept: tallest
        {0, 0.6, 0.0, 0, 19.0, 3.8},   // trunk 0.6 m from the first: removed
        {0, 10.0, 0.0, 0, 20.0, 4.0},  // kept
        {0, 10.5, 0.5, 0, 17.0, 1.0},  // sphere (centre z 16, r 1) inside (centre z 16, r 4): removed
        {0, 13.5, 0.0, 0, 19.9, 2.0},  // overlaps but sticks out: kept
    };
    CHECK(synth::removeDuplicateTrees(plants, 1.0) == 2);
    REQUIRE(plants.size() == 3);
    CHECK(plants[0].xM == 0.0);
    CHECK(plants[1].xM == 10.0);
    CHECK(plants[2].xM == 13.5);
    // Through the placer: two apexes 2.5 m apart survive a 1 m minimum distance, not a 3 m one.
    const Biome b = defaultBiome();
    const int fir = b.speciesIndex("Douglas-Fir");
    Grid<float> chm(60, 60, 0.5, 0, 0, 0.f);
    const double h = 20, r = b.species[static_cast<std::size_t>(fir)].allometry.crownRadiusM(h);
    rasterizeCrowns({{13.7, 15.1, h, r}, {16.2, 15.1, h - 0.3, r}}, chm);
    synth::CanopyParams p;
    p.maxIterations = 0;  // only the seeding and the final clean-up
    CHECK(synth::placeCanopy(chm, Grid<float>::like(chm, 0.f), uniformMap(chm, fir), b, p).trees.size() == 2);
    p.minTrunkDistanceM = 3.0;
    const auto merged = synth::placeCanopy(chm, Grid<float>::like(chm, 0.f), uniformMap(chm, fir), b, p);
    CHECK(merged.trees.size() == 1);
    CHECK(merged.duplicatesRemoved == 1);
}

TEST_CASE("bad placer input is rejected with a clear message", "[canopy]") {
    const Biome b = defaultBiome();
    const int fir = b.speciesIndex("Douglas-Fir");
    const Grid<float> chm(20, 20, 1.0, 0, 0, 10.f);
    const Grid<float> terrain = Grid<float>::like(chm, 0.f);
    const auto map = uniformMap(chm, fir);
    CHECK_THROWS_WITH(synth::placeCanopy(chm, Grid<float>(21, 20, 1.0), map, b, {}),
                      Catch::Contains("terrain") && Catch::Contains("geometry"));
    CHECK_THROWS_WITH(synth::placeCanopy(chm, Grid<float>(20, 20, 2.0), map, b, {}), Catch::Contains("geometry"));
    CHECK_THROWS_WITH(synth::placeCanopy(chm, terrain, Grid<std::int32_t>(20, 19, 1.0), b, {}), Catch::Contains("species map"));
    Grid<float> negative = chm;
    negative(4, 7) = -1.f;
    CHECK_THROWS_WITH(synth::placeCanopy(negative, terrain, map, b, {}), Catch::Contains("(4, 7)") && Catch::Contains("negative"));
    CHECK_THROWS_WITH(synth::placeCanopy(chm, terrain, uniformMap(chm, b.speciesIndex("Toyon")), b, {}),
                      Catch::Contains("not a canopy species"));
    synth::CanopyParams p;
    p.minVisibleFraction = 1.5;
    CHECK_THROWS_WITH(synth::placeCanopy(chm, terrain, map, b, p), Catch::Contains("min_visible_fraction"));
    CHECK_THROWS_WITH(synth::setCanopyParam(p, "min_visibel_fraction", 0.2), Catch::Contains("unknown canopy parameter"));
    CHECK_THROWS_WITH(synth::setCanopyParam(p, "max_iterations", 2.5), Catch::Contains("integer"));
}

TEST_CASE("canopy parameters: one description drives setting, validation and the docs table", "[canopy]") {
    // Every field: the default is valid, a value just outside its range is refused with the
    // key and the rule in the message, and docs/canopy.md has the field's row as generated.
    std::ifstream in(std::string(ECO_SOURCE_DIR) + "/docs/canopy.md");
    REQUIRE(in);
    std::stringstream docs;
    docs << in.rdbuf();
    const synth::CanopyParams defaults;
    REQUIRE_NOTHROW(synth::validateCanopyParams(defaults));
    for (const auto& f : synth::canopyParamFields()) {
        INFO(f.key);
        CHECK(docs.str().find(paramDocRow(f)) != std::string::npos);
        if (f.kind == synth::CanopyParamField::Kind::Seed) continue;
        const ParamRange& r = f.range;
        const double outside = r.highBound != ParamRange::Bound::None ? r.hi + 1 : r.lo - 1;
        synth::CanopyParams p;
        synth::setCanopyParam(p, f.key, outside);
        CHECK(f.value(p) == outside);
        CHECK_THROWS_WITH(synth::validateCanopyParams(p), Catch::Contains(std::string("'") + f.key + "' " + r.text()));
    }
    CHECK(ParamRange::openClosed(0, 10).text() == "must lie in (0, 10]");
    CHECK(ParamRange::atLeast(0).text() == "must be >= 0");
    CHECK_FALSE(ParamRange::atLeast(0).contains(std::numeric_limits<double>::quiet_NaN()));
}

TEST_CASE("canopy configs are read strictly", "[canopy]") {
    test::TempDir dir("canopy_config");
    {
        std::ofstream(dir.file("ok.toml")) << "[canopy]\nmin_visible_fraction = 0.3\nmax_iterations = 7\nseed = 99\n"
                                              "canopy_threshold_m = 2.5\ntarget_tolerance = 0.005\n[other]\nx = 1\n";
        synth::CanopyParams c;
        synth::SpeciesMapParams s;
        synth::loadCanopyConfig(dir.file("ok.toml"), c, s);
        CHECK(c.minVisibleFraction == 0.3);
        CHECK(c.maxIterations == 7);
        CHECK(c.seed == 99u);
        CHECK(c.canopyThresholdM == 2.5);
        CHECK(s.canopyThresholdM == 2.5);
        CHECK(s.targetTolerance == 0.005);
    }
    {
        std::ofstream(dir.file("typo.toml")) << "move_factor = 0.5\nring_facter = 1.0\n";
        synth::CanopyParams c;
        synth::SpeciesMapParams s;
        CHECK_THROWS_WITH(synth::loadCanopyConfig(dir.file("typo.toml"), c, s),
                          Catch::Contains("typo.toml:2") && Catch::Contains("ring_facter") && Catch::Contains("unknown key"));
    }
    {
        std::ofstream(dir.file("type.toml")) << "[canopy]\nmax_iterations = 2.5\n";
        synth::CanopyParams c;
        synth::SpeciesMapParams s;
        CHECK_THROWS_WITH(synth::loadCanopyConfig(dir.file("type.toml"), c, s), Catch::Contains("expected an integer"));
    }
    {
        std::ofstream(dir.file("range.toml")) << "min_visible_fraction = 2\n";
        synth::CanopyParams c;
        synth::SpeciesMapParams s;
        CHECK_THROWS_WITH(synth::loadCanopyConfig(dir.file("range.toml"), c, s), Catch::Contains("min_visible_fraction"));
    }
    {
        std::ofstream(dir.file("sweeps.toml")) << "[canopy]\ntarget_sweeps = 0\n";
        synth::CanopyParams c;
        synth::SpeciesMapParams s;
        CHECK_THROWS_WITH(synth::loadCanopyConfig(dir.file("sweeps.toml"), c, s),
                          Catch::Contains("sweeps.toml") && Catch::Contains("'target_sweeps' must lie in [1, 1000], got 0"));
    }
}

TEST_CASE("canopy files round-trip", "[canopy]") {
    test::TempDir dir("canopy_file");
    const Biome b = defaultBiome();
    const int fir = b.speciesIndex("Douglas-Fir");
    const SyntheticForest f = syntheticForest(b, fir);
    synth::CanopyRecord rec;
    rec.chmM = f.chm;
    rec.terrainM = Grid<float>::like(f.chm, 42.f);
    rec.speciesMap = uniformMap(f.chm, fir);
    rec.params.seed = 1234;
    rec.result = synth::placeCanopy(rec.chmM, rec.terrainM, rec.speciesMap, b, rec.params);
    rec.targets.push_back({"Douglas-Fir", 0.5, 0.49, 0.9, true, 1.5, 0.645, 12});
    synth::writeCanopyFile(dir.file("c.h5"), rec, b);
    const CanopyFileData d = readCanopyFile(dir.file("c.h5"), b);
    CHECK(sameTrees(d.trees, rec.result.trees));
    CHECK(d.speciesMap.data() == rec.speciesMap.data());
    CHECK(d.chmM.data() == rec.chmM.data());
    CHECK(d.chmM.sameGeometry(rec.chmM));
    CHECK(d.terrainM.data() == rec.terrainM.data());
    CHECK(d.seed == 1234u);
    CHECK(d.iterations.size() == rec.result.iterations.size() + 1);
    CHECK(d.iterations.back().iteration == -1);
    const h5::File h = h5::File::openRead(dir.file("c.h5"));
    CHECK(h.attrString("/", "format") == "eco-canopy");
    CHECK(h.attrInt("/", "schema_version") == kCanopySchemaVersion);
    for (const auto& field : synth::canopyParamFields())
        if (std::string(field.key) != "seed") CHECK(h.hasAttr("/", field.key));
    CHECK(h.attrString("/", "biome_toml").find("Redwood") != std::string::npos);
    CHECK(h.readStrings("/targets/species") == std::vector<std::string>{"Douglas-Fir"});
    // readTerrain finds the terrain in a canopy file.
    CHECK(readTerrain(dir.file("c.h5")).data() == rec.terrainM.data());
    CHECK_THROWS_WITH(readCanopyFile(dir.file("missing.h5"), b), Catch::Contains("missing.h5"));
}

TEST_CASE("apex trees stay at their CHM maximum with its height, the best state is kept", "[canopy]") {
    const Biome b = defaultBiome();
    int df = -1;
    for (const Species& s : b.species)
        if (s.name == "Douglas-Fir") df = s.id;
    REQUIRE(df >= 0);
    // Two overlapping crowns of different heights: the lower tree's visible crown is a
    // crescent whose centroid lies away from its apex, so the paper's move pulls it off.
    Grid<float> chm(80, 80, 0.5, 0, 0, 0.f);
    const Allometry& a = b.species[static_cast<std::size_t>(df)].allometry;
    const std::vector<GeneratedTree> trees = {{20.0, 20.0, 30.0, a.crownRadiusM(30)}, {20.0 + 1.3 * a.crownRadiusM(30), 20.3, 27.0, a.crownRadiusM(27)}};
    rasterizeCrowns(trees, chm);
    const Grid<float> terrain = Grid<float>::like(chm, 0.f);
    synth::CanopyParams p;
    p.ringSamples = 0;
    p.maxIterations = 5;
    p.coverageEpsilon = 0;
    const synth::CanopyResult anchored = synth::placeCanopy(chm, terrain, uniformMap(chm, df), b, p);
    INFO("seeds " << anchored.initialSeeds << ", duplicates " << anchored.duplicatesRemoved << ", final removed " << anchored.final.removed);
    REQUIRE(anchored.trees.size() == 2);
    for (const GeneratedTree& t : trees) CHECK(nearestDistance(anchored.trees, t.x, t.y) < 0.3);
    for (const Plant& t : anchored.trees) CHECK(std::abs(t.heightM - chm(chm.cellX(t.xM), chm.cellY(t.yM))) < 0.3);
    p.anchorApexTrees = 0;
    p.keepBestState = 0;
    const synth::CanopyResult moved = synth::placeCanopy(chm, terrain, uniformMap(chm, df), b, p);
    REQUIRE(moved.trees.size() == 2);
    CHECK(nearestDistance(moved.trees, trees[1].x, trees[1].y) > 0.3);  // the paper's move: off the apex

    // Keep-best: the coverage of the returned state is the best of the iterations.
    const SyntheticForest f = syntheticForest(b, df);
    synth::CanopyParams q;
    q.coverageEpsilon = 0;  // stop only when an iteration loses coverage
    q.maxIterations = 8;
    const synth::CanopyResult r = synth::placeCanopy(f.chm, Grid<float>::like(f.chm, 0.f), uniformMap(f.chm, df), b, q);
    double best = 0;
    for (const IterationStats& s : r.iterations) best = std::max(best, s.coverage);
    CHECK(r.final.coverage >= best - 0.01);  // the final clean-up may drop a starved tree or two
}

TEST_CASE("a top on a taller neighbour's flank is no CHM maximum but is found as a residual apex", "[canopy]") {
    const FlankPair pair = flankPair();
    const std::vector<GeneratedTree>& trees = pair.trees;
    const Grid<float>& chm = pair.chm;
    REQUIRE(4.35 < trees[0].crownRadiusM);
    for (const std::size_t i : synth::chmLocalMaxima(chm, 3.0, 1))
        CHECK(std::hypot(chm.cellCentreX(static_cast<int>(i % 80)) - trees[1].x, chm.cellCentreY(static_cast<int>(i / 80)) - trees[1].y) > 1.0);
    synth::CanopyParams p;
    p.ringSamples = 0;  // trees come from the seeding and the residual apices only
    const synth::CanopyResult found = pair.place(p);
    INFO("trees " << found.trees.size() << ", seeds " << found.initialSeeds);
    REQUIRE(found.trees.size() == 2);
    for (const GeneratedTree& t : trees) CHECK(nearestDistance(found.trees, t.x, t.y) < 0.5);
    for (const Plant& t : found.trees) CHECK(std::abs(t.heightM - (t.xM > 22 ? 27.0 : 30.0)) < 0.3);
    p.residualApices = 0;
    const synth::CanopyResult missed = pair.place(p);
    CHECK(nearestDistance(missed.trees, trees[1].x, trees[1].y) > 1.0);
}

TEST_CASE("two noise maxima of one crown top give one tree, two close tops with a saddle two", "[canopy]") {
    const Biome b = defaultBiome();
    const int df = b.speciesIndex("Douglas-Fir");
    const double cell = 0.914;
    const int n = 48;
    // A wide dome (flat within 0.04 m over a cell of its top) centred on cell (24, 24), with
    // two bumps of lidar noise two cells apart: both cells are strict 3 x 3 maxima.
    Grid<float> dome(n, n, cell, 0, 0, 0.f);
    const double cx = dome.cellCentreX(24), cy = dome.cellCentreY(24);
    for (int iy = 0; iy < n; ++iy)
        for (int ix = 0; ix < n; ++ix) {
            const double d = std::hypot(dome.cellCentreX(ix) - cx, dome.cellCentreY(iy) - cy);
            if (d < 8.0) dome(ix, iy) = static_cast<float>(20.0 - 6.0 * std::pow(d / 8.0, 2.5));
        }
    dome(23, 24) += 0.2f;
    dome(25, 24) += 0.25f;
    const auto maxima = synth::chmLocalMaxima(dome, 3.0, 1);
    REQUIRE(maxima.size() == 2);
    const Grid<float> terrain = Grid<float>::like(dome, 0.f);
    synth::CanopyParams p;
    p.ringSamples = 0;
    p.residualApices = 0;
    p.maxIterations = 0;  // the seeds as they are, then the final clean-up
    auto near = [&](const synth::CanopyResult& r) {
        std::size_t k = 0;
        for (const Plant& t : r.trees) k += std::hypot(t.xM - cx, t.yM - cy) < 2.5;
        return k;
    };
    const synth::CanopyResult merged = synth::placeCanopy(dome, terrain, uniformMap(dome, df), b, p);
    CHECK(merged.seedsMerged == 1);
    CHECK(near(merged) == 1);
    // The taller maximum is kept, at its cell.
    REQUIRE(merged.trees.size() == 1);
    CHECK(std::abs(merged.trees[0].xM - dome.cellCentreX(25)) < 0.5 * cell);
    p.seedMergeSaddleM = 0;
    const synth::CanopyResult off = synth::placeCanopy(dome, terrain, uniformMap(dome, df), b, p);
    CHECK(off.seedsMerged == 0);
    CHECK(near(off) == 2);

    // Two narrow cones two cells apart: the CHM drops 2 m between them, two trees stay.
    Grid<float> cones(n, n, cell, 0, 0, 0.f);
    for (const int c : {23, 25})
        for (int iy = 0; iy < n; ++iy)
            for (int ix = 0; ix < n; ++ix) {
                const double d = std::hypot(cones.cellCentreX(ix) - cones.cellCentreX(c), cones.cellCentreY(iy) - cy);
                if (d < 4.0) cones(ix, iy) = std::max(cones(ix, iy), static_cast<float>(12.0 - 2.5 * d));
            }
    REQUIRE(synth::chmLocalMaxima(cones, 3.0, 1).size() == 2);
    p.seedMergeSaddleM = 0.5;
    const synth::CanopyResult two = synth::placeCanopy(cones, terrain, uniformMap(cones, df), b, p);
    CHECK(two.seedsMerged == 0);
    CHECK(near(two) == 2);
}

TEST_CASE("the seed merge keeps two small noise-free crowns about a radius apart", "[canopy]") {
    // Two spheres of the placer's own model (Douglas-Fir, 7.0 and 6.9 m, radius about 1.7 m),
    // trunks 1.7 m apart (< 2 cells): the CHM between them drops only about 0.22 m, less than
    // seed_merge_saddle_m, so the saddle alone takes them for one top. Their trunks are about
    // one crown radius apart, beyond seed_merge_radius_fraction (0.6) of it: two trees stay.
    const Biome b = defaultBiome();
    const int df = b.speciesIndex("Douglas-Fir");
    const Allometry& allo = b.species[static_cast<std::size_t>(df)].allometry;
    const double cell = 0.914;
    const int n = 40;
    Grid<float> chm(n, n, cell, 0, 0, 0.f);
    const double y = chm.cellCentreY(20);
    const double xs[2] = {chm.cellCentreX(18) + 0.05, chm.cellCentreX(18) + 1.75};
    const double hs[2] = {7.0, 6.9};
    rasterizeCrowns({{xs[0], y, hs[0], allo.crownRadiusM(hs[0])}, {xs[1], y, hs[1], allo.crownRadiusM(hs[1])}}, chm);
    REQUIRE(synth::chmLocalMaxima(chm, 3.0, 1).size() == 2);
    REQUIRE(chm(19, 20) > 6.9f - 0.5f);  // no saddle deeper than seed_merge_saddle_m
    synth::CanopyParams p;  // the seeds as they are, then the final clean-up
    p.ringSamples = p.residualApices = p.maxIterations = 0;
    const Grid<float> terrain = Grid<float>::like(chm, 0.f);
    const synth::CanopyResult kept = synth::placeCanopy(chm, terrain, uniformMap(chm, df), b, p);
    CHECK(kept.seedsMerged == 0);
    REQUIRE(kept.trees.size() == 2);
    for (int k = 0; k < 2; ++k) CHECK(nearestDistance(kept.trees, xs[k], y) < 0.3);
    p.seedMergeRadiusFraction = 10;  // the saddle alone decides: one tree
    const synth::CanopyResult merged = synth::placeCanopy(chm, terrain, uniformMap(chm, df), b, p);
    CHECK(merged.seedsMerged == 1);
    CHECK(merged.trees.size() == 1);
}

TEST_CASE("the crescent of a crown whose apex is hidden under a taller one gives no tree top", "[canopy]") {
    // Two spheres of the placer's own model (Douglas-Fir): a 10 m tree and an 8 m one whose
    // trunk stands 1.7 m away, inside the taller crown (radius 2.2 m). The lower apex lies
    // about 1.2 m under the taller crown's surface: no top in the CHM, only a crescent of the
    // lower crown outside the taller disc. Its highest cell is a residual apex; the residual
    // apex fit finds the sphere that explains the crescent with its apex under the taller
    // crown, and that tree is not output. Without the fit a tree stands on the crescent.
    const Biome b = defaultBiome();
    const int df = b.speciesIndex("Douglas-Fir");
    const Allometry& a = b.species[static_cast<std::size_t>(df)].allometry;
    const double cell = 0.914;
    Grid<float> chm(40, 40, cell, 0, 0, 0.f);
    const double x0 = chm.cellCentreX(18) + 0.2, y0 = chm.cellCentreY(18) + 0.1;
    const std::vector<GeneratedTree> trees = {{x0, y0, 10.0, a.crownRadiusM(10.0)}, {x0 + 1.7, y0 + 0.2, 8.0, a.crownRadiusM(8.0)}};
    rasterizeCrowns(trees, chm);
    {
        // The lower apex is hidden: the taller sphere stands more than 0.3 m above it.
        const double r = trees[0].crownRadiusM, d = std::hypot(trees[1].x - x0, trees[1].y - y0);
        REQUIRE(10.0 - r + std::sqrt(r * r - d * d) > 8.0 + 0.9);
        REQUIRE(d + trees[1].crownRadiusM > r + cell);  // a crescent of at least a cell shows
    }
    const Grid<float> terrain = Grid<float>::like(chm, 0.f);
    synth::CanopyParams p;
    p.ringSamples = 0;  // trees come from the seeding and the residual apices only
    p.residualApexFit = 1;
    const synth::CanopyResult fitted = synth::placeCanopy(chm, terrain, uniformMap(chm, df), b, p);
    std::ostringstream where;
    for (const Plant& t : fitted.trees) where << " (" << t.xM - x0 << ", " << t.yM - y0 << ", " << t.heightM << ")";
    INFO("trees " << fitted.trees.size() << ", hidden apices " << fitted.hiddenApexTrees << ":" << where.str());
    REQUIRE(fitted.trees.size() == 1);
    CHECK(std::hypot(fitted.trees[0].xM - x0, fitted.trees[0].yM - y0) < 0.5);
    CHECK(std::abs(fitted.trees[0].heightM - 10.0) < 0.3);
    CHECK(fitted.hiddenApexTrees >= 1);
    p.residualApexFit = 0;
    p.crownFitPasses = 0;  // the crown fit (next test) drops that tree too
    const synth::CanopyResult plain = synth::placeCanopy(chm, terrain, uniformMap(chm, df), b, p);
    CHECK(plain.trees.size() == 2);
    CHECK(plain.hiddenApexTrees == 0);
}

TEST_CASE("the crown fit drops a tree on a hidden crown's crescent and keeps a small visible top", "[canopy]") {
    // Spheres of the placer's own model (Douglas-Fir) on 0.914 m cells, each pair on its own
    // CHM. Hidden: a 10 m tree and a 7.5 m one whose trunk stands 1.5 m away, its apex about
    // 1.6 m under the taller crown; only a crescent of the lower crown shows, and a tree
    // added there explains it. The crown fit finds the sphere that best explains what the
    // 10 m crown leaves (its apex under that crown) and the tree is not output; without the
    // fit it stays. Visible: a 10 m tree and a 6 m one 2.4 m away whose apex stands above the
    // taller crown's surface (a small tree beside a large one): kept, at its apex, with
    // and without the fit.
    const Biome b = defaultBiome();
    const int df = b.speciesIndex("Douglas-Fir");
    const Allometry& a = b.species[static_cast<std::size_t>(df)].allometry;
    const double cell = 0.914;
    auto pairChm = [&](double dx, double h2, std::vector<GeneratedTree>& trees) {
        Grid<float> chm(40, 40, cell, 0, 0, 0.f);
        const double x0 = chm.cellCentreX(18) + 0.2, y0 = chm.cellCentreY(18) + 0.1;
        trees = {{x0, y0, 10.0, a.crownRadiusM(10.0)}, {x0 + dx, y0 + 0.2, h2, a.crownRadiusM(h2)}};
        rasterizeCrowns(trees, chm);
        return chm;
    };
    auto taller = [&](const std::vector<GeneratedTree>& trees) {  // the 10 m surface above the lower trunk
        const double r = trees[0].crownRadiusM, d = std::hypot(trees[1].x - trees[0].x, trees[1].y - trees[0].y);
        return d < r ? 10.0 - r + std::sqrt(r * r - d * d) : 0.0;
    };
    auto describe = [](const synth::CanopyResult& r, const std::vector<GeneratedTree>& trees) {
        std::ostringstream o;
        o << r.trees.size() << " trees, crown fit hidden " << r.crownFitHidden << " (margin " << r.crownFitHiddenMarginM << " m):";
        for (const Plant& t : r.trees) o << " (" << t.xM - trees[0].x << ", " << t.yM - trees[0].y << ", " << t.heightM << ")";
        return o.str();
    };
    synth::CanopyParams p;
    p.crownFitPasses = 2;  // the crown fit on (off by default)

    std::vector<GeneratedTree> hidden;
    const Grid<float> hChm = pairChm(1.5, 7.5, hidden);
    REQUIRE(taller(hidden) > 7.5 + 1.2);                               // the lower apex is hidden
    REQUIRE(1.5 + hidden[1].crownRadiusM > hidden[0].crownRadiusM + cell);  // a crescent of a cell or more shows
    const Grid<float> terrain = Grid<float>::like(hChm, 0.f);
    const synth::CanopyResult fit = synth::placeCanopy(hChm, terrain, uniformMap(hChm, df), b, p);
    INFO("hidden pair, fit: " << describe(fit, hidden));
    REQUIRE(fit.trees.size() == 1);
    CHECK(fit.crownFitHidden >= 1);
    CHECK(nearestDistance(fit.trees, hidden[0].x, hidden[0].y) < 0.5);
    p.crownFitPasses = 0;
    const synth::CanopyResult noFit = synth::placeCanopy(hChm, terrain, uniformMap(hChm, df), b, p);
    INFO("hidden pair, no fit: " << describe(noFit, hidden));
    CHECK(noFit.trees.size() == 2);  // a tree on the crescent
    CHECK(noFit.crownFitHidden == 0);

    std::vector<GeneratedTree> visible;
    const Grid<float> vChm = pairChm(2.4, 6.0, visible);
    REQUIRE(taller(visible) < 6.0 - 0.3);  // the small tree's apex shows
    for (const int passes : {0, 2}) {
        p.crownFitPasses = passes;
        const synth::CanopyResult r = synth::placeCanopy(vChm, terrain, uniformMap(vChm, df), b, p);
        INFO("visible pair, passes " << passes << ": " << describe(r, visible));
        REQUIRE(r.trees.size() == 2);
        for (const GeneratedTree& t : visible) CHECK(nearestDistance(r.trees, t.x, t.y) < 0.5);
        for (const Plant& t : r.trees) CHECK(std::abs(t.heightM - (t.heightM > 8 ? 10.0 : 6.0)) < 0.3);
        CHECK(r.crownFitHidden == 0);
    }
}

TEST_CASE("after the crown fit an added tree on a conical crown keeps the CHM's height", "[canopy]") {
    // The flank pair of the next test, drawn as lidar-like crowns, not the placer's spheres:
    // z = h - D (d / r)^1.5 with D = 1.5 r (a pointed conifer crown), the lower trunk where
    // the taller crown is half a metre under the lower top. The lower tree is found
    // by the iterations (its apex is no CHM maximum); the crown fit's least-squares sphere
    // stands about a metre under such a top, and the tree must end at the CHM's height.
    FlankPair f = flankPair();
    {
        // The lower trunk where the taller cone's surface is 0.5 m under the lower top.
        const double r0 = f.trees[0].crownRadiusM;
        f.trees[1].x = f.trees[0].x + r0 * std::pow((30.0 - 26.5) / (1.5 * r0), 2.0 / 3.0);
    }
    for (int iy = 0; iy < f.chm.height(); ++iy)
        for (int ix = 0; ix < f.chm.width(); ++ix) {
            float z = 0;
            for (const GeneratedTree& t : f.trees) {
                const double d = std::hypot(f.chm.cellCentreX(ix) - t.x, f.chm.cellCentreY(iy) - t.y);
                if (d < t.crownRadiusM)
                    z = std::max(z, static_cast<float>(t.heightM - 1.5 * t.crownRadiusM * std::pow(d / t.crownRadiusM, 1.5)));
            }
            f.chm(ix, iy) = z;
        }
    synth::CanopyParams p;
    p.crownFitPasses = 2;  // the crown fit on (off by default)
    const synth::CanopyResult r = f.place(p);
    std::ostringstream where;
    for (const Plant& t : r.trees) where << " (" << t.xM << ", " << t.yM << ", " << t.heightM << ")";
    INFO(r.initialSeeds << " seeds, crown fit hidden " << r.crownFitHidden << ":" << where.str());
    REQUIRE(r.initialSeeds == 1);  // the lower top is no CHM maximum: not a seed
    REQUIRE(nearestDistance(r.trees, f.trees[1].x, f.trees[1].y) < 1.0);
    for (const Plant& t : r.trees) {
        if (std::hypot(t.xM - f.trees[1].x, t.yM - f.trees[1].y) >= 1.0) continue;
        CHECK(std::abs(t.heightM - 27.0) < 0.5);
    }
}

TEST_CASE("an added tree moves onto the CHM apex its crown explains", "[canopy]") {
    // The flank case of the residual apex test: the lower tree's apex is no CHM maximum.
    // Without residual apices the ring finds the lower crown and the tree then walks toward
    // the centroid of its visible part, away from the taller neighbour and off its apex; the
    // apex snap puts it back on the highest maximum of the CHM among its own visible cells.
    const FlankPair pair = flankPair();
    const std::vector<GeneratedTree>& trees = pair.trees;
    synth::CanopyParams p;
    p.residualApices = 0;  // the lower tree comes from the ring
    p.apexSnapRadiusFraction = 0;
    const synth::CanopyResult off = pair.place(p);
    p.apexSnapRadiusFraction = 0.75;
    const synth::CanopyResult on = pair.place(p);
    std::ostringstream where;
    for (const Plant& t : off.trees) where << " off (" << t.xM << ", " << t.yM << ", " << t.heightM << ")";
    for (const Plant& t : on.trees) where << " on (" << t.xM << ", " << t.yM << ", " << t.heightM << ")";
    INFO("snapped " << on.apexSnapped << ", crown fit hidden " << on.crownFitHidden << ":" << where.str());
    CHECK(off.apexSnapped == 0);
    CHECK(on.apexSnapped >= 1);
    CHECK(nearestDistance(off.trees, trees[1].x, trees[1].y) > 1.0);
    CHECK(nearestDistance(on.trees, trees[1].x, trees[1].y) < 0.5);
    for (const Plant& t : on.trees)
        if (std::hypot(t.xM - trees[1].x, t.yM - trees[1].y) < 0.5) CHECK(std::abs(t.heightM - 27.0) < 0.3);
    CHECK(nearestDistance(on.trees, trees[0].x, trees[0].y) < 0.3);  // the seeded tree stays
}
