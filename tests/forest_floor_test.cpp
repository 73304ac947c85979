// Tests of the forest floor maps (synth/forest_floor): grass from the abiotics reduced by
// crown alpha, litter proportional to cumulative alpha.
#include <omp.h>

#include <catch2/catch.hpp>

#include <cmath>

#include "biome.h"
#include "error.h"
#include "forest_floor.h"
#include "param_table_check.h"
#include "rng.h"

using namespace eco;

namespace {

/// Uniform annual abiotics on a w x h grid of 1 m cells.
FactorGrids uniformFeatures(int w, int h, float sun, float moisture, float temperature, float slope) {
    return FactorGrids::uniform(Grid<float>(w, h, 1.0), {sun, moisture, temperature, slope});
}

Plant plantAt(const Biome& b, const std::string& species, double x, double y, double r) {
    Plant p;
    p.speciesId = b.speciesIndex(species);
    p.xM = x;
    p.yM = y;
    p.crownRadiusM = r;
    p.heightM = 10;
    return p;
}

}  // namespace

TEST_CASE("grass suitability follows the grass responses of the abiotics", "[forest_floor]") {
    const Biome b = defaultBiome();
    synth::ForestFloorParams p;
    // At the optimum of every response: full density.
    const auto best = uniformFeatures(8, 8, static_cast<float>(p.grassResponse(Factor::Sun).c), static_cast<float>(p.grassResponse(Factor::Moisture).c),
                                      static_cast<float>(p.grassResponse(Factor::Temperature).c), static_cast<float>(p.grassResponse(Factor::Slope).c));
    const synth::ForestFloor open = synth::computeForestFloor(best, {}, {}, b, p);
    CHECK(open.suitability(3, 3) == Approx(1.0f));
    CHECK(open.grass(3, 3) == Approx(1.0f));
    CHECK(open.litter(3, 3) == 0.0f);
    // One response at its range: g(r) = (1 + a) * 0.01 - a < 0, clamped to 0.
    auto dark = best;
    dark[Factor::Sun].fill(static_cast<float>(p.grassResponse(Factor::Sun).c - p.grassResponse(Factor::Sun).r));
    CHECK(synth::computeForestFloor(dark, {}, {}, b, p).grass(3, 3) == 0.0f);
    // Halfway: the biome's shape at half the range.
    auto half = best;
    half[Factor::Slope].fill(static_cast<float>(p.grassResponse(Factor::Slope).c + 0.5 * p.grassResponse(Factor::Slope).r));
    CHECK(synth::computeForestFloor(half, {}, {}, b, p).grass(3, 3) ==
          Approx(b.vigour.g(0.5 * p.grassResponse(Factor::Slope).r, p.grassResponse(Factor::Slope).r)).epsilon(1e-5));
}

TEST_CASE("crowns reduce grass by (1 - alpha) each and add alpha to the litter", "[forest_floor]") {
    const Biome b = defaultBiome();
    synth::ForestFloorParams p;
    p.litterFullAlpha = 2.0;
    const auto f = uniformFeatures(20, 20, static_cast<float>(p.grassResponse(Factor::Sun).c), static_cast<float>(p.grassResponse(Factor::Moisture).c),
                                   static_cast<float>(p.grassResponse(Factor::Temperature).c), static_cast<float>(p.grassResponse(Factor::Slope).c));
    const Plant redwood = plantAt(b, "Redwood", 6.5, 10.5, 3.0);          // alpha 0.45
    const Plant oak = plantAt(b, "Coast Live Oak", 9.5, 10.5, 3.0);       // alpha 0.31
    const Plant fern = plantAt(b, "Western Swordfern", 15.5, 15.5, 0.6);  // alpha 0.68, undergrowth
    const double aR = b.species[static_cast<std::size_t>(redwood.speciesId)].alpha;
    const double aO = b.species[static_cast<std::size_t>(oak.speciesId)].alpha;
    const double aF = b.species[static_cast<std::size_t>(fern.speciesId)].alpha;
    const synth::ForestFloor ff = synth::computeForestFloor(f, {redwood, oak}, {fern}, b, p);
    // Cell (4, 10): centre (4.5, 10.5), under the Redwood only.
    CHECK(ff.grass(4, 10) == Approx(1.0 - aR).epsilon(1e-5));
    CHECK(ff.litter(4, 10) == Approx(aR / 2.0).epsilon(1e-5));
    // Cell (8, 10): centre (8.5, 10.5), under both crowns.
    CHECK(ff.grass(8, 10) == Approx((1.0 - aR) * (1.0 - aO)).epsilon(1e-5));
    CHECK(ff.litter(8, 10) == Approx((aR + aO) / 2.0).epsilon(1e-5));
    CHECK(ff.cumulativeAlpha(8, 10) == Approx(aR + aO).epsilon(1e-5));
    // The fern's own cell; and open ground far from all.
    CHECK(ff.grass(15, 15) == Approx(1.0 - aF).epsilon(1e-5));
    CHECK(ff.grass(1, 1) == Approx(1.0f));
    CHECK(ff.litter(1, 1) == 0.0f);
    // Only the canopy shades when asked.
    p.undergrowthShades = false;
    CHECK(synth::computeForestFloor(f, {redwood, oak}, {fern}, b, p).grass(15, 15) == Approx(1.0f));
    // Litter saturates at 1.
    p.litterFullAlpha = 0.5;
    CHECK(synth::computeForestFloor(f, {redwood, oak}, {}, b, p).litter(8, 10) == 1.0f);
}

TEST_CASE("grass falls and litter rises with cumulative alpha, identical for any thread count", "[forest_floor]") {
    const Biome b = defaultBiome();
    synth::ForestFloorParams p;
    const auto f = uniformFeatures(120, 90, static_cast<float>(p.grassResponse(Factor::Sun).c), static_cast<float>(p.grassResponse(Factor::Moisture).c),
                                   static_cast<float>(p.grassResponse(Factor::Temperature).c), static_cast<float>(p.grassResponse(Factor::Slope).c));
    std::vector<Plant> canopy, under;
    RandomStream rs(3, 4);
    const char* names[] = {"Redwood", "Douglas-Fir", "Coast Live Oak", "Toyon", "Western Swordfern"};
    for (int i = 0; i < 300; ++i)
        canopy.push_back(plantAt(b, names[i % 3], rs.uniform(0, 120), rs.uniform(0, 90), rs.uniform(1, 6)));
    for (int i = 0; i < 3000; ++i)
        under.push_back(plantAt(b, names[3 + i % 2], rs.uniform(0, 120), rs.uniform(0, 90), rs.uniform(0.1, 1)));
    const int before = omp_get_max_threads();
    omp_set_num_threads(1);
    const synth::ForestFloor one = synth::computeForestFloor(f, canopy, under, b, p);
    omp_set_num_threads(2);
    const synth::ForestFloor two = synth::computeForestFloor(f, canopy, under, b, p);
    omp_set_num_threads(before);
    CHECK(one.grass.data() == two.grass.data());
    CHECK(one.litter.data() == two.litter.data());
    // Uniform abiotics: grass is a decreasing function of cumulative alpha cell by cell.
    for (std::size_t i = 0; i < one.grass.size(); ++i) {
        const float a = one.cumulativeAlpha.data()[i], g = one.grass.data()[i];
        REQUIRE(g <= 1.0f);
        REQUIRE(g >= 0.0f);
        if (a == 0) REQUIRE(g == Approx(1.0f));
        else REQUIRE(g < 1.0f);
        REQUIRE(one.litter.data()[i] == Approx(std::min(1.0, a / p.litterFullAlpha)).margin(1e-6));
    }
}

TEST_CASE("forest floor parameters: one description drives validation, the record and the docs", "[forest_floor]") {
    test::checkParamTable(
        synth::forestFloorParamFields(), "docs/synth.md", [](const synth::ForestFloorParams& p) { p.validate(); },
        [](const synth::ForestFloorParams& p) { return p.asParameters(); }, 10);
}

TEST_CASE("forest floor parameters are validated", "[forest_floor]") {
    synth::ForestFloorParams p;
    p.grassResponse(Factor::Sun).r = 0;
    CHECK_THROWS_WITH(p.validate(), Catch::Contains("grass_sun"));
    synth::ForestFloorParams q;
    q.litterFullAlpha = -1;
    CHECK_THROWS_WITH(q.validate(), Catch::Contains("litter_full_alpha"));
    FactorGrids f = uniformFeatures(4, 4, 10, 80, 15, 0);
    f[Factor::Slope] = Grid<float>(5, 4, 1.0);
    CHECK_THROWS_AS(synth::computeForestFloor(f, {}, {}, defaultBiome(), synth::ForestFloorParams{}), ValidationError);
}
