// Counter-based random numbers (Philox4x32-10, Salmon et al. 2011).
//
// A value is a pure function of (seed, stream, counter): parallel code keys the stream by
// the entity (plant, cell, tree) and the counter by the step (month, draw), so results are
// bit-identical whatever the number of threads or the schedule.
#pragma once

#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>

#ifdef __SSE2__
#include <emmintrin.h>
#endif

namespace eco {

/// Philox4x32-10 block: 128-bit counter, 64-bit key, 128 random bits out.
inline std::array<std::uint32_t, 4> philox4x32(std::array<std::uint32_t, 4> ctr,
                                               std::array<std::uint32_t, 2> key) {
    constexpr std::uint32_t kMul0 = 0xD2511F53u, kMul1 = 0xCD9E8D57u;
    constexpr std::uint32_t kWeyl0 = 0x9E3779B9u, kWeyl1 = 0xBB67AE85u;
    for (int round = 0; round < 10; ++round) {
        const std::uint64_t p0 = static_cast<std::uint64_t>(kMul0) * ctr[0];
        const std::uint64_t p1 = static_cast<std::uint64_t>(kMul1) * ctr[2];
        ctr = {static_cast<std::uint32_t>(p1 >> 32) ^ ctr[1] ^ key[0], static_cast<std::uint32_t>(p1),
               static_cast<std::uint32_t>(p0 >> 32) ^ ctr[3] ^ key[1], static_cast<std::uint32_t>(p0)};
        key[0] += kWeyl0;
        key[1] += kWeyl1;
    }
    return ctr;
}

/// 128 random bits for (seed, stream, counter).
inline std::array<std::uint32_t, 4> randomBits(std::uint64_t seed, std::uint64_t stream,
                                               std::uint64_t counter) {
    return philox4x32({static_cast<std::uint32_t>(counter), static_cast<std::uint32_t>(counter >> 32),
                       static_cast<std::uint32_t>(stream), static_cast<std::uint32_t>(stream >> 32)},
                      {static_cast<std::uint32_t>(seed), static_cast<std::uint32_t>(seed >> 32)});
}

/// Uniform double in [0, 1) with 53 random bits.
inline double bitsToUnit(std::uint32_t hi, std::uint32_t lo) {
    const std::uint64_t v = (static_cast<std::uint64_t>(hi) << 21) ^ (lo >> 11);
    return static_cast<double>(v & ((std::uint64_t{1} << 53) - 1)) * 0x1.0p-53;
}

/// Sequential draws from one (seed, stream): each block of four 32-bit words is
/// philox(seed, stream, block). Cheap to construct; use one per entity and step.
class RandomStream {
public:
    RandomStream(std::uint64_t seed, std::uint64_t stream, std::uint64_t firstBlock = 0)
        : seed_(seed), stream_(stream), block_(firstBlock) {}

    std::uint32_t nextU32() {
        if (used_ == 4) {
            buf_ = randomBits(seed_, stream_, block_++);
            used_ = 0;
        }
        return buf_[used_++];
    }
    /// Uniform in [0, 1).
    double uniform() {
        const std::uint32_t a = nextU32();
        const std::uint32_t b = nextU32();
        return bitsToUnit(a, b);
    }
    /// Uniform in [lo, hi).
    double uniform(double lo, double hi) { return lo + (hi - lo) * uniform(); }
    /// Uniform integer in [0, n), n > 0 (rejection-free multiply-shift; bias < 2^-32).
    std::uint32_t below(std::uint32_t n) {
        return static_cast<std::uint32_t>((static_cast<std::uint64_t>(nextU32()) * n) >> 32);
    }
    /// Standard normal (Box-Muller; uses two uniforms).
    double normal() {
        const double u1 = 1.0 - uniform();  // (0, 1]
        const double u2 = uniform();
        return std::sqrt(-2.0 * std::log(u1)) * std::cos(6.283185307179586 * u2);
    }

private:
    std::uint64_t seed_, stream_, block_;
    std::array<std::uint32_t, 4> buf_{};
    int used_ = 4;
};

/// Combine several identifiers into one 64-bit stream id (SplitMix64 finaliser).
inline std::uint64_t mixStream(std::uint64_t a, std::uint64_t b) {
    std::uint64_t z = a * 0x9E3779B97F4A7C15ull + b + 0x632BE59BD9B4E019ull;
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
}

/// Words 0 and 1 of randomBits(seed, stream[i], counter) for i < n: many streams at one
/// counter, four at a time where SSE2 is available (integer arithmetic: the same bits as
/// randomBits, which tests/rng_test.cpp checks).
inline void randomBitsBatch(std::uint64_t seed, const std::uint64_t* stream, std::uint64_t counter, std::size_t n,
                            std::uint32_t* word0, std::uint32_t* word1) {
    std::size_t i = 0;
#ifdef __SSE2__
    const __m128i mul0 = _mm_set1_epi32(static_cast<int>(0xD2511F53u)), mul1 = _mm_set1_epi32(static_cast<int>(0xCD9E8D57u));
    // 32 x 32 -> 64-bit products of four lanes: low and high words, lane order kept.
    auto mulHiLo = [](__m128i a, __m128i m, __m128i& hi, __m128i& lo) {
        const __m128i even = _mm_mul_epu32(a, m);                                        // lanes 0, 2
        const __m128i odd = _mm_mul_epu32(_mm_srli_epi64(a, 32), _mm_srli_epi64(m, 32));  // lanes 1, 3
        lo = _mm_unpacklo_epi32(_mm_shuffle_epi32(even, 0x08), _mm_shuffle_epi32(odd, 0x08));
        hi = _mm_unpacklo_epi32(_mm_shuffle_epi32(even, 0x0D), _mm_shuffle_epi32(odd, 0x0D));
    };
    for (; i + 4 <= n; i += 4) {
        __m128i c0 = _mm_set1_epi32(static_cast<int>(static_cast<std::uint32_t>(counter)));
        __m128i c1 = _mm_set1_epi32(static_cast<int>(static_cast<std::uint32_t>(counter >> 32)));
        __m128i c2 = _mm_set_epi32(static_cast<int>(static_cast<std::uint32_t>(stream[i + 3])),
                                   static_cast<int>(static_cast<std::uint32_t>(stream[i + 2])),
                                   static_cast<int>(static_cast<std::uint32_t>(stream[i + 1])),
                                   static_cast<int>(static_cast<std::uint32_t>(stream[i])));
        __m128i c3 = _mm_set_epi32(static_cast<int>(static_cast<std::uint32_t>(stream[i + 3] >> 32)),
                                   static_cast<int>(static_cast<std::uint32_t>(stream[i + 2] >> 32)),
                                   static_cast<int>(static_cast<std::uint32_t>(stream[i + 1] >> 32)),
                                   static_cast<int>(static_cast<std::uint32_t>(stream[i] >> 32)));
        std::uint32_t key0 = static_cast<std::uint32_t>(seed), key1 = static_cast<std::uint32_t>(seed >> 32);
        for (int round = 0; round < 10; ++round) {
            __m128i hi0, lo0, hi1, lo1;
            mulHiLo(c0, mul0, hi0, lo0);
            mulHiLo(c2, mul1, hi1, lo1);
            c0 = _mm_xor_si128(_mm_xor_si128(hi1, c1), _mm_set1_epi32(static_cast<int>(key0)));
            c1 = lo1;
            c2 = _mm_xor_si128(_mm_xor_si128(hi0, c3), _mm_set1_epi32(static_cast<int>(key1)));
            c3 = lo0;
            key0 += 0x9E3779B9u;
            key1 += 0xBB67AE85u;
        }
        _mm_storeu_si128(reinterpret_cast<__m128i*>(word0 + i), c0);
        _mm_storeu_si128(reinterpret_cast<__m128i*>(word1 + i), c1);
    }
#endif
    for (; i < n; ++i) {
        const auto b = randomBits(seed, stream[i], counter);
        word0[i] = b[0];
        word1[i] = b[1];
    }
}

}  // namespace eco
