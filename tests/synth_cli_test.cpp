// Command-line tests of `eco` for the synth module (split from synth_test.cpp, issue 23):
// they run the eco binary (ECO_BINARY) and live in eco_cli_tests, apart from the unit tests.
#include <hdf5.h>
#include <omp.h>

#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>

#include "abiotics.h"
#include "biome.h"
#include "biome_db.h"
#include "canopy_placer.h"
#include "error.h"
#include "forest_floor.h"
#include "h5io.h"
#include "scene.h"
#include "terrain_io.h"
#include "test_util.h"
#include "undergrowth.h"

using namespace eco;

namespace {

// ------------------------------------------------------------------ the test world

constexpr int kSide = 200;   // cells
constexpr double kCell = 1.0;

std::vector<int> canopyMasks(const Biome& b) {
    std::vector<int> m(b.species.size(), 0);
    for (const SubBiome& sb : b.subBiomes)
        for (const auto& name : sb.canopySpecies) m[static_cast<std::size_t>(b.speciesIndex(name))] |= 1 << (sb.number - 1);
    return m;
}

DbHistogram triangleHistogram(double maxValue, int bins, double peakFraction) {
    DbHistogram h;
    for (int k = 0; k <= bins; ++k) h.edges.push_back(maxValue * k / bins);
    for (int k = 0; k < bins; ++k) {
        const double mid = (k + 0.5) / bins;
        const double v = mid < peakFraction ? mid / peakFraction : (1 - mid) / (1 - peakFraction);
        h.counts.push_back(std::round(1000 * v) + 1);
    }
    return h;
}

/// g target: inhibition below `hardCoreM`, 1 beyond.
DbPairStats pairStats(int source, int target, const DistanceBins& bins, double hardCoreM) {
    DbPairStats p;
    p.source = source;
    p.target = target;
    p.normalisation = 1.0;
    for (int k = 0; k < bins.count; ++k) {
        const double g = bins.hiM(k) <= hardCoreM ? 0.0 : 1.0;
        p.g.push_back(g);
        p.translateWeighted.push_back(g * bins.annulusAreaM2(k));
        p.pairCount.push_back(g * bins.annulusAreaM2(k));
    }
    p.separationCount.assign(static_cast<std::size_t>(SeparationBins{}.count), 0.0);
    return p;
}

DbRegion makeRegion(const Biome& b, int combination, int cluster, double density, Features centroidRaw,
                    const std::map<std::string, double>& shares, const DistanceBins& bins, double hardCoreM) {
    DbRegion r;
    r.combination = combination;
    r.cluster = cluster;
    r.centroidRaw = centroidRaw;
    r.areaM2 = 10000;
    r.densityPerM2 = density;
    const std::size_t ns = b.species.size();
    r.speciesCount.assign(ns, 0.0);
    r.speciesProportion.assign(ns, 0.0);
    r.canopySpeciesCount.assign(ns, 0.0);
    r.height.resize(ns);
    r.crownRadius.resize(ns);
    for (std::size_t s = 0; s < ns; ++s) {
        const Species& sp = b.species[s];
        const double hMax = std::min(sp.maxHeightM, 3.0);
        // Absent species: the edges every region shares, no counts.
        r.height[s] = triangleHistogram(hMax, 20, 0.5);
        r.crownRadius[s] = triangleHistogram(sp.allometry.crownRadiusM(hMax), 20, 0.5);
        std::fill(r.height[s].counts.begin(), r.height[s].counts.end(), 0.0);
        std::fill(r.crownRadius[s].counts.begin(), r.crownRadius[s].counts.end(), 0.0);
    }
    double total = 0;
    for (const auto& [name, share] : shares) total += share;
    std::vector<int> present;
    for (const auto& [name, share] : shares) {
        const std::size_t s = static_cast<std::size_t>(b.speciesIndex(name));
        r.speciesProportion[s] = share / total;
        r.speciesCount[s] = std::round(density * r.areaM2 * share / total);
        const Species& sp = b.species[s];
        const double hMax = std::min(sp.maxHeightM, 3.0);
        r.height[s] = triangleHistogram(hMax, 20, 0.15 + 0.1 * static_cast<double>(s % 5));
        r.crownRadius[s] = triangleHistogram(sp.allometry.crownRadiusM(hMax), 20, 0.35);
        present.push_back(static_cast<int>(s));
    }
    r.undergrowthCount = density * r.areaM2;
    std::sort(present.begin(), present.end());
    for (int i : present)
        for (int j : present) r.pairs.push_back(pairStats(i, j, bins, hardCoreM));
    return r;
}

struct World {
    Biome biome = defaultBiome();
    BiomeDatabase db;
    Grid<float> terrain;
    AnnualAbiotics features;
    std::vector<Plant> canopy;
};

World makeWorld(double hardCoreM = 0.8) {
    World w;
    const Biome& b = w.biome;
    BiomeDatabase& db = w.db;
    db.codeVersion = "test";
    db.createdUtc = "2000-01-01T00:00:00Z";
    db.biomeName = b.name;
    db.biomeToml = biomeToToml(b);
    for (const auto& s : b.species) db.speciesNames.push_back(s.name);
    for (const auto& sb : b.subBiomes) db.subBiomeNames.push_back(sb.name);
    db.canopySubBiomeMask = canopyMasks(b);
    db.seedingRadiusFactor = 12;
    db.pcfBins = DistanceBins{10.0, 40};
    // Combination 1 (Conifer): two regions by sun; combination 2 (California Oak): one.
    DbCombination c1;
    c1.mask = 1;
    c1.k = 2;
    c1.firstRegion = 0;
    c1.featureMean = {9.0, 100.0, 15.0, 0.0};
    c1.featureStd = {2.0, 1.0, 1.0, 1.0};
    DbCombination c2;
    c2.mask = 2;
    c2.k = 1;
    c2.firstRegion = 2;
    c2.featureMean = {9.0, 100.0, 15.0, 0.0};
    c2.featureStd = {2.0, 1.0, 1.0, 1.0};
    db.combinations = {c1, c2};
    db.regions.push_back(makeRegion(b, 1, 0, 1.2, {7.0, 100, 15, 0},
                                    {{"Western Swordfern", 0.4}, {"Redwood Sorrel", 0.3}, {"Tanoak", 0.2}, {"Toyon", 0.1}},
                                    db.pcfBins, hardCoreM));
    db.regions.push_back(makeRegion(b, 1, 1, 0.8, {11.0, 100, 15, 0},
                                    {{"Toyon", 0.5}, {"California Laurel", 0.3}, {"Western Swordfern", 0.2}}, db.pcfBins,
                                    hardCoreM));
    db.regions.push_back(makeRegion(b, 2, 0, 1.5, {9.0, 100, 15, 0},
                                    {{"Chamise", 0.35}, {"California Sagebrush", 0.35}, {"Toyon", 0.2}, {"Pacific Poison Oak", 0.1}},
                                    db.pcfBins, hardCoreM));
    for (auto& c : db.combinations)
        for (int r = c.firstRegion; r < c.firstRegion + c.k; ++r)
            for (std::size_t f = 0; f < kFeatureCount; ++f)
                db.regions[static_cast<std::size_t>(r)].centroidNormalised[f] =
                    (db.regions[static_cast<std::size_t>(r)].centroidRaw[f] - c.featureMean[f]) / c.featureStd[f];

    // Terrain and annual abiotics: a gentle tilt, sun from 6 (west) to 12 h/day (east).
    w.terrain = Grid<float>(kSide, kSide, kCell, 0.0, 0.0);
    w.features.sunHours = Grid<float>::like(w.terrain);
    w.features.moistureMm = Grid<float>::like(w.terrain, 100.0f);
    w.features.temperatureC = Grid<float>::like(w.terrain, 15.0f);
    w.features.slopeDeg = Grid<float>::like(w.terrain, 0.0f);
    for (int iy = 0; iy < kSide; ++iy)
        for (int ix = 0; ix < kSide; ++ix) {
            w.terrain(ix, iy) = static_cast<float>(100.0 + 0.02 * ix + 0.01 * iy);
            w.features.sunHours(ix, iy) = static_cast<float>(6.0 + 6.0 * (ix + 0.5) / kSide);
        }
    // Canopy: Redwoods west, Coast Live Oaks east, on a jittered lattice.
    const int redwood = b.speciesIndex("Redwood"), oak = b.speciesIndex("Coast Live Oak");
    for (int j = 0; j < 10; ++j)
        for (int i = 0; i < 10; ++i) {
            Plant t;
            const bool west = i < 5;
            t.speciesId = west ? redwood : oak;
            t.xM = 10.0 + 20.0 * i + 3.0 * std::sin(1.7 * j + i);
            t.yM = 10.0 + 20.0 * j + 3.0 * std::cos(2.3 * i + j);
            t.heightM = west ? 40.0 : 15.0;
            t.crownRadiusM = west ? 3.0 : 2.5;
            t.groundZM = w.terrain.sampleBilinear(t.xM, t.yM);
            w.canopy.push_back(t);
        }
    return w;
}

/// Files of the world for the command-line tests.
struct WorldFiles {
    std::string terrain, canopy, abiotics, db;
};

WorldFiles writeWorld(const World& w, const test::TempDir& dir) {
    WorldFiles f{dir.file("terrain.h5"), dir.file("canopy.h5"), dir.file("abiotics.h5"), dir.file("db.h5")};
    writeTerrainH5(f.terrain, w.terrain);
    CanopyRecord rec;
    rec.result.trees = w.canopy;
    rec.speciesMap = Grid<std::int32_t>::like(w.terrain, -1);
    rec.chmM = Grid<float>::like(w.terrain, 0.0f);
    rec.terrainM = w.terrain;
    rec.terrainSource = f.terrain;
    writeCanopyFile(f.canopy, rec, w.biome);
    Abiotics ab;
    for (int m = 0; m < 12; ++m) {
        ab.sunHours.months.push_back(w.features.sunHours);
        ab.moistureMm.months.push_back(w.features.moistureMm);
        ab.temperatureC.months.push_back(w.features.temperatureC);
    }
    ab.slopeDeg = w.features.slopeDeg;
    ab.elevationM = w.terrain;
    writeAbiotics(f.abiotics, ab, w.biome, AbioticParams{});
    writeBiomeDatabase(f.db, w.db);
    return f;
}

}  // namespace

// ======================================================================== cluster map

TEST_CASE("eco synth and eco compare write a scene and report it", "[synth][cli]") {
    const World w = makeWorld();
    test::TempDir dir("synth_cli");
    const WorldFiles f = writeWorld(w, dir);
    const auto r = test::runEco("synth --terrain " + f.terrain + " --canopy " + f.canopy + " --database " + f.db +
                                " --abiotics " + f.abiotics + " --out " + dir.file("out/scene.h5") + " --png " +
                                dir.file("png") + " --csv " + dir.file("plants.csv") + " --pdb " + dir.file("plants.pdb") +
                                " --refine --refine-sweeps 1 --refine-window 80,80,120,120");
    INFO(r.output);
    REQUIRE(r.exitCode == 0);
    CHECK_THAT(r.output, Catch::Contains("refinement: pair-correlation distance"));
    for (const char* name : {"out/scene.h5", "plants.csv", "plants.pdb", "png/scene.png", "png/scene_zoom.png",
                             "png/grass.png", "png/litter.png", "png/cluster_map.png"})
        CHECK(std::filesystem::exists(dir.file(name)));
    const auto c = test::runEco("compare " + dir.file("out/scene.h5") + " " + f.db + " --png " + dir.file("compare.png"));
    INFO(c.output);
    REQUIRE(c.exitCode == 0);
    CHECK_THAT(c.output, Catch::Contains("| region |") && Catch::Contains("pair-correlation distance"));
    CHECK(std::filesystem::exists(dir.file("compare.png")));
}

TEST_CASE("eco synth refuses bad inputs with one clear line and no output", "[synth][cli]") {
    const World w = makeWorld();
    test::TempDir dir("synth_bad");
    const WorldFiles f = writeWorld(w, dir);
    const std::string out = dir.file("scene.h5");
    auto synth = [&](const std::string& terrain, const std::string& canopy, const std::string& db) {
        return test::runEco("synth --terrain " + terrain + " --canopy " + canopy + " --database " + db + " --abiotics " +
                            f.abiotics + " --out " + out);
    };

    SECTION("a database of another schema version") {
        const std::string bad = dir.file("db_old.h5");
        std::filesystem::copy_file(f.db, bad);
        const hid_t file = H5Fopen(bad.c_str(), H5F_ACC_RDWR, H5P_DEFAULT);
        REQUIRE(file >= 0);
        REQUIRE(H5Adelete(file, "schema_version") >= 0);
        const hid_t space = H5Screate(H5S_SCALAR);
        const hid_t attr = H5Acreate2(file, "schema_version", H5T_STD_I64LE, space, H5P_DEFAULT, H5P_DEFAULT);
        const long long older = kBiomeDbOldestReadableVersion - 1;
        H5Awrite(attr, H5T_NATIVE_LLONG, &older);
        H5Aclose(attr);
        H5Sclose(space);
        H5Fclose(file);
        const auto r = synth(f.terrain, f.canopy, bad);
        INFO(r.output);
        CHECK(r.exitCode != 0);
        CHECK_THAT(r.output, Catch::Contains("db_old.h5") && Catch::Contains("schema_version") && Catch::Contains("eco: error"));
    }
    SECTION("a canopy tree outside the terrain") {
        std::vector<Plant> trees = w.canopy;
        trees[3].xM = kSide * kCell + 25.0;
        CanopyRecord rec;
        rec.result.trees = trees;
        rec.speciesMap = Grid<std::int32_t>::like(w.terrain, -1);
        rec.chmM = Grid<float>::like(w.terrain, 0.0f);
        rec.terrainM = w.terrain;
        writeCanopyFile(dir.file("outside.h5"), rec, w.biome);
        const auto r = synth(f.terrain, dir.file("outside.h5"), f.db);
        INFO(r.output);
        CHECK(r.exitCode != 0);
        CHECK_THAT(r.output, Catch::Contains("outside.h5") && Catch::Contains("canopy tree 3") &&
                                 Catch::Contains("outside the terrain"));
    }
    SECTION("a canopy placed on another terrain") {
        Grid<float> other(kSide / 2, kSide, kCell, 0, 0, 50.0f);
        writeTerrainH5(dir.file("other.h5"), other);
        const auto r = synth(dir.file("other.h5"), f.canopy, f.db);
        INFO(r.output);
        CHECK(r.exitCode != 0);
        CHECK_THAT(r.output, Catch::Contains("canopy.h5") && Catch::Contains("other.h5") &&
                                 Catch::Contains("was placed on a terrain of"));
    }
    SECTION("a missing file") {
        const auto r = synth(f.terrain, f.canopy, dir.file("nothing.h5"));
        INFO(r.output);
        CHECK(r.exitCode != 0);
        CHECK_THAT(r.output, Catch::Contains("nothing.h5"));
    }
    CHECK_FALSE(std::filesystem::exists(out));
    // No temporary files left beside the output either.
    for (const auto& e : std::filesystem::directory_iterator(dir.path()))
        CHECK(e.path().filename().string().find("scene") == std::string::npos);
}

TEST_CASE("eco compare refuses a scene from another database", "[synth][cli]") {
    const World w = makeWorld();
    test::TempDir dir("synth_cmp");
    const WorldFiles f = writeWorld(w, dir);
    REQUIRE(test::runEco("synth --terrain " + f.terrain + " --canopy " + f.canopy + " --database " + f.db +
                         " --abiotics " + f.abiotics + " --out " + dir.file("scene.h5"))
                .exitCode == 0);
    BiomeDatabase small = w.db;
    small.regions.resize(1);
    small.combinations.resize(1);
    small.combinations[0].k = 1;
    writeBiomeDatabase(dir.file("small.h5"), small);
    const auto r = test::runEco("compare " + dir.file("scene.h5") + " " + dir.file("small.h5"));
    INFO(r.output);
    CHECK(r.exitCode != 0);
    CHECK_THAT(r.output, Catch::Contains("another database"));
}
