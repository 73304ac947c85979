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

#include "cpu.h"

#ifdef __SSE2__
#include <emmintrin.h>
#endif
#ifdef ECO_HAVE_AVX2_KERNELS
#include <immintrin.h>
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

#ifdef ECO_HAVE_AVX2_KERNELS
/// randomBitsBatch's SSE2 loop on eight streams at a time (AVX2, chosen at run time:
/// core/cpu.h): the same layout in each 128-bit half (streams i, i + 2 | i + 4, i + 6 in
/// register A, i + 1, i + 3 | i + 5, i + 7 in B), so that the in-half shuffles pack them in
/// stream order. Returns how many leading streams it did (n rounded down to a multiple of 8).
ECO_TARGET_AVX2 inline std::size_t randomBitsBatchAvx2(std::uint64_t seed, const std::uint64_t* stream,
                                                       std::uint64_t counter, std::size_t n, std::uint32_t* word0,
                                                       std::uint32_t* word1) {
    const __m256i mul0 = _mm256_set1_epi64x(0xD2511F53), mul1 = _mm256_set1_epi64x(0xCD9E8D57);
    auto ll = [](std::uint64_t v) { return static_cast<long long>(v); };
    std::size_t i = 0;
    for (; i + 8 <= n; i += 8) {
        const __m256i ctr0 = _mm256_set1_epi64x(static_cast<std::uint32_t>(counter));
        const __m256i ctr1 = _mm256_set1_epi64x(static_cast<std::uint32_t>(counter >> 32));
        __m256i c0a = ctr0, c0b = ctr0, c1a = ctr1, c1b = ctr1;
        __m256i c2a = _mm256_set_epi64x(ll(stream[i + 6]), ll(stream[i + 4]), ll(stream[i + 2]), ll(stream[i]));
        __m256i c2b = _mm256_set_epi64x(ll(stream[i + 7]), ll(stream[i + 5]), ll(stream[i + 3]), ll(stream[i + 1]));
        __m256i c3a = _mm256_srli_epi64(c2a, 32), c3b = _mm256_srli_epi64(c2b, 32);
        std::uint32_t key0 = static_cast<std::uint32_t>(seed), key1 = static_cast<std::uint32_t>(seed >> 32);
        for (int round = 0; round < 10; ++round) {
            const __m256i k0 = _mm256_set1_epi64x(key0), k1 = _mm256_set1_epi64x(key1);
            const __m256i p0a = _mm256_mul_epu32(c0a, mul0), p0b = _mm256_mul_epu32(c0b, mul0);
            const __m256i p1a = _mm256_mul_epu32(c2a, mul1), p1b = _mm256_mul_epu32(c2b, mul1);
            c0a = _mm256_xor_si256(_mm256_xor_si256(_mm256_srli_epi64(p1a, 32), c1a), k0);
            c0b = _mm256_xor_si256(_mm256_xor_si256(_mm256_srli_epi64(p1b, 32), c1b), k0);
            c1a = p1a;
            c1b = p1b;
            c2a = _mm256_xor_si256(_mm256_xor_si256(_mm256_srli_epi64(p0a, 32), c3a), k1);
            c2b = _mm256_xor_si256(_mm256_xor_si256(_mm256_srli_epi64(p0b, 32), c3b), k1);
            c3a = p0a;
            c3b = p0b;
            key0 += 0x9E3779B9u;
            key1 += 0xBB67AE85u;
        }
        // Low halves of a (lanes 0, 2 of each half) and b (1, 3) in stream order.
        _mm256_storeu_si256(reinterpret_cast<__m256i*>(word0 + i),
                            _mm256_unpacklo_epi32(_mm256_shuffle_epi32(c0a, 0x08), _mm256_shuffle_epi32(c0b, 0x08)));
        _mm256_storeu_si256(reinterpret_cast<__m256i*>(word1 + i),
                            _mm256_unpacklo_epi32(_mm256_shuffle_epi32(c1a, 0x08), _mm256_shuffle_epi32(c1b, 0x08)));
    }
    return i;
}
#endif

/// Words 0 and 1 of randomBits(seed, stream[i], counter) for i < n: many streams at one
/// counter, eight at a time with AVX2 (chosen at run time), four with SSE2 (integer
/// arithmetic: the same bits as randomBits, which tests/rng_test.cpp checks for both forms).
/// The AVX2 loop is the SSE2 one at double width; the two are kept side by side rather than
/// behind a shared template, whose intrinsics would need GCC to inline across target
/// attributes in a fixed order.
inline void randomBitsBatch(std::uint64_t seed, const std::uint64_t* stream, std::uint64_t counter, std::size_t n,
                            std::uint32_t* word0, std::uint32_t* word1) {
    std::size_t i = 0;
#ifdef ECO_HAVE_AVX2_KERNELS
    if (avx2Kernels()) i = randomBitsBatchAvx2(seed, stream, counter, n, word0, word1);
#endif
#ifdef __SSE2__
    // Each 32-bit word of the state is kept in the low half of a 64-bit lane, streams (i, i + 2)
    // in register A and (i + 1, i + 3) in register B: PMULUDQ then gives a lane's whole 64-bit
    // product, whose high word is one shift away and whose low word is in place. High halves
    // of the lanes hold garbage (products, XORs of them) that no later step reads: PMULUDQ
    // reads low halves only, and the results are packed from the low halves.
    const __m128i mul0 = _mm_set1_epi64x(0xD2511F53), mul1 = _mm_set1_epi64x(0xCD9E8D57);
    auto pack = [](__m128i a, __m128i b) {  // low halves of a (lanes 0, 2) and b (1, 3) in stream order
        return _mm_unpacklo_epi32(_mm_shuffle_epi32(a, 0x08), _mm_shuffle_epi32(b, 0x08));
    };
    for (; i + 4 <= n; i += 4) {
        const __m128i ctr0 = _mm_set1_epi64x(static_cast<std::uint32_t>(counter));
        const __m128i ctr1 = _mm_set1_epi64x(static_cast<std::uint32_t>(counter >> 32));
        __m128i c0a = ctr0, c0b = ctr0, c1a = ctr1, c1b = ctr1;
        __m128i c2a = _mm_set_epi64x(static_cast<long long>(stream[i + 2]), static_cast<long long>(stream[i]));
        __m128i c2b = _mm_set_epi64x(static_cast<long long>(stream[i + 3]), static_cast<long long>(stream[i + 1]));
        __m128i c3a = _mm_srli_epi64(c2a, 32), c3b = _mm_srli_epi64(c2b, 32);
        std::uint32_t key0 = static_cast<std::uint32_t>(seed), key1 = static_cast<std::uint32_t>(seed >> 32);
        for (int round = 0; round < 10; ++round) {
            const __m128i k0 = _mm_set1_epi64x(key0), k1 = _mm_set1_epi64x(key1);
            const __m128i p0a = _mm_mul_epu32(c0a, mul0), p0b = _mm_mul_epu32(c0b, mul0);
            const __m128i p1a = _mm_mul_epu32(c2a, mul1), p1b = _mm_mul_epu32(c2b, mul1);
            c0a = _mm_xor_si128(_mm_xor_si128(_mm_srli_epi64(p1a, 32), c1a), k0);
            c0b = _mm_xor_si128(_mm_xor_si128(_mm_srli_epi64(p1b, 32), c1b), k0);
            c1a = p1a;
            c1b = p1b;
            c2a = _mm_xor_si128(_mm_xor_si128(_mm_srli_epi64(p0a, 32), c3a), k1);
            c2b = _mm_xor_si128(_mm_xor_si128(_mm_srli_epi64(p0b, 32), c3b), k1);
            c3a = p0a;
            c3b = p0b;
            key0 += 0x9E3779B9u;
            key1 += 0xBB67AE85u;
        }
        _mm_storeu_si128(reinterpret_cast<__m128i*>(word0 + i), pack(c0a, c0b));
        _mm_storeu_si128(reinterpret_cast<__m128i*>(word1 + i), pack(c1a, c1b));
    }
#endif
    for (; i < n; ++i) {
        const auto b = randomBits(seed, stream[i], counter);
        word0[i] = b[0];
        word1[i] = b[1];
    }
}

}  // namespace eco
