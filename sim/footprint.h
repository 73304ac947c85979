// Footprints on the simulation grid: the cells a crown disc covers, as row spans (paper §6.1,
// SPEC §5: "occupants: plants whose crown covers the cell"), and the radii over which a
// plant's footprint stays the same, so that a growing plant's spans are recomputed only when
// they change (docs/simulator.md, "Footprints").
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>

#include "cpu.h"

#ifdef ECO_HAVE_AVX2_KERNELS
#include <immintrin.h>
#endif

namespace eco::sim {

// A row span of a plant's footprint: cells [start, start + len) of one grid row; len 0 (and
// start the row's first cell) when no cell centre of that row lies within the crown.
struct Span {
    std::uint32_t start;
    std::uint32_t len;
};

// Closed interval of crown radii.
struct RadiusRange {
    double lo, hi;
};

// clamp(ceil(t), lo, hi) and clamp(floor(t), lo, hi) for integer bounds (|lo|, |hi| < 2^30),
// as ints. Clamping first gives the same integer (ceil and floor are monotone and the bounds
// are integers); the clamped value then fits an int, and one truncating conversion and a
// comparison replace SSE2's rounding sequence (the footprints were a tenth of the run).
// A NaN t gives hi (a defined value instead of converting NaN to int).
inline double clampForRounding(double t, int lo, int hi) {
    return std::max(static_cast<double>(lo), std::min(static_cast<double>(hi), t));  // min(hi, NaN) is hi
}
inline int ceilClamped(double t, int lo, int hi) {
    const double c = clampForRounding(t, lo, hi);
    const int i = static_cast<int>(c);  // towards zero: ceil(c) for c < 0, floor(c) for c >= 0
    return i + (static_cast<double>(i) < c);
}
inline int floorClamped(double t, int lo, int hi) {
    const double c = clampForRounding(t, lo, hi);
    const int i = static_cast<int>(c);
    return i - (c < static_cast<double>(i));
}

// Geometry of the simulation grid: W x H cells of edge `cell`, cell (0, 0) with its lower
// corner at (ox, oy); cell index iy * W + ix.
struct CellGrid {
    int W = 0, H = 0;
    double cell = 0.2, ox = 0, oy = 0;

    // Rows per call of rowBounds in forEachSpan (a multiple of 4).
    static constexpr int kRowChunk = 32;

    // The columns of the cell centres within the disc (x, y, r) on rows r0 .. r0 + n - 1
    // (n <= kRowChunk): a[k] .. b[k] for row r0 + k, a = max(ceil(.), -1) and
    // b = min(floor(.), W) (the other bounds change nothing in forEachSpan: an a beyond
    // W + 1 or a b below -2 is past the other end); a = 1, b = 0 for a row none of whose
    // points lies within the disc.
    void rowBoundsScalar(double x, double y, double r, int r0, int n, int* a, int* b) const {
        const double r2 = r * r;
        for (int k = 0; k < n; ++k) {
            const double dy = oy + (r0 + k + 0.5) * cell - y;
            a[k] = 1;
            b[k] = 0;
            if (dy * dy <= r2) {
                const double half = std::sqrt(r2 - dy * dy);
                a[k] = ceilClamped((x - half - ox) / cell - 0.5, -1, W + 1);
                b[k] = floorClamped((x + half - ox) / cell - 0.5, -2, W);
            }
        }
    }
#ifdef ECO_HAVE_AVX2_KERNELS
    // rowBoundsScalar four rows at a time (AVX2): its operations lane by lane, so the same
    // integers. Writes a and b up to n rounded up to a multiple of 4.
    ECO_TARGET_AVX2 void rowBoundsAvx2(double x, double y, double r, int r0, int n, int* a, int* b) const {
        const __m256d r2 = _mm256_set1_pd(r * r), halfCell = _mm256_set1_pd(0.5), cellW = _mm256_set1_pd(cell);
        const __m256d xv = _mm256_set1_pd(x), yv = _mm256_set1_pd(y), oxv = _mm256_set1_pd(ox), oyv = _mm256_set1_pd(oy);
        const __m256d aLo = _mm256_set1_pd(-1.0), aHi = _mm256_set1_pd(W + 1.0);
        const __m256d bLo = _mm256_set1_pd(-2.0), bHi = _mm256_set1_pd(static_cast<double>(W));
        const __m256d one = _mm256_set1_pd(1.0);
        for (int k = 0; k < n; k += 4) {
            const __m256d iy = _mm256_cvtepi32_pd(_mm_add_epi32(_mm_set1_epi32(r0 + k), _mm_setr_epi32(0, 1, 2, 3)));
            const __m256d dy = _mm256_sub_pd(_mm256_add_pd(oyv, _mm256_mul_pd(_mm256_add_pd(iy, halfCell), cellW)), yv);
            const __m256d dy2 = _mm256_mul_pd(dy, dy);
            const __m256d inside = _mm256_cmp_pd(dy2, r2, _CMP_LE_OQ);
            // NaN in the lanes outside the disc; replaced by (1, 0) below.
            const __m256d half = _mm256_sqrt_pd(_mm256_sub_pd(r2, dy2));
            const __m256d ta = _mm256_sub_pd(_mm256_div_pd(_mm256_sub_pd(_mm256_sub_pd(xv, half), oxv), cellW), halfCell);
            const __m256d tb = _mm256_sub_pd(_mm256_div_pd(_mm256_sub_pd(_mm256_add_pd(xv, half), oxv), cellW), halfCell);
            // clampForRounding: min(hi, t) is hi for a NaN t (MINPD returns its second
            // operand), then max with lo; then the truncation corrected by one where it
            // moved the wrong way (ceilClamped, floorClamped).
            const __m256d ca = _mm256_max_pd(_mm256_min_pd(ta, aHi), aLo);
            const __m256d cb = _mm256_max_pd(_mm256_min_pd(tb, bHi), bLo);
            const __m256d ia = _mm256_cvtepi32_pd(_mm256_cvttpd_epi32(ca));
            const __m256d ib = _mm256_cvtepi32_pd(_mm256_cvttpd_epi32(cb));
            const __m256d ceilA = _mm256_add_pd(ia, _mm256_and_pd(_mm256_cmp_pd(ia, ca, _CMP_LT_OQ), one));
            const __m256d floorB = _mm256_sub_pd(ib, _mm256_and_pd(_mm256_cmp_pd(cb, ib, _CMP_LT_OQ), one));
            _mm_storeu_si128(reinterpret_cast<__m128i*>(a + k), _mm256_cvttpd_epi32(_mm256_blendv_pd(one, ceilA, inside)));
            _mm_storeu_si128(reinterpret_cast<__m128i*>(b + k),
                             _mm256_cvttpd_epi32(_mm256_blendv_pd(_mm256_setzero_pd(), floorB, inside)));
        }
    }
#endif
    void rowBounds(double x, double y, double r, int r0, int n, int* a, int* b) const {
#ifdef ECO_HAVE_AVX2_KERNELS
        if (avx2Kernels()) return rowBoundsAvx2(x, y, r, r0, n, a, b);
#endif
        rowBoundsScalar(x, y, r, r0, n, a, b);
    }

    // Visit the cells whose centres lie within the disc (x, y, r), rows [r0, r1) only, as
    // row spans fn(iy, ixFirst, ixLast). When (rootIx, rootIy) >= 0 the root cell is always
    // part of the footprint ("at least its own cell").
    template <typename F>
    void forEachSpan(double x, double y, double r, int rootIx, int rootIy, int r0, int r1, F&& fn) const {
        int as[kRowChunk], bs[kRowChunk];
        for (int c0 = r0; c0 < r1; c0 += kRowChunk) {
            const int c1 = std::min(r1, c0 + kRowChunk);
            rowBounds(x, y, r, c0, c1 - c0, as, bs);
            for (int iy = c0; iy < c1; ++iy) {
                int a = as[iy - c0], b = bs[iy - c0];
                if (iy == rootIy) {
                    if (a > b) a = b = rootIx;
                    else { a = std::min(a, rootIx); b = std::max(b, rootIx); }
                }
                a = std::max(a, 0);
                b = std::min(b, W - 1);
                if (a <= b) fn(iy, a, b);
            }
        }
    }

    // Rows [lo, hi] whose centres may lie within r of y (plus the root row), clamped.
    void rowRange(double y, double r, int rootIy, int& lo, int& hi) const {
        lo = ceilClamped((y - r - oy) / cell - 0.5, -1, H);
        hi = floorClamped((y + r - oy) / cell - 0.5, -1, H);
        if (rootIy >= 0) {
            lo = std::min(lo, rootIy);
            hi = std::max(hi, rootIy);
        }
        lo = std::max(lo, 0);
        hi = std::min(hi, H - 1);
    }

    // The spans of the footprint of the crown (x, y, r) rooted in (rootIx, rootIy), rows lo..hi
    // (rowRange), into sp[0 .. hi - lo]: one span per row, length 0 for a row none of whose
    // cell centres lies within the crown.
    void footprintSpans(double x, double y, double r, int rootIx, int rootIy, int lo, int hi, Span* sp) const {
        for (int k = 0; k <= hi - lo; ++k) sp[k] = Span{static_cast<std::uint32_t>(static_cast<std::size_t>(lo + k) * W), 0};
        forEachSpan(x, y, r, rootIx, rootIy, lo, hi + 1, [&](int iy, int a, int z) {
            sp[iy - lo] = Span{static_cast<std::uint32_t>(static_cast<std::size_t>(iy) * W + a), static_cast<std::uint32_t>(z - a + 1)};
        });
    }

    // Radii [r, rHi] for which the footprint of the crown (x, y, r) is the one just computed
    // (rows lo..hi, spans sp). The rows and every row's span are monotone in the radius: each
    // step of rowRange and forEachSpan (square, difference, sqrt, division, ceil / floor,
    // min / max with the root cell, clamping) is monotone in floating point too. So a
    // footprint that is the same at r and at a probe radius is the same at every radius in
    // between. The probe is just below the distance to the nearest cell centre (or row
    // centre) outside the footprint, where the exact disc would first gain a cell; if the
    // rounding already differs there, the range is r alone.
    RadiusRange footprintRange(double x, double y, double r, int rootIx, int rootIy, int lo, int hi, const Span* sp) const {
        auto dx2 = [&](int ix) {
            const double d = ox + (ix + 0.5) * cell - x;
            return d * d;
        };
        auto dy2 = [&](int iy) {
            const double d = oy + (iy + 0.5) * cell - y;
            return d * d;
        };
        double d2 = HUGE_VAL;
        if (lo > 0) d2 = std::min(d2, dy2(lo - 1));
        if (hi < H - 1) d2 = std::min(d2, dy2(hi + 1));
        int filled = 0;
        for (int iy = lo; iy <= hi; ++iy) {
            const Span s = sp[iy - lo];
            const double rowD2 = dy2(iy);
            if (s.len == 0) {  // the row's nearest cell centre
                const int ix = floorClamped((x - ox) / cell, 0, W - 1);
                d2 = std::min(d2, rowD2 + dx2(ix));
                continue;
            }
            ++filled;
            const int a = static_cast<int>(s.start - static_cast<std::uint32_t>(iy) * static_cast<std::uint32_t>(W));
            const int b = a + static_cast<int>(s.len) - 1;
            if (a > 0) d2 = std::min(d2, rowD2 + dx2(a - 1));
            if (b < W - 1) d2 = std::min(d2, rowD2 + dx2(b + 1));
        }
        if (!(d2 < HUGE_VAL)) return RadiusRange{r, HUGE_VAL};  // the footprint is the whole grid
        const double probe = std::sqrt(d2) * (1.0 - 1e-9);
        if (!(probe > r)) return RadiusRange{r, r};
        int plo, phi;
        rowRange(y, probe, rootIy, plo, phi);
        if (plo != lo || phi != hi) return RadiusRange{r, r};
        bool same = true;
        int rows = 0;
        forEachSpan(x, y, probe, rootIx, rootIy, lo, hi + 1, [&](int iy, int a, int z) {
            const Span s = sp[iy - lo];
            ++rows;
            same = same && s.start == static_cast<std::uint32_t>(static_cast<std::size_t>(iy) * W + a) &&
                   s.len == static_cast<std::uint32_t>(z - a + 1);
        });
        return same && rows == filled ? RadiusRange{r, probe} : RadiusRange{r, r};
    }
};

}  // namespace eco::sim
