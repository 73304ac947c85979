// Philox4x32-10 known answers and statistical checks of the streams built on it.
// Statistical tests use fixed seeds (so they are deterministic) and thresholds chosen at a
// stated significance: a correct generator fails one with that probability per seed.
#include <catch2/catch.hpp>

#include <array>
#include <cmath>
#include <cstdint>
#include <vector>

#include "rng.h"

using eco::RandomStream;

TEST_CASE("rng: Philox4x32-10 known-answer vectors (Random123 kat_vectors)", "[rng]") {
    using A4 = std::array<std::uint32_t, 4>;
    // ctr = {0, 0, 0, 0}, key = {0, 0}.
    CHECK(eco::philox4x32({0, 0, 0, 0}, {0, 0}) == A4{0x6627e8d5u, 0xe169c58du, 0xbc57ac4cu, 0x9b00dbd8u});
    // All ones.
    CHECK(eco::philox4x32({0xffffffffu, 0xffffffffu, 0xffffffffu, 0xffffffffu}, {0xffffffffu, 0xffffffffu}) ==
          A4{0x408f276du, 0x41c83b0eu, 0xa20bc7c6u, 0x6d5451fdu});
    // Digits of pi.
    CHECK(eco::philox4x32({0x243f6a88u, 0x85a308d3u, 0x13198a2eu, 0x03707344u}, {0xa4093822u, 0x299f31d0u}) ==
          A4{0xd16cfe09u, 0x94fdccebu, 0x5001e420u, 0x24126ea1u});
}

TEST_CASE("rng: randomBits packs (seed, stream, counter) into key and counter", "[rng]") {
    const std::uint64_t seed = 0x0123456789abcdefull, stream = 0xfedcba9876543210ull, counter = 0x1122334455667788ull;
    const auto a = eco::randomBits(seed, stream, counter);
    const auto b = eco::philox4x32({0x55667788u, 0x11223344u, 0x76543210u, 0xfedcba98u}, {0x89abcdefu, 0x01234567u});
    CHECK(a == b);
}

TEST_CASE("rng: randomBitsBatch gives randomBits' words for every stream, at any batch length", "[rng]") {
    const std::uint64_t seed = 0x0123456789abcdefull;
    std::vector<std::uint64_t> streams;
    for (std::uint64_t i = 0; i < 23; ++i) streams.push_back(eco::mixStream(i, 77) ^ (i << 60));  // high words set too
    // The SSE2 form and, where the processor has AVX2, the AVX2 form (core/cpu.h).
    for (bool avx2 : {false, true}) {
        if (eco::setAvx2Kernels(avx2) != avx2) WARN("no AVX2 on this processor: its form of randomBitsBatch is not checked");
    for (std::uint64_t counter : {std::uint64_t{0}, std::uint64_t{1799}, std::uint64_t{0xfedcba9876543210ull}})
        for (std::size_t n : {std::size_t{0}, std::size_t{1}, std::size_t{4}, std::size_t{7}, std::size_t{8}, std::size_t{13},
                              streams.size()}) {
            std::vector<std::uint32_t> w0(n + 1, 0xDEADBEEFu), w1(n + 1, 0xDEADBEEFu);
            eco::randomBitsBatch(seed, streams.data(), counter, n, w0.data(), w1.data());
            for (std::size_t i = 0; i < n; ++i) {
                const auto b = eco::randomBits(seed, streams[i], counter);
                CHECK(w0[i] == b[0]);
                CHECK(w1[i] == b[1]);
            }
            CHECK(w0[n] == 0xDEADBEEFu);  // nothing written past n
        }
    }
    eco::setAvx2Kernels(true);  // back to the default
}

TEST_CASE("rng: randomBlocksBatch gives randomBits' four words for every (stream, counter), at any batch length", "[rng]") {
    const std::uint64_t seed = 0x0f1e2d3c4b5a6978ull;
    std::vector<std::uint64_t> streams, counters;
    for (std::uint64_t i = 0; i < 29; ++i) {
        streams.push_back(eco::mixStream(i / 3, 5) ^ (i << 59));                    // repeated streams, high words set
        counters.push_back(i % 3 == 0 ? i : eco::mixStream(i, 11) >> (i % 2 ? 0 : 40));  // small and full-width counters
    }
    for (bool avx2 : {false, true}) {
        if (eco::setAvx2Kernels(avx2) != avx2) WARN("no AVX2 on this processor: its form of randomBlocksBatch is not checked");
        for (std::size_t n : {std::size_t{0}, std::size_t{1}, std::size_t{3}, std::size_t{4}, std::size_t{8}, std::size_t{11},
                              std::size_t{16}, streams.size()}) {
            std::vector<std::uint32_t> w[4];
            for (auto& v : w) v.assign(n + 1, 0xDEADBEEFu);
            eco::randomBlocksBatch(seed, streams.data(), counters.data(), n, w[0].data(), w[1].data(), w[2].data(), w[3].data());
            for (std::size_t i = 0; i < n; ++i) {
                const auto b = eco::randomBits(seed, streams[i], counters[i]);
                for (int k = 0; k < 4; ++k) CHECK(w[k][i] == b[static_cast<std::size_t>(k)]);
            }
            for (const auto& v : w) CHECK(v[n] == 0xDEADBEEFu);  // nothing written past n
        }
    }
    eco::setAvx2Kernels(true);  // back to the default
}

TEST_CASE("rng: a stream's position (usedWords, buffered, nextBlock) continues it", "[rng]") {
    for (int skip : {0, 1, 2, 3, 4, 5, 7, 8, 13}) {
        RandomStream a(9, 1234, 5), b(9, 1234, 5);
        for (int i = 0; i < skip; ++i) a.nextU32(), b.nextU32();
        // The next 20 words from the position, against the stream itself.
        std::vector<std::uint32_t> words;
        for (int k = a.usedWords(); k < 4; ++k) words.push_back(a.buffered()[static_cast<std::size_t>(k)]);
        for (std::uint64_t blk = a.nextBlock(); words.size() < 20; ++blk)
            for (std::uint32_t x : eco::randomBits(9, a.streamId(), blk)) words.push_back(x);
        for (std::size_t i = 0; i < 20; ++i) CHECK(words[i] == b.nextU32());
    }
}

TEST_CASE("rng: streams are deterministic and block-addressable", "[rng]") {
    RandomStream a(42, 7), b(42, 7);
    std::vector<std::uint32_t> first;
    for (int i = 0; i < 100; ++i) {
        const auto x = a.nextU32();
        CHECK(x == b.nextU32());
        first.push_back(x);
    }
    // Draw k of a stream is word k % 4 of block k / 4.
    for (int k = 0; k < 100; ++k) CHECK(first[k] == eco::randomBits(42, 7, k / 4)[k % 4]);
    // Starting at a later block skips exactly those blocks.
    RandomStream c(42, 7, 5);
    CHECK(c.nextU32() == first[20]);
    // Another seed or stream gives another sequence.
    RandomStream d(43, 7), e(42, 8);
    int sameSeed = 0, sameStream = 0;
    for (int i = 0; i < 100; ++i) {
        sameSeed += d.nextU32() == first[i];
        sameStream += e.nextU32() == first[i];
    }
    CHECK(sameSeed == 0);
    CHECK(sameStream == 0);
}

TEST_CASE("rng: uniform mean and variance (z-tests, significance 1e-6 each)", "[rng]") {
    // For U(0,1): mean 1/2, variance 1/12; the sample variance has variance
    // (mu4 - sigma^4) / n with mu4 = 1/80. |z| < 4.89 is the two-sided 1e-6 bound.
    constexpr double kZ = 4.89;
    for (std::uint64_t seed : {1ull, 2ull, 12345ull}) {
        RandomStream rng(seed, 3);
        const int n = 1000000;
        double sum = 0, sum2 = 0;
        for (int i = 0; i < n; ++i) {
            const double u = rng.uniform();
            REQUIRE(u >= 0.0);
            REQUIRE(u < 1.0);
            sum += u;
            sum2 += u * u;
        }
        const double mean = sum / n;
        const double var = sum2 / n - mean * mean;
        const double zMean = (mean - 0.5) / std::sqrt(1.0 / 12.0 / n);
        const double zVar = (var - 1.0 / 12.0) / std::sqrt((1.0 / 80.0 - 1.0 / 144.0) / n);
        INFO("seed " << seed << ": mean " << mean << " (z " << zMean << "), variance " << var << " (z " << zVar << ")");
        CHECK(std::abs(zMean) < kZ);
        CHECK(std::abs(zVar) < kZ);
    }
}

TEST_CASE("rng: chi-square uniformity on 16 bins (significance 0.001)", "[rng]") {
    // 15 degrees of freedom: P(chi2 > 37.70) = 0.001.
    constexpr double kCritical = 37.70;
    constexpr int kBins = 16;
    for (std::uint64_t seed : {1ull, 99ull}) {
        const int n = 160000;
        std::array<double, kBins> uniformCounts{}, belowCounts{}, bitsCounts{};
        RandomStream rng(seed, 11);
        for (int i = 0; i < n; ++i) {
            uniformCounts[static_cast<std::size_t>(rng.uniform() * kBins)] += 1;
            belowCounts[rng.below(kBins)] += 1;
            // Counter-based use: one word per counter, as parallel code does.
            bitsCounts[eco::randomBits(seed, 12, static_cast<std::uint64_t>(i))[0] >> 28] += 1;
        }
        auto chi2 = [&](const std::array<double, kBins>& c) {
            const double expected = static_cast<double>(n) / kBins;
            double s = 0;
            for (double v : c) s += (v - expected) * (v - expected) / expected;
            return s;
        };
        INFO("seed " << seed);
        CHECK(chi2(uniformCounts) < kCritical);
        CHECK(chi2(belowCounts) < kCritical);
        CHECK(chi2(bitsCounts) < kCritical);
    }
}

TEST_CASE("rng: neighbouring streams and seeds are uncorrelated (significance 1e-6)", "[rng]") {
    // Pearson correlation of n independent pairs has standard deviation 1/sqrt(n);
    // |r| < 4.89 / sqrt(n) at two-sided 1e-6.
    const int n = 200000;
    const double bound = 4.89 / std::sqrt(static_cast<double>(n));
    auto correlation = [&](RandomStream a, RandomStream b) {
        double sa = 0, sb = 0, saa = 0, sbb = 0, sab = 0;
        for (int i = 0; i < n; ++i) {
            const double x = a.uniform(), y = b.uniform();
            sa += x;
            sb += y;
            saa += x * x;
            sbb += y * y;
            sab += x * y;
        }
        const double cov = sab / n - (sa / n) * (sb / n);
        return cov / std::sqrt((saa / n - sa / n * sa / n) * (sbb / n - sb / n * sb / n));
    };
    CHECK(std::abs(correlation(RandomStream(1, 0), RandomStream(1, 1))) < bound);
    CHECK(std::abs(correlation(RandomStream(1, 5), RandomStream(2, 5))) < bound);
    CHECK(std::abs(correlation(RandomStream(7, eco::mixStream(3, 0)), RandomStream(7, eco::mixStream(3, 1)))) < bound);
    // Lag-1 autocorrelation within one stream.
    RandomStream s(5, 5);
    RandomStream t(5, 5);
    t.uniform();
    CHECK(std::abs(correlation(s, t)) < bound + 1e-9);
}

TEST_CASE("rng: normal() has mean 0 and variance 1 (significance 1e-6)", "[rng]") {
    RandomStream rng(2024, 1);
    const int n = 400000;
    double sum = 0, sum2 = 0;
    for (int i = 0; i < n; ++i) {
        const double z = rng.normal();
        REQUIRE(std::isfinite(z));
        sum += z;
        sum2 += z * z;
    }
    const double mean = sum / n, var = sum2 / n - mean * mean;
    CHECK(std::abs(mean) < 4.89 / std::sqrt(static_cast<double>(n)));
    CHECK(std::abs(var - 1.0) < 4.89 * std::sqrt(2.0 / n));  // Var(s^2) = 2 / n for N(0, 1)
}

TEST_CASE("rng: mixStream spreads nearby identifiers", "[rng]") {
    CHECK(eco::mixStream(0, 0) != eco::mixStream(0, 1));
    CHECK(eco::mixStream(0, 1) != eco::mixStream(1, 0));
    CHECK(eco::mixStream(5, 6) == eco::mixStream(5, 6));
    // Bits flip about half the time between consecutive identifiers.
    int flipped = 0;
    for (std::uint64_t i = 0; i < 1000; ++i) flipped += __builtin_popcountll(eco::mixStream(9, i) ^ eco::mixStream(9, i + 1));
    CHECK(flipped / 1000.0 == Approx(32.0).margin(1.5));
}
