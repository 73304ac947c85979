#include "canopy_context.h"

#include <omp.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <memory>

#include "error.h"
#include "memory.h"

namespace eco {

int CanopyContextBins::binOf(double depthM) const {
    return static_cast<int>(std::upper_bound(edgesM.begin(), edgesM.end(), depthM) - edgesM.begin());
}

std::string CanopyContextBins::label(int k) const {
    char buf[96];
    if (k <= 0)
        std::snprintf(buf, sizeof buf, "< %g m", edgesM.front());
    else if (k >= count() - 1)
        std::snprintf(buf, sizeof buf, ">= %g m", edgesM.back());
    else
        std::snprintf(buf, sizeof buf, "[%g, %g) m", edgesM[static_cast<std::size_t>(k - 1)], edgesM[static_cast<std::size_t>(k)]);
    return buf;
}

void CanopyContextBins::validate(const std::string& what) const {
    if (edgesM.empty() || edgesM.size() > 64)
        throw ValidationError(what + ": canopy context bins need 1..64 edges, got " + std::to_string(edgesM.size()));
    for (std::size_t i = 0; i < edgesM.size(); ++i) {
        if (!std::isfinite(edgesM[i]))
            throw ValidationError(what + ": canopy context edge " + std::to_string(i) + " is not finite");
        if (i > 0 && !(edgesM[i] > edgesM[i - 1]))
            throw ValidationError(what + ": canopy context edges must be strictly ascending (edge " + std::to_string(i) +
                                  ")");
    }
}

Grid<std::uint8_t> canopyCoverMask(const Grid<float>& geometry, const std::vector<Plant>& canopy) {
    Grid<std::uint8_t> mask = Grid<std::uint8_t>::like(geometry, 0);
    const double cs = geometry.cellSizeM();
    const int w = geometry.width(), h = geometry.height();
    // Each thread marks the cells of its own share of the rows, from every tree.
#pragma omp parallel
    {
        const long long nt = omp_get_num_threads(), t0 = omp_get_thread_num();
        const int rowLo = static_cast<int>(h * t0 / nt), rowHi = static_cast<int>(h * (t0 + 1) / nt) - 1;
        for (const Plant& t : canopy) {
            const double r = t.crownRadiusM;
            if (!(r > 0)) continue;
            const int y0 = std::max(rowLo, static_cast<int>(std::floor((t.yM - r - geometry.originY()) / cs - 0.5)));
            const int y1 = std::min(rowHi, static_cast<int>(std::ceil((t.yM + r - geometry.originY()) / cs - 0.5)));
            for (int iy = y0; iy <= y1; ++iy) {
                const double dy = geometry.cellCentreY(iy) - t.yM;
                const double span2 = r * r - dy * dy;
                if (!(span2 > 0)) continue;
                const double half = std::sqrt(span2);
                int x0 = std::max(0, static_cast<int>(std::floor((t.xM - half - geometry.originX()) / cs - 0.5)));
                int x1 = std::min(w - 1, static_cast<int>(std::ceil((t.xM + half - geometry.originX()) / cs - 0.5)));
                for (int ix = x0; ix <= x1; ++ix) {
                    const double dx = geometry.cellCentreX(ix) - t.xM;
                    if (dx * dx + dy * dy < r * r) mask(ix, iy) = 1;
                }
            }
        }
    }
    return mask;
}

namespace {

constexpr double kFar = 1e20;

/// Squared Euclidean distance transform of one line (Felzenszwalb & Huttenlocher 2012):
/// d[q] = min_p (q - p)^2 + f[p]. v and z are scratch of n and n + 1.
void distanceTransform1d(const double* f, int n, double* d, int* v, double* z) {
    constexpr double inf = std::numeric_limits<double>::infinity();
    int k = 0;
    v[0] = 0;
    z[0] = -inf;
    z[1] = inf;
    auto meet = [&](int q, int p) { return ((f[q] + double(q) * q) - (f[p] + double(p) * p)) / (2.0 * (q - p)); };
    for (int q = 1; q < n; ++q) {
        double s = meet(q, v[k]);
        while (s <= z[k]) {  // z[0] = -inf ends the loop
            --k;
            s = meet(q, v[k]);
        }
        ++k;
        v[k] = q;
        z[k] = s;
        z[k + 1] = inf;
    }
    k = 0;
    for (int q = 0; q < n; ++q) {
        while (z[k + 1] < q) ++k;
        const double dq = q - v[k];
        d[q] = dq * dq + f[v[k]];
    }
}

/// No cell of the target class in the column.
constexpr std::uint32_t kNoneInColumn = std::numeric_limits<std::uint32_t>::max();

/// Distance (in cells) along its column from every cell to the nearest cell of the column
/// that is covered (toCovered) and uncovered (toOpen); kNoneInColumn where the column has
/// none. Two sweeps down and up the rows of a block of columns (reading the grid row by row
/// instead of a column at a time). Along the columns the input of the 2-D transform is 0 or
/// far, so its column pass is the square of this distance exactly.
void columnDistances(const Grid<std::uint8_t>& mask, std::uint32_t* toCovered, std::uint32_t* toOpen) {
    const int w = mask.width(), h = mask.height();
    constexpr int kBlockColumns = 256;
    const int nBlocks = (w + kBlockColumns - 1) / kBlockColumns;
#pragma omp parallel
    {
        std::vector<int> metCovered(static_cast<std::size_t>(kBlockColumns)), metOpen(static_cast<std::size_t>(kBlockColumns));
        // Rows first .. last (exclusive) in steps of step: the distance to the nearest cell of
        // each class met so far in each column; kept only where nearer when `nearer`.
        auto sweep = [&](int x0, int x1, int first, int last, int step, bool nearer) {
            std::fill(metCovered.begin(), metCovered.end(), -1);
            std::fill(metOpen.begin(), metOpen.end(), -1);
            for (int iy = first; iy != last; iy += step) {
                const std::uint8_t* m = &mask.data()[mask.index(0, iy)];
                std::uint32_t* rowC = toCovered + mask.index(0, iy);
                std::uint32_t* rowO = toOpen + mask.index(0, iy);
                for (int ix = x0; ix < x1; ++ix) {
                    int& mc = metCovered[static_cast<std::size_t>(ix - x0)];
                    int& mo = metOpen[static_cast<std::size_t>(ix - x0)];
                    if (m[ix] == 1)
                        mc = iy;
                    else if (m[ix] == 0)
                        mo = iy;
                    const std::uint32_t dc = mc < 0 ? kNoneInColumn : static_cast<std::uint32_t>(std::abs(iy - mc));
                    const std::uint32_t dn = mo < 0 ? kNoneInColumn : static_cast<std::uint32_t>(std::abs(iy - mo));
                    if (!nearer || dc < rowC[ix]) rowC[ix] = dc;
                    if (!nearer || dn < rowO[ix]) rowO[ix] = dn;
                }
            }
        };
#pragma omp for schedule(static)
        for (int b = 0; b < nBlocks; ++b) {
            const int x0 = b * kBlockColumns, x1 = std::min(w, x0 + kBlockColumns);
            sweep(x0, x1, 0, h, 1, false);
            sweep(x0, x1, h - 1, -1, -1, true);
        }
    }
}

/// The squared column distance of columnDistances as the 2-D transform's input: kFar where
/// the column has no target.
inline double squaredColumnDistance(std::uint32_t d) { return d == kNoneInColumn ? kFar : double(d) * double(d); }

}  // namespace

Grid<float> canopyDepthMap(const Grid<float>& geometry, const std::vector<Plant>& canopy) {
    const Grid<std::uint8_t> mask = canopyCoverMask(geometry, canopy);
    Grid<float> depth = Grid<float>::like(geometry, 0.0f);
    if (mask.empty()) return depth;
    // Squared Euclidean distance (cells^2) from every cell to the nearest uncovered cell
    // (toOpen) and to the nearest covered one (toCovered): the column pass into two arrays
    // of 4 bytes a cell (uninitialised: every cell is written), the row pass one row at a
    // time into scratch, and the depth made from the row at once (no full-grid arrays of
    // squared distances).
    const int w = mask.width(), h = mask.height();
    const std::size_t n = mask.size();
    const std::unique_ptr<std::uint32_t[]> colCovered(new std::uint32_t[n]), colOpen(new std::uint32_t[n]);
    columnDistances(mask, colCovered.get(), colOpen.get());
    const double cs = geometry.cellSizeM();
#pragma omp parallel
    {
        const std::size_t ws = static_cast<std::size_t>(w);
        std::vector<double> f(ws), toCovered(ws), toOpen(ws), z(ws + 1);
        std::vector<int> v(ws);
#pragma omp for schedule(static)
        for (int iy = 0; iy < h; ++iy) {
            const std::size_t row = mask.index(0, iy);
            for (std::size_t ix = 0; ix < ws; ++ix) f[ix] = squaredColumnDistance(colCovered[row + ix]);
            distanceTransform1d(f.data(), w, toCovered.data(), v.data(), z.data());
            for (std::size_t ix = 0; ix < ws; ++ix) f[ix] = squaredColumnDistance(colOpen[row + ix]);
            distanceTransform1d(f.data(), w, toOpen.data(), v.data(), z.data());
            for (std::size_t ix = 0; ix < ws; ++ix) {
                const std::size_t c = row + ix;
                const bool covered = mask.data()[c] != 0;
                const double d2 = covered ? toOpen[ix] : toCovered[ix];
                double dm = d2 >= kFar * 0.5 ? kCanopyDepthCapM : (std::sqrt(d2) - 0.5) * cs;
                dm = std::min(dm, kCanopyDepthCapM);
                depth.data()[c] = static_cast<float>(covered ? dm : -dm);
            }
        }
    }
    return depth;
}

Grid<std::uint8_t> canopyContextMap(const Grid<float>& depthM, const CanopyContextBins& bins) {
    Grid<std::uint8_t> ctx = Grid<std::uint8_t>::like(depthM, 0);
    const std::ptrdiff_t n = static_cast<std::ptrdiff_t>(depthM.size());
#pragma omp parallel for schedule(static)
    for (std::ptrdiff_t i = 0; i < n; ++i)
        ctx.data()[static_cast<std::size_t>(i)] = static_cast<std::uint8_t>(bins.binOf(depthM.data()[static_cast<std::size_t>(i)]));
    return ctx;
}

CanopyCover::CanopyCover(const std::vector<Plant>& canopy) {
    double x0 = kNone, y0 = kNone, x1 = -kNone, y1 = -kNone, radiusSum = 0;
    std::vector<const Plant*> trees;
    for (const Plant& t : canopy) {
        if (!(t.crownRadiusM > 0)) continue;
        trees.push_back(&t);
        x0 = std::min(x0, t.xM - t.crownRadiusM);
        x1 = std::max(x1, t.xM + t.crownRadiusM);
        y0 = std::min(y0, t.yM - t.crownRadiusM);
        y1 = std::max(y1, t.yM + t.crownRadiusM);
        radiusSum += t.crownRadiusM;
    }
    if (trees.empty()) return;
    // Cells of about the mean crown radius: a crown spans a few of them, a cell lists a few
    // crowns (at most 4096 cells a side, for memory). A crown is listed one cell beyond its
    // bounding box on each side, so that a point that the rounded distance test puts inside
    // it is never in a cell that does not list it.
    const double cell = std::max({0.25, radiusSum / static_cast<double>(trees.size()), std::max(x1 - x0, y1 - y0) / 4096});
    invCellM_ = 1.0 / cell;
    originX_ = x0 - cell;
    originY_ = y0 - cell;
    nx_ = static_cast<int>((x1 - originX_) * invCellM_) + 2;
    ny_ = static_cast<int>((y1 - originY_) * invCellM_) + 2;
    const std::size_t nCells = static_cast<std::size_t>(nx_) * static_cast<std::size_t>(ny_);
    auto cellOf = [&](double v, double origin, int n) { return std::clamp(static_cast<int>(std::floor((v - origin) * invCellM_)), 0, n - 1); };
    auto cellIndex = [&](int ix, int iy) { return static_cast<std::size_t>(iy) * static_cast<std::size_t>(nx_) + static_cast<std::size_t>(ix); };
    // The discs in the order of their trunk's cell (a query reads the discs of one cell, and
    // nearby queries nearby discs: one cache line per disc tested, not four arrays at random
    // places). The lowest crown over a point does not depend on the order.
    struct Box {
        int x0, x1, y0, y1;
    };
    std::vector<Box> box(trees.size());
    {
        std::vector<std::uint32_t> at;
        assignFresh(at, nCells + 1, 0u);
        std::vector<std::uint32_t> trunkCell(trees.size());
        for (std::size_t t = 0; t < trees.size(); ++t) {
            trunkCell[t] = static_cast<std::uint32_t>(cellIndex(cellOf(trees[t]->xM, originX_, nx_), cellOf(trees[t]->yM, originY_, ny_)));
            ++at[trunkCell[t] + 1];
        }
        for (std::size_t c = 0; c < nCells; ++c) at[c + 1] += at[c];
        resizeFresh(disc_, trees.size());
        for (std::size_t t = 0; t < trees.size(); ++t) {
            const Plant& p = *trees[t];
            const double x = p.xM, y = p.yM, r = p.crownRadiusM;
            const std::size_t k = at[trunkCell[t]]++;
            disc_[k] = Disc{x, y, r * r, p.heightM};
            box[k] = Box{std::max(0, cellOf(x - r, originX_, nx_) - 1), std::min(nx_ - 1, cellOf(x + r, originX_, nx_) + 1),
                         std::max(0, cellOf(y - r, originY_, ny_) - 1), std::min(ny_ - 1, cellOf(y + r, originY_, ny_) + 1)};
        }
    }
    // Each cell's list in tree order, made by bands of cell rows in parallel: the discs are in
    // row order of their trunks, so the ones whose boxes reach a band are one range of them
    // (trunk rows within the largest reach of the band). Every band counts and fills only
    // its own cells, each in tree order: the lists are the same for any number of threads.
    std::vector<int> trunkRow(box.size());
    int reach = 0;
    for (std::size_t k = 0; k < box.size(); ++k) {
        trunkRow[k] = cellOf(disc_[k].y, originY_, ny_);
        reach = std::max({reach, trunkRow[k] - box[k].y0, box[k].y1 - trunkRow[k]});
    }
    const int bandRows = std::max(16, 4 * reach);
    const int nBands = (ny_ + bandRows - 1) / bandRows;
    // f(cell, k) for every cell of band b listed by disc k, in disc order.
    auto forBandCells = [&](int b, auto&& f) {
        const int r0 = b * bandRows, r1 = std::min(ny_, r0 + bandRows);
        const std::size_t k0 = static_cast<std::size_t>(std::lower_bound(trunkRow.begin(), trunkRow.end(), r0 - reach) - trunkRow.begin());
        const std::size_t k1 = static_cast<std::size_t>(std::lower_bound(trunkRow.begin(), trunkRow.end(), r1 + reach) - trunkRow.begin());
        for (std::size_t k = k0; k < k1; ++k)
            for (int iy = std::max(box[k].y0, r0); iy <= std::min(box[k].y1, r1 - 1); ++iy)
                for (int ix = box[k].x0; ix <= box[k].x1; ++ix) f(cellIndex(ix, iy), k);
    };
    const bool parallel = nBands > 1 && box.size() >= 4096;
    assignFresh(start_, nCells + 1, 0u);
#pragma omp parallel for schedule(dynamic, 1) if (parallel)
    for (int b = 0; b < nBands; ++b) forBandCells(b, [&](std::size_t c, std::size_t) { ++start_[c + 1]; });
    for (std::size_t c = 0; c < nCells; ++c) start_[c + 1] += start_[c];
    resizeFresh(crown_, start_[nCells]);
    std::vector<std::uint32_t> fill;
    resizeFresh(fill, nCells);
    std::copy(start_.begin(), start_.end() - 1, fill.begin());
#pragma omp parallel for schedule(dynamic, 1) if (parallel)
    for (int b = 0; b < nBands; ++b)
        forBandCells(b, [&](std::size_t c, std::size_t k) { crown_[fill[c]++] = static_cast<std::uint32_t>(k); });
}

double CanopyCover::lowestCrownAboveM(double xM, double yM) const {
    double lowest = kNone;
    if (disc_.empty()) return lowest;
    const double fx = std::floor((xM - originX_) * invCellM_), fy = std::floor((yM - originY_) * invCellM_);
    if (!(fx >= 0 && fx < nx_ && fy >= 0 && fy < ny_)) return lowest;  // beyond every crown
    const std::size_t c = static_cast<std::size_t>(fy) * static_cast<std::size_t>(nx_) + static_cast<std::size_t>(fx);
    for (std::uint32_t e = start_[c]; e < start_[c + 1]; ++e) {
        const Disc& d = disc_[crown_[e]];
        const double dx = d.x - xM, dy = d.y - yM;
        if (dx * dx + dy * dy < d.radius2) lowest = std::min(lowest, d.height);
    }
    return lowest;
}

}  // namespace eco
