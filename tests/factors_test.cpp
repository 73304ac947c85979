// The factor axis (core/factors.h) and the vigour kernel (core/vigour.h), including the
// fifth factor, wind exposure (Zamuda & Brest's EcoMod): a species without a wind response
// is indifferent and keeps the vigour of the paper's four factors bit for bit (both
// kernels, against the kernels instantiated on four factors); and a test-only sixth factor,
// what the next factor does to Eq. 1, with the tables it is read from; docs/factors.md.
#include <catch2/catch.hpp>

#include <array>
#include <cmath>
#include <limits>
#include <string>

#include "abiotics.h"
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

// ---------------------------------------------------------------------------------------
// A test-only sixth factor: what a factor added after the wind does to Eq. 1, and the
// tables a new factor is read from (docs/factors.md "Adding a factor").

namespace {

constexpr std::size_t kSix = kFactorCount + 1;  // today's factors and one more

template <std::size_t N, typename T>
std::array<T, N + 1> withSixth(const std::array<T, N>& five, const T& sixth) {
    std::array<T, N + 1> out{};
    for (std::size_t f = 0; f < N; ++f) out[f] = five[f];
    out[N] = sixth;
    return out;
}

}  // namespace

TEST_CASE("a sixth factor nobody responds to leaves every vigour bit for bit, one that responds can win the min",
          "[factors][vigour]") {
    // A factor added to the table is one more entry of every Features and Responses: the
    // kernels, instantiated on six factors, must give the five-factor results bit for bit
    // when every species is indifferent to it (as responsesFor and defaultResponses leave
    // a species or the grass), whatever its value, and must let it win the min when the
    // species responds to it most strongly.
    const Biome b = defaultBiome();
    const VigourShape& g = b.vigour;
    const BatchVigourShape batch = BatchVigourShape::from(g);
    const double lnQ = std::log(g.q);
    RandomStream rng(23, 7);
    for (int k = 0; k < 300; ++k) {
        const Features x5 = randomFeatures(rng);
        const double sixth = k % 5 == 0 ? 0.0 : k % 13 == 0 ? -1e9 : rng.uniform(-50, 500);
        const FeaturesOf<kSix> x6 = withSixth(x5, sixth);
        for (const Species& s : b.species) {
            const ResponsesOf<kSix> r6 = withSixth(s.responses, Response::indifferent());
            REQUIRE(minResponse(g, r6, x6) == minResponse(g, s.responses, x5));
            REQUIRE(maxNormalisedDistance(r6, x6) == maxNormalisedDistance(s.responses, x5));
            REQUIRE(vigourAtDistance(s.alpha, maxNormalisedDistance(r6, x6), g.a, g.p, lnQ) ==
                    vigourAtDistance(s.alpha, maxNormalisedDistance(s.responses, x5), g.a, g.p, lnQ));
            const VigourCoeffsOf<kSix> k6 = VigourCoeffsOf<kSix>::from(s.alpha, r6);
            REQUIRE(k6.invR[kFactorCount] == 0.0);
            REQUIRE(batch.exponent(k6, x6) == batch.exponent(VigourCoeffs::from(s.alpha, s.responses), x5));
            // Responding: the min of the five and the sixth's own g, in both forms.
            const ResponsesOf<kSix> responding = withSixth(s.responses, Response{100.0, 80.0});
            const double five = minResponse(g, s.responses, x5);
            const double six = minResponse(g, responding, x6);
            REQUIRE(six == std::min(five, g.g(sixth - 100.0, 80.0)));
            const VigourCoeffsOf<kSix> kr = VigourCoeffsOf<kSix>::from(s.alpha, responding);
            REQUIRE(batch.fromExp(s.alpha, std::exp(batch.exponent(kr, x6))) == Approx(s.alpha * six).margin(1e-12));
        }
    }
}

TEST_CASE("responsesFor gives the factors named and leaves every other indifferent", "[factors][vigour]") {
    // The forest floor's grass is built so (synth/forest_floor.h): a factor added later
    // finds the grass indifferent to it with no line of its own.
    const Responses r = responsesFor({{Factor::Moisture, {76.0, 128.0}}, {Factor::Slope, {0.0, 50.0}}});
    for (std::size_t f = 0; f < kFactorCount; ++f) {
        INFO(kFactors[f].key);
        const bool named = f == factorIndex(Factor::Moisture) || f == factorIndex(Factor::Slope);
        CHECK(r[f].isIndifferent() == !named);
    }
    CHECK(r[factorIndex(Factor::Moisture)].c == 76.0);
    CHECK(r[factorIndex(Factor::Moisture)].r == 128.0);
    CHECK(r[factorIndex(Factor::Slope)].r == 50.0);
}

TEST_CASE("every factor has one map, and the simulator's static planes are the table's static maps", "[factors][abiotics]") {
    // The simulator reads the plant's sun and water from its sweep and the temperature from
    // the month's map; every other factor from a static map, in kStaticMaps' order
    // (sim/simulator_impl.h SitePlanes). A new static factor is one more row of
    // kAbioticMaps and thus one more plane there.
    std::array<int, kFactorCount> maps{};
    for (const AbioticMapInfo& m : kAbioticMaps) {
        INFO(m.name);
        ++maps[factorIndex(m.factor)];
        CHECK(std::string(m.dataset) == std::string("/") + m.name);
        CHECK(m.lo < m.hi);
    }
    for (std::size_t f = 0; f < kFactorCount; ++f) CHECK(maps[f] == 1);
    std::size_t next = 0;
    for (const AbioticMapInfo& m : kAbioticMaps) {
        if (m.isMonthly()) continue;
        REQUIRE(next < kStaticMapCount);
        CHECK(std::string(kStaticMaps[next].name) == m.name);
        CHECK(kStaticMaps[next].single == m.single);
        ++next;
    }
    CHECK(next == kStaticMapCount);
    for (const Factor f : {Factor::Sun, Factor::Moisture, Factor::Temperature}) CHECK(detail::isMonthlyFactor(f));
    CHECK_FALSE(detail::isMonthlyFactor(Factor::Slope));
    CHECK_FALSE(detail::isMonthlyFactor(Factor::Wind));
}
