// The factor axis (core/factors.h) and the vigour kernel (core/vigour.h), including a
// test-only fifth factor: wind exposure, as in Zamuda & Brest's afforestation model. The
// kernel is templated on the number of factors, so a five-factor table needs no change to
// it; docs/factors.md lists what a real fifth factor would touch.
#include <catch2/catch.hpp>

#include <cmath>
#include <limits>

#include "biome.h"
#include "factors.h"
#include "rng.h"
#include "vigour.h"

using namespace eco;

namespace {

constexpr std::size_t kFive = 5;
constexpr std::size_t kWind = 4;  // the test-only factor, after slope

/// A species' four responses from the biome, and a wind response (optimum 2 m/s, range 6).
ResponsesOf<kFive> withWind(const Species& s) {
    ResponsesOf<kFive> r{};
    for (std::size_t f = 0; f < kFactorCount; ++f) r[f] = s.responses[f];
    r[kWind] = Response{2.0, 6.0};
    return r;
}

FeaturesOf<kFive> withWind(const Features& x, double windMPerS) {
    FeaturesOf<kFive> y{};
    for (std::size_t f = 0; f < kFactorCount; ++f) y[f] = x[f];
    y[kWind] = windMPerS;
    return y;
}

}  // namespace

TEST_CASE("the factor table names the biome's response tables and the database's features", "[factors]") {
    REQUIRE(kFactors.size() == kFactorCount);
    CHECK(std::string(kFactors[factorIndex(Factor::Sun)].key) == "sun");
    CHECK(std::string(kFactors[factorIndex(Factor::Moisture)].key) == "moisture");
    CHECK(std::string(kFactors[factorIndex(Factor::Temperature)].key) == "temperature");
    CHECK(std::string(kFactors[factorIndex(Factor::Slope)].key) == "slope");
    const Biome b = defaultBiome();
    const Species& rw = b.species[static_cast<std::size_t>(b.speciesIndex("Redwood"))];
    CHECK(rw.response(Factor::Sun).c == 9.5);  // Table 3: sun 9.5 / 11, moisture 100 / 160
    CHECK(rw.response(Factor::Moisture).r == 160);
}

TEST_CASE("FactorGrids reads a cell's features in factor order", "[factors]") {
    FactorGrids g;
    for (std::size_t f = 0; f < kFactorCount; ++f) g.maps[f] = Grid<float>(3, 2, 1.0, 0, 0, static_cast<float>(f + 1));
    g[Factor::Moisture](2, 1) = 42.f;
    const Features x = g.at(2, 1);
    CHECK(x[0] == 1.0);
    CHECK(x[factorIndex(Factor::Moisture)] == 42.0);
    CHECK(x[3] == 4.0);
    CHECK(g.geometry().width() == 3);
}

TEST_CASE("scalar and batch vigour kernels agree, and min over g is g at the largest distance", "[factors][vigour]") {
    const Biome b = defaultBiome();
    const BatchVigourShape batch = BatchVigourShape::from(b.vigour);
    RandomStream rng(23, 2);
    for (int k = 0; k < 500; ++k) {
        const Features x = {rng.uniform(0, 16), rng.uniform(0, 250), rng.uniform(-5, 40), rng.uniform(0, 80)};
        for (const Species& s : b.species) {
            const double scalar = b.vigourOf(s.id, x);
            const double atMax = vigourAtDistance(s.alpha, maxNormalisedDistance(s.responses, x), b.vigour.a, b.vigour.p,
                                                  std::log(b.vigour.q));
            REQUIRE(atMax == scalar);  // g is monotone: bit for bit
            const VigourCoeffs k4 = VigourCoeffs::from(s.alpha, s.responses);
            const double batched = batch.fromExp(s.alpha, std::exp(batch.exponent(k4, x)));
            REQUIRE(batched == Approx(scalar).margin(1e-12));
        }
    }
}

TEST_CASE("a test-only fifth factor (wind) needs no change to the vigour kernel", "[factors][vigour]") {
    const Biome b = defaultBiome();
    const VigourShape& g = b.vigour;
    const BatchVigourShape batch = BatchVigourShape::from(g);
    RandomStream rng(23, 5);
    for (int k = 0; k < 300; ++k) {
        const Features x = {rng.uniform(0, 16), rng.uniform(0, 250), rng.uniform(-5, 40), rng.uniform(0, 80)};
        for (const Species& s : b.species) {
            const ResponsesOf<kFive> r5 = withWind(s);
            // Wind at its optimum: the five-factor vigour is the four-factor one, bit for bit
            // (g(0) = 1 is the largest response, so the fifth factor never wins the min).
            const double four = b.vigourOf(s.id, x);
            REQUIRE(s.alpha * minResponse(g, r5, withWind(x, 2.0)) == four);
            // Wind off its optimum: the min takes the wind's response when it is the lowest.
            const double wind = rng.uniform(0, 20);
            const double five = s.alpha * minResponse(g, r5, withWind(x, wind));
            REQUIRE(five == std::min(four, s.alpha * g.g(wind - 2.0, 6.0)));
            REQUIRE(five <= four);
            // The batch form of the same five factors.
            const VigourCoeffsOf<kFive> k5 = VigourCoeffsOf<kFive>::from(s.alpha, r5);
            REQUIRE(batch.fromExp(s.alpha, std::exp(batch.exponent(k5, withWind(x, wind)))) == Approx(five).margin(1e-12));
        }
    }
    // A wind far outside the range kills every species: vigour -a alpha < 0.
    const Species& rw = b.species[static_cast<std::size_t>(b.speciesIndex("Redwood"))];
    Features opt{};
    for (std::size_t f = 0; f < kFactorCount; ++f) opt[f] = rw.responses[f].c;
    CHECK(rw.alpha * minResponse(g, withWind(rw), withWind(opt, 40.0)) == Approx(-g.a * rw.alpha));
    CHECK(rw.alpha * minResponse(g, withWind(rw), withWind(opt, 2.0)) == Approx(rw.alpha));
}
