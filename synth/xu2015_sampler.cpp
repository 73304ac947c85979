// The Xu et al. 2015 sample-based sampler (SynthMethod::Xu2015; docs/synth.md section 2d):
// "we first choose an element from the sample pattern at random and place it at the synthesis
// area center ... In each extension, the element nearest to the center element in the
// synthesis pattern is set as the extending element ... we search the sample pattern and find
// the matching element whose histogram is the most similar to that of the extending element.
// We copy the neighborhood elements of the matching element to the synthesis area".
//
// 1. Analysis of the exemplar (n elements of T types in a rectangle): neighbourhood radius
//    R = radiusFactor / sqrt(n / area); each element whose R-disc lies inside the exemplar's
//    window (an "interior" element: its neighbourhood is completely observed) gets its
//    neighbours (offsets, types) and per type a histogram over shells x sectors (equal-width
//    rings, equal sectors counter-clockwise from east).
// 2. Growth, from a seed at the target's centre outwards. A point that has been extended
//    "covers" its R-disc: everything inside is final. Extending a point p (a placed element,
//    nearest to the centre first, or an empty spot when no element is left to extend: the
//    uncovered raster cell nearest to the centre):
//    * determined grids: those whose representative point (centre of the grid) lies within R
//      of an extended point (the paper's rule);
//    * p's per-type histograms over the determined grids, compared with each candidate's
//      (a random subset of `candidates` interior elements) over the same grids:
//      d_t = sqrt(D_t^T A D_t), A_ij = exp(-d(i, j) / sigma), d(i, j) = |shell_i - shell_j| +
//      circular sector difference (the paper's a_ij = e^(sigma d(i, j)) lost its sign or
//      fraction in print; with sigma "between 1 and 10", 5 in the paper, only d / sigma makes
//      A more than the identity: exp(-5 d) is below 0.7 % for any neighbour); dz = sum over types of d_t (equal weights); the smallest dz
//      wins (ties: the first in the random order);
//    * of the `verifyBest` nearest by histogram distance, the winner is the one whose copy has
//      the smallest share of conflicts plus the drift of the running count from the exemplar's
//      density times the area covered beyond `densityTolerance` expected neighbourhoods (an
//      extension: the paper leaves the density to the matching, which drifts to sparse or
//      dense neighbourhoods depending on the pattern);
//    * the winner's neighbours are copied at the same offsets from p, with their types and
//      exemplar index (sizes), where the spot is not covered yet, inside the target, and not
//      nearer than the minimum distance (minDistanceFactor x the exemplar's shortest
//      nearest-neighbour distance) to a placed element; an empty spot also gets the winner.
// 3. Tiles (tileM > 0): each tile grows on its own from its centre with its own stream; the
//    tiles are merged in order, an element nearer than the minimum distance to one of an
//    earlier tile being dropped.
// 4. On a terrain (sampleXu2015): elements on cells without a region, where the cluster map
//    makes their species impossible, or on a canopy trunk's exclusion disc are dropped; sizes
//    are the exemplar element's, except under a crown that is not taller than the copied
//    height: there drawSizes (the structured sampler's) draws a height below the crown and the
//    radius by allometry.
//
// Determinism: random numbers are Philox keyed by (seed, tile, extension); a tile's growth is
// serial; tiles are merged in a fixed order. Bit-identical for any thread count.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <memory>
#include <numeric>
#include <queue>

#include <omp.h>

#include "canopy_context.h"
#include "error.h"
#include "rng.h"
#include "sampling_detail.h"
#include "text_format.h"
#include "undergrowth.h"

namespace eco::synth {

using namespace detail;

namespace {

constexpr std::uint64_t kXuStream = 0x5855323031354752ull;    // "XU2015GR"
constexpr std::uint64_t kSpotStream = 0x5855323031355350ull;   // "XU2015SP"
constexpr std::uint64_t kXuSizeStream = 0x585532303135535aull;  // "XU2015SZ"
/// Adjacency weights below this are left out of the histogram distance.
constexpr double kAdjacencyCut = 1e-6;

using Clock = std::chrono::steady_clock;

/// Points in square buckets over a rectangle (points outside are clamped into edge buckets).
struct Buckets {
    double ox = 0, oy = 0, inv = 1;
    int nx = 1, ny = 1;
    std::vector<std::int32_t> head, next;
    std::vector<double> xs, ys;
    Buckets(const RectWindow& w, double cellM) : ox(w.x0), oy(w.y0), inv(1.0 / cellM) {
        nx = std::max(1, static_cast<int>(std::ceil(w.widthM() * inv)));
        ny = std::max(1, static_cast<int>(std::ceil(w.heightM() * inv)));
        head.assign(static_cast<std::size_t>(nx) * static_cast<std::size_t>(ny), -1);
    }
    int bx(double x) const { return std::clamp(static_cast<int>(std::floor((x - ox) * inv)), 0, nx - 1); }
    int by(double y) const { return std::clamp(static_cast<int>(std::floor((y - oy) * inv)), 0, ny - 1); }
    void add(double x, double y) {
        const std::size_t b = static_cast<std::size_t>(by(y)) * static_cast<std::size_t>(nx) + static_cast<std::size_t>(bx(x));
        next.push_back(head[b]);
        head[b] = static_cast<std::int32_t>(xs.size());
        xs.push_back(x);
        ys.push_back(y);
    }
    /// f(index, dx, dy, d2) for every point with d2 < r^2, (dx, dy) = point - (x, y).
    template <typename F>
    void forEachWithin(double x, double y, double r, F&& f) const {
        const int x0 = bx(x - r), x1 = bx(x + r), y0 = by(y - r), y1 = by(y + r);
        const double r2 = r * r;
        for (int j = y0; j <= y1; ++j)
            for (int i = x0; i <= x1; ++i)
                for (std::int32_t p = head[static_cast<std::size_t>(j) * static_cast<std::size_t>(nx) + static_cast<std::size_t>(i)];
                     p >= 0; p = next[static_cast<std::size_t>(p)]) {
                    const double dx = xs[static_cast<std::size_t>(p)] - x, dy = ys[static_cast<std::size_t>(p)] - y;
                    const double d2 = dx * dx + dy * dy;
                    if (d2 < r2) f(static_cast<std::size_t>(p), dx, dy, d2);
                }
    }
    bool anyWithin(double x, double y, double r) const {
        const int x0 = bx(x - r), x1 = bx(x + r), y0 = by(y - r), y1 = by(y + r);
        const double r2 = r * r;
        for (int j = y0; j <= y1; ++j)
            for (int i = x0; i <= x1; ++i)
                for (std::int32_t p = head[static_cast<std::size_t>(j) * static_cast<std::size_t>(nx) + static_cast<std::size_t>(i)];
                     p >= 0; p = next[static_cast<std::size_t>(p)]) {
                    const double dx = xs[static_cast<std::size_t>(p)] - x, dy = ys[static_cast<std::size_t>(p)] - y;
                    if (dx * dx + dy * dy < r2) return true;
                }
        return false;
    }
};

/// The shells x sectors partition of a neighbourhood disc of radius R.
struct Partition {
    double radiusM = 1;
    int shells = 3, sectors = 8, bins = 24;
    std::vector<double> repDx, repDy;  ///< [bin] representative point (centre of the grid)
    /// [bin] the bins j with a_ij >= kAdjacencyCut and their weights (i itself first, a = 1).
    std::vector<std::vector<std::pair<int, double>>> stencil;

    Partition(double r, const XuParams& p) : radiusM(r), shells(p.shells), sectors(p.sectors), bins(p.shells * p.sectors) {
        repDx.resize(static_cast<std::size_t>(bins));
        repDy.resize(static_cast<std::size_t>(bins));
        stencil.resize(static_cast<std::size_t>(bins));
        for (int s = 0; s < shells; ++s)
            for (int k = 0; k < sectors; ++k) {
                const int b = s * sectors + k;
                const double rr = (s + 0.5) * r / shells, a = (k + 0.5) * 2.0 * M_PI / sectors;
                repDx[static_cast<std::size_t>(b)] = rr * std::cos(a);
                repDy[static_cast<std::size_t>(b)] = rr * std::sin(a);
                auto& st = stencil[static_cast<std::size_t>(b)];
                st.emplace_back(b, 1.0);
                for (int s2 = 0; s2 < shells; ++s2)
                    for (int k2 = 0; k2 < sectors; ++k2) {
                        const int b2 = s2 * sectors + k2;
                        if (b2 == b) continue;
                        const int dk = std::abs(k - k2);
                        const int d = std::abs(s - s2) + std::min(dk, sectors - dk);
                        const double w = p.sigma > 0 ? std::exp(-d / p.sigma) : 0.0;
                        if (w >= kAdjacencyCut) st.emplace_back(b2, w);
                    }
            }
    }
    /// Bin of an offset with d2 < R^2.
    int binOf(double dx, double dy, double d2) const {
        const int s = std::min(shells - 1, static_cast<int>(std::sqrt(d2) / radiusM * shells));
        double a = std::atan2(dy, dx);
        if (a < 0) a += 2.0 * M_PI;
        const int k = std::min(sectors - 1, static_cast<int>(a / (2.0 * M_PI) * sectors));
        return s * sectors + k;
    }
};

/// Neighbourhoods of a set of centres in the exemplar (step 1): its interior elements, or
/// interior locations drawn at random (the candidates of an empty spot).
struct Analysed {
    const PointPattern* pattern = nullptr;
    const RectWindow* window = nullptr;
    int nTypes = 1;
    std::vector<std::uint32_t> interior;  ///< exemplar index of each centre (kNoElement for a location)
    // Per centre c, CSR:
    std::vector<std::size_t> nbrStart;    ///< neighbours [nbrStart[c], nbrStart[c + 1])
    std::vector<double> nbrDx, nbrDy;
    std::vector<std::uint32_t> nbrIndex;  ///< exemplar index
    std::vector<std::size_t> histStart;   ///< histogram entries [histStart[c], histStart[c + 1])
    std::vector<std::uint32_t> histFlat;  ///< type x bins + bin, ascending
    std::vector<double> histCount;
};
constexpr std::uint32_t kNoElement = 0xffffffffu;

/// Neighbourhoods of the centres (cx, cy) (self: exemplar index of the centre, or kNoElement).
Analysed analyse(const PointPattern& ex, const PointGrid& grid, const Partition& part, const std::vector<double>& cx,
                 const std::vector<double>& cy, const std::vector<std::uint32_t>& self) {
    Analysed a;
    a.pattern = &ex;
    a.nTypes = std::max<int>(1, static_cast<int>(ex.typeNames.size()));
    const std::vector<std::uint32_t>& order = grid.order();
    a.nbrStart.push_back(0);
    a.histStart.push_back(0);
    std::vector<std::uint32_t> flat, nb;
    for (std::size_t c = 0; c < cx.size(); ++c) {
        a.interior.push_back(self[c]);
        flat.clear();
        nb.clear();
        grid.forEachWithin(cx[c], cy[c], part.radiusM, [&](std::size_t s, double, double, double) {
            if (order[s] != self[c]) nb.push_back(order[s]);
        });
        std::sort(nb.begin(), nb.end());  // a fixed order, whatever the grid's
        for (const std::uint32_t j : nb) {
            const double dx = ex.x[j] - cx[c], dy = ex.y[j] - cy[c];
            a.nbrDx.push_back(dx);
            a.nbrDy.push_back(dy);
            a.nbrIndex.push_back(j);
            flat.push_back(static_cast<std::uint32_t>(ex.type[j] * part.bins + part.binOf(dx, dy, dx * dx + dy * dy)));
        }
        a.nbrStart.push_back(a.nbrDx.size());
        std::sort(flat.begin(), flat.end());
        for (std::size_t k = 0; k < flat.size();) {
            std::size_t e = k;
            while (e < flat.size() && flat[e] == flat[k]) ++e;
            a.histFlat.push_back(flat[k]);
            a.histCount.push_back(static_cast<double>(e - k));
            k = e;
        }
        a.histStart.push_back(a.histFlat.size());
    }
    return a;
}

/// One tile's growth (step 2).
class Grower {
public:
    Grower(const Analysed& ex, const Analysed& spots, const Partition& part, const XuParams& params, const RectWindow& tile, double minDistanceM,
           std::uint64_t seed, std::uint64_t tileStream)
        : ex_(ex), spots_(spots), part_(part), params_(params), tile_(tile), dmin_(minDistanceM), seed_(seed), stream_(tileStream),
          elems_(tile, part.radiusM), extended_(tile, part.radiusM) {
        cx_ = 0.5 * (tile.x0 + tile.x1);
        cy_ = 0.5 * (tile.y0 + tile.y1);
        rasterCell_ = 0.25 * part.radiusM;
        rnx_ = std::max(1, static_cast<int>(std::ceil(tile.widthM() / rasterCell_)));
        rny_ = std::max(1, static_cast<int>(std::ceil(tile.heightM() / rasterCell_)));
        covered_.assign(static_cast<std::size_t>(rnx_) * static_cast<std::size_t>(rny_), 0);
        rasterOrder_.resize(covered_.size());
        std::iota(rasterOrder_.begin(), rasterOrder_.end(), 0u);
        std::vector<double> d2(covered_.size());
        for (std::size_t c = 0; c < covered_.size(); ++c) {
            const double dx = rasterX(c) - cx_, dy = rasterY(c) - cy_;
            d2[c] = dx * dx + dy * dy;
        }
        std::stable_sort(rasterOrder_.begin(), rasterOrder_.end(), [&](std::uint32_t a, std::uint32_t b) { return d2[a] < d2[b]; });
        delta_.assign(static_cast<std::size_t>(ex.nTypes) * static_cast<std::size_t>(part.bins), 0.0);
        tcount_.assign(delta_.size(), 0.0);
        ccount_.assign(delta_.size(), 0.0);
        seen_.assign(delta_.size(), 0);
        typeSum_.assign(static_cast<std::size_t>(ex.nTypes), 0.0);
        typeSeen_.assign(static_cast<std::size_t>(ex.nTypes), 0);
        det_.assign(static_cast<std::size_t>(part.bins), 0);
        const RectWindow& ew = *ex.window;
        density_ = static_cast<double>(ex.pattern->size()) / ew.areaM2();
        discCount_ = std::max(1.0, density_ * M_PI * part.radiusM * part.radiusM);
    }

    void run() {
        using Item = std::pair<double, std::uint32_t>;
        std::priority_queue<Item, std::vector<Item>, std::greater<Item>> heap;
        std::size_t before = 0;
        auto pushNew = [&]() {
            for (std::size_t i = before; i < x.size(); ++i) {
                const double dx = x[i] - cx_, dy = y[i] - cy_;
                heap.emplace(dx * dx + dy * dy, static_cast<std::uint32_t>(i));
            }
            before = x.size();
        };
        std::size_t ptr = 0;
        for (;;) {
            if (!heap.empty()) {
                const std::uint32_t e = heap.top().second;
                heap.pop();
                extend(x[e], y[e], static_cast<std::int64_t>(e));
            } else {
                while (ptr < rasterOrder_.size() && covered_[rasterOrder_[ptr]]) ++ptr;
                if (ptr == rasterOrder_.size()) break;
                const std::uint32_t c = rasterOrder_[ptr];
                ++holeSeeds;
                extend(rasterX(c), rasterY(c), -1);
            }
            pushNew();
        }
    }

    std::vector<double> x, y;
    std::vector<std::uint32_t> source;
    std::int64_t extensions = 0, holeSeeds = 0, conflicts = 0;

private:
    double rasterX(std::size_t c) const { return tile_.x0 + (static_cast<double>(c % static_cast<std::size_t>(rnx_)) + 0.5) * rasterCell_; }
    double rasterY(std::size_t c) const { return tile_.y0 + (static_cast<double>(c / static_cast<std::size_t>(rnx_)) + 0.5) * rasterCell_; }

    /// Area (m^2, on the raster) of the tile within R of (px, py) not covered yet.
    double uncoveredAreaWithin(double px, double py) const {
        const double R = part_.radiusM;
        const int ix0 = std::max(0, static_cast<int>(std::floor((px - R - tile_.x0) / rasterCell_)));
        const int ix1 = std::min(rnx_ - 1, static_cast<int>(std::floor((px + R - tile_.x0) / rasterCell_)));
        const int iy0 = std::max(0, static_cast<int>(std::floor((py - R - tile_.y0) / rasterCell_)));
        const int iy1 = std::min(rny_ - 1, static_cast<int>(std::floor((py + R - tile_.y0) / rasterCell_)));
        std::int64_t n = 0;
        for (int iy = iy0; iy <= iy1; ++iy)
            for (int ix = ix0; ix <= ix1; ++ix) {
                const std::size_t c = static_cast<std::size_t>(iy) * static_cast<std::size_t>(rnx_) + static_cast<std::size_t>(ix);
                const double dx = rasterX(c) - px, dy = rasterY(c) - py;
                if (dx * dx + dy * dy < R * R && !covered_[c]) ++n;
            }
        return static_cast<double>(n) * rasterCell_ * rasterCell_;
    }

    bool inTile(double px, double py) const { return px >= tile_.x0 && py >= tile_.y0 && px < tile_.x1 && py < tile_.y1; }

    bool place(double px, double py, std::uint32_t src) {
        if (!inTile(px, py)) return false;
        if (extended_.anyWithin(px, py, part_.radiusM)) return false;  // covered: already final
        if (elems_.anyWithin(px, py, dmin_)) {
            ++conflicts;
            return false;
        }
        elems_.add(px, py);
        x.push_back(px);
        y.push_back(py);
        source.push_back(src);
        return true;
    }

    /// Extend point (px, py): a placed element (self >= 0) or an empty spot (self = -1).
    void extend(double px, double py, std::int64_t self) {
        const double R = part_.radiusM;
        const int B = part_.bins;
        bool all = true, any = false;
        for (int b = 0; b < B; ++b) {
            const bool d = extended_.anyWithin(px + part_.repDx[static_cast<std::size_t>(b)], py + part_.repDy[static_cast<std::size_t>(b)], R);
            det_[static_cast<std::size_t>(b)] = d ? 1 : 0;
            all = all && d;
            any = any || d;
        }
        if (self >= 0 && all) return;  // its whole neighbourhood is final: nothing to add
        const std::uint64_t ext = static_cast<std::uint64_t>(extensions++);
        // The point's histogram over the determined grids.
        target_.clear();
        if (any)
            elems_.forEachWithin(px, py, R, [&](std::size_t i, double dx, double dy, double d2) {
                if (static_cast<std::int64_t>(i) == self) return;
                const int b = part_.binOf(dx, dy, d2);
                if (det_[static_cast<std::size_t>(b)])
                    target_.push_back(static_cast<std::uint32_t>(ex_.pattern->type[source[i]] * B + b));
            });
        // Candidates: a random subset of the interior elements (all when there are few).
        RandomStream rs(seed_, mixStream(stream_, ext), 0);
        // An element is matched with exemplar elements, an empty spot with exemplar locations.
        const Analysed& set = self >= 0 ? ex_ : spots_;
        const std::size_t M = set.interior.size();
        const std::size_t K = params_.candidates == 0 ? M : std::min<std::size_t>(M, static_cast<std::size_t>(params_.candidates));
        const std::size_t offset = rs.below(static_cast<std::uint32_t>(M));
        // The `verify` best by histogram distance (ascending, ties in draw order) ...
        const std::size_t verify = static_cast<std::size_t>(std::max(1, params_.verifyBest));
        top_.clear();
        for (std::size_t k = 0; k < K; ++k) {
            const std::size_t c = K == M ? (offset + k) % M : rs.below(static_cast<std::uint32_t>(M));
            const double d = any ? distance(set, c) : 0.0;
            if (top_.size() == verify && !(d < top_.back().first)) continue;
            auto at = std::upper_bound(top_.begin(), top_.end(), d, [](double v, const std::pair<double, std::size_t>& e) { return v < e.first; });
            top_.insert(at, {d, c});
            if (top_.size() > verify) top_.pop_back();
        }
        // ... of which the one with the best score wins: the share of its copies that conflict
        // with the elements placed (a share, not a count, which would favour copies of few
        // elements) plus how far beyond the tolerance its copies would leave the running count
        // from the exemplar's density times the area covered so far (in neighbourhoods).
        const double newArea = uncoveredAreaWithin(px, py);
        std::size_t best = top_.front().second;
        if (top_.size() > 1) {
            double bestScore = std::numeric_limits<double>::infinity();
            for (const auto& [d, c] : top_) {
                std::int64_t copies = 0, clashes = 0;
                for (std::size_t k = set.nbrStart[c]; k < set.nbrStart[c + 1]; ++k) {
                    const double qx = px + set.nbrDx[k], qy = py + set.nbrDy[k];
                    if (!inTile(qx, qy) || extended_.anyWithin(qx, qy, R)) continue;
                    ++copies;
                    if (elems_.anyWithin(qx, qy, dmin_)) ++clashes;
                }
                const double share = copies > 0 ? static_cast<double>(clashes) / static_cast<double>(copies) : 0.0;
                const double drift = deficit_ + density_ * newArea - static_cast<double>(copies - clashes);
                const double excess = std::abs(drift) - params_.densityTolerance * discCount_;
                const double score = share + (params_.densityTolerance > 0 && excess > 0 ? excess / discCount_ : 0.0);
                if (score < bestScore) {
                    bestScore = score;
                    best = c;
                }
            }
        }
        deficit_ += density_ * newArea;
        const std::size_t placedBefore = x.size();
        // Copy the winner's neighbourhood at the same offsets from the point.
        for (std::size_t k = set.nbrStart[best]; k < set.nbrStart[best + 1]; ++k)
            place(px + set.nbrDx[k], py + set.nbrDy[k], set.nbrIndex[k]);
        deficit_ -= static_cast<double>(x.size() - placedBefore);
        // The point's disc is final now.
        extended_.add(px, py);
        const int ix0 = std::max(0, static_cast<int>(std::floor((px - R - tile_.x0) / rasterCell_)));
        const int ix1 = std::min(rnx_ - 1, static_cast<int>(std::floor((px + R - tile_.x0) / rasterCell_)));
        const int iy0 = std::max(0, static_cast<int>(std::floor((py - R - tile_.y0) / rasterCell_)));
        const int iy1 = std::min(rny_ - 1, static_cast<int>(std::floor((py + R - tile_.y0) / rasterCell_)));
        for (int iy = iy0; iy <= iy1; ++iy)
            for (int ix = ix0; ix <= ix1; ++ix) {
                const std::size_t c = static_cast<std::size_t>(iy) * static_cast<std::size_t>(rnx_) + static_cast<std::size_t>(ix);
                const double dx = rasterX(c) - px, dy = rasterY(c) - py;
                if (dx * dx + dy * dy < R * R) covered_[c] = 1;
            }
    }

    /// dz between the point's determined histogram (target_) and interior element c's.
    double distance(const Analysed& set, std::size_t c) {
        const int B = part_.bins;
        touched_.clear();
        for (const std::uint32_t f : target_) {
            tcount_[f] += 1.0;
            if (!seen_[f]) {
                seen_[f] = 1;
                touched_.push_back(f);
            }
        }
        for (std::size_t k = set.histStart[c]; k < set.histStart[c + 1]; ++k) {
            const std::uint32_t f = set.histFlat[k];
            if (!det_[f % static_cast<std::uint32_t>(B)]) continue;
            ccount_[f] = set.histCount[k];
            if (!seen_[f]) {
                seen_[f] = 1;
                touched_.push_back(f);
            }
        }
        for (const std::uint32_t f : touched_)
            delta_[f] = tcount_[f] - ccount_[f];
        types_.clear();
        for (const std::uint32_t f : touched_) {
            const std::uint32_t t = f / static_cast<std::uint32_t>(B), b = f % static_cast<std::uint32_t>(B);
            const double* row = delta_.data() + static_cast<std::size_t>(t) * static_cast<std::size_t>(B);
            double q = 0;
            for (const auto& [j, a] : part_.stencil[b]) q += a * row[j];
            typeSum_[t] += delta_[f] * q;
            if (!typeSeen_[t]) {
                typeSeen_[t] = 1;
                types_.push_back(t);
            }
        }
        double dz = 0;
        for (const std::uint32_t t : types_) {
            dz += std::sqrt(std::max(0.0, typeSum_[t]));
            typeSum_[t] = 0;
            typeSeen_[t] = 0;
        }
        for (const std::uint32_t f : touched_) {
            delta_[f] = 0;
            tcount_[f] = 0;
            ccount_[f] = 0;
            seen_[f] = 0;
        }
        return dz;
    }

    const Analysed& ex_;
    const Analysed& spots_;  ///< candidates of an empty spot: exemplar locations
    const Partition& part_;
    const XuParams& params_;
    RectWindow tile_;
    double dmin_;
    std::uint64_t seed_, stream_;
    Buckets elems_, extended_;
    double cx_ = 0, cy_ = 0, rasterCell_ = 1;
    int rnx_ = 1, rny_ = 1;
    std::vector<std::uint8_t> covered_;
    std::vector<std::uint32_t> rasterOrder_;
    std::vector<double> delta_, tcount_, ccount_, typeSum_;
    std::vector<std::uint8_t> seen_, typeSeen_, det_;
    std::vector<std::uint32_t> target_, touched_, types_;
    std::vector<std::pair<double, std::size_t>> top_;
    double density_ = 0;    ///< the exemplar's density, per m^2
    double discCount_ = 1;  ///< its expected count in a neighbourhood disc (at least 1)
    double deficit_ = 0;    ///< density x area covered - elements placed so far
};

}  // namespace

XuPattern synthesizeXuPattern(const PointPattern& ex, const RectWindow& w, const RectWindow& target, const XuParams& params,
                              std::uint64_t seed, const std::string& what) {
    params.validate();
    w.validate(what + " window");
    target.validate("synthesis target");
    const std::size_t n = ex.size();
    if (n < 2) throw ValidationError(what + ": " + std::to_string(n) + " plants; the Xu 2015 sampler needs at least 2");
    if (ex.y.size() != n || ex.type.size() != n)
        throw ValidationError(what + ": the pattern's x, y and type arrays differ in length");
    const int nTypes = std::max<int>(1, static_cast<int>(ex.typeNames.size()));
    for (std::size_t i = 0; i < n; ++i) {
        if (!w.contains(ex.x[i], ex.y[i]))
            throw ValidationError(what + ": plant " + std::to_string(i) + " at (" + formatNumber(ex.x[i]) + ", " +
                                  formatNumber(ex.y[i]) + ") lies outside its window " + formatNumber(w.x0) + "," +
                                  formatNumber(w.y0) + "," + formatNumber(w.x1) + "," + formatNumber(w.y1));
        if (ex.type[i] < 0 || ex.type[i] >= nTypes)
            throw ValidationError(what + ": plant " + std::to_string(i) + " has type " + std::to_string(ex.type[i]) +
                                  " outside 0.." + std::to_string(nTypes - 1));
    }
    XuPattern out;
    const double density = static_cast<double>(n) / w.areaM2();
    out.radiusM = params.radiusFactor / std::sqrt(density);
    const std::vector<double> nn = nearestNeighbourDistances(ex.x, ex.y);
    out.minDistanceM = params.minDistanceFactor * *std::min_element(nn.begin(), nn.end());
    // Coincident copies are always refused, whatever the factor.
    const double dmin = std::max(out.minDistanceM, 1e-9 * out.radiusM);
    const Partition part(out.radiusM, params);
    const PointGrid grid(ex.x, ex.y, out.radiusM);
    std::vector<double> cx, cy;
    std::vector<std::uint32_t> self;
    for (std::size_t i = 0; i < n; ++i)
        if (w.distanceToEdgeM(ex.x[i], ex.y[i]) >= out.radiusM) {
            cx.push_back(ex.x[i]);
            cy.push_back(ex.y[i]);
            self.push_back(static_cast<std::uint32_t>(i));
        }
    Analysed a = analyse(ex, grid, part, cx, cy, self);
    a.window = &w;
    out.interiorCandidates = static_cast<std::int64_t>(a.interior.size());
    if (a.interior.empty())
        throw ValidationError(what + ": no plant lies at least the neighbourhood radius R = " + formatNumber(out.radiusM, 4) +
                              " m (xu_radius_factor " + formatNumber(params.radiusFactor) + " / sqrt(density " +
                              formatNumber(density, 4) + " per m2)) inside its window " + formatNumber(w.x0) + "," +
                              formatNumber(w.y0) + "," + formatNumber(w.x1) + "," + formatNumber(w.y1) +
                              ": the exemplar is too small for its density; give a larger stand or a smaller xu_radius_factor");

    // Empty spots are matched with as many uniform random locations of the interior.
    cx.clear();
    cy.clear();
    {
        RandomStream rs(seed, kSpotStream, 0);
        for (std::size_t i = 0; i < self.size(); ++i) {
            cx.push_back(rs.uniform(w.x0 + out.radiusM, w.x1 - out.radiusM));
            cy.push_back(rs.uniform(w.y0 + out.radiusM, w.y1 - out.radiusM));
        }
        std::fill(self.begin(), self.end(), kNoElement);
    }
    Analysed spots = analyse(ex, grid, part, cx, cy, self);
    spots.window = &w;

    // Tiles, row-major from the target's lower-left corner.
    std::vector<RectWindow> tiles;
    if (params.tileM > 0) {
        const int tx = std::max(1, static_cast<int>(std::ceil(target.widthM() / params.tileM - 1e-9)));
        const int ty = std::max(1, static_cast<int>(std::ceil(target.heightM() / params.tileM - 1e-9)));
        for (int j = 0; j < ty; ++j)
            for (int i = 0; i < tx; ++i)
                tiles.push_back(RectWindow{target.x0 + i * params.tileM, target.y0 + j * params.tileM,
                                           std::min(target.x1, target.x0 + (i + 1) * params.tileM),
                                           std::min(target.y1, target.y0 + (j + 1) * params.tileM)});
    } else {
        tiles.push_back(target);
    }
    std::vector<std::unique_ptr<Grower>> grown(tiles.size());
#pragma omp parallel for schedule(dynamic, 1)
    for (std::int64_t t = 0; t < static_cast<std::int64_t>(tiles.size()); ++t) {
        auto g = std::make_unique<Grower>(a, spots, part, params, tiles[static_cast<std::size_t>(t)], dmin, seed,
                                          mixStream(kXuStream, static_cast<std::uint64_t>(t)));
        g->run();
        grown[static_cast<std::size_t>(t)] = std::move(g);
    }
    // Merge in tile order; across a border the earlier tile's element wins.
    out.tiles = static_cast<int>(tiles.size());
    Buckets border(target, std::max(dmin, out.radiusM));
    for (std::size_t t = 0; t < tiles.size(); ++t) {
        const Grower& g = *grown[t];
        out.extensions += g.extensions;
        out.holeSeeds += g.holeSeeds;
        out.conflicts += g.conflicts;
        const RectWindow& tw = tiles[t];
        std::vector<std::uint8_t> nearEdge(g.x.size(), 0);
        for (std::size_t i = 0; i < g.x.size(); ++i) {
            nearEdge[i] = tiles.size() > 1 && tw.distanceToEdgeM(g.x[i], g.y[i]) < dmin ? 1 : 0;
            if (nearEdge[i] && border.anyWithin(g.x[i], g.y[i], dmin)) {
                ++out.seamDrops;
                nearEdge[i] = 2;
                continue;
            }
            out.x.push_back(g.x[i]);
            out.y.push_back(g.y[i]);
            out.source.push_back(g.source[i]);
        }
        for (std::size_t i = 0; i < g.x.size(); ++i)
            if (nearEdge[i] == 1) border.add(g.x[i], g.y[i]);
    }
    return out;
}

UndergrowthSample sampleXu2015(const BiomeDatabase& db, const Biome& biome, const std::vector<Plant>& canopy,
                               const ClusterMap& map, const Grid<float>& terrainM, const SynthParams& params,
                               const XuExemplar& exemplar) {
    const auto t0 = Clock::now();
    UndergrowthSample out;
    auto mark = t0;
    auto phase = [&](const char* name) {
        const auto now = Clock::now();
        out.phases.push_back(UndergrowthSample::Phase{name, std::chrono::duration<double>(now - mark).count(), 0});
        mark = now;
    };
    const std::size_t nS = biome.species.size(), nR = db.regions.size();
    PointPattern ex;
    for (const auto& s : biome.species) ex.typeNames.push_back(s.name);
    for (const Plant& p : exemplar.plants) {
        if (p.speciesId < 0 || static_cast<std::size_t>(p.speciesId) >= nS)
            throw ValidationError(exemplar.source + ": species id " + std::to_string(p.speciesId) + " outside the biome");
        ex.x.push_back(p.xM);
        ex.y.push_back(p.yM);
        ex.type.push_back(p.speciesId);
    }
    const RectWindow target{terrainM.originX(), terrainM.originY(), terrainM.originX() + terrainM.extentX(),
                            terrainM.originY() + terrainM.extentY()};
    out.xu = synthesizeXuPattern(ex, exemplar.window, target, params.xu, params.seed, exemplar.source);
    phase("growth");

    // Cluster map and trunks (step 4).
    const std::vector<int> subMask = speciesSubBiomeMasks(biome);
    const TrunkIndex trunks(canopy, params.trunkExclusionFactor);
    const CanopyCover cover(canopy);
    const std::size_t n = out.xu.x.size();
    // 0 keep with the exemplar's size, 1 size drawn below the crown, 2 no region, 3 on a trunk.
    std::vector<std::uint8_t> fate(n, 0);
    std::vector<std::uint32_t> cellOf(n, 0);
#pragma omp parallel for schedule(static)
    for (std::int64_t ii = 0; ii < static_cast<std::int64_t>(n); ++ii) {
        const std::size_t i = static_cast<std::size_t>(ii);
        const double px = out.xu.x[i], py = out.xu.y[i];
        const Plant& src = exemplar.plants[out.xu.source[i]];
        const int ix = std::clamp(terrainM.cellX(px), 0, terrainM.width() - 1);
        const int iy = std::clamp(terrainM.cellY(py), 0, terrainM.height() - 1);
        const std::size_t cell = terrainM.index(ix, iy);
        cellOf[i] = static_cast<std::uint32_t>(cell);
        const int r = map.region.data()[cell];
        if (r < 0 || static_cast<std::size_t>(r) >= nR || !(map.seedWeight.data()[cell] > 0) ||
            (subMask[static_cast<std::size_t>(src.speciesId)] & map.combination.data()[cell]) == 0) {
            fate[i] = 2;
            continue;
        }
        if (trunks.onTrunk(px, py)) {
            fate[i] = 3;
            continue;
        }
        fate[i] = src.heightM < cover.lowestCrownAboveM(px, py) ? 0 : 1;
    }
    std::vector<Candidate> redraw;
    std::vector<std::size_t> redrawAt;
    for (std::size_t i = 0; i < n; ++i) {
        if (fate[i] == 2) ++out.xuDroppedOutsideRegion;
        if (fate[i] == 3) ++out.xuDroppedOnTrunk;
        if (fate[i] >= 2) continue;
        const Plant& src = exemplar.plants[out.xu.source[i]];
        Plant p;
        p.speciesId = src.speciesId;
        p.xM = out.xu.x[i];
        p.yM = out.xu.y[i];
        p.groundZM = terrainM.sampleBilinear(p.xM, p.yM);
        p.heightM = src.heightM;
        p.crownRadiusM = src.crownRadiusM;
        if (fate[i] == 1) {
            redrawAt.push_back(out.plants.size());
            redraw.push_back(Candidate{mixStream(kXuSizeStream, static_cast<std::uint64_t>(i)),
                                       static_cast<float>(p.xM - terrainM.originX()), static_cast<float>(p.yM - terrainM.originY()),
                                       cellOf[i], static_cast<std::uint16_t>(p.speciesId), 0});
        }
        out.plants.push_back(p);
        out.plantRegion.push_back(map.region.data()[cellOf[i]]);
    }
    // Copied heights that reach the crown above: drawn below it as the structured sampler does.
    UndergrowthSample drawn;
    drawSizes(db, biome, canopy, map, terrainM, params, db.hasContext(), redraw, drawn);
    for (std::size_t k = 0; k < redraw.size(); ++k) {
        Plant& p = out.plants[redrawAt[k]];
        p.heightM = drawn.plants[k].heightM;
        p.crownRadiusM = drawn.plants[k].crownRadiusM;
    }
    out.heightsLimitedByCrown = static_cast<std::int64_t>(redraw.size());
    out.darts = static_cast<std::int64_t>(n);
    out.dartsOnTrunks = out.xuDroppedOnTrunk;
    out.dartsInhibited = out.xu.conflicts;
    out.xu.x.clear();
    out.xu.y.clear();
    out.xu.source.clear();
    phase("canopy, cluster map and sizes");

    // Regions: cells and plants placed (the target count is the exemplar's density there).
    const double cellArea = terrainM.cellSizeM() * terrainM.cellSizeM();
    const double exDensity = static_cast<double>(exemplar.plants.size()) / exemplar.window.areaM2();
    out.regions.resize(nR);
    for (std::size_t r = 0; r < nR; ++r) out.regions[r].region = static_cast<int>(r);
    for (const std::int32_t r : map.region.data())
        if (r >= 0 && static_cast<std::size_t>(r) < nR) ++out.regions[static_cast<std::size_t>(r)].cells;
    for (auto& rs : out.regions) {
        rs.areaM2 = static_cast<double>(rs.cells) * cellArea;
        rs.targetDensityPerM2 = exDensity;
        rs.targetCount = std::llround(exDensity * rs.areaM2);
    }
    for (const std::int32_t r : out.plantRegion)
        if (r >= 0 && static_cast<std::size_t>(r) < nR) ++out.regions[static_cast<std::size_t>(r)].placed;
    out.passes = 1;
    out.seconds = std::chrono::duration<double>(Clock::now() - t0).count();
    return out;
}

}  // namespace eco::synth
