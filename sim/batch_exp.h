// exp over an array, for the vigour of every plant every month (Eq. 1 needs one exp per
// plant-month: on the benchmark hectare, the library's scalar exp was a tenth of the run).
//
// Cody-Waite reduction x = k ln 2 + r, |r| <= ln 2 / 2, then the Taylor polynomial of degree
// 13 in r (truncation below 2e-18 relative) and the scale 2^k from the exponent bits. Only
// additions, multiplications and integer bit operations, in a fixed order: the same bits on
// every x86-64 or other IEEE-754 machine for a given build, whatever the thread count; two
// values per SSE2 instruction where available. Accurate to a few ulp (tests/simulator_test.cpp
// compares it with std::exp); arguments are clamped to [-708, 709], where exp is normal.
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <cstring>

#ifdef __SSE2__
#include <emmintrin.h>
#endif

namespace eco::sim {

// The constants of both forms below.
struct BatchExpConst {
    static constexpr double kLog2e = 1.4426950408889634074;
    static constexpr double kLn2Hi = 6.93147180369123816490e-01;  // k * kLn2Hi is exact for |k| < 2^11
    static constexpr double kLn2Lo = 1.90821492927058770002e-10;
    static constexpr double kShift = 0x1.8p52;  // adding it rounds to an integer, held in the low bits
    static constexpr double kLo = -708.0, kHi = 709.0;
    // Horner over 1 / n!: the leading coefficient 1 / 13!, then n = 12 .. 0.
    static constexpr double kLead = 1.0 / 6227020800.0;
    static constexpr double kCoeff[13] = {1.0 / 479001600.0, 1.0 / 39916800.0, 1.0 / 3628800.0, 1.0 / 362880.0,
                                          1.0 / 40320.0, 1.0 / 5040.0, 1.0 / 720.0, 1.0 / 120.0, 1.0 / 24.0,
                                          1.0 / 6.0, 0.5, 1.0, 1.0};
};

inline double batchExpOne(double x) {
    using C = BatchExpConst;
    x = std::min(std::max(x, C::kLo), C::kHi);
    const double kd = x * C::kLog2e + C::kShift;
    const double k = kd - C::kShift;
    const double r = (x - k * C::kLn2Hi) - k * C::kLn2Lo;
    double p = C::kLead;
    for (double c : C::kCoeff) p = p * r + c;
    // 2^k: the low 12 bits of kd's representation are k mod 2^12 (the shift's mantissa bit
    // 2^51 is a multiple of 2^12), and k + 1023 lies in [1, 2046].
    std::uint64_t bits;
    std::memcpy(&bits, &kd, sizeof bits);
    const std::uint64_t scaleBits = (bits + 1023u) << 52;
    double scale;
    std::memcpy(&scale, &scaleBits, sizeof scale);
    return p * scale;
}

#ifdef __SSE2__
// Two lanes of batchExpOne: the same operations in the same order (SSE2 has no fused
// multiply-add), hence the same bits.
inline __m128d batchExpPair(__m128d x) {
    using C = BatchExpConst;
    const __m128d shift = _mm_set1_pd(C::kShift);
    x = _mm_min_pd(_mm_max_pd(x, _mm_set1_pd(C::kLo)), _mm_set1_pd(C::kHi));
    const __m128d kd = _mm_add_pd(_mm_mul_pd(x, _mm_set1_pd(C::kLog2e)), shift);
    const __m128d k = _mm_sub_pd(kd, shift);
    const __m128d r = _mm_sub_pd(_mm_sub_pd(x, _mm_mul_pd(k, _mm_set1_pd(C::kLn2Hi))), _mm_mul_pd(k, _mm_set1_pd(C::kLn2Lo)));
    __m128d p = _mm_set1_pd(C::kLead);
    for (double c : C::kCoeff) p = _mm_add_pd(_mm_mul_pd(p, r), _mm_set1_pd(c));
    const __m128i scale = _mm_slli_epi64(_mm_add_epi64(_mm_castpd_si128(kd), _mm_set1_epi64x(1023)), 52);
    return _mm_mul_pd(p, _mm_castsi128_pd(scale));
}
#endif

inline void batchExp(const double* x, double* y, std::size_t n) {
    std::size_t i = 0;
#ifdef __SSE2__
    for (; i + 2 <= n; i += 2) _mm_storeu_pd(y + i, batchExpPair(_mm_loadu_pd(x + i)));
#endif
    for (; i < n; ++i) y[i] = batchExpOne(x[i]);
}

}  // namespace eco::sim
