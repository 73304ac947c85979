// exp and log over arrays, for the simulator's per-plant, per-month arithmetic: the vigour of
// Eq. 1 (one exp per plant-month) and the crown radius of the allometry r = exp(a + b ln h)
// (one log and one exp per growing plant). On the benchmark hectare the library's scalar exp
// was a tenth of the run, and log and exp of the crown radius another twentieth.
//
// exp: Cody-Waite reduction x = k ln 2 + r, |r| <= ln 2 / 2, then the Taylor polynomial of
// degree 13 in r (truncation below 2e-18 relative) and the scale 2^k from the exponent bits.
// log: x = 2^k m with m in [sqrt(1/2), sqrt(2)) from the exponent bits, f = m - 1 (exact),
// s = f / (2 + f) and log(1 + f) = 2 atanh(s) = f - s (f - z Q(z)), z = s^2, Q the atanh
// series to z^10 (truncation below 1e-18 relative); then + k ln 2 in two parts.
// Only additions, multiplications, one division and integer bit operations, in a fixed
// order: the same bits on every x86-64 or other IEEE-754 machine for a given build, whatever
// the thread count; two values per SSE2 instruction where available. Accurate to a few ulp
// (tests/simulator_test.cpp compares them with std::exp and std::log); exp's arguments are
// clamped to [-708, 709], where exp is normal.
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <limits>

#include "cpu.h"

#ifdef __SSE2__
#include <emmintrin.h>
#endif
#ifdef ECO_HAVE_AVX2_KERNELS
#include <immintrin.h>
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

#ifdef ECO_HAVE_AVX2_KERNELS
// Four lanes of batchExpOne (AVX2, chosen at run time: core/cpu.h): the same operations in
// the same order, hence the same bits. Returns how many leading values it did (n rounded
// down to a multiple of 4).
ECO_TARGET_AVX2 inline std::size_t batchExpAvx2(const double* x, double* y, std::size_t n) {
    using C = BatchExpConst;
    const __m256d shift = _mm256_set1_pd(C::kShift);
    std::size_t i = 0;
    for (; i + 4 <= n; i += 4) {
        const __m256d v = _mm256_min_pd(_mm256_max_pd(_mm256_loadu_pd(x + i), _mm256_set1_pd(C::kLo)), _mm256_set1_pd(C::kHi));
        const __m256d kd = _mm256_add_pd(_mm256_mul_pd(v, _mm256_set1_pd(C::kLog2e)), shift);
        const __m256d k = _mm256_sub_pd(kd, shift);
        const __m256d r = _mm256_sub_pd(_mm256_sub_pd(v, _mm256_mul_pd(k, _mm256_set1_pd(C::kLn2Hi))),
                                        _mm256_mul_pd(k, _mm256_set1_pd(C::kLn2Lo)));
        __m256d p = _mm256_set1_pd(C::kLead);
        for (double c : C::kCoeff) p = _mm256_add_pd(_mm256_mul_pd(p, r), _mm256_set1_pd(c));
        const __m256i scale = _mm256_slli_epi64(_mm256_add_epi64(_mm256_castpd_si256(kd), _mm256_set1_epi64x(1023)), 52);
        _mm256_storeu_pd(y + i, _mm256_mul_pd(p, _mm256_castsi256_pd(scale)));
    }
    return i;
}
#endif

inline void batchExp(const double* x, double* y, std::size_t n) {
    std::size_t i = 0;
#ifdef ECO_HAVE_AVX2_KERNELS
    if (avx2Kernels()) i = batchExpAvx2(x, y, n);
#endif
#ifdef __SSE2__
    for (; i + 2 <= n; i += 2) _mm_storeu_pd(y + i, batchExpPair(_mm_loadu_pd(x + i)));
#endif
    for (; i < n; ++i) y[i] = batchExpOne(x[i]);
}

struct BatchLogConst {
    static constexpr double kLn2Hi = BatchExpConst::kLn2Hi, kLn2Lo = BatchExpConst::kLn2Lo;
    // Bits of sqrt(1/2) (rounded down): x - kOff splits x into 2^k and m in [sqrt(1/2), sqrt(2)).
    static constexpr std::uint64_t kOff = 0x3FE6A09E667F3BCDull;
    static constexpr std::uint64_t kMant = 0x000FFFFFFFFFFFFFull;
    static constexpr std::uint64_t kBias = 0x3FF0000000000000ull;  // 1023 << 52: keeps k + 1023 >= 0
    static constexpr double kTwo52 = 0x1p52;  // 2^52 + n as bits, minus 2^52: the integer n as a double
    static constexpr std::uint64_t kTwo52Bits = 0x4330000000000000ull;
    // Horner over 2 / (2j + 1): the leading coefficient (j = 10), then j = 9 .. 1.
    static constexpr double kLead = 2.0 / 21.0;
    static constexpr double kCoeff[9] = {2.0 / 19.0, 2.0 / 17.0, 2.0 / 15.0, 2.0 / 13.0, 2.0 / 11.0,
                                         2.0 / 9.0, 2.0 / 7.0, 2.0 / 5.0, 2.0 / 3.0};
};

// log(x) for a positive normal finite x (batchLogOne handles every x).
inline double batchLogNormal(double x) {
    using C = BatchLogConst;
    std::uint64_t bits;
    std::memcpy(&bits, &x, sizeof bits);
    const std::uint64_t t = bits - C::kOff;
    const std::uint64_t mBits = (t & C::kMant) + C::kOff;
    const std::uint64_t kBits = ((t + C::kBias) >> 52) | C::kTwo52Bits;  // 2^52 + k + 1023
    double m, kd;
    std::memcpy(&m, &mBits, sizeof m);
    std::memcpy(&kd, &kBits, sizeof kd);
    const double k = (kd - C::kTwo52) - 1023.0;
    const double f = m - 1.0;
    const double s = f / (2.0 + f);
    const double z = s * s;
    double q = C::kLead;
    for (double c : C::kCoeff) q = q * z + c;
    const double lo = k * C::kLn2Lo - s * (f - z * q);
    return k * C::kLn2Hi + (f + lo);
}

inline double batchLogOne(double x) {
    if (!(x > 0)) return x == 0 ? -std::numeric_limits<double>::infinity() : std::numeric_limits<double>::quiet_NaN();
    if (!(x <= std::numeric_limits<double>::max())) return x;  // +inf
    if (x < std::numeric_limits<double>::min()) return batchLogNormal(x * 0x1p54) - 54.0 * BatchLogConst::kLn2Hi - 54.0 * BatchLogConst::kLn2Lo;
    return batchLogNormal(x);
}

#ifdef __SSE2__
// Two lanes of batchLogNormal: the same operations in the same order, hence the same bits.
inline __m128d batchLogPair(__m128d x) {
    using C = BatchLogConst;
    const __m128i bits = _mm_castpd_si128(x);
    const __m128i t = _mm_sub_epi64(bits, _mm_set1_epi64x(static_cast<long long>(C::kOff)));
    const __m128d m = _mm_castsi128_pd(_mm_add_epi64(_mm_and_si128(t, _mm_set1_epi64x(static_cast<long long>(C::kMant))),
                                                     _mm_set1_epi64x(static_cast<long long>(C::kOff))));
    const __m128i kBits = _mm_or_si128(_mm_srli_epi64(_mm_add_epi64(t, _mm_set1_epi64x(static_cast<long long>(C::kBias))), 52),
                                       _mm_set1_epi64x(static_cast<long long>(C::kTwo52Bits)));
    const __m128d k = _mm_sub_pd(_mm_sub_pd(_mm_castsi128_pd(kBits), _mm_set1_pd(C::kTwo52)), _mm_set1_pd(1023.0));
    const __m128d f = _mm_sub_pd(m, _mm_set1_pd(1.0));
    const __m128d s = _mm_div_pd(f, _mm_add_pd(_mm_set1_pd(2.0), f));
    const __m128d z = _mm_mul_pd(s, s);
    __m128d q = _mm_set1_pd(C::kLead);
    for (double c : C::kCoeff) q = _mm_add_pd(_mm_mul_pd(q, z), _mm_set1_pd(c));
    const __m128d lo = _mm_sub_pd(_mm_mul_pd(k, _mm_set1_pd(C::kLn2Lo)), _mm_mul_pd(s, _mm_sub_pd(f, _mm_mul_pd(z, q))));
    return _mm_add_pd(_mm_mul_pd(k, _mm_set1_pd(C::kLn2Hi)), _mm_add_pd(f, lo));
}
#endif

// y[i] = log(x[i]); pairs of positive normal values two at a time, any other value alone.
inline void batchLog(const double* x, double* y, std::size_t n) {
    std::size_t i = 0;
#ifdef __SSE2__
    constexpr double kMin = std::numeric_limits<double>::min(), kMax = std::numeric_limits<double>::max();
    for (; i + 2 <= n; i += 2) {
        if (x[i] >= kMin && x[i] <= kMax && x[i + 1] >= kMin && x[i + 1] <= kMax) {
            _mm_storeu_pd(y + i, batchLogPair(_mm_loadu_pd(x + i)));
        } else {
            y[i] = batchLogOne(x[i]);
            y[i + 1] = batchLogOne(x[i + 1]);
        }
    }
#endif
    for (; i < n; ++i) y[i] = batchLogOne(x[i]);
}

}  // namespace eco::sim
