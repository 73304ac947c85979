// The biome database (core/biome_db): round trip of every field, the version and format
// checks, and the region lookup the synthesizer uses.
#include <catch2/catch.hpp>

#include <functional>

#include <cmath>
#include <limits>

#include "biome_db.h"
#include "error.h"
#include "h5io.h"
#include "test_util.h"

using namespace eco;

namespace {

/// A small database: 2 species, 2 sub-biomes, combinations 1 (k = 2) and 3 (k = 1).
BiomeDatabase sampleDb() {
    BiomeDatabase db;
    db.codeVersion = "test";
    db.createdUtc = "2024-01-02T03:04:05Z";
    db.biomeName = "Tiny";
    db.biomeToml = "[biome]\nname = \"Tiny\"\n";
    db.speciesNames = {"Fern", "Oak"};
    db.subBiomeNames = {"Wet", "Dry"};
    db.canopySubBiomeMask = {0, 3};
    db.seedingRadiusFactor = 12;
    db.pcfBins = DistanceBins{2.0, 4};
    db.separationBins = SeparationBins{-1.0, 1.0, 4};
    db.parameters = {{"kmax", "6"}, {"seed", "1"}};
    DbInput in;
    in.path = "sim.h5";
    in.abioticsPath = "abiotics.h5";
    in.seed = 0xFFFFFFFFFFFFFFF0ull;  // beyond int64: stored as its bits
    in.year = 50;
    in.window = RectWindow{1, 2, 3, 4};
    in.undergrowthPlants = 10;
    in.canopyTrees = 2;
    in.unlabelledPlants = 1;
    in.unlabelledAreaM2 = 5.5;
    in.parameters = "cell_size_m = 0.2";
    db.inputs.push_back(in);

    DbCombination c1;
    c1.mask = 1;
    c1.k = 2;
    c1.firstRegion = 0;
    c1.areaM2 = 100;
    c1.cellCount = 100;
    c1.featureMean = {10, 100, 15, 5};
    c1.featureStd = {1, 10, 1, 1};
    c1.silhouette = {std::numeric_limits<double>::quiet_NaN(), 0.7, 0.4};
    DbCombination c3 = c1;
    c3.mask = 3;
    c3.k = 1;
    c3.firstRegion = 2;
    c3.silhouette = {std::numeric_limits<double>::quiet_NaN()};
    db.combinations = {c1, c3};

    auto region = [&](int comb, int cluster, Features z, const DbCombination& c) {
        DbRegion r;
        r.combination = comb;
        r.cluster = cluster;
        r.centroidNormalised = z;
        for (std::size_t f = 0; f < kFactorCount; ++f) r.centroidRaw[f] = c.featureMean[f] + c.featureStd[f] * z[f];
        r.areaM2 = 50;
        r.cellCount = 50;
        r.undergrowthCount = 4;
        r.canopyCount = 1;
        r.densityPerM2 = 0.08;
        r.speciesCount = {3, 1};
        r.speciesProportion = {0.75, 0.25};
        r.canopySpeciesCount = {0, 1};
        r.height = {DbHistogram{{0, 0.5, 1}, {2, 1}, 0}, DbHistogram{{0, 10, 20}, {1, 0}, 0}};
        r.crownRadius = {DbHistogram{{0, 1, 2}, {3, 0}, 0}, DbHistogram{{0, 2, 4}, {0, 0}, 1}};
        DbPairStats p;
        p.source = 0;
        p.target = 3;  // Fern -> Oak (canopy)
        p.pairCount = {0, 2, 4, 6};
        p.translateWeighted = {0, 2.5, 4.5, 6.5};
        p.normalisation = 0.04;
        p.g = {0, 1, 2, 3};
        p.separationCount = {1, 0, 2, 0};
        p.separationUnderflow = 3;
        p.separationSources = 2;
        r.pairs = {p};
        // Canopy context: 2 bins (edge at 0 m), 2 species, 4 distance bins.
        r.contextAreaM2 = {30, 20};
        r.contextSpeciesCount = {2, 1, 0, 1};
        r.heightCovered = {DbHistogram{{0, 0.5, 1}, {0, 1}, 0}, DbHistogram{{0, 10, 20}, {0, 0}, 0}};
        r.contextCellPairs.assign(2 * 2 * 4, 0.0);
        for (std::size_t i = 0; i < r.contextCellPairs.size(); ++i) r.contextCellPairs[i] = static_cast<double>(i % 5);
        return r;
    };
    db.contextBins.edgesM = {0.0};
    db.regions = {region(1, 0, {-1, 0, 0, 0}, c1), region(1, 1, {1, 0, 0, 0}, c1), region(3, 0, {0, 0, 0, 0}, c3)};
    return db;
}

void sameSilhouette(const std::vector<double>& a, const std::vector<double>& b) {
    REQUIRE(b.size() >= a.size());
    for (std::size_t i = 0; i < b.size(); ++i) {
        if (i >= a.size() || std::isnan(a[i])) CHECK(std::isnan(b[i]));
        else CHECK(b[i] == a[i]);
    }
}

}  // namespace

TEST_CASE("biome database round trip keeps every field", "[biome_db]") {
    eco::test::TempDir dir("db");
    const std::string path = dir.file("db.h5");
    const BiomeDatabase a = sampleDb();
    writeBiomeDatabase(path, a);
    const BiomeDatabase b = readBiomeDatabase(path);
    CHECK(b.schemaVersion == kBiomeDbSchemaVersion);
    CHECK(b.codeVersion == a.codeVersion);
    CHECK(b.createdUtc == a.createdUtc);
    CHECK(b.biomeName == a.biomeName);
    CHECK(b.biomeToml == a.biomeToml);
    CHECK(b.speciesNames == a.speciesNames);
    CHECK(b.subBiomeNames == a.subBiomeNames);
    CHECK(b.canopySubBiomeMask == a.canopySubBiomeMask);
    CHECK(b.seedingRadiusFactor == a.seedingRadiusFactor);
    CHECK(b.pcfBins.rMaxM == a.pcfBins.rMaxM);
    CHECK(b.pcfBins.count == a.pcfBins.count);
    CHECK(b.separationBins.minM == a.separationBins.minM);
    CHECK(b.separationBins.maxM == a.separationBins.maxM);
    CHECK(b.separationBins.count == a.separationBins.count);
    CHECK(b.hasContext());
    CHECK(b.contextBins.edgesM == a.contextBins.edgesM);
    CHECK(b.parameters == a.parameters);
    REQUIRE(b.inputs.size() == 1);
    CHECK(b.inputs[0].path == "sim.h5");
    CHECK(b.inputs[0].abioticsPath == "abiotics.h5");
    CHECK(b.inputs[0].seed == a.inputs[0].seed);
    CHECK(b.inputs[0].year == 50);
    CHECK(b.inputs[0].window.x1 == 3);
    CHECK(b.inputs[0].undergrowthPlants == 10);
    CHECK(b.inputs[0].canopyTrees == 2);
    CHECK(b.inputs[0].unlabelledPlants == 1);
    CHECK(b.inputs[0].unlabelledAreaM2 == 5.5);
    CHECK(b.inputs[0].parameters == a.inputs[0].parameters);
    REQUIRE(b.combinations.size() == 2);
    for (std::size_t c = 0; c < 2; ++c) {
        CHECK(b.combinations[c].mask == a.combinations[c].mask);
        CHECK(b.combinations[c].k == a.combinations[c].k);
        CHECK(b.combinations[c].firstRegion == a.combinations[c].firstRegion);
        CHECK(b.combinations[c].areaM2 == a.combinations[c].areaM2);
        CHECK(b.combinations[c].cellCount == a.combinations[c].cellCount);
        CHECK(b.combinations[c].featureMean == a.combinations[c].featureMean);
        CHECK(b.combinations[c].featureStd == a.combinations[c].featureStd);
        sameSilhouette(a.combinations[c].silhouette, b.combinations[c].silhouette);
    }
    REQUIRE(b.regions.size() == 3);
    for (std::size_t r = 0; r < 3; ++r) {
        const DbRegion& x = a.regions[r];
        const DbRegion& y = b.regions[r];
        CHECK(y.combination == x.combination);
        CHECK(y.cluster == x.cluster);
        CHECK(y.centroidNormalised == x.centroidNormalised);
        CHECK(y.centroidRaw == x.centroidRaw);
        CHECK(y.areaM2 == x.areaM2);
        CHECK(y.cellCount == x.cellCount);
        CHECK(y.undergrowthCount == x.undergrowthCount);
        CHECK(y.canopyCount == x.canopyCount);
        CHECK(y.densityPerM2 == x.densityPerM2);
        CHECK(y.speciesCount == x.speciesCount);
        CHECK(y.speciesProportion == x.speciesProportion);
        CHECK(y.canopySpeciesCount == x.canopySpeciesCount);
        for (std::size_t s = 0; s < 2; ++s) {
            CHECK(y.height[s].edges == x.height[s].edges);
            CHECK(y.height[s].counts == x.height[s].counts);
            CHECK(y.crownRadius[s].counts == x.crownRadius[s].counts);
            CHECK(y.crownRadius[s].overflow == x.crownRadius[s].overflow);
            CHECK(y.heightCovered[s].edges == x.height[s].edges);
            CHECK(y.heightCovered[s].counts == x.heightCovered[s].counts);
        }
        CHECK(y.contextAreaM2 == x.contextAreaM2);
        CHECK(y.contextSpeciesCount == x.contextSpeciesCount);
        CHECK(y.contextCellPairs == x.contextCellPairs);
        REQUIRE(y.pairs.size() == 1);
        const DbPairStats* p = y.pair(0, 3);
        REQUIRE(p != nullptr);
        CHECK(y.pair(3, 0) == nullptr);
        CHECK(p->pairCount == x.pairs[0].pairCount);
        CHECK(p->translateWeighted == x.pairs[0].translateWeighted);
        CHECK(p->normalisation == x.pairs[0].normalisation);
        CHECK(p->g == x.pairs[0].g);
        CHECK(p->separationCount == x.pairs[0].separationCount);
        CHECK(p->separationUnderflow == 3);
        CHECK(p->separationSources == 2);
        CHECK(p->separationPerSource(2) == 1.0);
    }
    CHECK(b.categoryName(3) == "Oak (canopy)");
    CHECK(b.categoryName(0) == "Fern");
    CHECK(b.combinationName(3) == "1+2 (Wet, Dry)");
}

TEST_CASE("nearestRegion: nearest centroid in normalised units, stand-in combinations", "[biome_db]") {
    const BiomeDatabase db = sampleDb();
    // Combination 1: centroids at z_sun = -1 (raw 9 h) and +1 (raw 11 h); std of moisture
    // is 10, so a 5 mm difference in moisture weighs as 0.5.
    CHECK(db.nearestRegion(1, {9.2, 100, 15, 5}) == 0);
    CHECK(db.nearestRegion(1, {10.8, 100, 15, 5}) == 1);
    CHECK(db.nearestRegion(1, {10.1, 130, 15, 5}) == 1);
    CHECK(db.nearestRegion(3, {0, 0, 0, 0}) == 2);
    // Combination 2 (sub-biome 2 alone) is not stored: 3 (1+2) shares sub-biome 2.
    CHECK(db.standInCombination(2) == 3);
    CHECK(db.nearestRegion(2, {10, 100, 15, 5}) == 2);
    // 1+2+3 shares two sub-biomes with 3, one with 1.
    CHECK(db.standInCombination(7) == 3);
    // Sub-biome 3 alone shares nothing; 0 is "seeded by none".
    CHECK(db.standInCombination(4) == -1);
    CHECK(db.nearestRegion(4, {10, 100, 15, 5}) == -1);
    CHECK(db.nearestRegion(0, {10, 100, 15, 5}) == -1);
}

TEST_CASE("a NaN or negative canopy-context value is a clear IoError naming the dataset", "[biome_db][errors]") {
    eco::test::TempDir dir("db_ctx");
    BiomeDatabase db = sampleDb();
    db.regions[1].contextAreaM2[1] = std::numeric_limits<double>::quiet_NaN();
    const std::string nanPath = dir.file("nan.h5");
    writeBiomeDatabase(nanPath, db);
    CHECK_THROWS_WITH(readBiomeDatabase(nanPath), Catch::Contains("nan.h5") && Catch::Contains("region_0001/context_area_m2") &&
                                                      Catch::Contains("finite and non-negative"));
    db = sampleDb();
    db.regions[0].contextSpeciesCount[2] = -1;
    const std::string negPath = dir.file("neg.h5");
    writeBiomeDatabase(negPath, db);
    CHECK_THROWS_WITH(readBiomeDatabase(negPath), Catch::Contains("region_0000/context_species_count") && Catch::Contains("entry 2"));
    // A database with context in some regions but not all is refused on writing.
    db = sampleDb();
    db.regions[2].contextCellPairs.clear();
    CHECK_THROWS_WITH(writeBiomeDatabase(dir.file("partial.h5"), db), Catch::Contains("missing in some regions"));
}

TEST_CASE("every number of a database is checked on reading: densities, shares, histograms, g", "[biome_db][errors]") {
    // Issue 26: a negative density gave an empty scene, a NaN g a NaN refinement objective,
    // NaN bin edges were read without a word.
    eco::test::TempDir dir("db_values");
    const double nan = std::numeric_limits<double>::quiet_NaN();
    struct Case {
        const char* name;
        std::function<void(BiomeDatabase&)> spoil;
        const char* dataset;
    };
    const std::vector<Case> cases = {
        {"negative density", [](BiomeDatabase& d) { d.regions[1].densityPerM2 = -0.5; }, "/regions/density_per_m2: entry 1 is -0.5"},
        {"NaN density", [&](BiomeDatabase& d) { d.regions[0].densityPerM2 = nan; }, "/regions/density_per_m2: entry 0 is nan"},
        {"share above 1", [](BiomeDatabase& d) { d.regions[0].speciesProportion[0] = 1.5; }, "a share must lie in [0, 1]"},
        {"NaN g", [&](BiomeDatabase& d) { d.regions[0].pairs[0].g[3] = nan; }, "region_0000/pairs/g"},
        {"negative pair count", [](BiomeDatabase& d) { d.regions[2].pairs[0].pairCount[0] = -1; }, "region_0002/pairs/pair_count"},
        {"NaN height edge", [&](BiomeDatabase& d) { d.regions[0].height[0].edges[1] = nan; }, "region_0000/height_edges_m"},
        {"edges not increasing",
         [](BiomeDatabase& d) { std::swap(d.regions[0].crownRadius[0].edges[1], d.regions[0].crownRadius[0].edges[2]); },
         "must increase"},
        {"NaN centroid", [&](BiomeDatabase& d) { d.regions[1].centroidRaw[0] = nan; }, "/regions/centroid_raw"},
    };
    for (const Case& c : cases) {
        INFO(c.name);
        BiomeDatabase db = sampleDb();
        c.spoil(db);
        const std::string path = dir.file("bad.h5");
        writeBiomeDatabase(path, db);
        CHECK_THROWS_WITH(readBiomeDatabase(path), Catch::Contains("bad.h5") && Catch::Contains(c.dataset));
    }
    const std::string good = dir.file("good.h5");
    writeBiomeDatabase(good, sampleDb());
    CHECK_NOTHROW(readBiomeDatabase(good));
}

TEST_CASE("reading a database with another schema version or format is a clear IoError", "[biome_db][errors]") {
    eco::test::TempDir dir("db");
    const std::string v1 = dir.file("v1.h5");
    {
        h5::File f = h5::File::create(v1);
        f.setAttr("/", "format", std::string("eco-biome-db"));
        f.setAttr("/", "schema_version", static_cast<std::int64_t>(1));
    }
    CHECK_THROWS_AS(readBiomeDatabase(v1), IoError);
    CHECK_THROWS_WITH(readBiomeDatabase(v1), Catch::Contains("v1.h5") && Catch::Contains("schema_version 1 found") &&
                                                 Catch::Contains("versions 2..5 can be read"));
    const std::string other = dir.file("other.h5");
    {
        h5::File f = h5::File::create(other);
        f.setAttr("/", "format", std::string("eco-abiotics"));
    }
    CHECK_THROWS_WITH(readBiomeDatabase(other), Catch::Contains("other.h5") && Catch::Contains("not a biome database"));
    const std::string bare = dir.file("bare.h5");
    {
        h5::File f = h5::File::create(bare);
        f.setAttr("/", "format", std::string("eco-biome-db"));
        f.setAttr("/", "schema_version", static_cast<std::int64_t>(kBiomeDbSchemaVersion));
        f.setAttr("/", "code_version", std::string("x"));
        f.setAttr("/", "created_utc", std::string("x"));
        f.setAttr("/", "biome_name", std::string("x"));
        f.setAttr("/", "biome_toml", std::string("x"));
        f.setAttr("/", "seeding_radius_factor", 12.0);
    }
    CHECK_THROWS_WITH(readBiomeDatabase(bare), Catch::Contains("bare.h5") && Catch::Contains("/species/names"));
    CHECK_THROWS_WITH(readBiomeDatabase(dir.file("none.h5")), Catch::Contains("none.h5"));
}

TEST_CASE("a truncated pair dataset is reported with its name and shapes", "[biome_db][errors]") {
    eco::test::TempDir dir("db");
    const std::string path = dir.file("db.h5");
    BiomeDatabase db = sampleDb();
    db.regions[1].pairs[0].g.pop_back();
    CHECK_THROWS_AS(writeBiomeDatabase(path, db), ValidationError);
    CHECK_FALSE(std::filesystem::exists(path));  // atomic: nothing left behind
}
