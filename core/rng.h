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
    /// Where the stream stands, for callers that make its later blocks in a batch
    /// (randomBlocksBatch): the words of the current block not yet used are
    /// buffered()[usedWords() .. 3], then come blocks nextBlock(), nextBlock() + 1, ...
    int usedWords() const { return used_; }
    const std::array<std::uint32_t, 4>& buffered() const { return buf_; }
    std::uint64_t nextBlock() const { return block_; }
    std::uint64_t streamId() const { return stream_; }

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

/// Philox blocks of many (stream, counter) pairs at once: the kernels behind randomBitsBatch
/// (one counter for every stream) and randomBlocksBatch (a counter per stream). kPerLane:
/// counter[i] for stream i, else counter[0] for all. word2 / word3 may be null (not wanted).
namespace detail {

#ifdef ECO_HAVE_AVX2_KERNELS
/// The SSE2 loop of philoxBatch on eight streams at a time (AVX2, chosen at run time:
/// core/cpu.h): the same layout in each 128-bit half (streams i, i + 2 | i + 4, i + 6 in
/// register A, i + 1, i + 3 | i + 5, i + 7 in B), so that the in-half shuffles pack them in
/// stream order. Returns how many leading streams it did (n rounded down to a multiple of 8).
template <bool kPerLane>
ECO_TARGET_AVX2 inline std::size_t philoxBatchAvx2(std::uint64_t seed, const std::uint64_t* stream,
                                                   const std::uint64_t* counter, std::size_t n, std::uint32_t* word0,
                                                   std::uint32_t* word1, std::uint32_t* word2, std::uint32_t* word3) {
    const __m256i mul0 = _mm256_set1_epi64x(0xD2511F53), mul1 = _mm256_set1_epi64x(0xCD9E8D57);
    auto ll = [](std::uint64_t v) { return static_cast<long long>(v); };
    std::size_t i = 0;
    for (; i + 8 <= n; i += 8) {
        __m256i c0a, c0b;
        if (kPerLane) {
            c0a = _mm256_set_epi64x(ll(counter[i + 6]), ll(counter[i + 4]), ll(counter[i + 2]), ll(counter[i]));
            c0b = _mm256_set_epi64x(ll(counter[i + 7]), ll(counter[i + 5]), ll(counter[i + 3]), ll(counter[i + 1]));
        } else {
            c0a = c0b = _mm256_set1_epi64x(ll(counter[0]));
        }
        __m256i c1a = _mm256_srli_epi64(c0a, 32), c1b = _mm256_srli_epi64(c0b, 32);
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
        // Low halves of a (lanes 0, 2 of each half) and b (1, 3) in stream order (no lambda:
        // it would not inherit the target attribute).
#define ECO_PHILOX_PACK256(a, b) _mm256_unpacklo_epi32(_mm256_shuffle_epi32(a, 0x08), _mm256_shuffle_epi32(b, 0x08))
        _mm256_storeu_si256(reinterpret_cast<__m256i*>(word0 + i), ECO_PHILOX_PACK256(c0a, c0b));
        _mm256_storeu_si256(reinterpret_cast<__m256i*>(word1 + i), ECO_PHILOX_PACK256(c1a, c1b));
        if (word2 != nullptr) _mm256_storeu_si256(reinterpret_cast<__m256i*>(word2 + i), ECO_PHILOX_PACK256(c2a, c2b));
        if (word3 != nullptr) _mm256_storeu_si256(reinterpret_cast<__m256i*>(word3 + i), ECO_PHILOX_PACK256(c3a, c3b));
#undef ECO_PHILOX_PACK256
    }
    return i;
}
#endif

/// Words of philox(seed, stream[i], counter) for i < n (see the namespace comment): eight
/// streams at a time with AVX2 (chosen at run time), four with SSE2 (integer arithmetic: the
/// same bits as randomBits, which tests/rng_test.cpp checks for both forms). The AVX2 loop is
/// the SSE2 one at double width; the two are kept side by side rather than behind a shared
/// template, whose intrinsics would need GCC to inline across target attributes in a fixed
/// order.
template <bool kPerLane>
inline void philoxBatch(std::uint64_t seed, const std::uint64_t* stream, const std::uint64_t* counter, std::size_t n,
                        std::uint32_t* word0, std::uint32_t* word1, std::uint32_t* word2, std::uint32_t* word3) {
    std::size_t i = 0;
#ifdef ECO_HAVE_AVX2_KERNELS
    if (avx2Kernels()) i = philoxBatchAvx2<kPerLane>(seed, stream, counter, n, word0, word1, word2, word3);
#endif
#ifdef __SSE2__
    // Each 32-bit word of the state is kept in the low half of a 64-bit lane, streams (i, i + 2)
    // in register A and (i + 1, i + 3) in register B: PMULUDQ then gives a lane's whole 64-bit
    // product, whose high word is one shift away and whose low word is in place. High halves
    // of the lanes hold garbage (products, XORs of them) that no later step reads: PMULUDQ
    // reads low halves only, and the results are packed from the low halves.
    const __m128i mul0 = _mm_set1_epi64x(0xD2511F53), mul1 = _mm_set1_epi64x(0xCD9E8D57);
    auto ll = [](std::uint64_t v) { return static_cast<long long>(v); };
    auto pack = [](__m128i a, __m128i b) {  // low halves of a (lanes 0, 2) and b (1, 3) in stream order
        return _mm_unpacklo_epi32(_mm_shuffle_epi32(a, 0x08), _mm_shuffle_epi32(b, 0x08));
    };
    for (; i + 4 <= n; i += 4) {
        __m128i c0a, c0b;
        if (kPerLane) {
            c0a = _mm_set_epi64x(ll(counter[i + 2]), ll(counter[i]));
            c0b = _mm_set_epi64x(ll(counter[i + 3]), ll(counter[i + 1]));
        } else {
            c0a = c0b = _mm_set1_epi64x(ll(counter[0]));
        }
        __m128i c1a = _mm_srli_epi64(c0a, 32), c1b = _mm_srli_epi64(c0b, 32);
        __m128i c2a = _mm_set_epi64x(ll(stream[i + 2]), ll(stream[i]));
        __m128i c2b = _mm_set_epi64x(ll(stream[i + 3]), ll(stream[i + 1]));
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
        if (word2 != nullptr) _mm_storeu_si128(reinterpret_cast<__m128i*>(word2 + i), pack(c2a, c2b));
        if (word3 != nullptr) _mm_storeu_si128(reinterpret_cast<__m128i*>(word3 + i), pack(c3a, c3b));
    }
#endif
    for (; i < n; ++i) {
        const auto b = randomBits(seed, stream[i], kPerLane ? counter[i] : counter[0]);
        word0[i] = b[0];
        word1[i] = b[1];
        if (word2 != nullptr) word2[i] = b[2];
        if (word3 != nullptr) word3[i] = b[3];
    }
}

}  // namespace detail

/// Words 0 and 1 of randomBits(seed, stream[i], counter) for i < n: many streams at one
/// counter, eight at a time with AVX2 (chosen at run time), four with SSE2.
inline void randomBitsBatch(std::uint64_t seed, const std::uint64_t* stream, std::uint64_t counter, std::size_t n,
                            std::uint32_t* word0, std::uint32_t* word1) {
    detail::philoxBatch<false>(seed, stream, &counter, n, word0, word1, nullptr, nullptr);
}

/// The four words of randomBits(seed, stream[i], counter[i]) for i < n (word k of block i in
/// word[k][i]): a block per (stream, counter) pair, eight at a time with AVX2, four with SSE2.
inline void randomBlocksBatch(std::uint64_t seed, const std::uint64_t* stream, const std::uint64_t* counter,
                              std::size_t n, std::uint32_t* word0, std::uint32_t* word1, std::uint32_t* word2,
                              std::uint32_t* word3) {
    detail::philoxBatch<true>(seed, stream, counter, n, word0, word1, word2, word3);
}

}  // namespace eco
