// Tests of the undergrowth synthesizer (synth/undergrowth), the scene file, PDB export and
// comparison (synth/scene); the `eco synth` / `eco compare` commands are tested in
// synth_cli_test.cpp.
//
// The database is built in memory (no analyser, synth_world_fixture.h): a flat 200 x 200 m
// terrain whose sun rises from west to east, Redwoods (sub-biome 1, Conifer) in its western
// half and Coast Live Oaks (sub-biome 2, California Oak) in its eastern half. The database
// holds combination 1 split into two regions by sun, and combination 2; cells seeded by both
// (combination 3, absent from the database) are given a stand-in, as
// BiomeDatabase::nearestRegion does.
#include <hdf5.h>
#include <omp.h>

#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <map>
#include <set>

#include "abiotics.h"
#include "biome.h"
#include "biome_db.h"
#include "canopy_placer.h"
#include "error.h"
#include "forest_floor.h"
#include "h5io.h"
#include "param_table_check.h"
#include "scene.h"
#include "synth_world_fixture.h"
#include "terrain_io.h"
#include "test_util.h"
#include "undergrowth.h"

using namespace eco;

namespace {

// ------------------------------------------------------------------ statistics helpers

/// Regularised upper incomplete gamma Q(a, x) (series below a + 1, continued fraction above).
double gammaQ(double a, double x) {
    if (x <= 0) return 1.0;
    const double lnPre = a * std::log(x) - x - std::lgamma(a);
    if (x < a + 1) {
        double sum = 1.0 / a, term = sum;
        for (int n = 1; n < 1000; ++n) {
            term *= x / (a + n);
            sum += term;
            if (std::abs(term) < std::abs(sum) * 1e-15) break;
        }
        return 1.0 - sum * std::exp(lnPre);
    }
    double b = x + 1 - a, c = 1e300, d = 1 / b, h = d;
    for (int i = 1; i < 1000; ++i) {
        const double an = -i * (i - a);
        b += 2;
        d = an * d + b;
        if (std::abs(d) < 1e-300) d = 1e-300;
        c = b + an / c;
        if (std::abs(c) < 1e-300) c = 1e-300;
        d = 1 / d;
        const double del = d * c;
        h *= del;
        if (std::abs(del - 1) < 1e-15) break;
    }
    return std::exp(lnPre) * h;
}

/// Pearson chi-square p-value of `values` against the bin probabilities of a histogram
/// (bins of expected count < 5 are merged with their neighbour).
double chiSquarePValue(const DbHistogram& h, const std::vector<double>& values) {
    const std::size_t nb = h.counts.size();
    double total = 0;
    for (double c : h.counts) total += c;
    std::vector<double> observed(nb, 0.0);
    for (double v : values) {
        auto it = std::upper_bound(h.edges.begin(), h.edges.end(), v);
        std::size_t k = it == h.edges.begin() ? 0 : static_cast<std::size_t>(it - h.edges.begin()) - 1;
        observed[std::min(k, nb - 1)] += 1;
    }
    const double n = static_cast<double>(values.size());
    std::vector<double> obs, exp;
    double o = 0, e = 0;
    for (std::size_t k = 0; k < nb; ++k) {
        o += observed[k];
        e += n * h.counts[k] / total;
        if (e >= 5) {
            obs.push_back(o);
            exp.push_back(e);
            o = e = 0;
        }
    }
    if (e > 0 || o > 0) {
        if (exp.empty()) return 1.0;
        obs.back() += o;
        exp.back() += e;
    }
    double chi2 = 0;
    for (std::size_t k = 0; k < obs.size(); ++k) chi2 += (obs[k] - exp[k]) * (obs[k] - exp[k]) / exp[k];
    const double dof = static_cast<double>(obs.size()) - 1;
    return dof > 0 ? gammaQ(dof / 2, chi2 / 2) : 1.0;
}

// ------------------------------------------------------------------ the test world (synth_world_fixture.h)

using test::kCell;
using test::kSide;
using test::makeWorld;
using test::World;

bool samePlants(const std::vector<Plant>& a, const std::vector<Plant>& b) {
    if (a.size() != b.size()) return false;
    for (std::size_t i = 0; i < a.size(); ++i)
        if (a[i].speciesId != b[i].speciesId || std::memcmp(&a[i].xM, &b[i].xM, sizeof(double)) != 0 ||
            std::memcmp(&a[i].yM, &b[i].yM, sizeof(double)) != 0 || a[i].heightM != b[i].heightM ||
            a[i].crownRadiusM != b[i].crownRadiusM || a[i].groundZM != b[i].groundZM)
            return false;
    return true;
}

}  // namespace

// ======================================================================== cluster map

TEST_CASE("seeding labels match a direct per-cell evaluation of the analyser's rule", "[synth]") {
    const World w = makeWorld();
    Grid<float> weight;
    const Grid<std::int32_t> labels = seedingLabels(w.terrain, w.canopy, w.db.canopySubBiomeMask, 12.0, 4.0, &weight);
    std::int64_t mismatches = 0;
    for (int iy = 0; iy < kSide; iy += 3)
        for (int ix = 0; ix < kSide; ix += 3) {
            int mask = 0;
            double k = 0;
            for (const Plant& t : w.canopy) {
                const double dx = w.terrain.cellCentreX(ix) - t.xM, dy = w.terrain.cellCentreY(iy) - t.yM;
                const double R = 12.0 * t.crownRadiusM;
                if (dx * dx + dy * dy <= R * R) {
                    mask |= w.db.canopySubBiomeMask[static_cast<std::size_t>(t.speciesId)];
                    const double d = std::sqrt(dx * dx + dy * dy);
                    k += d <= 4.0 * t.crownRadiusM ? 1.0 : (R - d) / (8.0 * t.crownRadiusM);
                }
            }
            if (labels(ix, iy) != mask) ++mismatches;
            CHECK(weight(ix, iy) == Approx(std::min(1.0, k)).margin(1e-4));
        }
    CHECK(mismatches == 0);
    // Both sub-biomes occur, and their overlap.
    const auto& d = labels.data();
    CHECK(std::count(d.begin(), d.end(), 1) > 0);
    CHECK(std::count(d.begin(), d.end(), 2) > 0);
    CHECK(std::count(d.begin(), d.end(), 3) > 0);
}

TEST_CASE("the cluster map assigns each cell the database's nearest region", "[synth]") {
    const World w = makeWorld();
    const synth::ClusterMap map = synth::computeClusterMap(w.db, w.biome, w.canopy, w.features, synth::SynthParams{});
    std::set<int> seen;
    for (int iy = 0; iy < kSide; iy += 2)
        for (int ix = 0; ix < kSide; ix += 2) {
            const int expected = w.db.nearestRegion(map.combination(ix, iy), w.features.at(ix, iy));
            REQUIRE(map.region(ix, iy) == expected);
            seen.insert(expected);
            if (expected < 0) CHECK(map.seedWeight(ix, iy) == 0.0f);
        }
    CHECK(seen.count(0) == 1);
    CHECK(seen.count(1) == 1);
    CHECK(seen.count(2) == 1);
}

// ======================================================================== sampling

TEST_CASE("histogram quantiles invert the histogram's CDF", "[synth]") {
    DbHistogram h;
    h.edges = {0, 1, 2, 4};
    h.counts = {1, 0, 3};
    CHECK(synth::histogramQuantile(h, 0.0) == Approx(0.0));
    CHECK(synth::histogramQuantile(h, 0.125) == Approx(0.5));
    CHECK(synth::histogramQuantile(h, 0.25) == Approx(2.0));
    CHECK(synth::histogramQuantile(h, 0.625) == Approx(3.0));
    DbHistogram empty;
    empty.edges = {0, 1};
    empty.counts = {0};
    CHECK(synth::histogramQuantile(empty, 0.5) < 0);
}

TEST_CASE("the dart sampler's density, species proportions and sizes match the database", "[synth]") {
    const World w = makeWorld();
    synth::SynthParams params;
    params.method = synth::SynthMethod::Darts;  // height and radius histograms met one by one
    params.seed = 11;
    const synth::ClusterMap map = synth::computeClusterMap(w.db, w.biome, w.canopy, w.features, params);
    const synth::UndergrowthSample s = synth::sampleUndergrowth(w.db, w.biome, w.canopy, map, w.terrain, params);
    REQUIRE(s.plants.size() > 20000);
    for (const auto& r : s.regions) {
        INFO("region " << r.region);
        CHECK(r.placed == r.targetCount);
    }
    // Re-analysed from the plants alone (as eco compare does).
    const synth::SceneComparison c = synth::compareScene(w.canopy, s.plants, map.region, w.db);
    int checked = 0;
    for (const auto& r : c.regions) {
        if (r.areaM2 < 1000) continue;  // "enough area": at least 1000 m^2 (hundreds of plants)
        INFO("region " << r.region << ": density " << r.densityPerM2 << " target " << r.targetDensityPerM2);
        CHECK(std::abs(r.densityRelativeError) <= 0.05);
        CHECK(r.proportionMaxDifference <= 0.05);
        ++checked;
    }
    CHECK(checked == 3);
    // No plant on a trunk; every plant inside the terrain, on the terrain's surface.
    for (const Plant& p : s.plants) {
        REQUIRE(p.xM >= 0);
        REQUIRE(p.xM <= kSide * kCell);
        REQUIRE(p.groundZM == Approx(w.terrain.sampleBilinear(p.xM, p.yM)));
    }
    for (const Plant& t : w.canopy)
        for (const Plant& p : s.plants) {
            const double dx = p.xM - t.xM, dy = p.yM - t.yM;
            REQUIRE(dx * dx + dy * dy >= std::pow(params.trunkExclusionFactor * t.crownRadiusM, 2));
        }

    SECTION("size histograms pass a chi-square test at significance 0.001 (Bonferroni over all tests)") {
        std::vector<std::vector<std::vector<double>>> heights(w.db.regions.size(), std::vector<std::vector<double>>(w.biome.species.size()));
        auto radii = heights;
        for (std::size_t i = 0; i < s.plants.size(); ++i) {
            const Plant& p = s.plants[i];
            heights[static_cast<std::size_t>(s.plantRegion[i])][static_cast<std::size_t>(p.speciesId)].push_back(p.heightM);
            radii[static_cast<std::size_t>(s.plantRegion[i])][static_cast<std::size_t>(p.speciesId)].push_back(p.crownRadiusM);
        }
        struct Test {
            const DbHistogram* h;
            const std::vector<double>* v;
            std::string what;
        };
        std::vector<Test> tests;
        for (std::size_t r = 0; r < w.db.regions.size(); ++r)
            for (std::size_t sp = 0; sp < w.biome.species.size(); ++sp)
                if (heights[r][sp].size() >= 200) {
                    tests.push_back({&w.db.regions[r].height[sp], &heights[r][sp], "height"});
                    tests.push_back({&w.db.regions[r].crownRadius[sp], &radii[r][sp], "radius"});
                }
        REQUIRE(tests.size() >= 16);
        const double alpha = 0.001 / static_cast<double>(tests.size());
        for (const auto& t : tests) {
            const double p = chiSquarePValue(*t.h, *t.v);
            INFO(t.what << " of " << t.v->size() << " plants: p = " << p);
            CHECK(p > alpha);
        }
        // A wrong histogram is rejected: heights compared with another species' histogram.
        CHECK(chiSquarePValue(w.db.regions[0].height[static_cast<std::size_t>(w.biome.speciesIndex("Tanoak"))],
                              heights[0][static_cast<std::size_t>(w.biome.speciesIndex("Redwood Sorrel"))]) < alpha);
    }
}

TEST_CASE("species respect the seeding sub-biomes of each cell", "[synth]") {
    const World w = makeWorld();
    const synth::ClusterMap map = synth::computeClusterMap(w.db, w.biome, w.canopy, w.features, synth::SynthParams{});
    const synth::UndergrowthSample s = synth::sampleUndergrowth(w.db, w.biome, w.canopy, map, w.terrain, synth::SynthParams{});
    for (const Plant& p : s.plants) {
        const int mask = map.combination(map.combination.cellX(p.xM), map.combination.cellY(p.yM));
        int speciesMask = 0;
        for (int b : w.biome.species[static_cast<std::size_t>(p.speciesId)].subBiomes) speciesMask |= 1 << (b - 1);
        REQUIRE((mask & speciesMask) != 0);
    }
}

TEST_CASE("synthesis is identical with 1 and 2 threads", "[synth]") {
    const World w = makeWorld();
    synth::SynthParams params;
    params.seed = 5;
    synth::RefineParams rp;
    rp.sweeps = 2;  // both tilings (the second is shifted by half a tile)
    const int before = omp_get_max_threads();
    struct Out {
        synth::ClusterMap map;
        std::vector<Plant> plants;
        synth::RefineResult refine;
        synth::ForestFloor floor;
    };
    auto run = [&](int threads) {
        omp_set_num_threads(threads);
        Out o;
        o.map = synth::computeClusterMap(w.db, w.biome, w.canopy, w.features, params);
        o.plants = synth::sampleUndergrowth(w.db, w.biome, w.canopy, o.map, w.terrain, params).plants;
        o.refine = synth::refineUndergrowth(o.plants, w.canopy, o.map, w.terrain, w.db, params, rp);
        o.floor = synth::computeForestFloor(w.features, w.canopy, o.plants, w.biome, synth::ForestFloorParams{});
        return o;
    };
    const Out a = run(1), b = run(2);
    omp_set_num_threads(before);
    CHECK(a.map.region.data() == b.map.region.data());
    CHECK(a.map.combination.data() == b.map.combination.data());
    CHECK(std::memcmp(a.map.seedWeight.data().data(), b.map.seedWeight.data().data(), a.map.seedWeight.size() * sizeof(float)) == 0);
    CHECK(samePlants(a.plants, b.plants));
    CHECK(a.refine.accepted == b.refine.accepted);
    CHECK(a.refine.objectivePerSweep == b.refine.objectivePerSweep);
    CHECK(a.floor.grass.data() == b.floor.grass.data());
    CHECK(a.floor.litter.data() == b.floor.litter.data());
}

TEST_CASE("another seed gives another scene with the same statistics", "[synth]") {
    const World w = makeWorld();
    synth::SynthParams p1, p2;
    p2.seed = 2;
    const synth::ClusterMap map = synth::computeClusterMap(w.db, w.biome, w.canopy, w.features, p1);
    const auto a = synth::sampleUndergrowth(w.db, w.biome, w.canopy, map, w.terrain, p1);
    const auto b = synth::sampleUndergrowth(w.db, w.biome, w.canopy, map, w.terrain, p2);
    CHECK(a.plants.size() == b.plants.size());
    CHECK_FALSE(samePlants(a.plants, b.plants));
}

// ======================================================================== refinement

TEST_CASE("refinement lowers the pair-correlation distance and keeps the canopy, regions and species", "[synth]") {
    const World w = makeWorld(1.0);  // the database's undergrowth keeps 1 m apart; sampling does not
    synth::SynthParams params;
    const synth::ClusterMap map = synth::computeClusterMap(w.db, w.biome, w.canopy, w.features, params);
    synth::UndergrowthSample s = synth::sampleUndergrowth(w.db, w.biome, w.canopy, map, w.terrain, params);
    std::vector<Plant> plants = s.plants;
    const std::vector<Plant> canopyBefore = w.canopy;
    synth::RefineParams rp;
    rp.sweeps = 3;
    const synth::RefineResult r = synth::refineUndergrowth(plants, w.canopy, map, w.terrain, w.db, params, rp);
    INFO("distance " << r.distanceBefore << " -> " << r.distanceAfter << ", accepted " << r.accepted << " of " << r.proposals);
    CHECK(r.distanceAfter < 0.8 * r.distanceBefore);
    REQUIRE(r.objectivePerSweep.size() == 4);
    CHECK(r.objectivePerSweep.back() < r.objectivePerSweep.front());
    CHECK(r.accepted > 0);
    CHECK(samePlants(w.canopy, canopyBefore));
    REQUIRE(plants.size() == s.plants.size());
    for (std::size_t i = 0; i < plants.size(); ++i) {
        REQUIRE(plants[i].speciesId == s.plants[i].speciesId);
        REQUIRE(plants[i].heightM == s.plants[i].heightM);
        const int ix = map.region.cellX(plants[i].xM), iy = map.region.cellY(plants[i].yM);
        REQUIRE(map.region.inside(ix, iy));
        REQUIRE(map.region(ix, iy) == s.plantRegion[i]);
        REQUIRE(plants[i].groundZM == Approx(w.terrain.sampleBilinear(plants[i].xM, plants[i].yM)));
    }
    // The distance compareScene reports agrees (same estimator, all sources).
    const synth::SceneComparison after = synth::compareScene(w.canopy, plants, map.region, w.db, nullptr, 0);
    CHECK(after.pcfDistance == Approx(r.distanceAfter).epsilon(0.05));
}

TEST_CASE("refinement inside a window moves only the plants inside it", "[synth]") {
    const World w = makeWorld(1.0);
    const synth::ClusterMap map = synth::computeClusterMap(w.db, w.biome, w.canopy, w.features, synth::SynthParams{});
    const synth::UndergrowthSample s = synth::sampleUndergrowth(w.db, w.biome, w.canopy, map, w.terrain, synth::SynthParams{});
    std::vector<Plant> plants = s.plants;
    synth::RefineParams rp;
    rp.sweeps = 1;
    rp.useWindow = true;
    rp.window = RectWindow{50, 50, 100, 100};
    const synth::RefineResult r = synth::refineUndergrowth(plants, w.canopy, map, w.terrain, w.db, synth::SynthParams{}, rp);
    CHECK(r.accepted > 0);
    CHECK(r.distanceAfter < r.distanceBefore);
    for (std::size_t i = 0; i < plants.size(); ++i) {
        const bool inside = rp.window.contains(s.plants[i].xM, s.plants[i].yM);
        if (!inside) REQUIRE((plants[i].xM == s.plants[i].xM && plants[i].yM == s.plants[i].yM));
        else REQUIRE(rp.window.contains(plants[i].xM, plants[i].yM));
    }
}

// ======================================================================== files

TEST_CASE("scene files, CSV and PDB plant lists round-trip", "[synth]") {
    const World w = makeWorld();
    test::TempDir dir("synth_files");
    synth::SceneRecord rec;
    rec.params.seed = 77;
    rec.clusterMap = synth::computeClusterMap(w.db, w.biome, w.canopy, w.features, rec.params);
    rec.sampling = synth::sampleUndergrowth(w.db, w.biome, w.canopy, rec.clusterMap, w.terrain, rec.params);
    rec.undergrowth = rec.sampling.plants;
    rec.canopy = w.canopy;
    rec.terrainM = w.terrain;
    rec.floor = synth::computeForestFloor(w.features, w.canopy, rec.undergrowth, w.biome, rec.floorParams);
    rec.databasePath = "in-memory";
    synth::writeSceneFile(dir.file("scene.h5"), rec, w.biome, w.db);
    const synth::SceneData d = synth::readSceneFile(dir.file("scene.h5"), w.biome);
    CHECK(samePlants(d.canopy, rec.canopy));
    CHECK(samePlants(d.undergrowth, rec.undergrowth));
    CHECK(d.clusterMap.data() == rec.clusterMap.region.data());
    CHECK(d.combinationMap.data() == rec.clusterMap.combination.data());
    CHECK(d.grass.data() == rec.floor.grass.data());
    CHECK(d.litter.data() == rec.floor.litter.data());
    CHECK(d.seed == 77);
    {
        h5::File f = h5::File::openRead(dir.file("scene.h5"));
        CHECK(f.attrString("/", "format") == "eco-scene");
        CHECK(f.attrInt("/", "schema_version") == 1);
        // Typed attributes (docs/hdf5.md): a real as a double, not the text "4".
        CHECK_FALSE(f.attrIsString("/", "seed_inner_radius_factor"));
        CHECK(f.attrDouble("/", "seed_inner_radius_factor") == 4.0);
        CHECK(f.attrString("/undergrowth", "layer") == "undergrowth");
        CHECK(f.readF64("/regions/placed").size() == w.db.regions.size());
    }

    synth::writePdb(dir.file("scene.pdb"), rec.canopy, rec.undergrowth);
    const std::vector<synth::PdbSpecies> pdb = synth::readPdb(dir.file("scene.pdb"));
    std::size_t total = 0;
    for (const auto& sp : pdb) {
        total += sp.plants.size();
        for (const Plant& p : sp.plants) {
            REQUIRE(p.heightM >= sp.minHeightM - 1e-4);
            REQUIRE(p.heightM <= sp.maxHeightM + 1e-4);
        }
    }
    CHECK(total == rec.canopy.size() + rec.undergrowth.size());
    CHECK(std::is_sorted(pdb.begin(), pdb.end(), [](const synth::PdbSpecies& a, const synth::PdbSpecies& b) { return a.speciesId < b.speciesId; }));
    // The first canopy tree is the first plant of its species block (canopy is written first).
    const auto it = std::find_if(pdb.begin(), pdb.end(), [&](const synth::PdbSpecies& s) { return s.speciesId == w.canopy[0].speciesId; });
    REQUIRE(it != pdb.end());
    CHECK(it->plants[0].xM == Approx(w.canopy[0].xM).margin(1e-4));
    CHECK(it->plants[0].groundZM == Approx(w.canopy[0].groundZM).margin(1e-4));
    // A truncated file names the line.
    {
        std::ofstream(dir.file("bad.pdb")) << "1\n3 0.1 2.0 0.5\n2\n1 2 3 4 5\n";
        CHECK_THROWS_WITH(synth::readPdb(dir.file("bad.pdb")), Catch::Contains("bad.pdb") && Catch::Contains("file ends"));
    }
    // A damaged plant count is the same error, not an allocation of 10^14 plants (fuzz_csv:
    // AddressSanitizer's allocation-size-too-big; std::bad_alloc in a plain build).
    {
        std::ofstream(dir.file("count.pdb")) << "1\n3 0.1 2.0 0.5\n99999999999999\n1 2 3 4 5\n";
        CHECK_THROWS_AS(synth::readPdb(dir.file("count.pdb")), IoError);
        CHECK_THROWS_WITH(synth::readPdb(dir.file("count.pdb")), Catch::Contains("count.pdb:4") && Catch::Contains("file ends"));
    }

    // Seedlings far below a millimetre keep a nonzero height and crown radius (4 decimals
    // printed 168 of the demo's seedlings as 0.0000); lengths from 0.1 m up keep the earlier
    // "%.4f" text, and every value stays one fixed-point token.
    {
        const std::vector<Plant> tiny = {{2, 1.5, 2.5, 10.0, 2.293766e-7, 7.408e-7}, {2, 3.0, 4.0, 11.0, 0.01234567, 0.003},
                                         {2, 5.0, 6.0, 12.0, 33.25501, 4.748}};
        synth::writePdb(dir.file("tiny.pdb"), {}, tiny);
        const auto back = synth::readPdb(dir.file("tiny.pdb"));
        REQUIRE(back.size() == 1);
        REQUIRE(back[0].plants.size() == 3);
        for (std::size_t i = 0; i < tiny.size(); ++i) {
            CHECK(back[0].plants[i].heightM == Approx(tiny[i].heightM).epsilon(1e-3));
            CHECK(back[0].plants[i].crownRadiusM == Approx(tiny[i].crownRadiusM).epsilon(1e-3));
        }
        CHECK(back[0].minHeightM == Approx(2.293766e-7).epsilon(1e-3));
        std::ostringstream textStream;
        textStream << std::ifstream(dir.file("tiny.pdb")).rdbuf();
        const std::string text = textStream.str();
        CHECK_THAT(text, Catch::Contains("1.5000 2.5000 10.0000 0.0000002294 0.0000007408\n"));
        CHECK_THAT(text, Catch::Contains("3.0000 4.0000 11.0000 0.01235 0.003000\n"));
        CHECK_THAT(text, Catch::Contains("5.0000 6.0000 12.0000 33.2550 4.7480\n"));
        CHECK(text.find('e') == std::string::npos);
    }

    synth::writeScenePlantsCsv(dir.file("plants.csv"), rec.canopy, rec.undergrowth, w.biome);
    std::ifstream csv(dir.file("plants.csv"));
    std::string header;
    std::getline(csv, header);
    CHECK(header == "layer,species_id,species,x_m,y_m,ground_z_m,height_m,crown_radius_m");
    std::size_t lines = 0;
    for (std::string l; std::getline(csv, l);) ++lines;
    CHECK(lines == total);

    synth::writeScenePng(dir.file("scene.png"), rec.canopy, rec.undergrowth, w.terrain, &rec.floor, w.biome, "test");
    const RectWindow crop = synth::defaultZoomWindow(w.terrain, 40);
    synth::writeScenePng(dir.file("zoom.png"), rec.canopy, rec.undergrowth, w.terrain, &rec.floor, w.biome, "zoom", &crop, 400);
    CHECK(std::filesystem::file_size(dir.file("scene.png")) > 1000);
    CHECK(std::filesystem::file_size(dir.file("zoom.png")) > 1000);
}

TEST_CASE("synthesis and refinement parameters: one description drives validation, the record and the docs",
          "[synth]") {
    test::checkParamTable(
        synth::synthParamFields(), "docs/synth.md", [](const synth::SynthParams& p) { p.validate(); },
        [](const synth::SynthParams& p) { return p.asParameters(); }, 10);
    test::checkParamTable(
        synth::refineParamFields(), "docs/synth.md", [](const synth::RefineParams& p) { p.validate(); },
        [](const synth::RefineParams& p) { return p.asParameters(); }, 10);
    synth::SynthParams p;
    p.clusterSigmaMaxM = 0.1;  // below the smallest scale
    CHECK_THROWS_WITH(p.validate(), Catch::Contains("cluster_sigma_max_m") && Catch::Contains("cluster_sigma_min_m"));
}

TEST_CASE("the database's biome must match its species list", "[synth]") {
    World w = makeWorld();
    CHECK_NOTHROW(synth::databaseBiome(w.db));
    std::swap(w.db.speciesNames[0], w.db.speciesNames[1]);
    CHECK_THROWS_WITH(synth::databaseBiome(w.db), Catch::Contains("species 0"));
}
