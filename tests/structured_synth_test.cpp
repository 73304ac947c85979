// The structured sampler end to end (analysis -> database -> synthesis, issue 24): patterns
// of known structure are analysed into a database and synthesized on the same terrain and
// canopy; the scene must reproduce their pair correlation, canopy context and size coupling.
// Each test also runs the earlier dart sampler on the same database, which must fail the same
// bound, so the bounds measure the structure and cannot pass by construction.
#include <catch2/catch.hpp>
#include <omp.h>

#include <algorithm>
#include <cmath>

#include "analysis.h"
#include "biome.h"
#include "canopy_context.h"
#include "point_pattern.h"
#include "rng.h"
#include "undergrowth.h"

using namespace eco;

namespace {

constexpr double kSideM = 120.0;
constexpr double kCellM = 0.5;

const Biome& sonoma() {
    static const Biome b = defaultBiome();
    return b;
}
int sp(const std::string& name) { return sonoma().speciesIndex(name); }

struct Scene {
    Grid<float> terrain;
    FactorGrids features;
    std::vector<Plant> canopy;
};

/// A flat 120 m square with constant abiotics and Redwoods on a 16 m lattice (crowns of
/// radius 4 m: about 20 % cover, with open gaps between them).
Scene makeScene(double canopyHeightM = 30.0) {
    Scene s;
    const int n = static_cast<int>(kSideM / kCellM);
    s.terrain = Grid<float>(n, n, kCellM, 0, 0, 50.f);
    s.features = FactorGrids::uniform(s.terrain, {8, 100, 15, 5});
    for (double y = 8; y < kSideM; y += 16)
        for (double x = 8; x < kSideM; x += 16) {
            Plant t;
            t.speciesId = sp("Redwood");
            t.xM = x;
            t.yM = y;
            t.heightM = canopyHeightM;
            t.crownRadiusM = 4.0;
            t.groundZM = 50;
            s.canopy.push_back(t);
        }
    return s;
}

Plant undergrowthPlant(int species, double x, double y, double h) {
    Plant p;
    p.speciesId = species;
    p.xM = x;
    p.yM = y;
    p.heightM = h;
    p.crownRadiusM = sonoma().species[static_cast<std::size_t>(species)].allometry.crownRadiusM(h);
    p.groundZM = 50;
    return p;
}

bool inside(double x, double y) { return x >= 0 && y >= 0 && x < kSideM && y < kSideM; }

BiomeDatabase analyseScene(const Scene& s, const std::vector<Plant>& undergrowth) {
    analysis::AnalysisInput in;
    in.biome = &sonoma();
    in.canopy = s.canopy;
    in.undergrowth = undergrowth;
    in.features = s.features;
    in.window = RectWindow{0, 0, kSideM, kSideM};
    in.provenance.path = "memory";
    analysis::AnalysisParams ap;
    ap.kMax = 1;
    return analysis::analyse({in}, ap);
}

synth::UndergrowthSample synthesize(const Scene& s, const BiomeDatabase& db, synth::SynthMethod method, std::uint64_t seed = 3) {
    synth::SynthParams p;
    p.method = method;
    p.seed = seed;
    const synth::ClusterMap map = synth::computeClusterMap(db, sonoma(), s.canopy, s.features, p);
    return synth::sampleUndergrowth(db, sonoma(), s.canopy, map, s.terrain, p);
}

/// Pooled g of a pattern in the square, 0.25 m bins to 10 m (translation correction).
std::vector<double> pooledG(const std::vector<Plant>& plants) {
    PointPattern pp;
    pp.typeNames = {"all"};
    for (const Plant& p : plants) {
        pp.x.push_back(p.xM);
        pp.y.push_back(p.yM);
        pp.type.push_back(0);
    }
    PcfOptions o;
    o.bins = DistanceBins{10.0, 40};
    o.isotropic = false;
    const PairSums sums = countPairs(pp, RectWindow{0, 0, kSideM, kSideM}, o);
    std::vector<double> g(40);
    for (int k = 0; k < 40; ++k) g[static_cast<std::size_t>(k)] = sums.gTranslate(0, 0, k);
    return g;
}

double meanOver(const std::vector<double>& g, int from, int to) {
    double s = 0;
    for (int k = from; k < to; ++k) s += g[static_cast<std::size_t>(k)];
    return s / (to - from);
}

}  // namespace

TEST_CASE("a clustered (Thomas) pattern is synthesized with its clustering", "[synth][structured]") {
    const Scene s = makeScene();
    // Thomas process: 0.01 parents per m^2, 15 offspring each, sigma 1 m: g(r) - 1 =
    // exp(-r^2 / 4) / (4 pi 0.01) = 7.96 exp(-r^2 / 4).
    std::vector<Plant> ug;
    RandomStream rng(42, 7);
    const int fern = sp("Western Swordfern");
    for (int i = 0; i < 144; ++i) {
        const double px = rng.uniform(0, kSideM), py = rng.uniform(0, kSideM);
        for (int j = 0; j < 15; ++j) {
            const double x = px + rng.normal(), y = py + rng.normal();
            if (inside(x, y)) ug.push_back(undergrowthPlant(fern, x, y, rng.uniform(0.1, 1.0)));
        }
    }
    const BiomeDatabase db = analyseScene(s, ug);
    REQUIRE(db.hasContext());
    const std::vector<double> gIn = pooledG(ug);
    const double inShort = meanOver(gIn, 2, 8);  // 0.5 .. 2 m
    REQUIRE(inShort > 4.0);                      // the input is strongly clustered

    const synth::UndergrowthSample structured = synthesize(s, db, synth::SynthMethod::Structured);
    REQUIRE(structured.plants.size() > 1500);
    REQUIRE(structured.structure.size() == 1);
    CHECK(structured.structure[0].scales >= 1);
    const std::vector<double> gOut = pooledG(structured.plants);
    const double outShort = meanOver(gOut, 2, 8);
    INFO("g over 0.5-2 m: input " << inShort << ", structured " << outShort);
    CHECK(outShort == Approx(inShort).epsilon(0.35));
    CHECK(meanOver(gOut, 28, 40) == Approx(1.0).margin(0.25));  // 7-10 m: no clustering left

    // The dart sampler on the same database has none of it.
    const std::vector<double> gDarts = pooledG(synthesize(s, db, synth::SynthMethod::Darts).plants);
    INFO("darts " << meanOver(gDarts, 2, 8));
    CHECK(meanOver(gDarts, 2, 8) < 1.5);
}

TEST_CASE("an inhibited (hard-core) pattern keeps its hard core", "[synth][structured]") {
    const Scene s = makeScene();
    // Random sequential adsorption with a 1 m hard core, 0.4 plants per m^2.
    std::vector<Plant> ug;
    RandomStream rng(43, 7);
    const int toyon = sp("Toyon");
    const std::size_t want = static_cast<std::size_t>(0.4 * kSideM * kSideM);
    for (int attempt = 0; attempt < 400000 && ug.size() < want; ++attempt) {
        const double x = rng.uniform(0, kSideM), y = rng.uniform(0, kSideM);
        bool ok = true;
        for (const Plant& p : ug)
            if ((p.xM - x) * (p.xM - x) + (p.yM - y) * (p.yM - y) < 1.0) {
                ok = false;
                break;
            }
        if (ok) ug.push_back(undergrowthPlant(toyon, x, y, rng.uniform(0.2, 2.0)));
    }
    REQUIRE(ug.size() == want);
    const BiomeDatabase db = analyseScene(s, ug);
    const synth::UndergrowthSample out = synthesize(s, db, synth::SynthMethod::Structured);
    REQUIRE(out.structure[0].hardCoreM.size() == sonoma().species.size() * sonoma().species.size());
    CHECK(out.structure[0].hardCoreM[static_cast<std::size_t>(toyon) * sonoma().species.size() + static_cast<std::size_t>(toyon)] ==
          Approx(1.0));
    // Density held (RSA refills what the hard core rejects), and no pair closer than 1 m.
    CHECK(static_cast<double>(out.plants.size()) >= 0.95 * static_cast<double>(want));
    PointGrid grid([&] {
        std::vector<double> x;
        for (const Plant& p : out.plants) x.push_back(p.xM);
        return x;
    }(), [&] {
        std::vector<double> y;
        for (const Plant& p : out.plants) y.push_back(p.yM);
        return y;
    }(), 2.0);
    std::size_t close = 0;
    for (const Plant& p : out.plants)
        grid.forEachWithin(p.xM, p.yM, 0.999, [&](std::size_t, double, double, double d2) { close += d2 > 0; });
    CHECK(close == 0);
    const std::vector<double> g = pooledG(out.plants);
    CHECK(meanOver(g, 0, 4) < 0.05);
    CHECK(meanOver(g, 8, 40) == Approx(1.0).margin(0.2));
    // The darts have plenty of pairs inside the hard core.
    CHECK(meanOver(pooledG(synthesize(s, db, synth::SynthMethod::Darts).plants), 0, 4) > 0.5);
}

TEST_CASE("species keep their canopy context: shade lovers under crowns, others in the gaps", "[synth][structured]") {
    const Scene s = makeScene();
    const CanopyCover cover(s.canopy);
    // Sorrel only under crowns, Toyon only in the open, both uniform otherwise.
    std::vector<Plant> ug;
    RandomStream rng(44, 7);
    const int sorrel = sp("Redwood Sorrel"), toyon = sp("Toyon");
    while (ug.size() < 6000) {
        const double x = rng.uniform(0, kSideM), y = rng.uniform(0, kSideM);
        const bool covered = cover.covered(x, y);
        ug.push_back(undergrowthPlant(covered ? sorrel : toyon, x, y, covered ? rng.uniform(0.01, 0.2) : rng.uniform(0.2, 3.0)));
    }
    const BiomeDatabase db = analyseScene(s, ug);
    auto shareCovered = [&](const std::vector<Plant>& plants, int species) {
        double n = 0, c = 0;
        for (const Plant& p : plants)
            if (p.speciesId == species) {
                n += 1;
                c += cover.covered(p.xM, p.yM);
            }
        return n > 0 ? c / n : -1.0;
    };
    const synth::UndergrowthSample out = synthesize(s, db, synth::SynthMethod::Structured);
    // Context bins are whole cells (0.5 m), so a rim of plants within a cell of the crown
    // edge can land on the other side.
    CHECK(shareCovered(out.plants, sorrel) > 0.85);
    CHECK(shareCovered(out.plants, toyon) < 0.1);
    const synth::UndergrowthSample darts = synthesize(s, db, synth::SynthMethod::Darts);
    CHECK(shareCovered(darts.plants, sorrel) < 0.5);
    CHECK(shareCovered(darts.plants, toyon) > 0.1);
}

TEST_CASE("sizes are coupled by allometry and nothing is taller than the crown above it", "[synth][structured]") {
    // A low canopy (2 m) over undergrowth up to 3 m tall.
    const Scene s = makeScene(2.0);
    std::vector<Plant> ug;
    RandomStream rng(45, 7);
    const int toyon = sp("Toyon"), fern = sp("Western Swordfern");
    for (int i = 0; i < 5000; ++i) {
        const int species = i % 3 == 0 ? fern : toyon;
        ug.push_back(undergrowthPlant(species, rng.uniform(0, kSideM), rng.uniform(0, kSideM),
                                      species == fern ? rng.uniform(0.05, 1.2) : rng.uniform(0.1, 3.0)));
    }
    const BiomeDatabase db = analyseScene(s, ug);
    const synth::UndergrowthSample out = synthesize(s, db, synth::SynthMethod::Structured);
    const CanopyCover cover(s.canopy);
    std::size_t covered = 0, tooTall = 0, offAllometry = 0;
    for (const Plant& p : out.plants) {
        const double limit = cover.lowestCrownAboveM(p.xM, p.yM);
        if (limit < CanopyCover::kNone) {
            ++covered;
            tooTall += !(p.heightM < limit);
        }
        const double r = sonoma().species[static_cast<std::size_t>(p.speciesId)].allometry.crownRadiusM(p.heightM);
        offAllometry += std::abs(p.crownRadiusM - r) > 1e-12 * std::max(1.0, r);
    }
    REQUIRE(covered > 500);
    CHECK(tooTall == 0);
    CHECK(offAllometry == 0);
    CHECK(out.heightsLimitedByCrown > 0);
    // The open ground keeps the taller plants of the input.
    double tallOpen = 0;
    for (const Plant& p : out.plants) tallOpen += !cover.covered(p.xM, p.yM) && p.heightM > 2.0;
    CHECK(tallOpen > 100);
    // The dart sampler breaks both rules on the same database.
    const synth::UndergrowthSample darts = synthesize(s, db, synth::SynthMethod::Darts);
    std::size_t dartsTooTall = 0;
    for (const Plant& p : darts.plants) dartsTooTall += !(p.heightM < cover.lowestCrownAboveM(p.xM, p.yM));
    CHECK(dartsTooTall > 0);
}

TEST_CASE("the structured sampler is identical for 1 and 2 threads", "[synth][structured]") {
    const Scene s = makeScene();
    std::vector<Plant> ug;
    RandomStream rng(46, 7);
    for (int i = 0; i < 3000; ++i)
        ug.push_back(undergrowthPlant(i % 2 ? sp("Toyon") : sp("Redwood Sorrel"), rng.uniform(0, kSideM),
                                      rng.uniform(0, kSideM), rng.uniform(0.05, 1.0)));
    const BiomeDatabase db = analyseScene(s, ug);
    const int before = omp_get_max_threads();
    omp_set_num_threads(1);
    const synth::UndergrowthSample one = synthesize(s, db, synth::SynthMethod::Structured);
    omp_set_num_threads(2);
    const synth::UndergrowthSample two = synthesize(s, db, synth::SynthMethod::Structured);
    omp_set_num_threads(before);
    REQUIRE(one.plants.size() == two.plants.size());
    for (std::size_t i = 0; i < one.plants.size(); ++i) {
        REQUIRE(one.plants[i].xM == two.plants[i].xM);
        REQUIRE(one.plants[i].yM == two.plants[i].yM);
        REQUIRE(one.plants[i].heightM == two.plants[i].heightM);
        REQUIRE(one.plants[i].speciesId == two.plants[i].speciesId);
    }
}

TEST_CASE("the structured sampler's parallel paths give one scene for 1, 2 and 3 threads", "[synth][structured]") {
    // The test above runs below the sampler's parallel threshold (65536 candidates): here a
    // 400 m square at 0.5 m cells (about 200k darts) with clustered ferns, Toyon with
    // a hard core and Poisson sorrel, so that the threads split the candidate rows, the quota
    // keys, the hard cores' neighbour lists, the final order and the sizes; 3 threads split
    // every range unevenly.
    const Scene small = makeScene();
    std::vector<Plant> ug;
    RandomStream rng(47, 7);
    const int fern = sp("Western Swordfern"), toyon = sp("Toyon"), sorrel = sp("Redwood Sorrel");
    for (int i = 0; i < 100; ++i) {
        const double px = rng.uniform(0, kSideM), py = rng.uniform(0, kSideM);
        for (int j = 0; j < 12; ++j) {
            const double x = px + rng.normal(), y = py + rng.normal();
            if (inside(x, y)) ug.push_back(undergrowthPlant(fern, x, y, rng.uniform(0.1, 1.0)));
        }
    }
    std::vector<Plant> hard;
    for (int attempt = 0; attempt < 20000 && hard.size() < 2000; ++attempt) {
        const double x = rng.uniform(0, kSideM), y = rng.uniform(0, kSideM);
        bool ok = true;
        for (const Plant& p : hard) ok = ok && (p.xM - x) * (p.xM - x) + (p.yM - y) * (p.yM - y) >= 0.8 * 0.8;
        if (ok) hard.push_back(undergrowthPlant(toyon, x, y, rng.uniform(0.2, 2.0)));
    }
    ug.insert(ug.end(), hard.begin(), hard.end());
    for (int i = 0; i < 6000; ++i) ug.push_back(undergrowthPlant(sorrel, rng.uniform(0, kSideM), rng.uniform(0, kSideM), rng.uniform(0.05, 0.4)));
    const BiomeDatabase db = analyseScene(small, ug);

    Scene big;
    constexpr double kBigM = 400.0;
    big.terrain = Grid<float>(static_cast<int>(kBigM / kCellM), static_cast<int>(kBigM / kCellM), kCellM, 0, 0, 50.f);
    for (int iy = 0; iy < big.terrain.height(); ++iy)  // a slope, so that ground heights differ
        for (int ix = 0; ix < big.terrain.width(); ++ix) big.terrain(ix, iy) = static_cast<float>(50 + 0.05 * ix + 0.02 * iy);
    big.features = FactorGrids::uniform(big.terrain, {8, 100, 15, 5});
    for (double y = 8; y < kBigM; y += 16)
        for (double x = 8; x < kBigM; x += 16) big.canopy.push_back(undergrowthPlant(sp("Redwood"), x, y, 30.0));
    for (Plant& t : big.canopy) t.crownRadiusM = 4.0;

    const int before = omp_get_max_threads();
    std::vector<synth::UndergrowthSample> runs;
    for (int threads : {1, 2, 3}) {
        omp_set_num_threads(threads);
        runs.push_back(synthesize(big, db, synth::SynthMethod::Structured, 11));
    }
    omp_set_num_threads(before);
    const synth::UndergrowthSample& one = runs[0];
    REQUIRE(one.darts > 2 * 65536);      // well above the parallel threshold
    REQUIRE(one.dartsInhibited > 0);     // the hard cores took part
    REQUIRE(one.plants.size() > 50000);
    for (std::size_t k = 1; k < runs.size(); ++k) {
        const synth::UndergrowthSample& other = runs[k];
        INFO("threads: " << k + 1);
        REQUIRE(other.plants.size() == one.plants.size());
        CHECK(other.darts == one.darts);
        CHECK(other.dartsInhibited == one.dartsInhibited);
        CHECK(other.passes == one.passes);
        CHECK(other.plantRegion == one.plantRegion);
        std::size_t differ = 0;
        for (std::size_t i = 0; i < one.plants.size(); ++i) {
            const Plant &a = one.plants[i], &b = other.plants[i];
            differ += a.speciesId != b.speciesId || a.xM != b.xM || a.yM != b.yM || a.groundZM != b.groundZM ||
                      a.heightM != b.heightM || a.crownRadiusM != b.crownRadiusM;
        }
        CHECK(differ == 0);
    }
}

TEST_CASE("canopy depth map: the distance to the crown-cover edge, signed", "[synth][structured]") {
    // One crown of radius 5 m at the centre of a 40 m square of 0.5 m cells.
    const Grid<float> geometry(80, 80, 0.5, 0, 0);
    Plant t;
    t.xM = 20;
    t.yM = 20;
    t.crownRadiusM = 5;
    t.heightM = 20;
    const Grid<float> depth = canopyDepthMap(geometry, {t});
    // A cell centre at distance d from the trunk lies about 5 - d from the edge (inside +,
    // outside -), to within a cell.
    for (int iy = 0; iy < 80; iy += 3)
        for (int ix = 0; ix < 80; ix += 3) {
            const double d = std::hypot(geometry.cellCentreX(ix) - 20, geometry.cellCentreY(iy) - 20);
            const double expected = std::clamp(5.0 - d, -kCanopyDepthCapM, kCanopyDepthCapM);
            INFO("cell " << ix << "," << iy << " distance " << d);
            CHECK(depth(ix, iy) == Approx(expected).margin(0.6));
            CHECK((depth(ix, iy) > 0) == (d < 5));
        }
    CanopyContextBins bins;
    CHECK(bins.binOf(-100) == 0);
    CHECK(bins.binOf(0.0) == 5);
    CHECK(bins.binOf(100) == bins.count() - 1);
    CHECK(bins.coveredBin(5));
    CHECK_FALSE(bins.coveredBin(4));
}

TEST_CASE("canopy cover: lowest crown above a point equal to a direct search", "[synth][structured]") {
    // Crowns of very different radii (the cover's cells follow the mean one), points inside,
    // on and beyond them: the answer is the lowest tree whose disc holds the point. 6000 trees
    // take the parallel construction (bands of cell rows), on 1 and 2 threads.
    const int nTrees = GENERATE(300, 6000);
    const int threads = GENERATE(1, 2);
    const double side = std::sqrt(nTrees / 300.0);  // the same density at both sizes
    std::vector<Plant> canopy;
    RandomStream rs(9, 3);
    for (int i = 0; i < nTrees; ++i) {
        Plant t;
        t.xM = rs.uniform(-50, 50) * side;
        t.yM = rs.uniform(0, 80) * side;
        t.crownRadiusM = i % 50 == 0 ? rs.uniform(8, 15) : i % 7 == 0 ? 0.0 : rs.uniform(0.5, 3);
        t.heightM = rs.uniform(2, 30);
        canopy.push_back(t);
    }
    const int before = omp_get_max_threads();
    omp_set_num_threads(threads);
    const CanopyCover cover(canopy);
    omp_set_num_threads(before);
    int covered = 0;
    const int nPoints = nTrees > 1000 ? 4000 : 20000;
    for (int k = 0; k < nPoints; ++k) {
        double x = rs.uniform(-70, 70) * side, y = rs.uniform(-20, 100) * side;
        if (k % 4 == 0) {  // on a crown's rim
            const Plant& t = canopy[static_cast<std::size_t>(k) % canopy.size()];
            x = t.xM + t.crownRadiusM;
            y = t.yM;
        }
        double lowest = CanopyCover::kNone;
        for (const Plant& t : canopy) {
            const double dx = t.xM - x, dy = t.yM - y;
            if (t.crownRadiusM > 0 && dx * dx + dy * dy < t.crownRadiusM * t.crownRadiusM) lowest = std::min(lowest, t.heightM);
        }
        covered += lowest < CanopyCover::kNone;
        REQUIRE(cover.lowestCrownAboveM(x, y) == lowest);
    }
    CHECK(covered > nPoints / 10);
    CHECK(CanopyCover({}).lowestCrownAboveM(0, 0) == CanopyCover::kNone);
}

TEST_CASE("canopy depth map: equal to a brute-force distance transform", "[synth][structured]") {
    // Random crowns, some columns and rows without cover, on a grid small enough for the
    // direct evaluation of the definition: the distance between cell centres to the nearest
    // cell of the other kind, less half a cell, capped.
    const int w = 61, h = 47;
    const double cs = 0.7;
    const Grid<float> geometry(w, h, cs, 3, -2);
    std::vector<Plant> canopy;
    RandomStream rs(5, 17);
    for (int i = 0; i < 14; ++i) {
        Plant t;
        t.xM = 3 + rs.uniform(0, 0.6 * w * cs);
        t.yM = -2 + rs.uniform(0, h * cs);
        t.crownRadiusM = rs.uniform(0.3, 4.0);
        t.heightM = 10;
        canopy.push_back(t);
    }
    const Grid<std::uint8_t> mask = canopyCoverMask(geometry, canopy);
    const Grid<float> depth = canopyDepthMap(geometry, canopy);
    for (int iy = 0; iy < h; ++iy)
        for (int ix = 0; ix < w; ++ix) {
            const bool covered = mask(ix, iy) != 0;
            double best = -1;
            for (int jy = 0; jy < h; ++jy)
                for (int jx = 0; jx < w; ++jx)
                    if ((mask(jx, jy) != 0) != covered) {
                        const double d2 = double(jx - ix) * (jx - ix) + double(jy - iy) * (jy - iy);
                        if (best < 0 || d2 < best) best = d2;
                    }
            const double dm = best < 0 ? kCanopyDepthCapM : std::min(kCanopyDepthCapM, (std::sqrt(best) - 0.5) * cs);
            INFO("cell " << ix << "," << iy);
            REQUIRE(depth(ix, iy) == static_cast<float>(covered ? dm : -dm));
        }
}
