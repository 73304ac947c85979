// The factor axis (core/factors.h) and the vigour kernel (core/vigour.h), including the
// fifth factor, wind exposure (Zamuda & Brest's EcoMod): a species without a wind response
// is indifferent and keeps the vigour of the paper's four factors bit for bit (both
// kernels, against the kernels instantiated on four factors); docs/factors.md.
#include <catch2/catch.hpp>

#include <cmath>
#include <limits>

#include "biome.h"
#include "factors.h"
#include "rng.h"
#include "vigour.h"

using namespace eco;

namespace {

constexpr std::size_t kFour = 4;  // the paper's four factors, before wind

/// The first four of a species' responses (the paper's Eq. 1 without wind).
ResponsesOf<kFour> paperFour(const Responses& r5) {
    ResponsesOf<kFour> r{};
    for (std::size_t f = 0; f < kFour; ++f) r[f] = r5[f];
    return r;
}

FeaturesOf<kFour> paperFour(const Features& x5) {
    FeaturesOf<kFour> y{};
    for (std::size_t f = 0; f < kFour; ++f) y[f] = x5[f];
    return y;
}

Features randomFeatures(RandomStream& rng) {
    return {rng.uniform(0, 16), rng.uniform(0, 250), rng.uniform(-5, 40), rng.uniform(0, 80), rng.uniform(0, 20)};
}

}  // namespace

TEST_CASE("the factor table names the biome's response tables and the database's features", "[factors]") {
    REQUIRE(kFactors.size() == kFactorCount);
    CHECK(std::string(kFactors[factorIndex(Factor::Sun)].key) == "sun");
    CHECK(std::string(kFactors[factorIndex(Factor::Moisture)].key) == "moisture");
    CHECK(std::string(kFactors[factorIndex(Factor::Temperature)].key) == "temperature");
    CHECK(std::string(kFactors[factorIndex(Factor::Slope)].key) == "slope");
    CHECK(std::string(kFactors[factorIndex(Factor::Wind)].key) == "wind");
    CHECK(std::string(kFactors[factorIndex(Factor::Wind)].unit) == "m/s");
    for (std::size_t f = 0; f < kFour; ++f) CHECK(kFactors[f].responseRequired);
    CHECK_FALSE(kFactors[factorIndex(Factor::Wind)].responseRequired);
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
        const Features x = randomFeatures(rng);
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

TEST_CASE("a species indifferent to wind has its four-factor vigour bit for bit, in both kernels", "[factors][vigour]") {
    const Biome b = defaultBiome();  // Sonoma: no species gives a wind response
    const VigourShape& g = b.vigour;
    const BatchVigourShape batch = BatchVigourShape::from(g);
    const double lnQ = std::log(g.q);
    RandomStream rng(23, 5);
    for (const Species& s : b.species) REQUIRE(s.response(Factor::Wind).isIndifferent());
    for (int k = 0; k < 300; ++k) {
        Features x = randomFeatures(rng);
        if (k % 7 == 0) x[factorIndex(Factor::Wind)] = 0;  // calm and
        if (k % 11 == 0) x[factorIndex(Factor::Wind)] = 1e6;  // absurd winds too
        for (const Species& s : b.species) {
            const ResponsesOf<kFour> r4 = paperFour(s.responses);
            const FeaturesOf<kFour> x4 = paperFour(x);
            // Scalar: the min over g and the max-distance form, against the same kernels
            // instantiated on the four factors alone.
            REQUIRE(minResponse(g, s.responses, x) == minResponse(g, r4, x4));
            REQUIRE(maxNormalisedDistance(s.responses, x) == maxNormalisedDistance(r4, x4));
            REQUIRE(b.vigourOf(s.id, x) == s.alpha * minResponse(g, r4, x4));
            REQUIRE(vigourAtDistance(s.alpha, maxNormalisedDistance(s.responses, x), g.a, g.p, lnQ) ==
                    vigourAtDistance(s.alpha, maxNormalisedDistance(r4, x4), g.a, g.p, lnQ));
            // Batch: the exponent (hence every exp and vigour) is the four-factor one.
            const VigourCoeffs k5 = VigourCoeffs::from(s.alpha, s.responses);
            const VigourCoeffsOf<kFour> k4 = VigourCoeffsOf<kFour>::from(s.alpha, r4);
            REQUIRE(k5.invR[factorIndex(Factor::Wind)] == 0.0);
            REQUIRE(batch.exponent(k5, x) == batch.exponent(k4, x4));
        }
    }
}

TEST_CASE("a wind response enters the min of Eq. 1 when it is the lowest", "[factors][vigour]") {
    const Biome b = defaultBiome();
    const VigourShape& g = b.vigour;
    const BatchVigourShape batch = BatchVigourShape::from(g);
    RandomStream rng(23, 6);
    for (int k = 0; k < 300; ++k) {
        const Features x = randomFeatures(rng);
        const double wind = x[factorIndex(Factor::Wind)];
        for (Species s : b.species) {
            const double four = s.alpha * minResponse(g, paperFour(s.responses), paperFour(x));
            s.response(Factor::Wind) = Response{2.0, 6.0};
            const double five = s.alpha * minResponse(g, s.responses, x);
            REQUIRE(five == std::min(four, s.alpha * g.g(wind - 2.0, 6.0)));
            REQUIRE(five <= four);
            const VigourCoeffs k5 = VigourCoeffs::from(s.alpha, s.responses);
            REQUIRE(batch.fromExp(s.alpha, std::exp(batch.exponent(k5, x))) == Approx(five).margin(1e-12));
        }
    }
    // A wind far outside the range kills the species: vigour -a alpha < 0.
    Species rw = b.species[static_cast<std::size_t>(b.speciesIndex("Redwood"))];
    rw.response(Factor::Wind) = Response{2.0, 6.0};
    Features opt{};
    for (std::size_t f = 0; f < kFactorCount; ++f) opt[f] = rw.responses[f].c;
    opt[factorIndex(Factor::Wind)] = 40.0;
    CHECK(rw.alpha * minResponse(g, rw.responses, opt) == Approx(-g.a * rw.alpha));
    opt[factorIndex(Factor::Wind)] = 2.0;
    CHECK(rw.alpha * minResponse(g, rw.responses, opt) == Approx(rw.alpha));
}
