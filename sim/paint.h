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

#include "processes.h"

#ifdef __SSE2__
#include <emmintrin.h>
#endif

namespace eco::sim {

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
/// lane, as PaintLanesScalar (MINPD / MAXPD have the operand order of minOf / maxZero).
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
        const __m128i one = _mm_set1_epi32(1);
        std::size_t i = 0;
        for (; i + 4 <= len; i += 4, c += 4) {
            const __m128 t = _mm_loadu_ps(b.transmission + c);
            const __m128i k = _mm_loadu_si128(reinterpret_cast<const __m128i*>(b.painted + c));
            sun01 = _mm_add_pd(sun01, _mm_mul_pd(_mm_loadu_pd(b.base + c), _mm_cvtps_pd(t)));
            sun23 = _mm_add_pd(sun23, _mm_mul_pd(_mm_loadu_pd(b.base + c + 2), _mm_cvtps_pd(_mm_movehl_ps(t, t))));
            water01 = _mm_add_pd(water01, waterPair(b, c, k, demand));
            water23 = _mm_add_pd(water23, waterPair(b, c + 2, _mm_shuffle_epi32(k, 0xEE), demand));
            _mm_storeu_ps(b.transmission + c, _mm_mul_ps(t, keep4));
            _mm_storeu_si128(reinterpret_cast<__m128i*>(b.painted + c), _mm_add_epi32(k, one));
        }
        const std::size_t tail = len - i;
        if (tail & 2u) {  // lanes 0 and 1
            const __m128 t = _mm_castpd_ps(_mm_load_sd(reinterpret_cast<const double*>(b.transmission + c)));
            const __m128i k = _mm_loadl_epi64(reinterpret_cast<const __m128i*>(b.painted + c));
            sun01 = _mm_add_pd(sun01, _mm_mul_pd(_mm_loadu_pd(b.base + c), _mm_cvtps_pd(t)));
            water01 = _mm_add_pd(water01, waterPair(b, c, k, demand));
            _mm_store_sd(reinterpret_cast<double*>(b.transmission + c), _mm_castps_pd(_mm_mul_ps(t, keep4)));
            _mm_storel_epi64(reinterpret_cast<__m128i*>(b.painted + c), _mm_add_epi32(k, one));
            c += 2;
        }
        if (tail & 1u) {  // lane 0 (tail 1) or lane 2 (tail 3)
            const double s = b.base[c] * static_cast<double>(b.transmission[c]);
            const double w = waterDemandShareMm(b.avail[c], b.painted[c], demandMm) + b.rest[c];
            __m128d& sunLane = (tail & 2u) ? sun23 : sun01;
            __m128d& waterLane = (tail & 2u) ? water23 : water01;
            sunLane = _mm_add_sd(sunLane, _mm_set_sd(s));
            waterLane = _mm_add_sd(waterLane, _mm_set_sd(w));
            b.transmission[c] *= keep;
            ++b.painted[c];
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

}  // namespace eco::sim
