#include "seeding.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>

#include "error.h"

namespace eco {

Grid<std::int32_t> seedingLabels(const Grid<float>& geometry, const std::vector<Plant>& canopy,
                                 const std::vector<int>& speciesMask, double seedingRadiusFactor, double innerFactor,
                                 Grid<float>* seedWeight) {
    if (!(seedingRadiusFactor >= 0.0) || !std::isfinite(seedingRadiusFactor))
        throw ValidationError("seeding labels: seeding radius factor must be finite and >= 0");
    if (!(innerFactor >= 0.0) || !std::isfinite(innerFactor))
        throw ValidationError("seeding labels: inner radius factor must be finite and >= 0");
    Grid<std::int32_t> labels = Grid<std::int32_t>::like(geometry, 0);
    if (seedWeight) *seedWeight = Grid<float>::like(geometry, 0.0f);
    const double cs = geometry.cellSizeM();
    const int w = geometry.width(), h = geometry.height();
    if (w == 0 || h == 0) return labels;
    // The sub-biome bits that occur.
    int allBits = 0;
    for (int m : speciesMask) allBits |= m;
    std::vector<int> bits;
    for (int b = 0; b < 31; ++b)
        if (allBits & (1 << b)) bits.push_back(b);
    const std::size_t nBits = bits.size();
    // Bands of rows, each drawn by one thread from the trees that reach it, in tree order:
    // no two threads write a cell, and the sums add in the same order for any thread count.
    constexpr int kBandRows = 16;
    const int nBands = (h + kBandRows - 1) / kBandRows;
    struct Extent {
        int x0, x1, y0, y1;
    };
    std::vector<Extent> extent(canopy.size(), Extent{0, -1, 0, -1});
    std::vector<std::vector<std::uint32_t>> bandTrees(static_cast<std::size_t>(nBands));
    for (std::size_t t = 0; t < canopy.size(); ++t) {
        const Plant& p = canopy[t];
        if (p.speciesId < 0 || static_cast<std::size_t>(p.speciesId) >= speciesMask.size()) continue;
        if (speciesMask[static_cast<std::size_t>(p.speciesId)] == 0) continue;
        const double radius = seedingRadiusFactor * p.crownRadiusM;
        Extent e;
        e.x0 = std::max(0, static_cast<int>(std::floor((p.xM - radius - geometry.originX()) / cs - 0.5)));
        e.x1 = std::min(w - 1, static_cast<int>(std::ceil((p.xM + radius - geometry.originX()) / cs - 0.5)));
        e.y0 = std::max(0, static_cast<int>(std::floor((p.yM - radius - geometry.originY()) / cs - 0.5)));
        e.y1 = std::min(h - 1, static_cast<int>(std::ceil((p.yM + radius - geometry.originY()) / cs - 0.5)));
        if (e.x0 > e.x1 || e.y0 > e.y1) continue;
        extent[t] = e;
        for (int b = e.y0 / kBandRows; b <= e.y1 / kBandRows; ++b)
            bandTrees[static_cast<std::size_t>(b)].push_back(static_cast<std::uint32_t>(t));
    }
    const double invCs = 1.0 / cs;
    // The cells of row iy whose centre is within sqrt(r2) of the tree: the analyser's exact
    // test (dx^2 + dy^2 <= r2 in double), at the two ends of a span first guessed with sqrt.
    auto span = [&](const Plant& p, const Extent& e, double dy, double r2, int& xa, int& xb) {
        const double rest = r2 - dy * dy;
        if (rest < 0) return false;
        const double half = std::sqrt(rest);
        auto in = [&](int ix) {
            const double dx = geometry.cellCentreX(ix) - p.xM;
            return dx * dx + dy * dy <= r2;
        };
        // A first guess (the exact test below corrects it by a cell if rounding misled it).
        const double rel = (p.xM - geometry.originX()) * invCs - 0.5, halfCells = half * invCs;
        xa = std::clamp(static_cast<int>(std::ceil(rel - halfCells)), e.x0, e.x1);
        xb = std::clamp(static_cast<int>(std::floor(rel + halfCells)), e.x0, e.x1);
        while (xa > e.x0 && in(xa - 1)) --xa;
        while (xa <= e.x1 && !in(xa)) ++xa;
        while (xb < e.x1 && in(xb + 1)) ++xb;
        while (xb >= e.x0 && !in(xb)) --xb;
        return xa <= xb;
    };
    // The same span one row further from the tree's centre row: a subset of the last one
    // (dx^2 + dy^2 grows with |dy| in double too), so only its ends move inwards.
    auto shrink = [&](const Plant& p, double dy, double r2, int& xa, int& xb) {
        auto in = [&](int ix) {
            const double dx = geometry.cellCentreX(ix) - p.xM;
            return dx * dx + dy * dy <= r2;
        };
        while (xa <= xb && !in(xa)) ++xa;
        while (xb >= xa && !in(xb)) --xb;
        return xa <= xb;
    };
    // The row whose centre is nearest the tree (smallest dy^2 as computed): |dy| grows from
    // it both ways, so spans only shrink away from it.
    auto nearestRow = [&](const Plant& p) {
        const int guess = static_cast<int>(std::floor((p.yM - geometry.originY()) * invCs - 0.5));
        int best = guess;
        double bestD2 = std::numeric_limits<double>::infinity();
        for (int iy = guess - 1; iy <= guess + 2; ++iy) {
            const double dy = geometry.cellCentreY(iy) - p.yM;
            if (dy * dy < bestD2) {
                bestD2 = dy * dy;
                best = iy;
            }
        }
        return best;
    };
    const std::size_t W1 = static_cast<std::size_t>(w) + 1;
#pragma omp parallel
    {
        // Per band: per row and bit, +1 / -1 at the ends of every disc span (and of every
        // inner disc span): O(rows) per tree instead of O(cells).
        std::vector<std::int32_t> diff(static_cast<std::size_t>(kBandRows) * nBits * W1);
        std::vector<std::int32_t> innerDiff(seedWeight ? static_cast<std::size_t>(kBandRows) * W1 : 0);
        std::vector<std::vector<int>> fringe(static_cast<std::size_t>(kBandRows));
        // Per row: the number of fringe cells left of each column (a span's fringe cells in
        // two reads instead of a binary search).
        std::vector<std::uint32_t> fringeBefore(seedWeight ? static_cast<std::size_t>(kBandRows) * W1 : 0);
        struct Span {
            std::uint32_t tree;
            int iy, xa, xb;
        };
        std::vector<Span> spans;  // the band's disc spans, in tree then row order
#pragma omp for schedule(dynamic, 1)
        for (int b = 0; b < nBands; ++b) {
            const int by0 = b * kBandRows, by1 = std::min(h - 1, by0 + kBandRows - 1);
            std::fill(diff.begin(), diff.end(), 0);
            std::fill(innerDiff.begin(), innerDiff.end(), 0);
            spans.clear();
            const std::vector<std::uint32_t>& trees = bandTrees[static_cast<std::size_t>(b)];
            for (std::size_t q = 0; q < trees.size(); ++q) {
                // The trees of a band lie anywhere in the list: fetch a few ahead (at 3072^2
                // the load of the crown radius was a sixth of this function's time).
                constexpr std::size_t kAhead = 8;
                if (q + kAhead < trees.size()) {
                    __builtin_prefetch(&canopy[trees[q + kAhead]]);
                    __builtin_prefetch(&extent[trees[q + kAhead]]);
                }
                const std::uint32_t t = trees[q];
                const Plant& p = canopy[t];
                const Extent& e = extent[t];
                const int mask = speciesMask[static_cast<std::size_t>(p.speciesId)];
                const double radius = seedingRadiusFactor * p.crownRadiusM;
                const double r2 = radius * radius;
                const double inner = std::min(innerFactor, seedingRadiusFactor) * p.crownRadiusM;
                const bool withInner = seedWeight && inner > 0;
                const double i2 = inner * inner;
                const int yA = std::max(e.y0, by0), yB = std::min(e.y1, by1);
                if (yA > yB) continue;
                auto addRow = [&](int iy, int xa, int xb) {
                    if (seedWeight) spans.push_back(Span{t, iy, xa, xb});
                    const std::size_t row = static_cast<std::size_t>(iy - by0);
                    for (std::size_t k = 0; k < nBits; ++k)
                        if (mask & (1 << bits[k])) {
                            std::int32_t* d = &diff[(row * nBits + k) * W1];
                            ++d[xa];
                            --d[xb + 1];
                        }
                };
                auto addInner = [&](int iy, int xa, int xb) {
                    std::int32_t* d = &innerDiff[static_cast<std::size_t>(iy - by0) * W1];
                    ++d[xa];
                    --d[xb + 1];
                };
                // From the band's row nearest the tree outwards, both ways: the first row of
                // each way is found from its square root, the others by moving the last
                // row's ends inwards (the same cells as the square root and tests per row).
                const int mid = std::clamp(nearestRow(p), yA, yB);
                int oa = 0, ob = -1, ia = 0, ib = -1;  // the spans of row mid
                bool outer = false, innerOn = false;
                {
                    const double dy = geometry.cellCentreY(mid) - p.yM;
                    outer = span(p, e, dy, r2, oa, ob);
                    if (outer) {
                        addRow(mid, oa, ob);
                        if (withInner) innerOn = span(p, e, dy, i2, ia, ib);
                        if (innerOn) addInner(mid, ia, ib);
                    }
                }
                if (!outer) continue;  // the nearest row misses the disc: so do the others
                for (const int step : {1, -1}) {
                    int xa = oa, xb = ob, ja = ia, jb = ib;
                    bool inn = innerOn;
                    for (int iy = mid + step; iy >= yA && iy <= yB; iy += step) {
                        const double dy = geometry.cellCentreY(iy) - p.yM;
                        if (r2 - dy * dy < 0 || !shrink(p, dy, r2, xa, xb)) break;
                        addRow(iy, xa, xb);
                        if (inn) {
                            inn = i2 - dy * dy >= 0 && shrink(p, dy, i2, ja, jb);
                            if (inn) addInner(iy, ja, jb);
                        }
                    }
                }
            }
            for (int iy = by0; iy <= by1; ++iy) {
                const std::size_t row = static_cast<std::size_t>(iy - by0);
                std::int32_t* lrow = &labels(0, iy);
                for (std::size_t k = 0; k < nBits; ++k) {
                    const std::int32_t* d = &diff[(row * nBits + k) * W1];
                    const std::int32_t bit = 1 << bits[k];
                    std::int32_t run = 0;
                    for (int ix = 0; ix < w; ++ix) {
                        run += d[ix];
                        lrow[ix] |= run > 0 ? bit : 0;
                    }
                }
                if (!seedWeight) continue;
                // Inside an inner disc the weight is 1 (min(1, sum) with a term of 1); the
                // other seeded cells (the fringe) get the sum of their kernel terms below.
                float* wrow = &(*seedWeight)(0, iy);
                auto& fr = fringe[row];
                fr.clear();
                std::uint32_t* before = &fringeBefore[row * W1];
                std::int32_t run = 0;
                for (int ix = 0; ix < w; ++ix) {
                    before[ix] = static_cast<std::uint32_t>(fr.size());
                    run += innerDiff[row * W1 + static_cast<std::size_t>(ix)];
                    if (run > 0) wrow[ix] = 1.0f;
                    else if (lrow[ix] != 0) fr.push_back(ix);
                }
                before[w] = static_cast<std::uint32_t>(fr.size());
            }
            if (!seedWeight) continue;
            // k = (R - d) / (R - inner) in the annulus (single precision; the same arithmetic for
            // any thread count), added in tree order to the fringe cells of each row.
            for (const Span& sp : spans) {
                const std::size_t row = static_cast<std::size_t>(sp.iy - by0);
                const std::uint32_t f0 = fringeBefore[row * W1 + static_cast<std::size_t>(sp.xa)];
                const std::uint32_t f1 = fringeBefore[row * W1 + static_cast<std::size_t>(sp.xb) + 1];
                if (f0 == f1) continue;
                const int* fr = fringe[row].data();
                const Plant& p = canopy[sp.tree];
                const double radius = seedingRadiusFactor * p.crownRadiusM;
                const double fall = radius - std::min(innerFactor, seedingRadiusFactor) * p.crownRadiusM;
                const float pxRel = static_cast<float>(p.xM - geometry.originX());
                const float csf = static_cast<float>(cs), radf = static_cast<float>(radius);
                const float invFall = fall > 0 ? static_cast<float>(1.0 / fall) : 0.0f;
                const double dy = geometry.cellCentreY(sp.iy) - p.yM;
                const float dy2 = static_cast<float>(dy * dy);
                float* wrow = &(*seedWeight)(0, sp.iy);
                for (std::uint32_t f = f0; f < f1; ++f) {
                    const int ix = fr[f];
                    // The terms are >= 0: a sum that reached 1 ends at 1 (the cap below).
                    if (wrow[ix] >= 1.0f) continue;
                    if (!(fall > 0)) {
                        wrow[ix] += 1.0f;
                        continue;
                    }
                    const float dx = (static_cast<float>(ix) + 0.5f) * csf - pxRel;
                    const float k = (radf - std::sqrt(dx * dx + dy2)) * invFall;
                    wrow[ix] += std::min(1.0f, std::max(0.0f, k));
                }
            }
            // The band's weights capped at 1 (here rather than in a serial pass at the end).
            for (int iy = by0; iy <= by1; ++iy) {
                float* wrow = &(*seedWeight)(0, iy);
                for (int ix = 0; ix < w; ++ix) wrow[ix] = std::min(wrow[ix], 1.0f);
            }
        }
    }
    return labels;
}

}  // namespace eco
