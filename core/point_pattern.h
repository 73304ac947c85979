// Second-order statistics of point patterns, shared by the analyser (biome databases), the
// synthesizer's refinement and `eco pcf` / `eco compare`: distance and separation bins,
// edge-correction weights, a uniform-grid neighbour index, and the annulus estimator of
// the pair-correlation function g(r). docs/analysis.md derives the formulas.
//
// The estimator (translation edge correction, Ohser & Stoyan) for types i and j in a window
// W of area |W|, over the distance bin [lo, hi) of annulus area A = pi (hi^2 - lo^2):
//
//   g_ij = S / (A * N),   S = sum over ordered pairs (x in X_i, y in X_j, x != y,
//                                 lo <= |y - x| < hi) of |W| / |W n (W + (y - x))|,
//                         N = n_i (n_j - [i == j]) / |W|          (pairs per m^2).
//
// It is the difference over the bin of spatstat's K-function with correction = "translate"
// (Kest for i == j, Kcross otherwise), divided by the annulus area, and is checked
// against it in tests/pcf_test.cpp. S, N and the raw pair count are kept separately so that
// several windows pool as a ratio (sum of S over sum of N), as spatstat pools ratio fv's.
//
// Determinism: the parallel functions accumulate floating-point sums per fixed chunk of
// points and add the chunks in index order, so results are bit-identical for any number
// of OpenMP threads.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <string>
#include <vector>

#include "grid.h"

namespace eco {

/// Axis-aligned rectangle [x0, x1] x [y0, y1] in world metres.
struct RectWindow {
    double x0 = 0, y0 = 0, x1 = 1, y1 = 1;
    double widthM() const { return x1 - x0; }
    double heightM() const { return y1 - y0; }
    double areaM2() const { return widthM() * heightM(); }
    bool contains(double x, double y) const { return x >= x0 && x <= x1 && y >= y0 && y <= y1; }
    /// Distance in metres from (x, y) (inside) to the nearest side.
    double distanceToEdgeM(double x, double y) const {
        return std::min(std::min(x - x0, x1 - x), std::min(y - y0, y1 - y));
    }
    /// ValidationError unless the corners are finite and x0 < x1, y0 < y1; `what` names it.
    void validate(const std::string& what) const;
};

/// Equal distance bins [k w, (k + 1) w), k = 0..count-1, w = rMaxM / count.
struct DistanceBins {
    double rMaxM = 10.0;
    int count = 40;
    double widthM() const { return rMaxM / count; }
    double loM(int k) const { return rMaxM * k / count; }
    double hiM(int k) const { return rMaxM * (k + 1) / count; }
    double midM(int k) const { return 0.5 * (loM(k) + hiM(k)); }
    /// Area of the annulus of bin k, m^2.
    double annulusAreaM2(int k) const;
    /// count + 1 edges, metres.
    std::vector<double> edgesM() const;
    /// Bin of a distance, or -1 when r is negative or >= rMaxM.
    int binOf(double r) const {
        if (!(r >= 0.0) || r >= rMaxM) return -1;
        const int k = static_cast<int>(r * count / rMaxM);
        return k < count ? k : count - 1;
    }
    void validate(const std::string& what) const;
};

/// Bins of the edge-to-edge separation of two disks, s = |p_i - p_j| - r_i - r_j (metres):
/// count equal bins from minM to maxM. minM < 0 gives overlap bins (negative s);
/// separations below minM are counted apart as underflow.
struct SeparationBins {
    double minM = -12.0;
    double maxM = 4.0;
    int count = 64;
    double widthM() const { return (maxM - minM) / count; }
    double loM(int k) const { return minM + (maxM - minM) * k / count; }
    double hiM(int k) const { return minM + (maxM - minM) * (k + 1) / count; }
    std::vector<double> edgesM() const;
    /// Bin of a separation: -1 below minM (underflow), count at or above maxM.
    int binOf(double s) const {
        if (s < minM) return -1;
        if (!(s < maxM)) return count;
        const int k = static_cast<int>((s - minM) * count / (maxM - minM));
        return k < count ? k : count - 1;
    }
    void validate(const std::string& what) const;
};

/// Translation edge-correction weight of a rectangle, |W| / |W n (W + u)| for the
/// displacement u = (dx, dy); requires |dx| < width and |dy| < height.
inline double translationWeight(const RectWindow& w, double dx, double dy) {
    return w.areaM2() / ((w.widthM() - std::abs(dx)) * (w.heightM() - std::abs(dy)));
}

/// Ripley's isotropic edge-correction weight of a rectangle for a circle of radius r
/// around (x, y) inside it: 2 pi r / (length of the circle inside W). Exact while r is at
/// most half the shorter side (then at most two adjacent sides cut the circle).
double isotropicWeight(const RectWindow& w, double x, double y, double r);

/// Normalisation N of the annulus estimator: n_i (n_j - [sameType]) / |W|, pairs per m^2.
inline double pairNormalisation(double nI, double nJ, bool sameType, double areaM2) {
    return nI * (nJ - (sameType ? 1.0 : 0.0)) / areaM2;
}

/// g = weightedSum / (annulusArea * normalisation); 0 when the normalisation is 0 (fewer
/// than two points), so that an empty pattern never produces NaN.
inline double annulusPcf(double weightedSum, double annulusAreaM2, double normalisation) {
    return normalisation > 0.0 ? weightedSum / (annulusAreaM2 * normalisation) : 0.0;
}

/// A window that is a union of grid cells (a region of the analyser), with its set
/// covariance gamma(u) = |W n (W + u)| tabulated at whole-cell lags up to maxLagCells.
/// gamma of a union of squares is exactly the bilinear interpolation of that table, so
/// overlapM2() is exact, not an approximation.
class CellWindow {
public:
    CellWindow() = default;
    /// Set covariances of every window 0..nLabels-1 of a label grid at once (cells with a
    /// label outside that range belong to none), for lags up to maxLagM in x and y.
    /// Integer counts: identical for any thread count.
    static std::vector<CellWindow> fromLabels(const Grid<std::int32_t>& labels, int nLabels, double maxLagM);

    double areaM2() const { return areaM2_; }
    double cellSizeM() const { return cellSizeM_; }
    int maxLagCells() const { return lag_; }
    /// gamma(u) in m^2 for |dx|, |dy| up to maxLagM (0 beyond the table).
    double overlapM2(double dx, double dy) const {
        const double fx = dx * invCell_ + lag_, fy = dy * invCell_ + lag_;  // >= 0 inside the table
        if (!(fx >= 0.0 && fy >= 0.0)) return 0.0;
        const int ix = static_cast<int>(fx), iy = static_cast<int>(fy);
        if (ix + 1 >= side_ || iy + 1 >= side_) return 0.0;
        const double tx = fx - ix, ty = fy - iy;
        const double* r0 = table_.data() + static_cast<std::size_t>(iy) * static_cast<std::size_t>(side_) + static_cast<std::size_t>(ix);
        const double* r1 = r0 + side_;
        return (r0[0] * (1.0 - tx) + r0[1] * tx) * (1.0 - ty) + (r1[0] * (1.0 - tx) + r1[1] * tx) * ty;
    }
    /// |W| / gamma(u), the translation weight; 0 where gamma is 0.
    double translationWeight(double dx, double dy) const {
        const double g = overlapM2(dx, dy);
        return g > 0.0 ? areaM2_ / g : 0.0;
    }

private:
    double cellSizeM_ = 1.0, invCell_ = 1.0;
    double areaM2_ = 0.0;
    int lag_ = 0, side_ = 1;
    std::vector<double> table_;  ///< [2 lag + 1]^2: cell pairs at each whole-cell lag times the cell area
};

/// Uniform-grid index of points for fixed-radius neighbour queries. Points are copied
/// sorted by cell (row-major); `order()[s]` is the caller's index of sorted point s, so
/// payload arrays can be permuted once with permuted().
class PointGrid {
public:
    PointGrid() = default;
    PointGrid(const std::vector<double>& x, const std::vector<double>& y, double cellSizeM);

    std::size_t size() const { return xs_.size(); }
    const std::vector<std::uint32_t>& order() const { return order_; }
    const std::vector<double>& xs() const { return xs_; }
    const std::vector<double>& ys() const { return ys_; }
    double cellSizeM() const { return cell_; }

    /// `values` reordered to the grid's sorted order.
    template <typename T>
    std::vector<T> permuted(const std::vector<T>& values) const {
        std::vector<T> out(order_.size());
        for (std::size_t s = 0; s < order_.size(); ++s) out[s] = values[order_[s]];
        return out;
    }

    /// Calls f(s, dx, dy, d2) for every sorted point s with d2 = dx^2 + dy^2 < radius^2,
    /// (dx, dy) = point - (x, y). Points after `minSorted` only (pass 0 for all).
    template <typename F>
    void forEachWithin(double x, double y, double radius, F&& f, std::size_t minSorted = 0) const {
        if (xs_.empty()) return;
        const double r2 = radius * radius;
        const int cx0 = std::max(0, static_cast<int>(std::floor((x - radius - ox_) * invCell_)));
        const int cx1 = std::min(nx_ - 1, static_cast<int>(std::floor((x + radius - ox_) * invCell_)));
        const int cy0 = std::max(0, static_cast<int>(std::floor((y - radius - oy_) * invCell_)));
        const int cy1 = std::min(ny_ - 1, static_cast<int>(std::floor((y + radius - oy_) * invCell_)));
        if (cx0 > cx1 || cy0 > cy1) return;  // the disc misses the grid
        for (int cy = cy0; cy <= cy1; ++cy) {
            const std::size_t row = static_cast<std::size_t>(cy) * static_cast<std::size_t>(nx_);
            std::size_t b = start_[row + static_cast<std::size_t>(cx0)];
            const std::size_t e = start_[row + static_cast<std::size_t>(cx1) + 1];
            if (e <= minSorted) continue;
            if (b < minSorted) b = minSorted;
            // Branch-free compaction of the accepted points, then the callback: about half
            // the candidates are accepted, a branch per candidate would mispredict often.
            constexpr std::size_t kBlock = 64;
            std::uint32_t idx[kBlock];
            double bdx[kBlock], bdy[kBlock], bd2[kBlock];
            for (std::size_t s0 = b; s0 < e; s0 += kBlock) {
                const std::size_t s1 = std::min(e, s0 + kBlock);
                std::size_t n = 0;
                for (std::size_t s = s0; s < s1; ++s) {
                    const double dx = xs_[s] - x, dy = ys_[s] - y;
                    const double d2 = dx * dx + dy * dy;
                    idx[n] = static_cast<std::uint32_t>(s);
                    bdx[n] = dx;
                    bdy[n] = dy;
                    bd2[n] = d2;
                    n += d2 < r2 ? 1 : 0;
                }
                for (std::size_t i = 0; i < n; ++i) f(static_cast<std::size_t>(idx[i]), bdx[i], bdy[i], bd2[i]);
            }
        }
    }

private:
    double ox_ = 0, oy_ = 0, cell_ = 1, invCell_ = 1;
    int nx_ = 0, ny_ = 0;
    std::vector<std::size_t> start_;  ///< [nx * ny + 1]: first sorted point of each cell
    std::vector<double> xs_, ys_;
    std::vector<std::uint32_t> order_;
};

/// A marked point pattern: positions (metres) and a type 0..typeNames.size()-1 per point.
struct PointPattern {
    std::vector<double> x, y;
    std::vector<int> type;
    std::vector<std::string> typeNames;  ///< at least one
    std::size_t size() const { return x.size(); }
};

struct PcfOptions {
    DistanceBins bins;
    bool isotropic = true;  ///< also accumulate Ripley's isotropic weights
};

/// Raw pair sums of a pattern in a rectangle, per ordered type pair (from i to j) and bin.
struct PairSums {
    int nTypes = 0;
    DistanceBins bins;
    RectWindow window;
    std::vector<std::int64_t> typeCount;   ///< [nTypes] points per type
    std::vector<std::int64_t> pairCount;   ///< [i][j][bin] ordered pairs (raw)
    std::vector<double> translateSum;      ///< [i][j][bin] sum of |W| / gamma(u)
    std::vector<double> isotropicSum;      ///< [i][j][bin] sum of Ripley weights (empty if off)

    std::size_t index(int i, int j, int k) const {
        return (static_cast<std::size_t>(i) * static_cast<std::size_t>(nTypes) + static_cast<std::size_t>(j)) *
                   static_cast<std::size_t>(bins.count) +
               static_cast<std::size_t>(k);
    }
    /// N for types i -> j (see the top of this file).
    double normalisation(int i, int j) const {
        return pairNormalisation(static_cast<double>(typeCount[static_cast<std::size_t>(i)]),
                                 static_cast<double>(typeCount[static_cast<std::size_t>(j)]), i == j, window.areaM2());
    }
    /// g_ij of bin k with translation (or isotropic) correction.
    double gTranslate(int i, int j, int k) const {
        return annulusPcf(translateSum[index(i, j, k)], bins.annulusAreaM2(k), normalisation(i, j));
    }
    double gIsotropic(int i, int j, int k) const {
        return annulusPcf(isotropicSum[index(i, j, k)], bins.annulusAreaM2(k), normalisation(i, j));
    }
    /// Sums with all types merged into one (the unmarked pattern).
    PairSums merged() const;
};

/// Pair sums of a pattern in a rectangular window. Neighbours through a uniform grid;
/// OpenMP over fixed chunks. ValidationError when a point lies outside the window, a type
/// is out of range, or rMax exceeds half the window's shorter side (the translation and
/// isotropic weights are then undefined or unbounded).
PairSums countPairs(const PointPattern& pattern, const RectWindow& window, const PcfOptions& options);

/// Read a point pattern from CSV: a header naming the columns x and y (or x_m, y_m) and
/// optionally species (or type); other columns are ignored; fields may be "quoted".
/// Types are numbered in sorted name order (as R's factor levels); without a species
/// column every point has type 0, named "all". Blank lines and lines starting with '#'
/// are skipped. IoError "FILE:LINE: ..." for a malformed row (wrong number of fields, a
/// coordinate that is not a finite number) and, when `window` is given, for a point
/// outside it.
PointPattern readPointPatternCsv(const std::string& path, const RectWindow* window = nullptr);

/// Distance from every point to its nearest other point (metres), through an exact FLANN
/// kd-tree; infinity for a pattern of one point. Coincident points have distance 0.
/// Deterministic: the tree is exact (single index, no randomised search).
std::vector<double> nearestNeighbourDistances(const std::vector<double>& x, const std::vector<double>& y);

/// Clark and Evans' (1954) aggregation index of a point pattern in a rectangle: the mean
/// nearest-neighbour distance over its expectation under complete spatial randomness with
/// Donnelly's (1978) edge correction, E = 0.5 sqrt(A/n) + (0.0514 + 0.0412/sqrt(n)) P/n.
/// R < 1: clustered; R = 1: random; R > 1: regular. NaN for fewer than two points.
struct ClarkEvans {
    std::size_t n = 0;
    double meanNearestM = 0;    ///< observed mean nearest-neighbour distance
    double expectedM = 0;       ///< its expectation under CSR (Donnelly)
    double index = 0;           ///< R = meanNearestM / expectedM
};
ClarkEvans clarkEvans(const std::vector<double>& x, const std::vector<double>& y, const RectWindow& window);

/// Write pair correlation as CSV (atomic), one header line and one row per ordered type pair
/// and bin: from,to,r_lo,r_hi,r_mid,pair_count,translate_weighted,normalisation_per_m2,
/// g_trans,g_iso,window_x0,window_y0,window_x1,window_y1 (g_iso empty when not computed). With more than one type the unmarked pattern follows
/// as from = to = "all" unless a type is already named so.
void writePcfCsv(const std::string& path, const PairSums& sums, const std::vector<std::string>& typeNames);

}  // namespace eco
