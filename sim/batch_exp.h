// exp over an array, for the vigour of every plant every month (Eq. 1 needs one exp per
// plant-month: on the benchmark hectare, the library's scalar exp was a tenth of the run).
//
// Cody-Waite reduction x = k ln 2 + r, |r| <= ln 2 / 2, then the Taylor polynomial of degree
// 13 in r (truncation below 2e-18 relative) and the scale 2^k from the exponent bits. Only
// additions, multiplications and integer bit operations, in a fixed order: the same bits on
// every x86-64 or other IEEE-754 machine for a given build, whatever the thread count, and
// a plain loop the compiler vectorises. Accurate to a few ulp (tests/simulator_test.cpp
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

inline double batchExpOne(double x) {
    constexpr double kLog2e = 1.4426950408889634074;
    constexpr double kLn2Hi = 6.93147180369123816490e-01;  // k * kLn2Hi is exact for |k| < 2^11
    constexpr double kLn2Lo = 1.90821492927058770002e-10;
    constexpr double kShift = 0x1.8p52;  // adding it rounds to an integer, held in the low bits
    x = std::min(std::max(x, -708.0), 709.0);
    const double kd = x * kLog2e + kShift;
    const double k = kd - kShift;
    const double r = (x - k * kLn2Hi) - k * kLn2Lo;
    // Horner over 1 / n!, n = 13 .. 0.
    double p = 1.0 / 6227020800.0;
    p = p * r + 1.0 / 479001600.0;
    p = p * r + 1.0 / 39916800.0;
    p = p * r + 1.0 / 3628800.0;
    p = p * r + 1.0 / 362880.0;
    p = p * r + 1.0 / 40320.0;
    p = p * r + 1.0 / 5040.0;
    p = p * r + 1.0 / 720.0;
    p = p * r + 1.0 / 120.0;
    p = p * r + 1.0 / 24.0;
    p = p * r + 1.0 / 6.0;
    p = p * r + 0.5;
    p = p * r + 1.0;
    p = p * r + 1.0;
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
    const __m128d shift = _mm_set1_pd(0x1.8p52);
    x = _mm_min_pd(_mm_max_pd(x, _mm_set1_pd(-708.0)), _mm_set1_pd(709.0));
    const __m128d kd = _mm_add_pd(_mm_mul_pd(x, _mm_set1_pd(1.4426950408889634074)), shift);
    const __m128d k = _mm_sub_pd(kd, shift);
    const __m128d r = _mm_sub_pd(_mm_sub_pd(x, _mm_mul_pd(k, _mm_set1_pd(6.93147180369123816490e-01))),
                                 _mm_mul_pd(k, _mm_set1_pd(1.90821492927058770002e-10)));
    static constexpr double kCoeff[13] = {1.0 / 479001600.0, 1.0 / 39916800.0, 1.0 / 3628800.0, 1.0 / 362880.0,
                                          1.0 / 40320.0, 1.0 / 5040.0, 1.0 / 720.0, 1.0 / 120.0, 1.0 / 24.0,
                                          1.0 / 6.0, 0.5, 1.0, 1.0};
    __m128d p = _mm_set1_pd(1.0 / 6227020800.0);
    for (double c : kCoeff) p = _mm_add_pd(_mm_mul_pd(p, r), _mm_set1_pd(c));
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
