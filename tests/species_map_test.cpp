// Species map (paper §5.1): vigour argmax with the height rule, target bisection globally and
// inside a brush, infeasible targets, strict parsing and bad input.
#include <catch2/catch.hpp>
#include <omp.h>

#include <cmath>
#include <memory>
#include <set>

#include "biome.h"
#include "error.h"
#include "param_table_check.h"
#include "rng.h"
#include "species_map.h"
#include "terrain_io.h"
#include "test_util.h"

using namespace eco;

namespace {

/// A small landscape with gradients: sun 4..14 h along x, moisture 30..190 mm along y,
/// temperature 19 C, slope 20 degrees, a 30 m CHM with a bare strip on the west edge. A
/// little per-cell noise keeps whole rows and columns from tying (as in real maps).
synth::SpeciesMapInputs gradientInputs(int w = 64, int h = 48) {
    synth::SpeciesMapInputs in;
    in.chmM = Grid<float>(w, h, 1.0, 0, 0, 30.f);
    in.features = FactorGrids::uniform(in.chmM, {0, 0, 19, 20});
    for (int iy = 0; iy < h; ++iy)
        for (int ix = 0; ix < w; ++ix) {
            RandomStream noise(99, static_cast<std::uint64_t>(iy * w + ix));
            in.features[Factor::Sun](ix, iy) = static_cast<float>(4.0 + 10.0 * ix / (w - 1) + noise.uniform(-0.3, 0.3));
            in.features[Factor::Moisture](ix, iy) = static_cast<float>(30.0 + 160.0 * iy / (h - 1) + noise.uniform(-5, 5));
            in.features[Factor::Temperature](ix, iy) = static_cast<float>(19.0 + noise.uniform(-1, 1));
            if (ix < 4) in.chmM(ix, iy) = 0.f;
        }
    return in;
}

/// Reference argmax from Biome::vigourOf, written independently of the library.
int referenceArgmax(const Biome& b, const synth::SpeciesMapInputs& in, int ix, int iy) {
    int best = -1;
    double bestV = 0;
    for (const auto& s : b.species) {
        if (!s.canopy || s.maxHeightM < in.chmM(ix, iy)) continue;
        const double v = b.vigourOf(s.id, in.features.at(ix, iy));
        if (v > bestV) {
            bestV = v;
            best = s.id;
        }
    }
    return best;
}

}  // namespace

TEST_CASE("unweighted vigour equals Biome::vigourOf (Eq. 1 with the exact g)", "[species_map]") {
    const Biome b = defaultBiome();
    RandomStream rng(7, 1);
    int exact = 0, total = 0;
    for (int k = 0; k < 2000; ++k) {
        const double sun = rng.uniform(0, 16), moist = rng.uniform(0, 250), temp = rng.uniform(-5, 40),
                     slope = rng.uniform(0, 80);
        for (const auto& s : b.species) {
            const double ref = b.vigourOf(s.id, {sun, moist, temp, slope});
            const double fast = synth::unweightedVigour(b, s.id, {sun, moist, temp, slope});
            REQUIRE(fast == Approx(ref).margin(1e-12));
            exact += fast == ref;
            ++total;
        }
    }
    CHECK(exact == total);  // g is monotone, so min over g equals g at the max distance, bit for bit
    // g(0) = 1 and g(r) = (1 + a) * 0.01 - a, as in Eq. 1.
    const auto& rw = b.species[static_cast<std::size_t>(b.speciesIndex("Redwood"))];
    Features optimum{};
    for (std::size_t f = 0; f < kFactorCount; ++f) optimum[f] = rw.responses[f].c;
    Features offSun = optimum;
    offSun[factorIndex(Factor::Sun)] += rw.response(Factor::Sun).r;
    CHECK(synth::unweightedVigour(b, rw.id, optimum) == Approx(rw.alpha));
    CHECK(synth::unweightedVigour(b, rw.id, offSun) ==
          Approx(rw.alpha * (1.2 * 0.01 - 0.2)));
}

TEST_CASE("species map is the vigour argmax over tall-enough canopy species", "[species_map]") {
    const Biome b = defaultBiome();
    synth::SpeciesMapInputs in = gradientInputs();
    // Some cells taller than every species but Redwood (110 m), some taller than all.
    in.chmM(40, 10) = 60.f;
    in.chmM(41, 10) = 120.f;
    const Grid<std::int32_t> map = synth::computeSpeciesMap(b, in);
    REQUIRE(map.sameGeometry(in.chmM));
    std::set<int> seen;
    for (int iy = 0; iy < in.chmM.height(); ++iy)
        for (int ix = 0; ix < in.chmM.width(); ++ix) {
            const int s = map(ix, iy);
            REQUIRE(s == referenceArgmax(b, in, ix, iy));
            if (s >= 0) {
                REQUIRE(b.species[static_cast<std::size_t>(s)].canopy);
                REQUIRE(b.species[static_cast<std::size_t>(s)].maxHeightM >= in.chmM(ix, iy));
            }
            seen.insert(s);
        }
    CHECK(seen.size() >= 3);  // the gradients make several species dominant
    const int redwood = b.speciesIndex("Redwood");
    CHECK((map(40, 10) == redwood || map(40, 10) == -1));
    CHECK(map(41, 10) == -1);  // 120 m: no species is that tall
}

TEST_CASE("a cell where every vigour is <= 0 has no species", "[species_map]") {
    const Biome b = defaultBiome();
    synth::SpeciesMapInputs in = gradientInputs(8, 8);
    in.features[Factor::Temperature].fill(80.f);  // far outside every temperature range
    const auto map = synth::computeSpeciesMap(b, in);
    for (const auto s : map.data()) CHECK(s == -1);
}

TEST_CASE("species map and target bisection do not depend on the thread count", "[species_map]") {
    const Biome b = defaultBiome();
    const synth::SpeciesMapInputs in = gradientInputs(96, 80);
    const int redwood = b.speciesIndex("Redwood");
    omp_set_num_threads(1);
    synth::SpeciesMapParams p1;
    const auto r1 = synth::meetTarget(b, in, p1, redwood, 0.3);
    const auto m1 = synth::computeSpeciesMap(b, in, p1);
    omp_set_num_threads(2);
    synth::SpeciesMapParams p2;
    const auto r2 = synth::meetTarget(b, in, p2, redwood, 0.3);
    const auto m2 = synth::computeSpeciesMap(b, in, p2);
    CHECK(m1.data() == m2.data());
    CHECK(r1.weight == r2.weight);
    CHECK(r1.achieved == r2.achieved);
}

TEST_CASE("bisection meets a feasible global target within 1 %", "[species_map]") {
    const Biome b = defaultBiome();
    const synth::SpeciesMapInputs in = gradientInputs();
    for (const char* name : {"Redwood", "Douglas-Fir", "Oregon White Oak"}) {
        for (double target : {0.1, 0.35, 0.6}) {
            synth::SpeciesMapParams p;
            const int s = b.speciesIndex(name);
            const synth::TargetResult r = synth::meetTarget(b, in, p, s, target);
            INFO(name << " target " << target << " achieved " << r.achieved << " reachable " << r.reachable);
            if (target > r.reachable + p.targetTolerance) {
                CHECK_FALSE(r.feasible);
                continue;
            }
            CHECK(r.feasible);
            CHECK(std::abs(r.achieved - target) <= 0.01);
            // The map computed with the new weights holds exactly the reported fraction.
            const auto map = synth::computeSpeciesMap(b, in, p);
            CHECK(synth::speciesFraction(map, in.chmM, s, p.canopyThresholdM) == r.achieved);
            CHECK(r.alpha == Approx(r.weight * b.species[static_cast<std::size_t>(s)].alpha));
            // The biome's own alpha (its light absorption) is left alone.
            CHECK(b.species[static_cast<std::size_t>(s)].alpha == defaultBiome().species[static_cast<std::size_t>(s)].alpha);
        }
    }
    // Coast Live Oak grows to 25 m only: on a 30 m canopy no target above 0 is reachable.
    {
        synth::SpeciesMapParams p;
        const auto oak = synth::meetTarget(b, in, p, b.speciesIndex("Coast Live Oak"), 0.2);
        CHECK_FALSE(oak.feasible);
        CHECK(oak.reachable == 0.0);
        CHECK(oak.achieved == 0.0);
    }
    synth::SpeciesMapParams p;
    const auto zero = synth::meetTarget(b, in, p, b.speciesIndex("Redwood"), 0.0);
    CHECK(zero.feasible);
    CHECK(zero.achieved == 0.0);
}

TEST_CASE("an infeasible target is reported with the best reachable fraction", "[species_map]") {
    const Biome b = defaultBiome();
    synth::SpeciesMapInputs in = gradientInputs();
    // Redwood's temperature range is 19 +- 32 C: make half the forest far too hot for it but
    // fine for Coast Live Oak? No species survives 60 C, so that half has no species at all.
    for (int iy = 0; iy < in.chmM.height() / 2; ++iy)
        for (int ix = 0; ix < in.chmM.width(); ++ix) in.features[Factor::Temperature](ix, iy) = 60.f;
    synth::SpeciesMapParams p;
    const int redwood = b.speciesIndex("Redwood");
    const synth::TargetResult r = synth::meetTarget(b, in, p, redwood, 0.9);
    CHECK_FALSE(r.feasible);
    CHECK(r.reachable < 0.9 - 0.01);
    CHECK(r.achieved == Approx(r.reachable).margin(1e-12));
    CHECK(r.reachable == Approx(0.5).margin(0.03));
    const auto map = synth::computeSpeciesMap(b, in, p);
    CHECK(synth::speciesFraction(map, in.chmM, redwood, p.canopyThresholdM) == r.achieved);
}

TEST_CASE("a target inside a brush mask changes the map only inside it", "[species_map]") {
    const Biome b = defaultBiome();
    const synth::SpeciesMapInputs in = gradientInputs();
    auto mask = std::make_shared<Grid<std::uint8_t>>(Grid<std::uint8_t>::like(in.chmM, 0));
    for (int iy = 10; iy < 40; ++iy)
        for (int ix = 20; ix < 50; ++ix) (*mask)(ix, iy) = 1;
    synth::SpeciesMapParams p;
    const auto before = synth::computeSpeciesMap(b, in, p);
    const int fir = b.speciesIndex("Douglas-Fir");
    const synth::TargetResult r = synth::meetTarget(b, in, p, fir, 0.5, mask, "brush");
    CHECK(r.feasible);
    CHECK(std::abs(r.achieved - 0.5) <= 0.01);
    REQUIRE(p.localWeights.size() == 1);
    CHECK(p.weights.empty());  // the global weights are untouched
    const auto after = synth::computeSpeciesMap(b, in, p);
    CHECK(synth::speciesFraction(after, in.chmM, fir, p.canopyThresholdM, mask.get()) == r.achieved);
    for (std::size_t i = 0; i < after.size(); ++i)
        if (mask->data()[i] == 0) REQUIRE(after.data()[i] == before.data()[i]);
    // Meeting it again with the same brush replaces the brush weight, not adds another.
    synth::meetTarget(b, in, p, fir, 0.3, mask, "brush");
    CHECK(p.localWeights.size() == 1);
}

TEST_CASE("several targets are met one after another", "[species_map]") {
    const Biome b = defaultBiome();
    const synth::SpeciesMapInputs in = gradientInputs();
    synth::SpeciesMapParams p;
    const auto results = synth::meetTargets(b, in, p, {{"Redwood", 0.3}, {"Douglas-Fir", 0.2}});
    REQUIRE(results.size() == 2);
    const auto map = synth::computeSpeciesMap(b, in, p);
    for (const auto& r : results) {
        INFO(r.species << " achieved " << r.achieved);
        CHECK(r.feasible);
        CHECK(std::abs(r.achieved - r.requested) <= 0.01);
        CHECK(synth::speciesFraction(map, in.chmM, b.speciesIndex(r.species), p.canopyThresholdM) == r.achieved);
    }
}

TEST_CASE("targets are parsed strictly", "[species_map]") {
    const Biome b = defaultBiome();
    const auto t = synth::parseSpeciesTarget("Redwood=0.4", b);
    CHECK(t.species == "Redwood");
    CHECK(t.fraction == 0.4);
    CHECK(synth::parseSpeciesTarget("Coast Live Oak = 1", b).species == "Coast Live Oak");
    auto message = [&](const std::string& text) {
        try {
            synth::parseSpeciesTarget(text, b);
        } catch (const ValidationError& e) {
            return std::string(e.what());
        }
        return std::string("no error");
    };
    CHECK_THAT(message("Redwod=0.4"), Catch::Contains("unknown species 'Redwod'") && Catch::Contains("Douglas-Fir"));
    CHECK_THAT(message("Toyon=0.4"), Catch::Contains("not a canopy species"));
    CHECK_THAT(message("Redwood=1.5"), Catch::Contains("[0, 1]"));
    CHECK_THAT(message("Redwood=-0.1"), Catch::Contains("[0, 1]"));
    CHECK_THAT(message("Redwood=0.4x"), Catch::Contains("not a number"));
    CHECK_THAT(message("Redwood=nan"), Catch::Contains("[0, 1]"));
    CHECK_THAT(message("Redwood"), Catch::Contains("SPECIES=FRACTION"));
}

TEST_CASE("species-map parameters: one description drives validation, the canopy config and the docs",
          "[species_map]") {
    const Biome biome = defaultBiome();
    test::checkParamTable(
        synth::speciesMapParamFields(), "docs/canopy.md",
        [&](const synth::SpeciesMapParams& p) { synth::validateSpeciesMapParams(p, biome); },
        [](const synth::SpeciesMapParams&) { return std::vector<std::pair<std::string, std::string>>{}; }, 0);
}

TEST_CASE("bad species-map input is rejected with a clear message", "[species_map]") {
    const Biome b = defaultBiome();
    synth::SpeciesMapParams p;
    {
        synth::SpeciesMapInputs in = gradientInputs();
        in.chmM(3, 5) = -2.f;
        CHECK_THROWS_WITH(synth::computeSpeciesMap(b, in), Catch::Contains("negative height") && Catch::Contains("(3, 5)"));
    }
    {
        synth::SpeciesMapInputs in = gradientInputs();
        in.features[Factor::Slope] = Grid<float>(10, 10, 1.0);
        CHECK_THROWS_AS(synth::computeSpeciesMap(b, in), ValidationError);
    }
    const synth::SpeciesMapInputs in = gradientInputs();
    CHECK_THROWS_WITH(synth::meetTarget(b, in, p, b.speciesIndex("Redwood"), 1.2), Catch::Contains("[0, 1]"));
    CHECK_THROWS_WITH(synth::meetTarget(b, in, p, b.speciesIndex("Toyon"), 0.2), Catch::Contains("not a canopy species"));
    CHECK_THROWS_WITH(synth::meetTargets(b, in, p, {{"Redwood", 0.7}, {"Douglas-Fir", 0.5}}), Catch::Contains("sum to"));
    CHECK_THROWS_WITH(synth::meetTargets(b, in, p, {{"Redwood", 0.2}, {"Redwood", 0.3}}), Catch::Contains("twice"));
    CHECK_THROWS_WITH(synth::meetTargets(b, in, p, {{"Nope", 0.2}}), Catch::Contains("unknown species"));
    auto empty = std::make_shared<Grid<std::uint8_t>>(Grid<std::uint8_t>::like(in.chmM, 0));
    CHECK_THROWS_WITH(synth::meetTarget(b, in, p, b.speciesIndex("Redwood"), 0.2, empty, "m.png"),
                      Catch::Contains("no forested cell") && Catch::Contains("m.png"));
    auto small = std::make_shared<Grid<std::uint8_t>>(Grid<std::uint8_t>(5, 5, 1.0, 0, 0, 1));
    CHECK_THROWS_WITH(synth::meetTarget(b, in, p, b.speciesIndex("Redwood"), 0.2, small, "m.png"), Catch::Contains("geometry"));
}

TEST_CASE("a mask image must have the CHM's pixel size", "[species_map]") {
    test::TempDir dir("species_mask");
    const Grid<float> chm(32, 24, 0.914);
    Grid<float> grey(32, 24, 0.914);
    for (int iy = 0; iy < 24; ++iy)
        for (int ix = 0; ix < 32; ++ix) grey(ix, iy) = ix < 16 ? 1.f : 0.f;
    writeTerrainImage(dir.file("mask.png"), grey);
    const auto mask = synth::readMaskImage(dir.file("mask.png"), chm);
    CHECK(mask(0, 0) == 1);
    CHECK(mask(31, 23) == 0);
    CHECK(synth::forestedCells(Grid<float>::like(chm, 10.f), 3.0, &mask) == 16u * 24u);
    writeTerrainImage(dir.file("small.png"), Grid<float>(16, 16, 1.0));
    CHECK_THROWS_WITH(synth::readMaskImage(dir.file("small.png"), chm),
                      Catch::Contains("small.png") && Catch::Contains("never resampled"));
}

// ---------------------------------------------------------------------------------------
// Wind (issue 30 item 1): validation on a ridge-and-valley terrain

namespace {

/// Two canopy species that differ in temperature optimum (14 / 16 degC) and, with
/// `withWind`, in their response to wind: "Windbreak" tolerates exposure (optimum 5 m/s, the
/// full strength), "Hollow" needs shelter (optimum 0). The other factors have ranges wide
/// enough not to matter. Prevailing wind from the west at 5 m/s, threshold 45 degrees, 10
/// samples: EcoMod's defaults.
Biome windBiome(bool withWind) {
    const std::string windyResponse = withWind ? "wind = { c = 5.0, r = 4.0 }\n" : "";
    const std::string shelteredResponse = withWind ? "wind = { c = 0.0, r = 4.0 }\n" : "";
    std::string text = R"([biome]
name = "Ridge and valley"
[climate]
latitude_deg = 38.58
lapse_rate_c_per_km = 9.8
temperature_c = [10, 10, 10, 10, 10, 10, 10, 10, 10, 10, 10, 10]
rainfall_mm = [50, 50, 50, 50, 50, 50, 50, 50, 50, 50, 50, 50]
sky_clarity = [0.7, 0.7, 0.7, 0.7, 0.7, 0.7, 0.7, 0.7, 0.7, 0.7, 0.7, 0.7]
[soil]
runoff_limit_mm = 100
slope_threshold_deg = 5
slope_max_deg = 55
evaporation_fraction = 0.25
saturation_mm = 180
[vigour]
a = 0.2
q = 0.01
p = 4.5
[wind]
direction_deg = 270
strength_m_s = 5
threshold_deg = 45
samples = 10
[growth_periods]
all = [0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11]
[allometry.A]
a = -0.5
b = 0.8
[[sub_biome]]
number = 1
name = "Forest"
canopy = ["Windbreak", "Hollow"]
[[species]]
name = "Windbreak"
sub_biomes = [1]
max_age_years = 200
max_height_m = 30
alpha = 0.5
sun = { c = 10, r = 1000 }
moisture = { c = 100, r = 10000 }
temperature = { c = 14, r = 4 }
slope = { c = 0, r = 1000 }
)" + windyResponse + R"(growth_period = "all"
allometry = "A"
canopy = true
[[species]]
name = "Hollow"
sub_biomes = [1]
max_age_years = 200
max_height_m = 30
alpha = 0.5
sun = { c = 10, r = 1000 }
moisture = { c = 100, r = 10000 }
temperature = { c = 16, r = 4 }
slope = { c = 0, r = 1000 }
)" + shelteredResponse + R"(growth_period = "all"
allometry = "A"
canopy = true
)";
    return parseBiome(text, withWind ? "ridge-valley-wind.toml" : "ridge-valley.toml");
}

}  // namespace

TEST_CASE("wind: on ridges and valleys the wind-tolerant species gains the exposed ridges and loses the shelter",
          "[species_map][wind]") {
    // Ridges running north-south, z = 30 cos(2 pi x / 200 m), 5 m cells, three wavelengths:
    // crests at x = 0, 200, 400 m, valleys between. With the wind from the west the lee
    // (east) slopes are sheltered by the crest upwind; crests and windward slopes are open.
    const double cellM = 5.0, wavelengthM = 200.0, amplitudeM = 30.0;
    const int w = 120, h = 40;
    Grid<float> terrain(w, h, cellM, 0, 0, 0.f);
    for (int iy = 0; iy < h; ++iy)
        for (int ix = 0; ix < w; ++ix)
            terrain(ix, iy) = static_cast<float>(amplitudeM * std::cos(2 * M_PI * terrain.cellCentreX(ix) / wavelengthM));
    // The classes come from the terrain's geometry, not from the wind map: a crest band
    // (within 20 m of a crest line) and lee mid-slopes (25..75 m east of a crest). The
    // westernmost wavelength is left out: its lee has no terrain upwind inside the grid.
    auto phaseM = [&](int ix) { return std::fmod(terrain.cellCentreX(ix), wavelengthM); };
    auto isRidge = [&](int ix) { return ix * cellM >= wavelengthM - 20 && (phaseM(ix) <= 20 || phaseM(ix) >= wavelengthM - 20); };
    auto isLee = [&](int ix) { return ix * cellM >= wavelengthM && phaseM(ix) >= 25 && phaseM(ix) <= 75; };

    // Annual factors: the wind from the model under test; a temperature of 14..16 degC
    // drawn per cell (independent of the terrain), which alone decides between the species
    // when wind does not count; the other factors constant.
    const Biome windy = windBiome(true), calm = windBiome(false);
    synth::SpeciesMapInputs in;
    in.chmM = Grid<float>::like(terrain, 12.f);
    in.features = FactorGrids::uniform(terrain, {10, 100, 15, 0, 0});
    in.features[Factor::Wind] = windSpeedMS(terrain, windy.wind);
    for (int iy = 0; iy < h; ++iy)
        for (int ix = 0; ix < w; ++ix) {
            RandomStream noise(30, static_cast<std::uint64_t>(iy * w + ix));
            in.features[Factor::Temperature](ix, iy) = static_cast<float>(noise.uniform(14.0, 16.0));
        }

    struct Shares {
        double ridge = 0, lee = 0, ridgeWind = 0, leeWind = 0;
    };
    auto sharesOf = [&](const Biome& b) {
        const Grid<std::int32_t> map = synth::computeSpeciesMap(b, in);
        const int windbreak = b.speciesIndex("Windbreak");
        double nRidge = 0, nLee = 0;
        Shares s;
        for (int iy = 0; iy < h; ++iy)
            for (int ix = 0; ix < w; ++ix) {
                REQUIRE(map(ix, iy) >= 0);
                const double isWindbreak = map(ix, iy) == windbreak ? 1.0 : 0.0;
                if (isRidge(ix)) {
                    s.ridge += isWindbreak;
                    s.ridgeWind += in.features[Factor::Wind](ix, iy);
                    ++nRidge;
                }
                if (isLee(ix)) {
                    s.lee += isWindbreak;
                    s.leeWind += in.features[Factor::Wind](ix, iy);
                    ++nLee;
                }
            }
        REQUIRE(nRidge >= 400);
        REQUIRE(nLee >= 400);
        s.ridge /= nRidge;
        s.lee /= nLee;
        s.ridgeWind /= nRidge;
        s.leeWind /= nLee;
        return s;
    };
    const Shares without = sharesOf(calm), with = sharesOf(windy);
    INFO("Windbreak's share on ridges " << without.ridge << " -> " << with.ridge << ", in the lee " << without.lee
                                        << " -> " << with.lee << "; mean wind ridges " << with.ridgeWind
                                        << " m/s, lee " << with.leeWind << " m/s");
    // The map really is exposed on the crests and sheltered in the lee.
    CHECK(with.ridgeWind > 4.0);
    CHECK(with.leeWind < 1.5);
    // Without wind responses the temperature draw decides: about half each, wherever.
    CHECK(without.ridge == Approx(0.5).margin(0.1));
    CHECK(without.lee == Approx(0.5).margin(0.1));
    // The stated margin: the tolerant species gains at least 0.3 of the exposed ridges and
    // loses at least 0.3 of the sheltered lee slopes.
    CHECK(with.ridge - without.ridge >= 0.3);
    CHECK(without.lee - with.lee >= 0.3);
    // Vigour says the same at the extremes: on the windiest crest cell the tolerant
    // species, in the calmest lee cell the one that needs shelter.
    const int crest = static_cast<int>(wavelengthM / cellM), lee = static_cast<int>((wavelengthM + 50) / cellM);
    const Features xc = in.features.at(crest, h / 2), xl = in.features.at(lee, h / 2);
    const int wb = windy.speciesIndex("Windbreak"), ho = windy.speciesIndex("Hollow");
    CHECK(windy.vigourOf(wb, xc) - windy.vigourOf(ho, xc) > 0.2);
    CHECK(windy.vigourOf(ho, xl) - windy.vigourOf(wb, xl) > 0.2);
}
