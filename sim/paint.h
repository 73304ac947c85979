// The paint step of the monthly sweep: one plant taking its shares of a row span of cells
// (paper §6.1; SPEC §5). The per-cell formulas are those of processes.h; what this file adds
// is the summation order and a vectorised form of it.
//
// A plant's sun and water sums are kept in four lanes: the cell at position i of a row span
// goes into lane i mod 4, and the total is (lane 0 + lane 1) + (lane 2 + lane 3). This order
// is fixed by the data alone (never by the thread count or the instruction set), so the
// SSE2 kernel and the portable one give the same bits (tests/simulator_test.cpp compares
// them), and four independent sums let the cells of a span be processed side by side
// instead of waiting on one chain of additions.
#pragma once

#include <cstddef>
#include <cstdint>

#include "cpu.h"
#include "processes.h"

#ifdef __SSE2__
#include <emmintrin.h>
#endif
#ifdef ECO_HAVE_AVX2_KERNELS
#include <immintrin.h>
#endif

namespace eco::sim {

/// Cells past a span's end that a paint kernel may read and store back unchanged.
constexpr std::size_t kPaintPad = 3;

/// What the occupants of a band's cells share during a month, one array per field (index:
/// cell - first cell of the band). Filled by the sweep's prepare pass.
struct BandCells {
    const double* base;     // canopy-shaded sun
    const double* avail;    // water after the canopy trees
    const double* rest;     // remainder / (n + 1): every occupant's equal share and the seeding share
    float* transmission;    // product of (1 - alpha) over the occupants painted so far
    std::int32_t* painted;  // occupants painted so far (height rank of the next)
};

/// Portable kernel: lanes as plain doubles.
struct PaintLanesScalar {
    double sun[4] = {0, 0, 0, 0}, water[4] = {0, 0, 0, 0};

    // Cells [c, c + len) of one row, for a plant whose species keeps `keep` of the light.
    void span(const BandCells& b, std::size_t c, std::size_t len, float keep, double demand) {
        for (std::size_t i = 0; i < len; ++i, ++c) {
            const std::size_t lane = i & 3u;
            sun[lane] += b.base[c] * static_cast<double>(b.transmission[c]);
            water[lane] += waterDemandShareMm(b.avail[c], b.painted[c], demand) + b.rest[c];
            b.transmission[c] *= keep;
            ++b.painted[c];
        }
    }
    double sunTotal() const { return (sun[0] + sun[1]) + (sun[2] + sun[3]); }
    double waterTotal() const { return (water[0] + water[1]) + (water[2] + water[3]); }
};

#ifdef __SSE2__
/// SSE2 kernel: lanes 0-1 and 2-3 in two registers per sum; the same operations, lane by
/// lane, as PaintLanesScalar (MINPD / MAXPD have the operand order of minOf / maxZero). A
/// span is taken four cells at a time with no branch on its length: the last group is
/// masked, its cells past the span's end adding +0 to their lanes (every lane is a sum of
/// values >= 0, so x + 0 is x) and getting their own transmission and count stored back.
/// It therefore reads and rewrites up to kPaintPad cells past a span's end: the arrays must
/// extend that far (BandScratch pads them), and nothing else may change those cells meanwhile.
// The masked group of four cells at c of the vector kernels: all ones in the 32-bit lanes
// of the cells inside the span (`remaining` = cells of the span from c on, >= 1).
inline __m128i paintGroupMask(std::size_t remaining) {
    const int inside = static_cast<int>(remaining < 4 ? remaining : 4);
    return _mm_cmpgt_epi32(_mm_set1_epi32(inside), _mm_setr_epi32(0, 1, 2, 3));
}
// The group's transmissions (t) and painted counts (k) stored back: times keep and plus 1
// inside the span, unchanged outside it.
inline void paintGroupStore(const BandCells& b, std::size_t c, __m128 t, __m128i k, __m128 keep4, __m128i in) {
    const __m128 inPs = _mm_castsi128_ps(in);
    _mm_storeu_ps(b.transmission + c, _mm_or_ps(_mm_and_ps(inPs, _mm_mul_ps(t, keep4)), _mm_andnot_ps(inPs, t)));
    _mm_storeu_si128(reinterpret_cast<__m128i*>(b.painted + c), _mm_sub_epi32(k, in));  // k - (-1) inside
}

struct PaintLanesSse2 {
    __m128d sun01 = _mm_setzero_pd(), sun23 = _mm_setzero_pd();
    __m128d water01 = _mm_setzero_pd(), water23 = _mm_setzero_pd();

    static __m128d waterPair(const BandCells& b, std::size_t c, __m128i k, __m128d demand) {
        const __m128d taken = _mm_mul_pd(_mm_cvtepi32_pd(k), demand);
        const __m128d left = _mm_max_pd(_mm_sub_pd(_mm_loadu_pd(b.avail + c), taken), _mm_setzero_pd());
        return _mm_add_pd(_mm_min_pd(left, demand), _mm_loadu_pd(b.rest + c));
    }

    void span(const BandCells& b, std::size_t c, std::size_t len, float keep, double demandMm) {
        const __m128d demand = _mm_set1_pd(demandMm);
        const __m128 keep4 = _mm_set1_ps(keep);
        for (std::size_t i = 0; i < len; i += 4, c += 4) {
            const __m128i in = paintGroupMask(len - i);
            const __m128d in01 = _mm_castsi128_pd(_mm_unpacklo_epi32(in, in));
            const __m128d in23 = _mm_castsi128_pd(_mm_unpackhi_epi32(in, in));
            const __m128 t = _mm_loadu_ps(b.transmission + c);
            const __m128i k = _mm_loadu_si128(reinterpret_cast<const __m128i*>(b.painted + c));
            sun01 = _mm_add_pd(sun01, _mm_and_pd(in01, _mm_mul_pd(_mm_loadu_pd(b.base + c), _mm_cvtps_pd(t))));
            sun23 = _mm_add_pd(sun23, _mm_and_pd(in23, _mm_mul_pd(_mm_loadu_pd(b.base + c + 2), _mm_cvtps_pd(_mm_movehl_ps(t, t)))));
            water01 = _mm_add_pd(water01, _mm_and_pd(in01, waterPair(b, c, k, demand)));
            water23 = _mm_add_pd(water23, _mm_and_pd(in23, waterPair(b, c + 2, _mm_shuffle_epi32(k, 0xEE), demand)));
            paintGroupStore(b, c, t, k, keep4, in);
        }
    }
    static double total(__m128d a, __m128d b) {
        const double l01 = _mm_cvtsd_f64(a) + _mm_cvtsd_f64(_mm_unpackhi_pd(a, a));
        const double l23 = _mm_cvtsd_f64(b) + _mm_cvtsd_f64(_mm_unpackhi_pd(b, b));
        return l01 + l23;
    }
    double sunTotal() const { return total(sun01, sun23); }
    double waterTotal() const { return total(water01, water23); }
};
using PaintLanes = PaintLanesSse2;
#else
using PaintLanes = PaintLanesScalar;
#endif

#ifdef ECO_HAVE_AVX2_KERNELS
/// AVX2 kernel, chosen at run time on processors that have AVX2 (core/cpu.h): lanes 0-3
/// in one register per sum, otherwise the SSE2 kernel's operations (masked last group, the
/// same padding), lane by lane: the same bits (tested).
struct PaintLanesAvx2 {
    __m256d sun, water;

    ECO_TARGET_AVX2 PaintLanesAvx2() : sun(_mm256_setzero_pd()), water(_mm256_setzero_pd()) {}

    ECO_TARGET_AVX2 void span(const BandCells& b, std::size_t c, std::size_t len, float keep, double demandMm) {
        const __m256d demand = _mm256_set1_pd(demandMm);
        const __m128 keep4 = _mm_set1_ps(keep);
        for (std::size_t i = 0; i < len; i += 4, c += 4) {
            const __m128i in = paintGroupMask(len - i);
            const __m256d in4 = _mm256_castsi256_pd(_mm256_cvtepi32_epi64(in));  // -1 -> all 64 bits set
            const __m128 t = _mm_loadu_ps(b.transmission + c);
            const __m128i k = _mm_loadu_si128(reinterpret_cast<const __m128i*>(b.painted + c));
            sun = _mm256_add_pd(sun, _mm256_and_pd(in4, _mm256_mul_pd(_mm256_loadu_pd(b.base + c), _mm256_cvtps_pd(t))));
            const __m256d taken = _mm256_mul_pd(_mm256_cvtepi32_pd(k), demand);
            const __m256d spare = _mm256_max_pd(_mm256_sub_pd(_mm256_loadu_pd(b.avail + c), taken), _mm256_setzero_pd());
            const __m256d w = _mm256_add_pd(_mm256_min_pd(spare, demand), _mm256_loadu_pd(b.rest + c));
            water = _mm256_add_pd(water, _mm256_and_pd(in4, w));
            paintGroupStore(b, c, t, k, keep4, in);
        }
    }
    ECO_TARGET_AVX2 static double total(__m256d v) {
        const __m128d lo = _mm256_castpd256_pd128(v), hi = _mm256_extractf128_pd(v, 1);
        const double l01 = _mm_cvtsd_f64(lo) + _mm_cvtsd_f64(_mm_unpackhi_pd(lo, lo));
        const double l23 = _mm_cvtsd_f64(hi) + _mm_cvtsd_f64(_mm_unpackhi_pd(hi, hi));
        return l01 + l23;
    }
    ECO_TARGET_AVX2 double sunTotal() const { return total(sun); }
    ECO_TARGET_AVX2 double waterTotal() const { return total(water); }
};
#endif

}  // namespace eco::sim
