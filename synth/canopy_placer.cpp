#include "canopy_placer.h"

#include <omp.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <limits>
#include <numeric>
#include <type_traits>
#include <utility>
#include <sstream>
#include <cstdio>
#include <cstdlib>
#include <map>
#include <mutex>
#include <new>
#include <unordered_map>

#ifdef __SSE2__
#include <emmintrin.h>
#endif

#if defined(__linux__)
#include <sys/mman.h>
#endif

#include "error.h"
#include "h5io.h"
#include "chart.h"
#include "image_out.h"
#include "memory.h"
#include "rng.h"
#include "strict_toml.h"
#include "text_format.h"

namespace eco::synth {

namespace {

/// Blocks of the placer's large buffers: 2 MiB-aligned, marked for transparent huge pages
/// (madvise; Linux, when the kernel's THP mode is "madvise" or "always"). During a placement
/// (a HugeBlockScope) a freed block is kept and handed to a later buffer that fits in it, so
/// that the iterations reuse memory already mapped rather than fault and zero fresh pages.
/// At 3072^2 cells a placement touched about 500 MB of fresh memory in 4 KiB pages: 127k
/// page faults and about a quarter of its CPU time on this VM. Only where memory comes
/// from changes, never a result.
class HugeBlocks {
public:
    static constexpr std::size_t kHuge = std::size_t{2} << 20;
    /// Smaller buffers come from operator new: at 1024^2 (buffers of 1-6 MB) the heap often
    /// hands back memory already mapped by earlier work (bench_canopy: the abiotics), which
    /// fresh huge blocks would have to fault and zero (0.80 -> 0.93-1.00 s CPU there).
    static constexpr std::size_t kMinBytes = std::size_t{8} << 20;
    static constexpr std::size_t kMaxSpare = std::size_t{4} << 30;  ///< kept blocks at most (bytes)
    static HugeBlocks& instance() {
        static HugeBlocks blocks;
        return blocks;
    }
    void* take(std::size_t bytes) {
        const std::size_t rounded = (bytes + kHuge - 1) / kHuge * kHuge;
        {
            std::lock_guard<std::mutex> lock(mutex_);
            const auto it = spare_.lower_bound(rounded);  // the smallest kept block that fits
            if (it != spare_.end()) {
                void* p = it->second;
                live_[p] = it->first;
                spareBytes_ -= it->first;
                spare_.erase(it);
                return p;
            }
        }
        void* p = std::aligned_alloc(kHuge, rounded);
        if (p == nullptr) throw std::bad_alloc();
#ifdef MADV_HUGEPAGE
        madvise(p, rounded, MADV_HUGEPAGE);  // advice only: a refusal changes nothing
#endif
        std::lock_guard<std::mutex> lock(mutex_);
        live_[p] = rounded;
        return p;
    }
    void give(void* p) noexcept {
        {
            std::lock_guard<std::mutex> lock(mutex_);
            const auto it = live_.find(p);
            const std::size_t size = it->second;
            live_.erase(it);
            if (scopes_ > 0 && spareBytes_ + size <= kMaxSpare) {
                spare_.emplace(size, p);
                spareBytes_ += size;
                return;
            }
        }
        std::free(p);
    }
    void enter() {
        std::lock_guard<std::mutex> lock(mutex_);
        ++scopes_;
    }
    void leave() noexcept {
        std::multimap<std::size_t, void*> release;
        {
            std::lock_guard<std::mutex> lock(mutex_);
            if (--scopes_ > 0) return;
            release.swap(spare_);
            spareBytes_ = 0;
        }
        for (const auto& b : release) std::free(b.second);
    }

private:
    std::mutex mutex_;
    int scopes_ = 0;
    std::unordered_map<void*, std::size_t> live_;  ///< blocks in use and their sizes
    std::multimap<std::size_t, void*> spare_;      ///< freed blocks kept for reuse, by size
    std::size_t spareBytes_ = 0;
};

/// Freed huge blocks are kept for reuse while a scope is open (one placement).
struct HugeBlockScope {
    HugeBlockScope() { HugeBlocks::instance().enter(); }
    ~HugeBlockScope() { HugeBlocks::instance().leave(); }
    HugeBlockScope(const HugeBlockScope&) = delete;
    HugeBlockScope& operator=(const HugeBlockScope&) = delete;
};

/// Allocator of the placer's large buffers (render and visibility grids, tree lists, point
/// grids, the greedy acceptance's arrays): HugeBlocks from kMinBytes up, operator new below.
/// Elements made without a value are default-initialised (left unwritten for plain types):
/// every such buffer is filled before it is read, the big ones in parallel loops, which
/// then take the first-touch page faults on all threads instead of a serial memset.
template <typename T>
struct HugePageAllocator {
    using value_type = T;
    HugePageAllocator() = default;
    template <typename U>
    HugePageAllocator(const HugePageAllocator<U>&) noexcept {}
    template <typename U>
    struct rebind {
        using other = HugePageAllocator<U>;
    };
    template <typename U>
    void construct(U* p) noexcept(std::is_nothrow_default_constructible<U>::value) {
        ::new (static_cast<void*>(p)) U;
    }
    template <typename U, typename... Args>
    void construct(U* p, Args&&... args) {
        ::new (static_cast<void*>(p)) U(std::forward<Args>(args)...);
    }
    T* allocate(std::size_t n) {
        const std::size_t bytes = n * sizeof(T);
        if (bytes < HugeBlocks::kMinBytes) return static_cast<T*>(::operator new(bytes));
        return static_cast<T*>(HugeBlocks::instance().take(bytes));
    }
    void deallocate(T* p, std::size_t n) noexcept {
        if (n * sizeof(T) < HugeBlocks::kMinBytes) ::operator delete(p);
        else HugeBlocks::instance().give(p);
    }
    template <typename U>
    bool operator==(const HugePageAllocator<U>&) const noexcept { return true; }
    template <typename U>
    bool operator!=(const HugePageAllocator<U>&) const noexcept { return false; }
};
template <typename T>
using Buf = std::vector<T, HugePageAllocator<T>>;

constexpr double kTwoPi = 6.283185307179586;
constexpr std::uint64_t kStreamRing = 0x63616e6f70790001ull;  // ring sampling, per (iteration, tree id)
/// Rows per render band: small enough to balance two to a few dozen threads, large enough
/// that a crown rarely spans many bands. Only performance depends on it, never results.
constexpr int kBandRows = 16;
/// Light per-item loops (a copy, a bound) run in parallel only from this many items: below,
/// the fork and the barrier cost more than the loop, and on a loaded machine a thread that
/// waits at a barrier spins on CPU time (bench_canopy 1024^2: 0.81 -> 0.88-1.02 s CPU).
constexpr std::size_t kParallelItems = std::size_t{1} << 18;

std::string num(double v) { return formatNumber(v, 6); }

using Clock = std::chrono::steady_clock;
double secondsSince(Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); }

/// Whether cell (ix, iy), in the set (inSet(index)), is a strict maximum of the CHM over the
/// (2R + 1)^2 window among the cells of the set (the others do not compete); on a plateau
/// the cell of lowest index wins.
template <typename InSet>
inline bool strictMaximumIn(const Grid<float>& chm, int ix, int iy, int R, InSet&& inSet) {
    const int w = chm.width(), h = chm.height();
    const float v = chm(ix, iy);
    const std::size_t i = chm.index(ix, iy);
    for (int jy = std::max(0, iy - R); jy <= std::min(h - 1, iy + R); ++jy)
        for (int jx = std::max(0, ix - R); jx <= std::min(w - 1, ix + R); ++jx) {
            const float u = chm(jx, jy);
            const std::size_t j = chm.index(jx, jy);
            if (j == i || !inSet(j)) continue;
            if (u > v || (u == v && j < i)) return false;
        }
    return true;
}

/// Strict maxima of the CHM >= minHeightM over a (2R + 1)^2 window among the cells for which
/// inSet(index) holds (cells outside the set neither are maxima nor compete); a plateau goes
/// to its cell of lowest index. Cell indices in row order.
template <typename InSet>
Buf<std::size_t> localMaxima(const Grid<float>& chm, double minHeightM, int radiusCells, InSet&& inSet) {
    const int w = chm.width(), h = chm.height(), R = std::max(1, radiusCells);
    Buf<Buf<std::size_t>> rows(static_cast<std::size_t>(h));
#pragma omp parallel for schedule(dynamic, 16)
    for (int iy = 0; iy < h; ++iy) {
        for (int ix = 0; ix < w; ++ix) {
            const float v = chm(ix, iy);
            if (!(v >= minHeightM)) continue;
            const std::size_t i = chm.index(ix, iy);
            if (!inSet(i)) continue;
            if (strictMaximumIn(chm, ix, iy, R, inSet)) rows[static_cast<std::size_t>(iy)].push_back(i);
        }
    }
    Buf<std::size_t> out;
    for (const auto& r : rows) out.insert(out.end(), r.begin(), r.end());
    return out;
}

// ------------------------------------------------------------------------- rendering

/// A crown to render: trunk (x, y), apex height h, radius r (metres).
struct Crown {
    double x, y, h, r;
};

/// Depth and id buffers plus, per crown, the number of cells of its disc.
struct Frame {
    Buf<float> depth;        ///< crown surface above ground; lowest() where uncovered
    Buf<std::int32_t> id;    ///< top crown, -1 where none
    Buf<std::int32_t> disc;  ///< per crown: cells whose centre lies inside its disc
    Buf<Crown> crowns;       ///< the crowns rendered (kept as a buffer between renders)
    Buf<float> depth2;       ///< render<true> only: the second-highest crown surface, lowest() where none
};

/// Rows [y0, y1] whose cell centres can lie inside the crown's disc (y0 > y1: none).
inline void crownRows(const Crown& c, double originY, double cell, int height, int& y0, int& y1) {
    y0 = std::max(0, static_cast<int>(std::floor((c.y - c.r - originY) / cell - 0.5)));
    y1 = std::min(height - 1, static_cast<int>(std::ceil((c.y + c.r - originY) / cell - 0.5)));
}

/// Render crowns top-down. Each band of kBandRows rows is written by one thread, its crowns
/// visited in index order with a strict depth test, so a tie goes to the lower index and
/// the buffers do not depend on the number of threads.
template <bool Second = false>
void render(const Buf<Crown>& crowns, int w, int h, double cell, double ox, double oy, Frame& f) {
    const std::size_t nCells = static_cast<std::size_t>(w) * static_cast<std::size_t>(h);
    // Cleared band by band in the parallel loop below (two grids of 4 bytes a cell: on one
    // thread their fill was a serial part of every render).
    f.depth.resize(nCells);
    f.id.resize(nCells);
    if constexpr (Second) f.depth2.resize(nCells);
    f.disc.assign(crowns.size(), 0);
    const int nBands = (h + kBandRows - 1) / kBandRows;
    // Bucket crowns by band (counting sort keeps index order inside a band).
    Buf<std::size_t> start(static_cast<std::size_t>(nBands) + 1, 0);
    Buf<int> rowLo(crowns.size()), rowHi(crowns.size());
#pragma omp parallel for schedule(static) if (crowns.size() >= kParallelItems)
    for (std::ptrdiff_t t = 0; t < static_cast<std::ptrdiff_t>(crowns.size()); ++t) {
        const std::size_t k = static_cast<std::size_t>(t);
        crownRows(crowns[k], oy, cell, h, rowLo[k], rowHi[k]);
        if (!(crowns[k].r > 0)) rowHi[k] = rowLo[k] - 1;  // no disc: in no band
    }
    for (std::size_t t = 0; t < crowns.size(); ++t) {
        if (rowLo[t] > rowHi[t]) continue;
        for (int b = rowLo[t] / kBandRows; b <= rowHi[t] / kBandRows; ++b) ++start[static_cast<std::size_t>(b) + 1];
    }
    for (int b = 0; b < nBands; ++b) start[static_cast<std::size_t>(b) + 1] += start[static_cast<std::size_t>(b)];
    Buf<std::int32_t> entries(start.back());
    Buf<std::int32_t> entryDisc(start.back(), 0);
    {
        Buf<std::size_t> fill(start.begin(), start.end() - 1);
        for (std::size_t t = 0; t < crowns.size(); ++t) {
            if (rowLo[t] > rowHi[t]) continue;
            for (int b = rowLo[t] / kBandRows; b <= rowHi[t] / kBandRows; ++b)
                entries[fill[static_cast<std::size_t>(b)]++] = static_cast<std::int32_t>(t);
        }
    }
#pragma omp parallel for schedule(dynamic, 1)
    for (int b = 0; b < nBands; ++b) {
        const int bandLo = b * kBandRows, bandHi = std::min(h, bandLo + kBandRows) - 1;
        {
            const std::size_t lo = static_cast<std::size_t>(bandLo) * static_cast<std::size_t>(w);
            const std::size_t hi = static_cast<std::size_t>(bandHi + 1) * static_cast<std::size_t>(w);
            std::fill(f.depth.begin() + static_cast<std::ptrdiff_t>(lo), f.depth.begin() + static_cast<std::ptrdiff_t>(hi),
                      std::numeric_limits<float>::lowest());
            std::fill(f.id.begin() + static_cast<std::ptrdiff_t>(lo), f.id.begin() + static_cast<std::ptrdiff_t>(hi), -1);
            if constexpr (Second)
                std::fill(f.depth2.begin() + static_cast<std::ptrdiff_t>(lo), f.depth2.begin() + static_cast<std::ptrdiff_t>(hi),
                          std::numeric_limits<float>::lowest());
        }
        const std::size_t eEnd = start[static_cast<std::size_t>(b) + 1];
        for (std::size_t e = start[static_cast<std::size_t>(b)]; e < eEnd; ++e) {
            // The crowns of a band come in index order, spread over the whole list once
            // iterations have appended trees: fetch a few entries ahead (at 3072^2 the load
            // of the crown was a quarter of the render's time, waiting on memory).
            constexpr std::size_t kAhead = 8;
            if (e + kAhead < eEnd) {
                const std::size_t ahead = static_cast<std::size_t>(entries[e + kAhead]);
                __builtin_prefetch(&crowns[ahead]);
                __builtin_prefetch(&rowLo[ahead]);
                __builtin_prefetch(&rowHi[ahead]);
            }
            const std::int32_t t = entries[e];
            const Crown& c = crowns[static_cast<std::size_t>(t)];
            const double r2 = c.r * c.r, base = c.h - c.r;
            std::int32_t count = 0;
            const int yA = std::max(bandLo, rowLo[static_cast<std::size_t>(t)]);
            const int yB = std::min(bandHi, rowHi[static_cast<std::size_t>(t)]);
            for (int iy = yA; iy <= yB; ++iy) {
                const double dy = oy + (iy + 0.5) * cell - c.y;
                const double rem = r2 - dy * dy;
                if (!(rem > 0)) continue;
                const double hw = std::sqrt(rem);
                const int xA = std::max(0, static_cast<int>(std::ceil((c.x - hw - ox) / cell - 0.5)));
                const int xB = std::min(w - 1, static_cast<int>(std::floor((c.x + hw - ox) / cell - 0.5)));
                if (xA > xB) continue;
                float* depthRow = f.depth.data() + static_cast<std::size_t>(iy) * static_cast<std::size_t>(w);
                std::int32_t* idRow = f.id.data() + static_cast<std::size_t>(iy) * static_cast<std::size_t>(w);
                float* secondRow = Second ? f.depth2.data() + static_cast<std::size_t>(iy) * static_cast<std::size_t>(w) : nullptr;
                // Single precision inside the span (offsets of a few metres), written as
                // branch-free selects so that the loop vectorises.
                const float r2f = static_cast<float>(r2), dy2 = static_cast<float>(dy * dy);
                const float basef = static_cast<float>(base), cellf = static_cast<float>(cell);
                const float dx0 = static_cast<float>(ox + (xA + 0.5) * cell - c.x);
                std::int32_t n = 0;
                for (int ix = xA; ix <= xB; ++ix) {
                    const float dx = dx0 + static_cast<float>(ix - xA) * cellf;
                    const float d2 = dx * dx + dy2;
                    const bool in = d2 < r2f;
                    const float z = basef + std::sqrt(std::max(r2f - d2, 0.0f));
                    const bool top = in & (z > depthRow[ix]);
                    n += static_cast<std::int32_t>(in);
                    if constexpr (Second) {
                        // The second surface: the lower of the new crown and the old top.
                        const float zIn = in ? z : std::numeric_limits<float>::lowest();
                        secondRow[ix] = std::max(secondRow[ix], std::min(zIn, depthRow[ix]));
                    }
                    depthRow[ix] = top ? z : depthRow[ix];
                    idRow[ix] = top ? t : idRow[ix];
                }
                count += n;
            }
            entryDisc[e] = count;
        }
    }
    for (std::size_t e = 0; e < entries.size(); ++e) f.disc[static_cast<std::size_t>(entries[e])] += entryDisc[e];
}

/// What a render says about the CHM footprint and each crown's visible part of it.
struct Visibility {
    Buf<std::int64_t> visible;  ///< footprint cells where the crown is on top
    Buf<std::int64_t> sumX;     ///< sum of their column indices
    Buf<std::int64_t> sumY;     ///< sum of their row indices
    Buf<std::uint8_t> open;     ///< per cell: on the footprint and uncovered
    /// per cell: on the footprint and uncovered, or above the crown surface by more than the
    /// tolerance (no crown explains it)
    Buf<std::uint8_t> unexplained;
    std::int64_t footprint = 0;
    std::int64_t covered = 0;
    double sumSquaredErrorM2 = 0;
};

void measure(const Frame& f, const Grid<float>& chm, double thresholdM, double toleranceM, std::size_t nCrowns,
             Visibility& v) {
    const int w = chm.width(), h = chm.height();
    v.visible.assign(nCrowns, 0);
    v.sumX.assign(nCrowns, 0);
    v.sumY.assign(nCrowns, 0);
    v.open.resize(chm.size());
    v.unexplained.resize(chm.size());
    const float tol = static_cast<float>(toleranceM);
    std::vector<std::int64_t> rowFoot(static_cast<std::size_t>(h), 0), rowCovered(static_cast<std::size_t>(h), 0);
    std::vector<double> rowSq(static_cast<std::size_t>(h), 0.0);
    std::int64_t* visible = v.visible.data();
    std::int64_t* sumX = v.sumX.data();
    std::int64_t* sumY = v.sumY.data();
#pragma omp parallel for schedule(static)
    for (int iy = 0; iy < h; ++iy) {
        const std::size_t row = static_cast<std::size_t>(iy) * static_cast<std::size_t>(w);
        std::int64_t foot = 0, covered = 0;
        double sq = 0;
        // Runs of one id along the row are summed locally and flushed once (integer sums:
        // the totals do not depend on the order of the atomic additions).
        std::int32_t runId = -1;
        std::int64_t runN = 0, runX = 0;
        auto flush = [&] {
            if (runId >= 0 && runN > 0) {
#pragma omp atomic
                visible[runId] += runN;
#pragma omp atomic
                sumX[runId] += runX;
#pragma omp atomic
                sumY[runId] += runN * iy;
            }
            runN = 0;
            runX = 0;
        };
        for (int ix = 0; ix < w; ++ix) {
            const std::size_t i = row + static_cast<std::size_t>(ix);
            const float c = chm.data()[i];
            const std::int32_t id = f.id[i];
            v.open[i] = c >= thresholdM && id < 0;
            v.unexplained[i] = c >= thresholdM && (id < 0 || c > f.depth[i] + tol);
            if (!(c >= thresholdM)) continue;
            ++foot;
            const double rendered = id >= 0 ? static_cast<double>(f.depth[i]) : 0.0;
            sq += (rendered - c) * (rendered - c);
            if (id < 0) continue;
            ++covered;
            if (id != runId) {
                flush();
                runId = id;
            }
            ++runN;
            runX += ix;
        }
        flush();
        rowFoot[static_cast<std::size_t>(iy)] = foot;
        rowCovered[static_cast<std::size_t>(iy)] = covered;
        rowSq[static_cast<std::size_t>(iy)] = sq;
    }
    v.footprint = v.covered = 0;
    v.sumSquaredErrorM2 = 0;
    for (int iy = 0; iy < h; ++iy) {  // fixed order: the double sum is thread-independent
        v.footprint += rowFoot[static_cast<std::size_t>(iy)];
        v.covered += rowCovered[static_cast<std::size_t>(iy)];
        v.sumSquaredErrorM2 += rowSq[static_cast<std::size_t>(iy)];
    }
}

// ------------------------------------------------------------------------- spatial hashing

/// Uniform grid of point indices, built once by a counting sort (compressed rows: one index
/// array, one offset per bucket; no allocation per bucket or query). A uniform grid rather
/// than FLANN: crowns have a bounded radius, so a radius query touches 3 x 3 buckets, and
/// results come in index order (deterministic).
class PointGrid {
public:
    /// A point as stored, in bucket order beside its id: the queries read these packed
    /// copies rather than the caller's array (at 3072^2 cells, 700k trees, reading the trees
    /// at random was most of the ring's time: cache misses).
    struct Point {
        double x, y, r, h;
    };
    /// Points 0..n-1 at (xOf(i), yOf(i)); buckets of at least bucketM metres over the extent.
    template <typename XOf, typename YOf>
    PointGrid(double originX, double originY, double extentX, double extentY, double bucketM, std::size_t n, XOf&& xOf,
              YOf&& yOf)
        : PointGrid(originX, originY, extentX, extentY, bucketM, n, xOf, yOf, [](std::size_t) { return 0.0; }) {}
    /// Same, each point with a radius rOf(i) (Point::r).
    template <typename XOf, typename YOf, typename ROf>
    PointGrid(double originX, double originY, double extentX, double extentY, double bucketM, std::size_t n, XOf&& xOf,
              YOf&& yOf, ROf&& rOf)
        : PointGrid(originX, originY, extentX, extentY, bucketM, n, xOf, yOf, rOf, [](std::size_t) { return 0.0; }) {}
    /// Same, each point with a radius rOf(i) and a height hOf(i) (Point::r, Point::h).
    template <typename XOf, typename YOf, typename ROf, typename HOf>
    PointGrid(double originX, double originY, double extentX, double extentY, double bucketM, std::size_t n, XOf&& xOf,
              YOf&& yOf, ROf&& rOf, HOf&& hOf)
        : ox_(originX), oy_(originY), s_(std::max(bucketM, std::max(extentX, extentY) / 4096.0)) {
        nx_ = std::max(1, static_cast<int>(std::ceil(extentX / s_)) + 1);
        ny_ = std::max(1, static_cast<int>(std::ceil(extentY / s_)) + 1);
        start_.assign(static_cast<std::size_t>(nx_) * static_cast<std::size_t>(ny_) + 1, 0);
        Buf<std::uint32_t> bucket(n);
#pragma omp parallel for schedule(static)
        for (std::ptrdiff_t i = 0; i < static_cast<std::ptrdiff_t>(n); ++i)
            bucket[static_cast<std::size_t>(i)] = static_cast<std::uint32_t>(bucketOf(xOf(static_cast<std::size_t>(i)), yOf(static_cast<std::size_t>(i))));
        for (std::size_t i = 0; i < n; ++i) ++start_[bucket[i] + 1];
        for (std::size_t b = 1; b < start_.size(); ++b) start_[b] += start_[b - 1];
        ids_.resize(n);
        {
            Buf<std::uint32_t> fill(start_.begin(), start_.end() - 1);
            for (std::size_t i = 0; i < n; ++i) ids_[fill[bucket[i]]++] = static_cast<std::int32_t>(i);
        }
        points_.resize(n);
#pragma omp parallel for schedule(static) if (n >= kParallelItems)
        for (std::ptrdiff_t e = 0; e < static_cast<std::ptrdiff_t>(n); ++e) {
            const std::size_t i = static_cast<std::size_t>(ids_[static_cast<std::size_t>(e)]);
            points_[static_cast<std::size_t>(e)] = {xOf(i), yOf(i), rOf(i), hOf(i)};
        }
    }
    /// The point ids in bucket order (rows of buckets south to north, west to east, index
    /// order inside a bucket): a spatially coherent order of all points.
    const Buf<std::int32_t>& bucketOrder() const { return ids_; }
    /// Calls fn(id, point) for every point whose bucket lies within `radius` of (x, y), in
    /// index order per bucket; stops early when fn returns true (and then returns true).
    template <typename Fn>
    bool anyPoint(double x, double y, double radius, Fn&& fn) const {
        const int bx0 = clampX(static_cast<int>(std::floor((x - radius - ox_) / s_)));
        const int bx1 = clampX(static_cast<int>(std::floor((x + radius - ox_) / s_)));
        const int by0 = clampY(static_cast<int>(std::floor((y - radius - oy_) / s_)));
        const int by1 = clampY(static_cast<int>(std::floor((y + radius - oy_) / s_)));
        for (int by = by0; by <= by1; ++by) {
            const std::size_t row = static_cast<std::size_t>(by) * static_cast<std::size_t>(nx_);
            // The buckets bx0..bx1 of a row are contiguous in the arrays.
            const std::uint32_t e0 = start_[row + static_cast<std::size_t>(bx0)];
            const std::uint32_t e1 = start_[row + static_cast<std::size_t>(bx1) + 1];
            for (std::uint32_t e = e0; e < e1; ++e)
                if (fn(ids_[e], points_[e])) return true;
        }
        return false;
    }
    /// Calls fn(id) for every point whose bucket lies within `radius` of (x, y), in index
    /// order per bucket; stops early when fn returns true (and then returns true).
    template <typename Fn>
    bool any(double x, double y, double radius, Fn&& fn) const {
        return anyPoint(x, y, radius, [&](std::int32_t id, const Point&) { return fn(id); });
    }

private:
    int clampX(int b) const { return std::clamp(b, 0, nx_ - 1); }
    int clampY(int b) const { return std::clamp(b, 0, ny_ - 1); }
    std::size_t bucketOf(double x, double y) const {
        const int bx = clampX(static_cast<int>(std::floor((x - ox_) / s_)));
        const int by = clampY(static_cast<int>(std::floor((y - oy_) / s_)));
        return static_cast<std::size_t>(by) * static_cast<std::size_t>(nx_) + static_cast<std::size_t>(bx);
    }
    double ox_, oy_, s_;
    int nx_ = 1, ny_ = 1;
    Buf<std::uint32_t> start_;
    Buf<std::int32_t> ids_;
    Buf<Point> points_;
};

/// Greedy selection in a fixed priority order, computed in parallel with the serial result:
/// item `order[k]` is accepted unless blocked(i) or it conflicts with an accepted item earlier
/// in the order. conflicts(i, fn) calls fn(j) for every candidate j that may conflict with i
/// (any order, any superset of the true conflicts is fine: they are filtered by
/// earlier-in-order and conflict(i, j)). The conflict lists are built in parallel (pure
/// functions of the inputs), then one serial pass in order decides: the same result as
/// accepting one by one, for any number of threads.
template <typename Blocked, typename Neighbours, typename Conflict>
Buf<char> greedyAccept(const Buf<std::size_t>& order, std::size_t nItems, Blocked&& blocked,
                               Neighbours&& neighbours, Conflict&& conflict) {
    Buf<std::uint32_t> rank(nItems, std::numeric_limits<std::uint32_t>::max());
    for (std::size_t k = 0; k < order.size(); ++k) rank[order[k]] = static_cast<std::uint32_t>(k);
    // Fixed blocks of the order (independent of the thread count), each with its own list
    // of (position, earlier conflicting item) pairs.
    constexpr std::size_t kBlock = 4096;
    const std::size_t nBlocks = (order.size() + kBlock - 1) / kBlock;
    Buf<Buf<std::pair<std::uint32_t, std::uint32_t>>> edges(nBlocks);
    Buf<char> isBlocked(order.size(), 0);
#pragma omp parallel for schedule(dynamic, 1)
    for (std::ptrdiff_t b = 0; b < static_cast<std::ptrdiff_t>(nBlocks); ++b) {
        auto& out = edges[static_cast<std::size_t>(b)];
        const std::size_t k0 = static_cast<std::size_t>(b) * kBlock, k1 = std::min(order.size(), k0 + kBlock);
        for (std::size_t k = k0; k < k1; ++k) {
            const std::size_t i = order[k];
            if (blocked(i)) {
                isBlocked[k] = 1;
                continue;
            }
            neighbours(i, [&](std::size_t j) {
                if (rank[j] < k && conflict(i, j)) out.emplace_back(static_cast<std::uint32_t>(k), rank[j]);
            });
        }
    }
    Buf<char> acceptedAt(order.size(), 0);  // by position in the order
    for (std::size_t b = 0; b < nBlocks; ++b) {
        const auto& list = edges[b];
        std::size_t e = 0;
        const std::size_t k0 = b * kBlock, k1 = std::min(order.size(), k0 + kBlock);
        for (std::size_t k = k0; k < k1; ++k) {
            bool ok = !isBlocked[k];
            for (; e < list.size() && list[e].first == k; ++e)
                if (acceptedAt[list[e].second]) ok = false;
            acceptedAt[k] = ok;
        }
    }
    Buf<char> accepted(nItems, 0);
    for (std::size_t k = 0; k < order.size(); ++k) accepted[order[k]] = acceptedAt[k];
    return accepted;
}

// ------------------------------------------------------------------------- nearest mapped cell

/// 1D squared distance transform along one line with the nearest site (Felzenszwalb and
/// Huttenlocher's lower envelope of parabolas). f[q] = squared distance so far (inf: none),
/// site[q] = its cell; on exit both hold the result along the line.
void lowerEnvelope(std::vector<double>& f, std::vector<std::int64_t>& site, std::vector<int>& v,
                   std::vector<double>& z, std::vector<double>& outF, std::vector<std::int64_t>& outSite) {
    const int n = static_cast<int>(f.size());
    constexpr double inf = std::numeric_limits<double>::infinity();
    int k = -1;
    for (int q = 0; q < n; ++q) {
        if (!std::isfinite(f[static_cast<std::size_t>(q)])) continue;
        while (k >= 0) {
            const int p = v[static_cast<std::size_t>(k)];
            const double s = ((f[static_cast<std::size_t>(q)] + static_cast<double>(q) * q) -
                              (f[static_cast<std::size_t>(p)] + static_cast<double>(p) * p)) /
                             (2.0 * (q - p));
            if (s <= z[static_cast<std::size_t>(k)]) --k;
            else break;
        }
        ++k;
        v[static_cast<std::size_t>(k)] = q;
        z[static_cast<std::size_t>(k)] = k == 0 ? -inf
                                                : ((f[static_cast<std::size_t>(q)] + static_cast<double>(q) * q) -
                                                   (f[static_cast<std::size_t>(v[static_cast<std::size_t>(k) - 1])] +
                                                    static_cast<double>(v[static_cast<std::size_t>(k) - 1]) *
                                                        v[static_cast<std::size_t>(k) - 1])) /
                                                      (2.0 * (q - v[static_cast<std::size_t>(k) - 1]));
        z[static_cast<std::size_t>(k) + 1] = inf;
    }
    if (k < 0) {
        for (int q = 0; q < n; ++q) {
            outF[static_cast<std::size_t>(q)] = inf;
            outSite[static_cast<std::size_t>(q)] = -1;
        }
        return;
    }
    int j = 0;
    for (int q = 0; q < n; ++q) {
        while (z[static_cast<std::size_t>(j) + 1] < q) ++j;
        const int p = v[static_cast<std::size_t>(j)];
        outF[static_cast<std::size_t>(q)] = static_cast<double>(q - p) * (q - p) + f[static_cast<std::size_t>(p)];
        outSite[static_cast<std::size_t>(q)] = site[static_cast<std::size_t>(p)];
    }
}

/// The species map with every -1 replaced by the species of the nearest mapped cell (exact
/// Euclidean distance transform, columns then rows). All -1 when nothing is mapped.
Grid<std::int32_t> fillFromNearest(const Grid<std::int32_t>& map) {
    const int w = map.width(), h = map.height();
    constexpr double inf = std::numeric_limits<double>::infinity();
    std::vector<double> colF(map.size(), inf);
    std::vector<std::int64_t> colSite(map.size(), -1);
    // Pass 1: along each column (x fixed), nearest mapped cell in that column.
#pragma omp parallel
    {
        std::vector<double> f(static_cast<std::size_t>(h)), outF(static_cast<std::size_t>(h)), z(static_cast<std::size_t>(h) + 1);
        std::vector<std::int64_t> site(static_cast<std::size_t>(h)), outSite(static_cast<std::size_t>(h));
        std::vector<int> v(static_cast<std::size_t>(h));
#pragma omp for schedule(static)
        for (int ix = 0; ix < w; ++ix) {
            for (int iy = 0; iy < h; ++iy) {
                const std::size_t i = map.index(ix, iy);
                f[static_cast<std::size_t>(iy)] = map.data()[i] >= 0 ? 0.0 : inf;
                site[static_cast<std::size_t>(iy)] = map.data()[i] >= 0 ? static_cast<std::int64_t>(i) : -1;
            }
            lowerEnvelope(f, site, v, z, outF, outSite);
            for (int iy = 0; iy < h; ++iy) {
                colF[map.index(ix, iy)] = outF[static_cast<std::size_t>(iy)];
                colSite[map.index(ix, iy)] = outSite[static_cast<std::size_t>(iy)];
            }
        }
    }
    Grid<std::int32_t> out = map;
#pragma omp parallel
    {
        std::vector<double> f(static_cast<std::size_t>(w)), outF(static_cast<std::size_t>(w)), z(static_cast<std::size_t>(w) + 1);
        std::vector<std::int64_t> site(static_cast<std::size_t>(w)), outSite(static_cast<std::size_t>(w));
        std::vector<int> v(static_cast<std::size_t>(w));
#pragma omp for schedule(static)
        for (int iy = 0; iy < h; ++iy) {
            for (int ix = 0; ix < w; ++ix) {
                f[static_cast<std::size_t>(ix)] = colF[map.index(ix, iy)];
                site[static_cast<std::size_t>(ix)] = colSite[map.index(ix, iy)];
            }
            lowerEnvelope(f, site, v, z, outF, outSite);
            for (int ix = 0; ix < w; ++ix)
                if (map(ix, iy) < 0 && outSite[static_cast<std::size_t>(ix)] >= 0)
                    out(ix, iy) = map.data()[static_cast<std::size_t>(outSite[static_cast<std::size_t>(ix)])];
        }
    }
    return out;
}

// ------------------------------------------------------------------------- the placer

struct Tree {
    double x, y;     ///< trunk, world metres
    double heightM;  ///< apex above ground
    double radiusM;  ///< crown radius
    std::uint64_t uid;  ///< creation order; keys the tree's random stream
    std::int32_t species;
    bool apex = false;  ///< at a maximum of the CHM or of its unexplained cells: stays there
    bool hidden = false;  ///< fitted apex under another crown: explains the CHM, not output
};  // 48 bytes: the lists of 700k trees at 3072^2 are read at every step

/// Read-only lookups of the placer: CHM heights, species, crown radii.
class Scene {
public:
    Scene(const Grid<float>& chm, const Grid<std::int32_t>& speciesMap, const Biome& biome, const CanopyParams& p)
        : chm_(chm), map_(speciesMap), biome_(biome), p_(p) {
        bool anyNone = false;
        for (const std::int32_t s : speciesMap.data()) anyNone = anyNone || s < 0;
        if (anyNone) {
            filled_ = fillFromNearest(speciesMap);
            // Nothing mapped at all: the tallest canopy species (lower index on a tie).
            int tallest = -1;
            for (const auto& s : biome.species)
                if (s.canopy && (tallest < 0 || s.maxHeightM > biome.species[static_cast<std::size_t>(tallest)].maxHeightM))
                    tallest = s.id;
            for (auto& s : filled_.data())
                if (s < 0) s = tallest;
        }
    }
    const Grid<float>& chm() const { return chm_; }
    bool inside(double x, double y) const {
        return x >= chm_.originX() && y >= chm_.originY() && x < chm_.originX() + chm_.extentX() &&
               y < chm_.originY() + chm_.extentY();
    }
    std::size_t cellIndex(double x, double y) const {
        const int ix = std::clamp(chm_.cellX(x), 0, chm_.width() - 1);
        const int iy = std::clamp(chm_.cellY(y), 0, chm_.height() - 1);
        return chm_.index(ix, iy);
    }
    /// CHM at (x, y): bilinear over those of the four surrounding cells on the footprint
    /// (weights renormalised), so a trunk near a crown edge does not average in the ground;
    /// the nearest cell when none of the four is on the footprint.
    double heightAt(double x, double y) const {
        const double fx = (x - chm_.originX()) / chm_.cellSizeM() - 0.5;
        const double fy = (y - chm_.originY()) / chm_.cellSizeM() - 0.5;
        const int x0 = static_cast<int>(std::floor(fx)), y0 = static_cast<int>(std::floor(fy));
        const double tx = fx - x0, ty = fy - y0;
        double sum = 0, wsum = 0;
        const double wts[4] = {(1 - tx) * (1 - ty), tx * (1 - ty), (1 - tx) * ty, tx * ty};
        const int dxs[4] = {0, 1, 0, 1}, dys[4] = {0, 0, 1, 1};
        for (int k = 0; k < 4; ++k) {
            const double v = chm_.clamped(x0 + dxs[k], y0 + dys[k]);
            if (v >= p_.canopyThresholdM && wts[k] > 0) {
                sum += wts[k] * v;
                wsum += wts[k];
            }
        }
        if (wsum > 0) return sum / wsum;
        return chm_.data()[cellIndex(x, y)];
    }
    int speciesAt(double x, double y) const {
        const std::size_t i = cellIndex(x, y);
        const int s = map_.data()[i];
        return s >= 0 ? s : filled_.data()[i];
    }
    bool mapped(double x, double y) const { return map_.data()[cellIndex(x, y)] >= 0; }
    double radiusFor(int species, double heightM) const {
        return biome_.species[static_cast<std::size_t>(species)].allometry.crownRadiusM(heightM);
    }
    /// A tree at (x, y) with the CHM's height there.
    Tree makeTree(double x, double y, double heightM, std::uint64_t uid) const {
        const int s = speciesAt(x, y);
        return {x, y, heightM, radiusFor(s, heightM), uid, s};
    }

private:
    const Grid<float>& chm_;
    const Grid<std::int32_t>& map_;
    Grid<std::int32_t> filled_;
    const Biome& biome_;
    const CanopyParams& p_;
};

Buf<Crown> crownsOf(const Buf<Tree>& trees) {
    Buf<Crown> c(trees.size());
    for (std::size_t i = 0; i < trees.size(); ++i) c[i] = {trees[i].x, trees[i].y, trees[i].heightM, trees[i].radiusM};
    return c;
}

/// Render the trees and measure them against the CHM.
void renderAndMeasure(const Buf<Tree>& trees, const Grid<float>& chm, const CanopyParams& p, Frame& frame,
                      Visibility& vis) {
    Buf<Crown>& cr = frame.crowns;
    cr.resize(trees.size());
    for (std::size_t i = 0; i < trees.size(); ++i) cr[i] = {trees[i].x, trees[i].y, trees[i].heightM, trees[i].radiusM};
    render(cr, chm.width(), chm.height(), chm.cellSizeM(), chm.originX(), chm.originY(), frame);
    measure(frame, chm, p.canopyThresholdM, p.residualToleranceM, trees.size(), vis);
}

void fillStats(IterationStats& s, std::size_t trees, const Visibility& vis) {
    s.trees = trees;
    s.coverage = vis.footprint ? static_cast<double>(vis.covered) / static_cast<double>(vis.footprint) : 1.0;
    s.rmseM = vis.footprint ? std::sqrt(vis.sumSquaredErrorM2 / static_cast<double>(vis.footprint)) : 0.0;
}

bool starved(std::size_t t, const Frame& frame, const Visibility& vis, double minFraction) {
    const double disc = frame.disc[t];
    if (!(disc > 0)) return true;
    return static_cast<double>(vis.visible[t]) < minFraction * disc;
}

/// A tree at the CHM maximum of cell (ix, iy), refined to sub-cell precision by a parabola
/// through the cell and its two neighbours along x and along y when both are in the set of
/// the maximum (inSet), with the CHM's height there.
template <typename InSet>
Tree apexTree(const Scene& scene, int ix, int iy, std::uint64_t uid, bool anchored, InSet&& inSet) {
    const Grid<float>& chm = scene.chm();
    const double c = chm(ix, iy);
    auto offset = [&](int x0, int y0, int x1, int y1) {
        if (!chm.inside(x0, y0) || !chm.inside(x1, y1) || !inSet(chm.index(x0, y0)) || !inSet(chm.index(x1, y1))) return 0.0;
        const double lo = chm(x0, y0), hi = chm(x1, y1);
        const double curvature = lo - 2.0 * c + hi;
        if (!(curvature < 0)) return 0.0;
        return std::clamp(0.5 * (lo - hi) / curvature, -0.5, 0.5);
    };
    const double ox = offset(ix - 1, iy, ix + 1, iy);
    const double oy = offset(ix, iy - 1, ix, iy + 1);
    const double x = chm.cellCentreX(ix) + ox * chm.cellSizeM();
    const double y = chm.cellCentreY(iy) + oy * chm.cellSizeM();
    double height = scene.heightAt(x, y);
    if (height < c) height = c;  // the maximum cell is a lower bound of the apex
    Tree t = scene.makeTree(x, y, height, uid);
    t.apex = anchored;
    return t;
}

/// The residual apex fit (CanopyParams::residualApexFit). The tree t made at the residual
/// apex cell (ix, iy) is replaced by the sphere of the crown model that stays under the CHM
/// and touches (within fitTolM) the most unexplained cells of its disc, the apex cell among
/// them: apex positions within 2 cells of the cell's centre (whole cells, then the half cells
/// around the best), each as high as the CHM allows (no cell of the inner 0.7 of its disc
/// below the sphere), of t's radius (the CHM's height at the cell); the best one then takes
/// the radius of its own height. It is tried only where a higher 8-neighbour of the cell is
/// explained by another crown (the cell may be the top of the crescent that crown leaves of
/// a lower one), and kept only when it touches more cells than the sphere at t's own
/// position does. t.hidden: the CHM at the fitted apex's cell stands more than hiddenTolM
/// above the sphere (the apex is under another crown).
constexpr double kApexFitCore = 0.7;
template <typename InSet>
void fitResidualApex(const Scene& scene, int ix, int iy, double fitTolM, double hiddenTolM, InSet&& unexplained, Tree& t) {
    const Grid<float>& chm = scene.chm();
    const int w = chm.width(), h = chm.height();
    const double c = chm(ix, iy);
    bool besideTaller = false;
    for (int jy = std::max(0, iy - 1); jy <= std::min(h - 1, iy + 1); ++jy)
        for (int jx = std::max(0, ix - 1); jx <= std::min(w - 1, ix + 1); ++jx)
            besideTaller = besideTaller || (chm(jx, jy) > c && !unexplained(chm.index(jx, jy)));
    if (!besideTaller) return;
    // Touched cells of the highest sphere of radius r at (x0, y0) under the CHM (-1: it does
    // not touch the apex cell); its apex height in hOut. Only the cells within kApexFitCore x r
    // of the apex count: near its rim a sphere is steep, and a rim a few centimetres off
    // its true place stands above the ground beside the crown and would pull it down.
    auto evaluate = [&](double x0, double y0, double r, double& hOut) -> int {
        const double rc = kApexFitCore * r;
        const int x0c = std::max(0, chm.cellX(x0 - rc)), x1c = std::min(w - 1, chm.cellX(x0 + rc));
        const int y0c = std::max(0, chm.cellY(y0 - rc)), y1c = std::min(h - 1, chm.cellY(y0 + rc));
        const double r2 = r * r, rc2 = rc * rc;
        double top = std::numeric_limits<double>::infinity();
        for (int jy = y0c; jy <= y1c; ++jy) {
            const double dy = chm.cellCentreY(jy) - y0;
            for (int jx = x0c; jx <= x1c; ++jx) {
                const double dx = chm.cellCentreX(jx) - x0;
                const double d2 = dx * dx + dy * dy;
                if (d2 >= rc2) continue;
                top = std::min(top, static_cast<double>(chm(jx, jy)) + r - std::sqrt(r2 - d2));
            }
        }
        if (!std::isfinite(top)) return -1;
        {
            const double dx = chm.cellCentreX(ix) - x0, dy = chm.cellCentreY(iy) - y0;
            const double d2 = dx * dx + dy * dy;
            if (d2 >= rc2 || c - (top - r + std::sqrt(r2 - d2)) > fitTolM) return -1;
        }
        int touched = 0;
        for (int jy = y0c; jy <= y1c; ++jy) {
            const double dy = chm.cellCentreY(jy) - y0;
            for (int jx = x0c; jx <= x1c; ++jx) {
                const double dx = chm.cellCentreX(jx) - x0;
                const double d2 = dx * dx + dy * dy;
                if (d2 >= rc2 || !unexplained(chm.index(jx, jy))) continue;
                touched += chm(jx, jy) - (top - r + std::sqrt(r2 - d2)) <= fitTolM;
            }
        }
        hOut = top;
        return touched;
    };
    double hOwn = 0;
    const int own = evaluate(t.x, t.y, t.radiusM, hOwn);
    const double half = 0.5 * chm.cellSizeM();
    int best = -1, bestOff = 0, bestX = 0, bestY = 0;
    double bx = 0, by = 0, top = 0;
    auto consider = [&](int ox, int oy) {  // offsets in half cells
        const double x0 = chm.cellCentreX(ix) + ox * half, y0 = chm.cellCentreY(iy) + oy * half;
        double h0 = 0;
        const int n = evaluate(x0, y0, t.radiusM, h0);
        const int off = ox * ox + oy * oy;
        if (n > best || (n == best && off < bestOff)) {
            best = n;
            bestOff = off;
            bestX = ox;
            bestY = oy;
            bx = x0;
            by = y0;
            top = h0;
        }
    };
    // Whole cells first (up to 2 away), then the half cells around the best of them.
    for (int oy = -4; oy <= 4; oy += 2)
        for (int ox = -4; ox <= 4; ox += 2) consider(ox, oy);
    const int sx = bestX, sy = bestY;
    for (int oy = sy - 1; oy <= sy + 1; ++oy)
        for (int ox = sx - 1; ox <= sx + 1; ++ox)
            if ((ox != sx || oy != sy) && std::abs(ox) <= 4 && std::abs(oy) <= 4) consider(ox, oy);
    if (best <= own) return;
    {
        // The radius of the height found (a hidden apex stands above the cell: a wider crown).
        double top2 = 0;
        if (evaluate(bx, by, scene.radiusFor(t.species, top), top2) >= 0) top = top2;
    }
    const bool anchored = t.apex;
    const std::uint64_t uid = t.uid;
    t = scene.makeTree(bx, by, top, uid);
    t.apex = anchored;
    const int cx = std::clamp(chm.cellX(bx), 0, w - 1), cy = std::clamp(chm.cellY(by), 0, h - 1);
    const double dx = chm.cellCentreX(cx) - bx, dy = chm.cellCentreY(cy) - by;
    const double own2 = top - t.radiusM + std::sqrt(std::max(0.0, t.radiusM * t.radiusM - dx * dx - dy * dy));
    t.hidden = chm(cx, cy) > own2 + hiddenTolM;
}

/// The apex snap (CanopyParams::apexSnapRadiusFraction): tree t, index self of the render whose
/// top-crown ids are `owner`, moves onto the highest strict 3 x 3 maximum of the CHM among
/// its own cells (owner == self; the others neither are maxima nor compete; a plateau goes
/// to its cell of lowest index) that is >= minHeightM and whose centre lies within reachM of
/// its trunk; apexTree refines the position and takes the CHM's height there. Returns
/// whether t moved. Reads the CHM and the render only: trees are snapped in parallel.
bool snapToOwnApex(const Scene& scene, const Buf<std::int32_t>& owner, std::int32_t self, double reachM,
                   double minHeightM, Tree& t) {
    const Grid<float>& chm = scene.chm();
    const int w = chm.width(), h = chm.height();
    auto own = [&](std::size_t i) { return owner[i] == self; };
    const int x0 = std::max(0, chm.cellX(t.x - reachM)), x1 = std::min(w - 1, chm.cellX(t.x + reachM));
    const int y0 = std::max(0, chm.cellY(t.y - reachM)), y1 = std::min(h - 1, chm.cellY(t.y + reachM));
    int bx = -1, by = -1;
    float best = 0;
    for (int iy = y0; iy <= y1; ++iy)
        for (int ix = x0; ix <= x1; ++ix) {
            const std::size_t i = chm.index(ix, iy);
            const float v = chm(ix, iy);
            if (!own(i) || !(v >= minHeightM) || (bx >= 0 && !(v > best))) continue;
            const double dx = chm.cellCentreX(ix) - t.x, dy = chm.cellCentreY(iy) - t.y;
            if (dx * dx + dy * dy > reachM * reachM || !strictMaximumIn(chm, ix, iy, 1, own)) continue;
            bx = ix;
            by = iy;
            best = v;
        }
    if (bx < 0) return false;
    const Tree moved = apexTree(scene, bx, by, t.uid, t.apex, own);
    if (moved.x == t.x && moved.y == t.y) return false;
    t = moved;
    return true;
}

/// The crown fit (CanopyParams::crownFitPasses). Tree t, index self of the render in f (made
/// by render<true>, with the second surface), is replaced by the sphere of the crown model
/// (apex within reachM of t, any height, the allometric radius of that height) that
/// minimises sum (max(others, sphere) - CHM)^2 over the cells around it, where `others` is
/// the render without t (its second surface where t is on top, else the top one; the ground,
/// 0, where none): the sphere that explains best what the other crowns leave of the CHM, its
/// apex under a neighbour's crown if need be. Positions: t's own, a grid of half cells
/// within reachM, then the four quarter-cell steps around the best. Height at a position: the
/// fixed point h = mean of (CHM - (sphere - h)) over the cells where the sphere is on top
/// (the least-squares height of those cells), from the CHM at the position, at most
/// kFitHeightSteps steps, the best one kept. Reads the CHM and the render only: trees are
/// fitted in parallel, the same for any thread count. Returns the margin of the fitted tree:
/// the CHM at its apex's cell minus its sphere there (large when the apex lies under another
/// crown: a tree that explains the crescent of a hidden top).
/// static_cast<int>(std::floor(v)) and ...(std::ceil(v)) for v well inside the int range,
/// without the library's rounding (at baseline x86-64 a long sequence).
inline int floorToInt(double v) {
    const int t = static_cast<int>(v);
    return t - (static_cast<double>(t) > v);
}
inline int ceilToInt(double v) {
    const int t = static_cast<int>(v);
    return t + (static_cast<double>(t) < v);
}
constexpr int kFitHeightSteps = 4;
constexpr std::uint64_t kFitSeedStride = 8;    ///< every 8th seed is fitted for the hidden margin
constexpr double kFitSeedQuantile = 0.9;      ///< of the seeds' margins
constexpr double kFitSeedMarginFactor = 2.0;  ///< hidden margin >= this x that quantile
constexpr double kFitConvergeM = 0.03;
constexpr float kFitCapM = 2.0f;  ///< squared errors capped at this^2 (m^2)
double fitCrown(const Scene& scene, const Frame& f, std::int32_t self, double reachM, double minHeightM, Tree& t) {
    const Grid<float>& chm = scene.chm();
    const int w = chm.width(), h = chm.height();
    const double cell = chm.cellSizeM();
    // The tallest CHM near the positions bounds the heights, hence the radii and the window.
    double hMax = 0;
    {
        const double probe = reachM + 2.0 * cell;
        const int x0 = std::max(0, chm.cellX(t.x - probe)), x1 = std::min(w - 1, chm.cellX(t.x + probe));
        const int y0 = std::max(0, chm.cellY(t.y - probe)), y1 = std::min(h - 1, chm.cellY(t.y + probe));
        for (int iy = y0; iy <= y1; ++iy)
            for (int ix = x0; ix <= x1; ++ix) hMax = std::max(hMax, static_cast<double>(chm(ix, iy)));
    }
    const double hTop = hMax + 0.5;
    const double rMax = scene.radiusFor(t.species, hTop);
    const double reach = reachM + rMax + cell;
    const int x0 = std::max(0, chm.cellX(t.x - reach)), x1 = std::min(w - 1, chm.cellX(t.x + reach));
    const int y0 = std::max(0, chm.cellY(t.y - reach)), y1 = std::min(h - 1, chm.cellY(t.y + reach));
    const int nx = x1 - x0 + 1, ny = y1 - y0 + 1;
    if (nx <= 0 || ny <= 0) return 0.0;
    // Per window cell: the CHM c, the surface of the other crowns o and the capped squared
    // error of the others alone eo (buffers kept per thread: no allocation per tree).
    constexpr float kCap2 = kFitCapM * kFitCapM;
    thread_local std::vector<float> cs, os, eos;
    const std::size_t nWin = static_cast<std::size_t>(nx) * static_cast<std::size_t>(ny);
    cs.resize(nWin);
    os.resize(nWin);
    eos.resize(nWin);
    for (int iy = y0; iy <= y1; ++iy)
        for (int ix = x0; ix <= x1; ++ix) {
            const std::size_t i = chm.index(ix, iy);
            const std::size_t k = static_cast<std::size_t>(iy - y0) * static_cast<std::size_t>(nx) + static_cast<std::size_t>(ix - x0);
            const float o = std::max(0.0f, f.id[i] == self ? f.depth2[i] : f.depth[i]);
            const float c = std::max(0.0f, chm(ix, iy));
            os[k] = o;
            cs[k] = c;
            eos[k] = std::min((o - c) * (o - c), kCap2);
        }
    const double cx0 = chm.cellCentreX(x0), cy0 = chm.cellCentreY(y0);
    // Only the cells where the sphere rises above the others change the error: it is compared
    // as the sum over them of (sphere - c)^2 - (o - c)^2 (0 = no better than without t).
    // A height step at a position sums over the cells of its sphere's footprint, within the
    // window of radius rMax around the position (at most kSpan cells a side):
    // StepSums of the error, of (c - g) and of the count over the fitting cells.
    constexpr int kSpan = 64;
    constexpr float kInf = std::numeric_limits<float>::infinity();
    struct StepSums {
        double e = 0, sum = 0;
        int n = 0;
    };
    struct Footprint {
        int jx0, jx1, jy0, jy1;  // the rMax window
        int xa, xb, ya, yb;      // the cells of the sphere of radius r in it
    };
    auto window = [&](double x, double y) {
        Footprint q;
        q.jy0 = std::max(0, floorToInt((y - rMax - cy0) / cell));
        q.jy1 = std::min({ny - 1, q.jy0 + kSpan - 1, ceilToInt((y + rMax - cy0) / cell)});
        q.jx0 = std::max(0, floorToInt((x - rMax - cx0) / cell));
        q.jx1 = std::min({nx - 1, q.jx0 + kSpan - 1, ceilToInt((x + rMax - cx0) / cell)});
        return q;
    };
    auto clip = [&](Footprint& q, double x, double y, double r) {
        q.ya = std::max(q.jy0, ceilToInt((y - r - cy0) / cell));
        q.yb = std::min(q.jy1, floorToInt((y + r - cy0) / cell));
        q.xa = std::max(q.jx0, ceilToInt((x - r - cx0) / cell));
        q.xb = std::min(q.jx1, floorToInt((x + r - cx0) / cell));
    };
    auto footprint = [&](double x, double y, double r) {
        Footprint q = window(x, y);
        clip(q, x, y, r);
        return q;
    };
    // One height step at one position (hf the apex height, r its radius).
    auto stepAt = [&](double x, double y, float hf, float r) {
        const float r2 = r * r;
        const Footprint q = footprint(x, y, r);
        StepSums s;
        for (int jy = q.ya; jy <= q.yb; ++jy) {
            const double dy = cy0 + jy * cell - y;
            const float dy2 = static_cast<float>(dy * dy);
            if (!(dy2 < r2)) continue;
            const std::size_t row = static_cast<std::size_t>(jy) * static_cast<std::size_t>(nx);
            for (int jx = q.xa; jx <= q.xb; ++jx) {
                const double dx = cx0 + jx * cell - x;
                const float d2 = static_cast<float>(dx * dx) + dy2;
                const float g = std::sqrt(std::max(r2 - d2, 0.0f)) - r;
                const std::size_t k = row + static_cast<std::size_t>(jx);
                const float z = hf + g, o = os[k], c = cs[k];
                const bool on = (d2 < r2) & (z > o);
                // Squared errors capped at kFitCapM^2 (a robust fit): a sphere a few
                // centimetres off its place has rim cells on the ground beside the crown,
                // errors of the whole crown depth that would pull it down and in.
                const float ez = std::min((z - c) * (z - c), kCap2), eo = eos[k];
                const bool fits = on & ((z - c) * (z - c) < kCap2);
                s.e += on ? static_cast<double>(ez - eo) : 0.0;
                s.sum += fits ? static_cast<double>(c - g) : 0.0;
                s.n += fits;
            }
        }
        return s;
    };
    // A height step at four positions in one sweep over the union of their footprints, the
    // four in the lanes of one vector: per position the same operations on the same cells in
    // the same order as stepAt (a cell outside a position's footprint has its squared
    // distance infinite there and adds +0 to its sums), hence the same sums. A Quad holds
    // the positions' windows and their squared distances per column and row (computed once
    // for the steps of the fixed point; a step's footprints lie inside the windows).
    struct Quad {
        double xs[4], ys[4];
        Footprint q[4];
        int ux0, ux1, uy0, uy1;  // the union of the windows
    };
    thread_local std::vector<float> rawx, rawy, dxq, dyq;
    auto prepare = [&](Quad& g) {
        g.ux0 = g.uy0 = std::numeric_limits<int>::max();
        g.ux1 = g.uy1 = -1;
        for (int p = 0; p < 4; ++p) {
            g.q[p] = window(g.xs[p], g.ys[p]);
            g.ux0 = std::min(g.ux0, g.q[p].jx0);
            g.ux1 = std::max(g.ux1, g.q[p].jx1);
            g.uy0 = std::min(g.uy0, g.q[p].jy0);
            g.uy1 = std::max(g.uy1, g.q[p].jy1);
        }
        if (g.ux1 < g.ux0 || g.uy1 < g.uy0) return;
        rawx.resize(4 * static_cast<std::size_t>(g.ux1 - g.ux0 + 1));
        rawy.resize(4 * static_cast<std::size_t>(g.uy1 - g.uy0 + 1));
        for (int p = 0; p < 4; ++p) {
            for (int jx = g.ux0; jx <= g.ux1; ++jx) {
                const double dx = cx0 + jx * cell - g.xs[p];
                rawx[4 * static_cast<std::size_t>(jx - g.ux0) + p] = static_cast<float>(dx * dx);
            }
            for (int jy = g.uy0; jy <= g.uy1; ++jy) {
                const double dy = cy0 + jy * cell - g.ys[p];
                rawy[4 * static_cast<std::size_t>(jy - g.uy0) + p] = static_cast<float>(dy * dy);
            }
        }
    };
    // Lanes with active[p] false are not evaluated (their sums 0).
    auto stepAt4 = [&](Quad& g, const float* hfs, const float* rs, const bool* active, StepSums* out) {
        int ux0 = std::numeric_limits<int>::max(), ux1 = -1, uy0 = std::numeric_limits<int>::max(), uy1 = -1;
        for (int p = 0; p < 4; ++p) {
            out[p] = StepSums{};
            Footprint& q = g.q[p];
            clip(q, g.xs[p], g.ys[p], rs[p]);
            if (!active[p] || q.xa > q.xb || q.ya > q.yb) {
                q.xa = q.ya = 1;  // empty
                q.xb = q.yb = 0;
                continue;
            }
            ux0 = std::min(ux0, q.xa);
            ux1 = std::max(ux1, q.xb);
            uy0 = std::min(uy0, q.ya);
            uy1 = std::max(uy1, q.yb);
        }
        if (ux1 < ux0) return;
        dxq.resize(4 * static_cast<std::size_t>(ux1 - ux0 + 1));
        dyq.resize(4 * static_cast<std::size_t>(uy1 - uy0 + 1));
#ifdef __SSE2__
        {
            const __m128 inf = _mm_set1_ps(kInf);
            const __m128i xa = _mm_setr_epi32(g.q[0].xa, g.q[1].xa, g.q[2].xa, g.q[3].xa);
            const __m128i xb = _mm_setr_epi32(g.q[0].xb, g.q[1].xb, g.q[2].xb, g.q[3].xb);
            const __m128i ya = _mm_setr_epi32(g.q[0].ya, g.q[1].ya, g.q[2].ya, g.q[3].ya);
            const __m128i yb = _mm_setr_epi32(g.q[0].yb, g.q[1].yb, g.q[2].yb, g.q[3].yb);
            for (int jx = ux0; jx <= ux1; ++jx) {
                const __m128i j = _mm_set1_epi32(jx);
                const __m128 out = _mm_castsi128_ps(_mm_or_si128(_mm_cmpgt_epi32(xa, j), _mm_cmpgt_epi32(j, xb)));
                const __m128 raw = _mm_loadu_ps(&rawx[4 * static_cast<std::size_t>(jx - g.ux0)]);
                _mm_storeu_ps(&dxq[4 * static_cast<std::size_t>(jx - ux0)], _mm_or_ps(_mm_andnot_ps(out, raw), _mm_and_ps(out, inf)));
            }
            for (int jy = uy0; jy <= uy1; ++jy) {
                const __m128i j = _mm_set1_epi32(jy);
                const __m128 out = _mm_castsi128_ps(_mm_or_si128(_mm_cmpgt_epi32(ya, j), _mm_cmpgt_epi32(j, yb)));
                const __m128 raw = _mm_loadu_ps(&rawy[4 * static_cast<std::size_t>(jy - g.uy0)]);
                _mm_storeu_ps(&dyq[4 * static_cast<std::size_t>(jy - uy0)], _mm_or_ps(_mm_andnot_ps(out, raw), _mm_and_ps(out, inf)));
            }
        }
        const __m128 r = _mm_setr_ps(rs[0], rs[1], rs[2], rs[3]);
        const __m128 r2 = _mm_mul_ps(r, r);
        const __m128 hf = _mm_setr_ps(hfs[0], hfs[1], hfs[2], hfs[3]);
        const __m128 cap2 = _mm_set1_ps(kCap2), zero = _mm_setzero_ps();
        __m128d eLo = _mm_setzero_pd(), eHi = _mm_setzero_pd(), sLo = _mm_setzero_pd(), sHi = _mm_setzero_pd();
        __m128i cnt = _mm_setzero_si128();
        for (int jy = uy0; jy <= uy1; ++jy) {
            const __m128 dy2 = _mm_loadu_ps(&dyq[4 * static_cast<std::size_t>(jy - uy0)]);
            if (_mm_movemask_ps(_mm_cmplt_ps(dy2, r2)) == 0) continue;
            const std::size_t row = static_cast<std::size_t>(jy) * static_cast<std::size_t>(nx);
            for (int jx = ux0; jx <= ux1; ++jx) {
                const __m128 d2 = _mm_add_ps(_mm_loadu_ps(&dxq[4 * static_cast<std::size_t>(jx - ux0)]), dy2);
                const __m128 g = _mm_sub_ps(_mm_sqrt_ps(_mm_max_ps(_mm_sub_ps(r2, d2), zero)), r);
                const std::size_t k = row + static_cast<std::size_t>(jx);
                const __m128 z = _mm_add_ps(hf, g), o = _mm_set1_ps(os[k]), c = _mm_set1_ps(cs[k]);
                const __m128 on = _mm_and_ps(_mm_cmplt_ps(d2, r2), _mm_cmpgt_ps(z, o));
                const __m128 dz = _mm_sub_ps(z, c);
                const __m128 sq = _mm_mul_ps(dz, dz);
                const __m128 fits = _mm_and_ps(on, _mm_cmplt_ps(sq, cap2));
                const __m128 de = _mm_and_ps(on, _mm_sub_ps(_mm_min_ps(sq, cap2), _mm_set1_ps(eos[k])));
                const __m128 ds = _mm_and_ps(fits, _mm_sub_ps(c, g));
                eLo = _mm_add_pd(eLo, _mm_cvtps_pd(de));
                eHi = _mm_add_pd(eHi, _mm_cvtps_pd(_mm_movehl_ps(de, de)));
                sLo = _mm_add_pd(sLo, _mm_cvtps_pd(ds));
                sHi = _mm_add_pd(sHi, _mm_cvtps_pd(_mm_movehl_ps(ds, ds)));
                cnt = _mm_sub_epi32(cnt, _mm_castps_si128(fits));
            }
        }
        double e[4], sm[4];
        std::int32_t nn[4];
        _mm_storeu_pd(e, eLo);
        _mm_storeu_pd(e + 2, eHi);
        _mm_storeu_pd(sm, sLo);
        _mm_storeu_pd(sm + 2, sHi);
        _mm_storeu_si128(reinterpret_cast<__m128i*>(nn), cnt);
        for (int p = 0; p < 4; ++p) out[p] = {e[p], sm[p], nn[p]};
#else
        for (int jx = ux0; jx <= ux1; ++jx)
            for (int p = 0; p < 4; ++p)
                dxq[4 * static_cast<std::size_t>(jx - ux0) + p] =
                    jx >= g.q[p].xa && jx <= g.q[p].xb ? rawx[4 * static_cast<std::size_t>(jx - g.ux0) + p] : kInf;
        for (int jy = uy0; jy <= uy1; ++jy)
            for (int p = 0; p < 4; ++p)
                dyq[4 * static_cast<std::size_t>(jy - uy0) + p] =
                    jy >= g.q[p].ya && jy <= g.q[p].yb ? rawy[4 * static_cast<std::size_t>(jy - g.uy0) + p] : kInf;
        for (int jy = uy0; jy <= uy1; ++jy) {
            const std::size_t row = static_cast<std::size_t>(jy) * static_cast<std::size_t>(nx);
            for (int jx = ux0; jx <= ux1; ++jx) {
                const std::size_t k = row + static_cast<std::size_t>(jx);
                for (int p = 0; p < 4; ++p) {
                    const float r = rs[p], r2 = r * r;
                    const float d2 = dxq[4 * static_cast<std::size_t>(jx - ux0) + p] + dyq[4 * static_cast<std::size_t>(jy - uy0) + p];
                    const float g = std::sqrt(std::max(r2 - d2, 0.0f)) - r;
                    const float z = hfs[p] + g, c = cs[k];
                    const bool on = (d2 < r2) & (z > os[k]);
                    const bool fits = on & ((z - c) * (z - c) < kCap2);
                    out[p].e += on ? static_cast<double>(std::min((z - c) * (z - c), kCap2) - eos[k]) : 0.0;
                    out[p].sum += fits ? static_cast<double>(c - g) : 0.0;
                    out[p].n += fits;
                }
            }
        }
#endif
    };
    // The fixed point of the height at a position from hStart, at most kFitHeightSteps steps,
    // the best kept.
    auto bestHeight = [&](double x, double y, double hStart, double& eOut) {
        double hCur = hStart, bestH = hStart, bestE = std::numeric_limits<double>::infinity();
        for (int step = 0; step < kFitHeightSteps; ++step) {
            const StepSums s = stepAt(x, y, static_cast<float>(hCur), static_cast<float>(scene.radiusFor(t.species, hCur)));
            if (s.e < bestE) {
                bestE = s.e;
                bestH = hCur;
            }
            if (s.n == 0) break;
            const double hNext = std::clamp(s.sum / s.n, minHeightM, hTop);
            if (std::abs(hNext - hCur) < kFitConvergeM) break;
            hCur = hNext;
        }
        eOut = bestE;
        return bestH;
    };
    // Positions evaluated four at a time: bestHeight in the four lanes of stepAt4, a lane
    // leaving the sweeps when its fixed point ends; the same steps, hence the same heights
    // and errors, as bestHeight one position at a time.
    struct Candidate {
        double x, y, hStart, h = 0, e = 0;
    };
    auto evaluate = [&](Candidate* cands, int count) {
        for (int base = 0; base < count; base += 4) {
            const int m = std::min(4, count - base);
            if (m == 1) {
                Candidate& cd = cands[base];
                cd.h = bestHeight(cd.x, cd.y, cd.hStart, cd.e);
                continue;
            }
            Quad g;
            double hCur[4], bestH[4], bestE[4];
            float hfs[4] = {0, 0, 0, 0}, rs[4] = {0, 0, 0, 0};
            bool active[4];
            for (int p = 0; p < 4; ++p) {
                const Candidate& cd = cands[base + std::min(p, m - 1)];
                g.xs[p] = cd.x;
                g.ys[p] = cd.y;
                hCur[p] = bestH[p] = cd.hStart;
                bestE[p] = std::numeric_limits<double>::infinity();
                active[p] = p < m;
            }
            prepare(g);
            for (int step = 0; step < kFitHeightSteps; ++step) {
                bool any = false;
                for (int p = 0; p < 4; ++p) {
                    any = any || active[p];
                    if (!active[p]) continue;
                    hfs[p] = static_cast<float>(hCur[p]);
                    rs[p] = static_cast<float>(scene.radiusFor(t.species, hCur[p]));
                }
                if (!any) break;
                StepSums s[4];
                stepAt4(g, hfs, rs, active, s);
                for (int p = 0; p < 4; ++p) {
                    if (!active[p]) continue;
                    if (s[p].e < bestE[p]) {
                        bestE[p] = s[p].e;
                        bestH[p] = hCur[p];
                    }
                    if (s[p].n == 0) {
                        active[p] = false;
                        continue;
                    }
                    const double hNext = std::clamp(s[p].sum / s[p].n, minHeightM, hTop);
                    if (std::abs(hNext - hCur[p]) < kFitConvergeM) {
                        active[p] = false;
                        continue;
                    }
                    hCur[p] = hNext;
                }
            }
            for (int p = 0; p < m; ++p) {
                cands[base + p].h = bestH[p];
                cands[base + p].e = bestE[p];
            }
        }
    };
    auto cellHeight = [&](double x, double y) {
        return std::max(minHeightM, static_cast<double>(chm.clamped(chm.cellX(x), chm.cellY(y))));
    };
    double bx = t.x, by = t.y, be = 0;
    double bh = bestHeight(t.x, t.y, cellHeight(t.x, t.y), be);
    const double step = 0.25 * cell;
    const int n = static_cast<int>(std::floor(reachM / step));
    thread_local std::vector<Candidate> grid;
    grid.clear();
    for (int j = -n; j <= n; j += 2)
        for (int i = -n; i <= n; i += 2) {
            if ((i == 0 && j == 0) || (i * i + j * j) * step * step > reachM * reachM) continue;
            const double x = t.x + i * step, y = t.y + j * step;
            grid.push_back({x, y, cellHeight(x, y)});
        }
    evaluate(grid.data(), static_cast<int>(grid.size()));
    for (const Candidate& cd : grid)
        if (cd.e < be) {
            be = cd.e;
            bh = cd.h;
            bx = cd.x;
            by = cd.y;
        }
    {
        const double cx = bx, cy = by, ch = bh;
        Candidate quarter[4];
        int m = 0;
        for (int j = -1; j <= 1; ++j)
            for (int i = -1; i <= 1; ++i) {
                if ((i == 0) == (j == 0)) continue;  // the four quarter-cell steps along the axes
                quarter[m++] = {cx + i * step, cy + j * step, ch};
            }
        evaluate(quarter, m);
        for (int p = 0; p < m; ++p)
            if (quarter[p].e < be) {
                be = quarter[p].e;
                bh = quarter[p].h;
                bx = quarter[p].x;
                by = quarter[p].y;
            }
    }
    if (!scene.inside(bx, by)) return 0.0;
    const bool anchored = t.apex;
    t = scene.makeTree(bx, by, bh, t.uid);
    t.apex = anchored;
    const int cx = std::clamp(chm.cellX(bx), 0, w - 1), cy = std::clamp(chm.cellY(by), 0, h - 1);
    const double dx = chm.cellCentreX(cx) - bx, dy = chm.cellCentreY(cy) - by;
    const double own = bh - t.radiusM + std::sqrt(std::max(0.0, t.radiusM * t.radiusM - dx * dx - dy * dy));
    return chm(cx, cy) - own;
}

/// Lowest CHM cell on the segment between two trunks (cells sampled every half cell, the
/// end cells included).
double segmentMinimum(const Grid<float>& chm, double x0, double y0, double x1, double y1) {
    const double len = std::hypot(x1 - x0, y1 - y0);
    const int steps = std::max(1, static_cast<int>(std::ceil(2.0 * len / chm.cellSizeM())));
    double lo = std::numeric_limits<double>::infinity();
    for (int k = 0; k <= steps; ++k) {
        const double t = static_cast<double>(k) / steps;
        const int ix = std::clamp(chm.cellX(x0 + t * (x1 - x0)), 0, chm.width() - 1);
        const int iy = std::clamp(chm.cellY(y0 + t * (y1 - y0)), 0, chm.height() - 1);
        lo = std::min(lo, static_cast<double>(chm(ix, iy)));
    }
    return lo;
}

/// Keep flags of the seed merge among the trees with eligible(i) (the others are kept):
/// tallest first (ties to the lower index), a tree goes when a kept one earlier in the order
/// has its trunk less than kSeedMergeCells cells and radiusFraction x its crown radius away
/// and the CHM on the segment between the two trunks never drops more than saddleM below the
/// lower tree's height: no saddle between them, well inside one crown, so two maxima of one
/// crown top's noise, not two tops (two small noise-free crowns stand about a radius apart).
constexpr double kSeedMergeCells = 2.0;
template <typename Eligible>
Buf<char> seedMergeKeepFlags(const Buf<Tree>& trees, const Grid<float>& chm, double saddleM, double radiusFraction,
                                     Eligible&& eligible) {
    Buf<std::size_t> order;
    for (std::size_t i = 0; i < trees.size(); ++i)
        if (eligible(i)) order.push_back(i);
    std::stable_sort(order.begin(), order.end(),
                     [&](std::size_t a, std::size_t b) { return trees[a].heightM > trees[b].heightM; });
    const double reach = kSeedMergeCells * chm.cellSizeM();
    const PointGrid grid(chm.originX(), chm.originY(), chm.extentX(), chm.extentY(), reach, trees.size(),
                         [&](std::size_t i) { return trees[i].x; }, [&](std::size_t i) { return trees[i].y; });
    Buf<char> keep = greedyAccept(
        order, trees.size(), [](std::size_t) { return false; },
        [&](std::size_t i, auto&& fn) {
            grid.any(trees[i].x, trees[i].y, reach, [&](std::int32_t j) {
                fn(static_cast<std::size_t>(j));
                return false;
            });
        },
        [&](std::size_t i, std::size_t j) {
            const Tree& a = trees[i];
            const Tree& b = trees[j];
            const double dx = b.x - a.x, dy = b.y - a.y;
            if (dx * dx + dy * dy >= reach * reach) return false;
            // b is the taller (earlier in the order): within a fraction of its crown radius.
            const double near = radiusFraction * b.radiusM;
            if (dx * dx + dy * dy >= near * near) return false;
            return segmentMinimum(chm, a.x, a.y, b.x, b.y) >= a.heightM - saddleM;
        });
    for (std::size_t i = 0; i < trees.size(); ++i)
        if (!eligible(i)) keep[i] = 1;
    return keep;
}

/// Initial seeds at the CHM maxima.
Buf<Tree> initialSeeds(const Scene& scene, const CanopyParams& p) {
    const Grid<float>& chm = scene.chm();
    const auto maxima = chmLocalMaxima(chm, p.minSeedHeightM, p.localMaximumRadiusCells);
    Buf<Tree> trees(maxima.size());
    const std::size_t w = static_cast<std::size_t>(chm.width());
#pragma omp parallel for schedule(static)
    for (std::ptrdiff_t k = 0; k < static_cast<std::ptrdiff_t>(maxima.size()); ++k) {
        const std::size_t i = maxima[static_cast<std::size_t>(k)];
        trees[static_cast<std::size_t>(k)] = apexTree(scene, static_cast<int>(i % w), static_cast<int>(i / w),
                                                      static_cast<std::uint64_t>(k), p.anchorApexTrees != 0,
                                                      [](std::size_t) { return true; });
    }
    return trees;
}

/// Largest crown radius any canopy species reaches at the CHM's largest height.
double largestRadius(const Biome& biome, double maxHeightM) {
    double r = 0;
    for (const auto& s : biome.species)
        if (s.canopy) r = std::max(r, s.allometry.crownRadiusM(std::max(maxHeightM, 0.0)));
    return r;
}

/// Keep flags of the duplicate removal (see removeDuplicateTrees): tallest first, ties to the
/// larger crown then the lower index; a crown goes when its trunk is within minTrunkDistanceM
/// of a kept trunk or its sphere lies inside a kept sphere (centres at apex - radius).
Buf<char> duplicateKeepFlags(const Buf<Crown>& c, double minTrunkDistanceM, double originX,
                                     double originY, double extentX, double extentY) {
    double maxR = 0;
    for (const auto& k : c) maxR = std::max(maxR, k.r);
    // Sorted on packed keys (the comparison read the crowns at random); a strict total
    // order, so the same order as any other sort.
    struct Key {
        double h, r;
        std::size_t i;
    };
    Buf<Key> keys(c.size());
#pragma omp parallel for schedule(static) if (c.size() >= kParallelItems)
    for (std::ptrdiff_t i = 0; i < static_cast<std::ptrdiff_t>(c.size()); ++i)
        keys[static_cast<std::size_t>(i)] = {c[static_cast<std::size_t>(i)].h, c[static_cast<std::size_t>(i)].r, static_cast<std::size_t>(i)};
    std::sort(keys.begin(), keys.end(), [](const Key& a, const Key& b) {
        if (a.h != b.h) return a.h > b.h;
        if (a.r != b.r) return a.r > b.r;
        return a.i < b.i;
    });
    Buf<std::size_t> order(c.size());
    for (std::size_t k = 0; k < keys.size(); ++k) order[k] = keys[k].i;
    const double reach = std::max({minTrunkDistanceM, maxR, 1e-6});
    const PointGrid all(originX, originY, extentX, extentY, reach, c.size(), [&](std::size_t i) { return c[i].x; },
                        [&](std::size_t i) { return c[i].y; }, [&](std::size_t i) { return c[i].r; },
                        [&](std::size_t i) { return c[i].h; });
    const double minD2 = minTrunkDistanceM * minTrunkDistanceM;
    // A crown goes when a kept crown earlier in the order (at least as tall) holds it. The
    // test reads the grid's packed copies (b), not the crowns at random.
    return greedyAccept(
        order, c.size(), [](std::size_t) { return false; },
        [&](std::size_t i, auto&& fn) {
            const Crown& a = c[i];
            all.anyPoint(a.x, a.y, reach, [&](std::int32_t j, const PointGrid::Point& b) {
                const double dx = b.x - a.x, dy = b.y - a.y;
                const double d2 = dx * dx + dy * dy;
                bool holds = d2 < minD2;
                if (!holds) {
                    const double dz = (b.h - b.r) - (a.h - a.r);
                    holds = std::sqrt(d2 + dz * dz) + a.r <= b.r;
                }
                if (holds) fn(static_cast<std::size_t>(j));
                return false;
            });
        },
        [](std::size_t, std::size_t) { return true; });
}

}  // namespace

// ------------------------------------------------------------------------- parameters

const std::vector<CanopyParamField>& canopyParamFields() {
    using K = CanopyParamField::Kind;
    using R = ParamRange;
    static const std::vector<CanopyParamField> fields = {
        {"canopy_threshold_m", "footprint / forested area: CHM >= this; also the species-map threshold", "m", K::Real,
         &CanopyParams::canopyThresholdM, nullptr, R::atLeast(0)},
        {"min_seed_height_m", "trees are seeded, and may move, only where the CHM is >= this", "m", K::Real,
         &CanopyParams::minSeedHeightM, nullptr, R::above(0)},
        {"local_maximum_radius_cells", "initial seeds: strict maxima over a (2R+1)^2 window", "cells", K::Integer, nullptr,
         &CanopyParams::localMaximumRadiusCells, R::closed(1, 64)},
        {"min_visible_fraction", "a tree is starved (removed) below this visible share of its crown disc", "", K::Real,
         &CanopyParams::minVisibleFraction, nullptr, R::closed(0, 1)},
        {"max_iterations", "iterations of the placer at most", "", K::Integer, nullptr, &CanopyParams::maxIterations, R::closed(0, 100000)},
        {"move_factor", "fraction of the way to the visible centroid per iteration (1 = paper)", "", K::Real,
         &CanopyParams::moveFactor, nullptr, R::closed(0, 1)},
        {"ring_samples", "candidate new trees per tree and iteration", "", K::Integer, nullptr, &CanopyParams::ringSamples,
         R::closed(0, 1024)},
        {"ring_factor", "ring radius = factor * (r_i + r_new)", "", K::Real, &CanopyParams::ringFactor, nullptr,
         R::openClosed(0, 10)},
        {"anchor_apex_trees", "trees seeded at CHM maxima stay there, at the CHM's height; 0 = they move", "", K::Integer,
         nullptr, &CanopyParams::anchorApexTrees, R::closed(0, 1)},
        {"seed_merge_saddle_m", "final: of two seeded trees < 2 cells apart with no CHM saddle deeper than this between them the lower goes; 0 = off",
         "m", K::Real, &CanopyParams::seedMergeSaddleM, nullptr, R::atLeast(0)},
        {"seed_merge_radius_fraction", "final seed merge: only trunks closer than this fraction of the taller crown's radius; 10 = no limit",
         "", K::Real, &CanopyParams::seedMergeRadiusFraction, nullptr, R::openClosed(0, 10)},
        {"residual_apices", "each iteration adds trees at maxima of the CHM cells no crown explains; 0 = ring only", "",
         K::Integer, nullptr, &CanopyParams::residualApices, R::closed(0, 1)},
        {"residual_tolerance_m", "a covered cell more than this above the crowns is unexplained", "m", K::Real,
         &CanopyParams::residualToleranceM, nullptr, R::atLeast(0)},
        {"support_fraction", "an added tree needs this share of its disc unexplained; 0 = the paper's rule", "", K::Real,
         &CanopyParams::supportFraction, nullptr, R::closed(0, 1)},
        {"residual_apex_fit", "added trees at residual apices take the sphere under the CHM touching most unexplained cells; hidden apices not output; 0 = at the cell",
         "", K::Integer, nullptr, &CanopyParams::residualApexFit, R::closed(0, 1)},
        {"residual_apex_fit_tolerance_m", "residual apex fit: a cell is touched when the sphere is at most this below the CHM", "m",
         K::Real, &CanopyParams::residualApexFitToleranceM, nullptr, R::atLeast(0)},
        {"apex_snap_radius_fraction", "final: added trees move onto the highest CHM maximum of their own visible cells within this fraction of their crown radius; 0 = off",
         "", K::Real, &CanopyParams::apexSnapRadiusFraction, nullptr, R::closed(0, 10)},
        {"crown_fit_passes", "final: passes of the crown fit (added trees take the sphere that best explains what the other crowns leave of the CHM; hidden apices not output); 0 = off",
         "", K::Integer, nullptr, &CanopyParams::crownFitPasses, R::closed(0, 10)},
        {"crown_fit_reach_m", "crown fit: apex positions searched within this distance of the tree", "m", K::Real,
         &CanopyParams::crownFitReachM, nullptr, R::closed(0, 5)},
        {"crown_fit_hidden_m", "crown fit: a fitted apex this far under the CHM is hidden (at least 2 x the seeds' 90 % margin)", "m",
         K::Real, &CanopyParams::crownFitHiddenM, nullptr, R::closed(0, 100)},
        {"keep_best_state", "end in the iteration of highest coverage; 0 = the last one", "", K::Integer, nullptr,
         &CanopyParams::keepBestState, R::closed(0, 1)},
        {"min_trunk_distance_m", "duplicates: trunks closer than this", "m", K::Real, &CanopyParams::minTrunkDistanceM,
         nullptr, R::atLeast(0)},
        {"coverage_epsilon", "stop when an iteration gains less coverage (share of the forested area)", "", K::Real, &CanopyParams::coverageEpsilon,
         nullptr, R::closed(0, 1)},
        {"seed", "random seed of the ring sampling", "", K::Seed, nullptr, nullptr, R::any(), &CanopyParams::seed},
    };
    return fields;
}

double canopyParamValue(const CanopyParams& p, const CanopyParamField& f) { return f.value(p); }

void setCanopyParam(CanopyParams& p, const std::string& key, double value) {
    setParam(p, canopyParamFields(), key, value, "canopy parameter");
}

void validateCanopyParams(const CanopyParams& p) { validateParams(p, canopyParamFields(), "canopy parameter"); }

// ------------------------------------------------------------------------- public functions

std::vector<std::size_t> chmLocalMaxima(const Grid<float>& chm, double minHeightM, int radiusCells) {
    const auto m = localMaxima(chm, minHeightM, radiusCells, [](std::size_t) { return true; });
    return std::vector<std::size_t>(m.begin(), m.end());
}

CrownRender renderCrowns(const std::vector<Plant>& plants, const Grid<float>& like) {
    Buf<Crown> crowns(plants.size());
    for (std::size_t i = 0; i < plants.size(); ++i)
        crowns[i] = {plants[i].xM, plants[i].yM, plants[i].heightM, plants[i].crownRadiusM};
    Frame f;
    render(crowns, like.width(), like.height(), like.cellSizeM(), like.originX(), like.originY(), f);
    CrownRender out{Grid<float>::like(like, 0.f), Grid<std::int32_t>::like(like, -1)};
    for (std::size_t i = 0; i < like.size(); ++i) {
        out.treeIndex.data()[i] = f.id[i];
        out.surfaceM.data()[i] = f.id[i] >= 0 ? f.depth[i] : 0.f;
    }
    return out;
}

CanopyResult placeCanopy(const Grid<float>& chmM, const Grid<float>& terrainM, const Grid<std::int32_t>& speciesMap,
                         const Biome& biome, const CanopyParams& params, const CanopyProgress& progress) {
    const auto tStart = Clock::now();
    const HugeBlockScope hugeBlocks;  // first: every buffer of the placement is released before it closes
    validateCanopyParams(params);
    if (chmM.empty()) throw ValidationError("canopy placer: the CHM is empty");
    auto geom = [](const auto& g) {
        return std::to_string(g.width()) + " x " + std::to_string(g.height()) + " cells of " + num(g.cellSizeM()) +
               " m, origin (" + num(g.originX()) + ", " + num(g.originY()) + ")";
    };
    if (!chmM.sameGeometry(terrainM))
        throw ValidationError("canopy placer: the CHM (" + geom(chmM) + ") and the terrain (" + geom(terrainM) +
                              ") differ in geometry");
    if (!chmM.sameGeometry(speciesMap))
        throw ValidationError("canopy placer: the CHM (" + geom(chmM) + ") and the species map (" + geom(speciesMap) +
                              ") differ in geometry");
    // The grids are checked in parallel; the serial scans below only run to name the first
    // offending cell.
    bool badChm = false, badMap = false;
    const auto badSpecies = [&](int s) {
        return s < -1 || s >= static_cast<int>(biome.species.size()) ||
               (s >= 0 && !biome.species[static_cast<std::size_t>(s)].canopy);
    };
#pragma omp parallel for schedule(static) reduction(|| : badChm, badMap) if (chmM.size() >= 16 * kParallelItems)
    for (std::ptrdiff_t i = 0; i < static_cast<std::ptrdiff_t>(chmM.size()); ++i) {
        const float v = chmM.data()[static_cast<std::size_t>(i)];
        badChm = badChm || !std::isfinite(v) || v < 0;
        badMap = badMap || badSpecies(speciesMap.data()[static_cast<std::size_t>(i)]);
    }
    for (int iy = 0; iy < chmM.height() && badChm; ++iy)
        for (int ix = 0; ix < chmM.width(); ++ix) {
            const float v = chmM(ix, iy);
            if (!std::isfinite(v) || v < 0)
                throw ValidationError("canopy placer: CHM height " + num(v) + " m at cell (" + std::to_string(ix) + ", " +
                                      std::to_string(iy) + ") is negative or not finite");
        }
    bool anyCanopy = false;
    for (const auto& s : biome.species) anyCanopy = anyCanopy || s.canopy;
    if (!anyCanopy) throw ValidationError("canopy placer: biome '" + biome.name + "' has no canopy species");
    for (std::size_t i = 0; i < speciesMap.size() && badMap; ++i) {
        const int s = speciesMap.data()[i];
        if (badSpecies(s))
            throw ValidationError("canopy placer: species map value " + std::to_string(s) + " at cell (" +
                                  std::to_string(i % static_cast<std::size_t>(speciesMap.width())) + ", " +
                                  std::to_string(i / static_cast<std::size_t>(speciesMap.width())) +
                                  ") is not a canopy species of biome '" + biome.name + "' nor -1");
    }
    const Scene scene(chmM, speciesMap, biome, params);
    const double cell = chmM.cellSizeM();
    const double maxRadius = std::max(largestRadius(biome, chmM.maxValue()), cell);
    CanopyResult result;

    // Initial seeding.
    auto tIter = Clock::now();
    Buf<Tree> trees = initialSeeds(scene, params);
    std::uint64_t nextUid = trees.size();
    result.initialSeeds = trees.size();
    Frame frame;
    Visibility vis;
    renderAndMeasure(trees, chmM, params, frame, vis);
    {
        IterationStats s;
        s.iteration = 0;
        s.added = trees.size();
        fillStats(s, trees.size(), vis);
        s.seconds = secondsSince(tIter);
        result.iterations.push_back(s);
        if (progress) progress(s);
    }

    result.stopReason = params.maxIterations == 0 ? "iteration cap" : "";
    // The best state so far (highest coverage; the stop rule returns to it when the last
    // iterations lost coverage).
    // Room for the trees the iterations add, reserved once (4 x the seeds; more when needed):
    // growing the lists by doubling left the memory of each smaller copy behind, and
    // capacity never written costs nothing (pages are mapped when first touched).
    const std::size_t roomFor = std::max<std::size_t>(4 * trees.size(), 1024);
    trees.reserve(roomFor);
    Buf<Tree> bestTrees;
    bestTrees.reserve(roomFor);
    bestTrees.assign(trees.begin(), trees.end());
    std::size_t bestIteration = 0;
    Buf<Tree> next;
    next.reserve(roomFor);
    Buf<std::uint32_t> from;
    from.reserve(roomFor);
    for (int it = 1; it <= params.maxIterations; ++it) {
        tIter = Clock::now();
        IterationStats s;
        s.iteration = it;

        // Remove sun-starved trees; move the others toward the centroid of their visible crown.
        // (next and from keep their buffers across iterations: fresh large allocations cost
        // page faults on every iteration.)
        next.clear();
        next.reserve(trees.size());
        from.clear();
        from.reserve(trees.size());
        for (std::size_t t = 0; t < trees.size(); ++t)
            if (!starved(t, frame, vis, params.minVisibleFraction)) {
                next.push_back(trees[t]);
                from.push_back(static_cast<std::uint32_t>(t));
            }
        s.removed = trees.size() - next.size();
#pragma omp parallel for schedule(static)
        for (std::ptrdiff_t k = 0; k < static_cast<std::ptrdiff_t>(next.size()); ++k) {
            Tree& tr = next[static_cast<std::size_t>(k)];
            if (tr.apex) continue;  // at its apex already
            const std::size_t t = from[static_cast<std::size_t>(k)];
            const std::int64_t n = vis.visible[t];
            if (n <= 0) continue;
            const double cx = chmM.originX() + (static_cast<double>(vis.sumX[t]) / static_cast<double>(n) + 0.5) * cell;
            const double cy = chmM.originY() + (static_cast<double>(vis.sumY[t]) / static_cast<double>(n) + 0.5) * cell;
            const double nx = tr.x + params.moveFactor * (cx - tr.x);
            const double ny = tr.y + params.moveFactor * (cy - tr.y);
            const double nh = scene.heightAt(nx, ny);
            if (nh < params.minSeedHeightM) continue;  // never walk off the canopy
            tr = scene.makeTree(nx, ny, nh, tr.uid);
        }
        trees.swap(next);

        const float* chmData = chmM.data().data();
        auto unexplained = [&](std::size_t i) { return vis.unexplained[i] != 0; };
        // Support of a crown of radius r centred on cell (ix, iy): the share of its disc's cells
        // (centres inside, clipped to the grid) that are unexplained.
        auto supported = [&](int ix, int iy, double radiusM) {
            if (!(params.supportFraction > 0)) return true;
            const double reach = radiusM / cell;
            const int rows = static_cast<int>(reach);
            std::int64_t disc = 0, open = 0;
            for (int dy = -rows; dy <= rows; ++dy) {
                const int jy = iy + dy;
                if (jy < 0 || jy >= chmM.height()) continue;
                const double half = std::sqrt(std::max(0.0, reach * reach - dy * dy));
                // Strictly inside: the cells whose centre offset |dx| < half.
                const int span = static_cast<int>(std::ceil(half)) - 1;
                if (span < 0) continue;
                const int jx0 = std::max(0, ix - span), jx1 = std::min(chmM.width() - 1, ix + span);
                const std::size_t row = static_cast<std::size_t>(jy) * static_cast<std::size_t>(chmM.width());
                disc += jx1 - jx0 + 1;
                for (int jx = jx0; jx <= jx1; ++jx) open += unexplained(row + static_cast<std::size_t>(jx));
            }
            return static_cast<double>(open) >= params.supportFraction * static_cast<double>(disc);
        };
        // Trunks of the trees so far (rebuilt after the residual apices for the ring).
        auto trunkGrid = [&](const Buf<Tree>& ts) {
            return PointGrid(chmM.originX(), chmM.originY(), chmM.extentX(), chmM.extentY(), maxRadius, ts.size(),
                             [&](std::size_t i) { return ts[i].x; }, [&](std::size_t i) { return ts[i].y; },
                             [&](std::size_t i) { return ts[i].radiusM; });
        };
        if (params.residualApices != 0) {
            // Residual apices: strict maxima of the CHM among the footprint cells that no
            // crown of the last render explains (uncovered, or standing above the rendered
            // surface by more than the tolerance). A tree whose top shows beside a taller
            // neighbour's crown is not a maximum of the CHM, but it is one of this set.
            const auto apices = localMaxima(chmM, params.minSeedHeightM, 1, unexplained);
            // Support and the candidate trees depend on the last render only: in parallel.
            const std::size_t w = static_cast<std::size_t>(chmM.width());
            Buf<Tree> cand(apices.size());
            Buf<std::uint8_t> candSupported(apices.size());
#pragma omp parallel for schedule(dynamic, 64)
            for (std::ptrdiff_t k = 0; k < static_cast<std::ptrdiff_t>(apices.size()); ++k) {
                const std::size_t i = apices[static_cast<std::size_t>(k)];
                const int ix = static_cast<int>(i % w), iy = static_cast<int>(i / w);
                const double r = scene.radiusFor(scene.speciesAt(chmM.cellCentreX(ix), chmM.cellCentreY(iy)), chmData[i]);
                candSupported[static_cast<std::size_t>(k)] = supported(ix, iy, r);
                if (candSupported[static_cast<std::size_t>(k)]) {
                    Tree& c = cand[static_cast<std::size_t>(k)];
                    c = apexTree(scene, ix, iy, 0, params.anchorApexTrees != 0, unexplained);
                    if (params.residualApexFit != 0)
                        fitResidualApex(scene, ix, iy, params.residualApexFitToleranceM, params.residualToleranceM,
                                        unexplained, c);
                }
            }
            // Tallest first: a lower candidate inside an accepted one's crown and below its
            // surface is explained by it (one uncovered crown gives one tree, not one per bump).
            Buf<std::size_t> order;
            for (std::size_t k = 0; k < apices.size(); ++k)
                if (candSupported[k]) order.push_back(k);
            std::stable_sort(order.begin(), order.end(),
                             [&](std::size_t a, std::size_t b) { return chmData[apices[a]] > chmData[apices[b]]; });
            const std::size_t firstNew = trees.size();
            const double d2 = params.minTrunkDistanceM * params.minTrunkDistanceM;
            const PointGrid oldTrunks = trunkGrid(trees);
            auto cellXY = [&](std::size_t k, double& x, double& y) {
                const std::size_t i = apices[k];
                x = chmM.cellCentreX(static_cast<int>(i % w));
                y = chmM.cellCentreY(static_cast<int>(i / w));
            };
            // Candidates' own trunks, for the conflicts among them.
            const PointGrid candTrunks(chmM.originX(), chmM.originY(), chmM.extentX(), chmM.extentY(), maxRadius,
                                       order.size(), [&](std::size_t p) { return cand[order[p]].x; },
                                       [&](std::size_t p) { return cand[order[p]].y; });
            // A candidate is explained by an existing trunk closer than minTrunkDistanceM, or
            // by an accepted candidate earlier in the order: its trunk that close, or its
            // crown above the candidate's cell.
            const Buf<char> accept = greedyAccept(
                order, apices.size(),
                [&](std::size_t k) {
                    double x, y;
                    cellXY(k, x, y);
                    auto near = [&](double px, double py) {
                        return oldTrunks.any(px, py, params.minTrunkDistanceM, [&](std::int32_t j) {
                            const Tree& o = trees[static_cast<std::size_t>(j)];
                            return (o.x - px) * (o.x - px) + (o.y - py) * (o.y - py) < d2;
                        });
                    };
                    // A fitted tree (residualApexFit) moved off the cell: its trunk too.
                    return near(x, y) || (params.residualApexFit != 0 && (cand[k].x != x || cand[k].y != y) &&
                                          near(cand[k].x, cand[k].y));
                },
                [&](std::size_t k, auto&& fn) {
                    double x, y;
                    cellXY(k, x, y);
                    candTrunks.any(x, y, maxRadius, [&](std::int32_t p) {
                        fn(order[static_cast<std::size_t>(p)]);
                        return false;
                    });
                },
                [&](std::size_t k, std::size_t j) {
                    double x, y;
                    cellXY(k, x, y);
                    const Tree& o = cand[j];
                    const double dd = (o.x - x) * (o.x - x) + (o.y - y) * (o.y - y);
                    if (dd < d2) return true;
                    if (dd >= o.radiusM * o.radiusM) return false;
                    const double z = chmData[apices[k]];
                    return z <= o.heightM - o.radiusM + std::sqrt(o.radiusM * o.radiusM - dd) + params.residualToleranceM;
                });
            for (const std::size_t k : order) {
                if (!accept[k]) continue;
                Tree c = cand[k];
                c.uid = nextUid++;
                trees.push_back(c);
            }
            s.added += trees.size() - firstNew;
        }

        // Ring seeding where the CHM is uncovered: candidates per tree in parallel (pure
        // functions of the tree and its random stream), accepted serially in tree order. A
        // candidate needs the same support as a residual apex.
        if (params.ringSamples > 0) {
            const int K = params.ringSamples;
            std::vector<std::array<double, 2>> ring(static_cast<std::size_t>(K));
            for (int k = 0; k < K; ++k) ring[static_cast<std::size_t>(k)] = {std::cos(kTwoPi * k / K), std::sin(kTwoPi * k / K)};
            // Candidates of fixed blocks of trees (independent of the thread count) taken in
            // the trunk grid's bucket order, so that neighbouring trees are visited together
            // (trees appended by earlier iterations lie anywhere in the list: in list order
            // every lookup of the render, the CHM and the trunks missed the cache at 3072^2).
            // Each block lists (tree, candidate) in that order; the lists are then gathered in
            // (tree, direction) order, the order of acceptance.
            const PointGrid trunks = trunkGrid(trees);
            const Buf<std::int32_t>& visit = trunks.bucketOrder();
            constexpr std::size_t kRingBlock = 1024;
            const std::size_t nBlocks = (trees.size() + kRingBlock - 1) / kRingBlock;
            Buf<Buf<Tree>> blockCand(nBlocks);
            Buf<Buf<std::int32_t>> blockOwner(nBlocks);
            Buf<std::uint32_t> candStart(trees.size() + 1, 0);  // first the count per tree
#pragma omp parallel for schedule(dynamic, 1)
            for (std::ptrdiff_t bb = 0; bb < static_cast<std::ptrdiff_t>(nBlocks); ++bb) {
              auto& out = blockCand[static_cast<std::size_t>(bb)];
              auto& owner = blockOwner[static_cast<std::size_t>(bb)];
              const std::size_t t0 = static_cast<std::size_t>(bb) * kRingBlock, t1 = std::min(trees.size(), t0 + kRingBlock);
              for (std::size_t v = t0; v < t1; ++v) {
                const std::int32_t tt = visit[v];
                const Tree& tr = trees[static_cast<std::size_t>(tt)];
                RandomStream rng(params.seed, mixStream(mixStream(kStreamRing, static_cast<std::uint64_t>(it)), tr.uid));
                const double phase = rng.uniform() * kTwoPi / K;
                const double cp = std::cos(phase), sp = std::sin(phase);
                std::uint32_t made = 0;
                for (int k = 0; k < K; ++k) {
                    // Direction: the k-th of K evenly spaced ones, rotated by the tree's phase.
                    const double ux = ring[static_cast<std::size_t>(k)][0] * cp - ring[static_cast<std::size_t>(k)][1] * sp;
                    const double uy = ring[static_cast<std::size_t>(k)][0] * sp + ring[static_cast<std::size_t>(k)][1] * cp;
                    // First guess: a new crown as large as tree i's, tangent to it. It must
                    // stand on an uncovered footprint cell of the last render (cheap test
                    // first); its CHM height then gives r_new and the ring at
                    // ringFactor * (r_i + r_new), which must pass the same test.
                    const double gx = tr.x + params.ringFactor * 2.0 * tr.radiusM * ux;
                    const double gy = tr.y + params.ringFactor * 2.0 * tr.radiusM * uy;
                    if (!scene.inside(gx, gy)) continue;
                    const std::size_t gi = scene.cellIndex(gx, gy);
                    if (!vis.open[gi]) continue;
                    const double gh = scene.heightAt(gx, gy);
                    const double rNew = gh >= params.minSeedHeightM ? scene.radiusFor(scene.speciesAt(gx, gy), gh) : tr.radiusM;
                    const double d = params.ringFactor * (tr.radiusM + rNew);
                    const double x = tr.x + d * ux, y = tr.y + d * uy;
                    if (!scene.inside(x, y)) continue;
                    const std::size_t ci = scene.cellIndex(x, y);
                    if (!vis.open[ci]) continue;
                    const double hNew = scene.heightAt(x, y);
                    if (hNew < params.minSeedHeightM) continue;
                    const bool inCrown = trunks.anyPoint(x, y, maxRadius, [&](std::int32_t, const PointGrid::Point& o) {
                        const double dx = o.x - x, dy = o.y - y;
                        return dx * dx + dy * dy < o.r * o.r;
                    });
                    if (inCrown) continue;
                    const Tree c = scene.makeTree(x, y, hNew, 0);
                    if (!supported(chmM.cellX(x), chmM.cellY(y), c.radiusM)) continue;
                    out.push_back(c);
                    owner.push_back(tt);
                    ++made;
                }
                candStart[static_cast<std::size_t>(tt) + 1] = made;  // each tree is in one block only
              }
            }
            for (std::size_t t = 0; t < trees.size(); ++t) candStart[t + 1] += candStart[t];
            Buf<Tree> cands(candStart.back());
#pragma omp parallel for schedule(dynamic, 1)
            for (std::ptrdiff_t bb = 0; bb < static_cast<std::ptrdiff_t>(nBlocks); ++bb) {
                auto& out = blockCand[static_cast<std::size_t>(bb)];
                const auto& owner = blockOwner[static_cast<std::size_t>(bb)];
                // A tree's candidates are consecutive in its block's list, in direction order.
                for (std::size_t e = 0; e < out.size();) {
                    const std::size_t t = static_cast<std::size_t>(owner[e]);
                    for (std::uint32_t pos = candStart[t]; e < out.size() && static_cast<std::size_t>(owner[e]) == t; ++e, ++pos)
                        cands[pos] = out[e];
                }
                Buf<Tree>().swap(out);
            }
            // Accept in order: a candidate whose trunk lies in an accepted new crown, or whose
            // crown holds an accepted new trunk, is dropped.
            const PointGrid candTrunks = trunkGrid(cands);
            Buf<std::size_t> inOrder(cands.size());
            std::iota(inOrder.begin(), inOrder.end(), 0);
            const Buf<char> accept = greedyAccept(
                inOrder, cands.size(), [](std::size_t) { return false; },
                [&](std::size_t i, auto&& fn) {
                    candTrunks.any(cands[i].x, cands[i].y, maxRadius, [&](std::int32_t j) {
                        fn(static_cast<std::size_t>(j));
                        return false;
                    });
                },
                [&](std::size_t i, std::size_t j) {
                    const Tree& c = cands[i];
                    const Tree& o = cands[j];
                    const double dx = o.x - c.x, dy = o.y - c.y;
                    const double rr = std::max(o.radiusM, c.radiusM);
                    return dx * dx + dy * dy < rr * rr;
                });
            Buf<Tree> fresh;
            for (std::size_t i = 0; i < cands.size(); ++i) {
                if (!accept[i]) continue;
                fresh.push_back(cands[i]);
                fresh.back().uid = nextUid++;
            }
            if (params.residualApexFit != 0) {
                // Each new tree to the highest unexplained cell within half its crown radius
                // (the ring's random spot of the gap moved to a crown's top), fitted there as a
                // residual apex is; it still moves in later iterations. Per tree, in parallel.
#pragma omp parallel for schedule(dynamic, 64)
                for (std::ptrdiff_t k = 0; k < static_cast<std::ptrdiff_t>(fresh.size()); ++k) {
                    Tree& c = fresh[static_cast<std::size_t>(k)];
                    const double x = c.x, y = c.y, reach = 0.5 * c.radiusM;
                    const int cx0 = std::max(0, chmM.cellX(x - reach)), cx1 = std::min(chmM.width() - 1, chmM.cellX(x + reach));
                    const int cy0 = std::max(0, chmM.cellY(y - reach)), cy1 = std::min(chmM.height() - 1, chmM.cellY(y + reach));
                    int bx = -1, by = -1;
                    float bz = -1;
                    for (int jy = cy0; jy <= cy1; ++jy)
                        for (int jx = cx0; jx <= cx1; ++jx) {
                            const double dx = chmM.cellCentreX(jx) - x, dy = chmM.cellCentreY(jy) - y;
                            if (dx * dx + dy * dy > reach * reach) continue;
                            const std::size_t j = chmM.index(jx, jy);
                            if (!unexplained(j) || !(chmData[j] > bz)) continue;
                            bz = chmData[j];
                            bx = jx;
                            by = jy;
                        }
                    if (bx < 0 || !(bz >= params.minSeedHeightM)) continue;
                    c = apexTree(scene, bx, by, c.uid, false, unexplained);
                    fitResidualApex(scene, bx, by, params.residualApexFitToleranceM, params.residualToleranceM, unexplained, c);
                }
            }
            s.added += fresh.size();
            trees.insert(trees.end(), fresh.begin(), fresh.end());
        }

        renderAndMeasure(trees, chmM, params, frame, vis);
        fillStats(s, trees.size(), vis);
        s.seconds = secondsSince(tIter);
        const double gain = s.coverage - result.iterations.back().coverage;
        result.iterations.push_back(s);
        if (progress) progress(s);
        if (s.coverage > result.iterations[bestIteration].coverage) {
            if (bestTrees.capacity() < trees.size()) bestTrees.reserve(trees.size() + trees.size() / 4);
            bestTrees.assign(trees.begin(), trees.end());
            bestIteration = result.iterations.size() - 1;
        }
        if (gain < params.coverageEpsilon) {
            result.stopReason = "coverage gain " + num(gain) + " below epsilon " + num(params.coverageEpsilon);
            break;
        }
        if (it == params.maxIterations) result.stopReason = "iteration cap (" + std::to_string(it) + ")";
    }

    if (params.keepBestState != 0 && bestIteration + 1 != result.iterations.size()) {
        trees = bestTrees;
        renderAndMeasure(trees, chmM, params, frame, vis);
        result.stopReason += "; back to iteration " + std::to_string(result.iterations[bestIteration].iteration) +
                             " (coverage " + num(result.iterations[bestIteration].coverage) + ")";
    }
    // Final clean-up: added trees onto their apex, starved trees of the last render, then
    // duplicates, tallest first.
    tIter = Clock::now();
    IterationStats fin;
    fin.iteration = -1;
    if (params.apexSnapRadiusFraction > 0) {
        // The render in `frame` is that of `trees` (the last iteration or the best state).
        const std::uint64_t seeds = result.initialSeeds;
        std::size_t snapped = 0;
#pragma omp parallel for schedule(dynamic, 256) reduction(+ : snapped)
        for (std::ptrdiff_t k = 0; k < static_cast<std::ptrdiff_t>(trees.size()); ++k) {
            Tree& t = trees[static_cast<std::size_t>(k)];
            if (t.uid < seeds || t.hidden) continue;
            snapped += snapToOwnApex(scene, frame.id, static_cast<std::int32_t>(k), params.apexSnapRadiusFraction * t.radiusM,
                                     params.minSeedHeightM, t);
        }
        result.apexSnapped = snapped;
    }
    {
        Buf<Tree>& kept = next;
        kept.clear();
        kept.reserve(trees.size());
        for (std::size_t t = 0; t < trees.size(); ++t)
            if (!starved(t, frame, vis, params.minVisibleFraction)) kept.push_back(trees[t]);
        fin.removed = trees.size() - kept.size();
        trees.swap(kept);
    }
    {
        // Trees whose fitted apex lies under another crown: their top is not in the CHM.
        Buf<Tree>& kept = next;
        kept.clear();
        for (const Tree& t : trees)
            if (!t.hidden) kept.push_back(t);
        result.hiddenApexTrees = trees.size() - kept.size();
        trees.swap(kept);
    }
    if (params.seedMergeSaddleM > 0) {
        // Two maxima of one crown top's lidar noise: the lower seed goes. Done here rather
        // than at the seeding: removing seeds there changed the iterations' additions and
        // cost recall (docs/canopy.md, "One top, one seed").
        const std::uint64_t seeds = result.initialSeeds;
        const auto keep = seedMergeKeepFlags(trees, chmM, params.seedMergeSaddleM, params.seedMergeRadiusFraction,
                                             [&](std::size_t i) { return trees[i].apex && trees[i].uid < seeds; });
        Buf<Tree>& kept = next;
        kept.clear();
        for (std::size_t i = 0; i < trees.size(); ++i)
            if (keep[i]) kept.push_back(trees[i]);
        result.seedsMerged = trees.size() - kept.size();
        trees.swap(kept);
    }
    auto removeDuplicates = [&] {
        const auto keep = duplicateKeepFlags(crownsOf(trees), params.minTrunkDistanceM, chmM.originX(), chmM.originY(),
                                             chmM.extentX(), chmM.extentY());
        Buf<Tree>& kept = next;
        kept.clear();
        for (std::size_t i = 0; i < trees.size(); ++i)
            if (keep[i]) kept.push_back(trees[i]);
        result.duplicatesRemoved += trees.size() - kept.size();
        trees.swap(kept);
    };
    removeDuplicates();
    // The crown fit runs on the cleaned list (two added trees on one crown would each see the
    // other explain it); then its hidden trees go, and the duplicates of trees it moved
    // onto one apex.
    double crownFitRaiseM = 0;  // the crown fit: largest rise of a kept tree onto the CHM (below)
    if (params.crownFitPasses > 0) {
        // The crown fit: every added tree (not the seeds) takes the sphere that best explains
        // what the other crowns leave of the CHM (fitCrown), crownFitPasses times, each pass on
        // a fresh render of the last; then the trees whose fitted apex lies under another crown
        // by more than the hidden margin are not output (their top is not in the CHM). The
        // margin is max(crownFitHiddenM, kFitSeedMarginFactor x the kFitSeedQuantile quantile
        // of the margins of every kFitSeedStride-th seed, fitted in the last pass but not moved):
        // seeds stand on true tops, so their margins say how far the crowns of this CHM are
        // from spheres (about 0.05 m on a CHM of spheres, 1.3-1.9 m on the lidar-like ones).
        const std::uint64_t seeds = result.initialSeeds;
        Buf<double> margin(trees.size(), 0.0);
        Buf<Tree> fitted;
        Buf<std::pair<std::uint64_t, std::uint32_t>> order;
        constexpr int kFitBandRows = 8;
        for (int pass = 1; pass <= params.crownFitPasses; ++pass) {
            const bool last = pass == params.crownFitPasses;
            Buf<Crown>& cr = frame.crowns;
            cr.resize(trees.size());
            for (std::size_t i = 0; i < trees.size(); ++i) cr[i] = {trees[i].x, trees[i].y, trees[i].heightM, trees[i].radiusM};
            render<true>(cr, chmM.width(), chmM.height(), cell, chmM.originX(), chmM.originY(), frame);
            fitted.assign(trees.begin(), trees.end());
            // The trees to fit, in raster order of bands of kFitBandRows rows (x inside a
            // band): each fit reads a window of the CHM and of the render around its tree,
            // and in list order (trees appended by the iterations, spread over the map)
            // neighbouring fits rarely share those cache lines. Each fit reads only the CHM
            // and the render, so the order does not change the result.
            order.clear();
            for (std::size_t k = 0; k < trees.size(); ++k) {
                const Tree& t = trees[k];
                const bool seed = t.uid < seeds;
                if (t.hidden || (seed && (!last || t.uid % kFitSeedStride != 0))) continue;
                const int cx = std::clamp(chmM.cellX(t.x), 0, chmM.width() - 1);
                const int cy = std::clamp(chmM.cellY(t.y), 0, chmM.height() - 1);
                const std::uint64_t key = (static_cast<std::uint64_t>(cy / kFitBandRows) << 40) |
                                          (static_cast<std::uint64_t>(cx) << 20) | static_cast<std::uint64_t>(cy % kFitBandRows);
                order.push_back({key, static_cast<std::uint32_t>(k)});
            }
            std::sort(order.begin(), order.end());
#pragma omp parallel for schedule(dynamic, 64)
            for (std::ptrdiff_t j = 0; j < static_cast<std::ptrdiff_t>(order.size()); ++j) {
                const std::size_t k = order[static_cast<std::size_t>(j)].second;
                margin[k] = fitCrown(scene, frame, static_cast<std::int32_t>(k), params.crownFitReachM, params.minSeedHeightM, fitted[k]);
            }
            for (std::size_t k = 0; k < trees.size(); ++k) {
                if (trees[k].uid >= seeds && !trees[k].hidden) trees[k] = fitted[k];
            }
        }
        Buf<double> seedMargins;
        for (std::size_t k = 0; k < trees.size(); ++k)
            if (trees[k].uid < seeds && trees[k].uid % kFitSeedStride == 0 && !trees[k].hidden) seedMargins.push_back(margin[k]);
        std::sort(seedMargins.begin(), seedMargins.end());
        const double q = seedMargins.empty() ? 0.0
                                             : seedMargins[std::min(seedMargins.size() - 1,
                                                                    static_cast<std::size_t>(kFitSeedQuantile *
                                                                                             static_cast<double>(seedMargins.size())))];
        const double hiddenMargin = std::max(params.crownFitHiddenM, kFitSeedMarginFactor * q);
        crownFitRaiseM = kFitSeedMarginFactor * q;
        std::size_t hidden = 0;
        for (std::size_t k = 0; k < trees.size(); ++k)
            if (trees[k].uid >= seeds && !trees[k].hidden && margin[k] > hiddenMargin) {
                trees[k].hidden = true;
                ++hidden;
            }
        result.crownFitHidden = hidden;
        result.crownFitHiddenMarginM = hiddenMargin;
    }
    if (params.crownFitPasses > 0) {
        Buf<Tree>& kept = next;
        kept.clear();
        for (const Tree& t : trees)
            if (!t.hidden) kept.push_back(t);
        result.hiddenApexTrees += trees.size() - kept.size();
        trees.swap(kept);
        // The fit's sphere is the least-squares crown: on a CHM of pointed or flat-topped
        // crowns it stands under the top (about a metre on a conifer), so a kept tree whose
        // CHM stands above its sphere's apex takes the CHM's height at its trunk, raised by at
        // most what the seeds' misfit allows (2 x its 90 % quantile: about 0.1 m on a CHM of
        // spheres, 2.6-3.8 m on lidar-like ones), since the CHM beside a small top can be a
        // taller neighbour's flank.
        {
            const std::uint64_t seeds = result.initialSeeds;
#pragma omp parallel for schedule(static)
            for (std::ptrdiff_t k = 0; k < static_cast<std::ptrdiff_t>(trees.size()); ++k) {
                Tree& t = trees[static_cast<std::size_t>(k)];
                if (t.uid < seeds) continue;
                const double hc = std::min(scene.heightAt(t.x, t.y), t.heightM + crownFitRaiseM);
                if (!(hc > t.heightM)) continue;
                const bool anchored = t.apex;
                t = scene.makeTree(t.x, t.y, hc, t.uid);
                t.apex = anchored;
            }
        }
        removeDuplicates();
    }
    renderAndMeasure(trees, chmM, params, frame, vis);
    fillStats(fin, trees.size(), vis);
    fin.seconds = secondsSince(tIter);
    result.final = fin;
    if (progress) progress(fin);

    resizeFresh(result.trees, trees.size());  // 34 MB at 3072^2: its pages faulted in by every thread
    std::size_t fallbackTrees = 0;
#pragma omp parallel for schedule(static) reduction(+ : fallbackTrees) if (trees.size() >= kParallelItems)
    for (std::ptrdiff_t k = 0; k < static_cast<std::ptrdiff_t>(trees.size()); ++k) {
        const Tree& t = trees[static_cast<std::size_t>(k)];
        Plant& p = result.trees[static_cast<std::size_t>(k)];
        p.speciesId = t.species;
        p.xM = t.x;
        p.yM = t.y;
        p.groundZM = terrainM.sampleBilinear(t.x, t.y);
        p.heightM = t.heightM;
        p.crownRadiusM = t.radiusM;
        if (!scene.mapped(t.x, t.y)) ++fallbackTrees;
    }
    result.fallbackTrees = fallbackTrees;
    result.seconds = secondsSince(tStart);
    return result;
}

std::size_t removeDuplicateTrees(std::vector<Plant>& plants, double minTrunkDistanceM) {
    if (!std::isfinite(minTrunkDistanceM) || minTrunkDistanceM < 0)
        throw ValidationError("removeDuplicateTrees: minimum trunk distance must be >= 0, got " + num(minTrunkDistanceM));
    if (plants.empty()) return 0;
    Buf<Crown> crowns(plants.size());
    double x0 = plants[0].xM, x1 = x0, y0 = plants[0].yM, y1 = y0;
    for (std::size_t i = 0; i < plants.size(); ++i) {
        const Plant& p = plants[i];
        crowns[i] = {p.xM, p.yM, p.heightM, p.crownRadiusM};
        x0 = std::min(x0, p.xM);
        x1 = std::max(x1, p.xM);
        y0 = std::min(y0, p.yM);
        y1 = std::max(y1, p.yM);
    }
    const auto keep = duplicateKeepFlags(crowns, minTrunkDistanceM, x0, y0, x1 - x0, y1 - y0);
    std::vector<Plant> kept;
    for (std::size_t i = 0; i < plants.size(); ++i)
        if (keep[i]) kept.push_back(plants[i]);
    const std::size_t removed = plants.size() - kept.size();
    plants.swap(kept);
    return removed;
}

// ------------------------------------------------------------------------- configuration

void readCanopyConfig(StrictTable& t, CanopyParams& canopy, SpeciesMapParams& speciesMap) {
    readParams(t, canopy, canopyParamFields());
    speciesMap.canopyThresholdM = canopy.canopyThresholdM;
    readParams(t, speciesMap, speciesMapParamFields());
    try {
        validateCanopyParams(canopy);
        validateParams(speciesMap, speciesMapParamFields(), "species map parameter");
    } catch (const ValidationError& e) {
        throw ValidationError(t.file() + ": " + (t.context().empty() ? "" : t.context() + ": ") + e.what());
    }
}

void loadCanopyConfig(const std::string& path, CanopyParams& canopy, SpeciesMapParams& speciesMap) {
    const toml::table root = parseTomlFile(path);
    if (const toml::node* n = root.get("canopy")) {
        const toml::table* t = n->as_table();
        if (!t) throw ValidationError(path + ": 'canopy' must be a table");
        StrictTable table(*t, path, "[canopy]");
        readCanopyConfig(table, canopy, speciesMap);
        table.finish();
    } else {
        StrictTable table(root, path, "");
        readCanopyConfig(table, canopy, speciesMap);
        table.finish();
    }
}

// ------------------------------------------------------------------------- files

// The canopy record flattened into the canopy file's contents (core/canopy_file.h writes it).
void writeCanopyFile(const std::string& path, const CanopyRecord& rec, const Biome& biome) {
    CanopyFileContents c;
    c.trees = rec.result.trees;
    c.speciesMap = rec.speciesMap;
    c.chmM = rec.chmM;
    c.terrainM = rec.terrainM;
    c.iterations = rec.result.iterations;
    c.iterations.push_back(rec.result.final);  // the final clean-up as iteration -1
    c.stopReason = rec.result.stopReason;
    c.initialSeeds = static_cast<std::int64_t>(rec.result.initialSeeds);
    c.duplicatesRemoved = static_cast<std::int64_t>(rec.result.duplicatesRemoved);
    c.fallbackTrees = static_cast<std::int64_t>(rec.result.fallbackTrees);
    c.seconds = rec.result.seconds;
    for (const auto& t : rec.targets)
        c.targets.push_back(CanopyTargetRow{t.species, t.requested, t.achieved, t.reachable, t.weight, t.alpha, t.feasible,
                                            t.iterations});
    if (!rec.speciesParams.localWeights.empty()) {  // the first brush's mask
        const auto& lw = rec.speciesParams.localWeights.front();
        Grid<std::int32_t> m32 = Grid<std::int32_t>::like(*lw.mask, 0);
        for (std::size_t i = 0; i < m32.size(); ++i) m32.data()[i] = lw.mask->data()[i] ? 1 : 0;
        c.targetMask = std::move(m32);
    }
    c.seed = rec.params.seed;
    for (const auto& field : canopyParamFields())
        if (field.kind != CanopyParamField::Kind::Seed) c.realParameters.emplace_back(field.key, canopyParamValue(rec.params, field));
    for (const auto& field : speciesMapParamFields()) {  // reals as double, integers as int64 attributes
        if (field.kind == SpeciesMapParamField::Kind::Real)
            c.realParameters.emplace_back(field.key, field.value(rec.speciesParams));
        else
            c.integerParameters.emplace_back(field.key, static_cast<std::int64_t>(rec.speciesParams.*(field.integer)));
    }
    c.speciesWeights.assign(biome.species.size(), 1.0);
    for (std::size_t i = 0; i < rec.speciesParams.weights.size() && i < c.speciesWeights.size(); ++i)
        c.speciesWeights[i] = rec.speciesParams.weights[i];
    c.terrainSource = rec.terrainSource;
    c.chmSource = rec.chmSource;
    c.abioticsSource = rec.abioticsSource;
    c.biomeSource = rec.biomeSource;
    c.maskSource = rec.maskSource;
    eco::writeCanopyFile(path, c, biome);
}

void writeCanopyPng(const std::string& path, const std::vector<Plant>& trees, const Grid<float>& terrainM,
                    const Biome& biome, const std::string& title) {
    if (terrainM.empty()) throw ValidationError(path + ": cannot draw on an empty terrain");
    const CrownRender r = renderCrowns(trees, terrainM);
    // Shade crowns and ground together: the hillshade of the terrain plus the crown surface.
    Grid<float> surface = terrainM;
    for (std::size_t i = 0; i < surface.size(); ++i) surface.data()[i] += r.surfaceM.data()[i];
    const Grid<float> shade = hillshade(surface);
    const int w = terrainM.width(), h = terrainM.height();
    const int factor = downsampleFactor(w, h, 1024);
    const int pw = std::max(1, w / factor), ph = std::max(1, h / factor);
    Canvas picture(pw, ph);
    for (int py = 0; py < ph; ++py)
        for (int px = 0; px < pw; ++px) {
            const int ix = std::min(w - 1, px * factor + factor / 2);
            const int iy = std::max(0, h - 1 - (py * factor + factor / 2));  // image row 0 = north
            const std::size_t i = terrainM.index(ix, iy);
            const float s = shade.data()[i];
            const std::int32_t t = r.treeIndex.data()[i];
            Rgb c;
            if (t >= 0) {
                const Rgb base = categoryColour(trees[static_cast<std::size_t>(t)].speciesId);
                const float k = 0.35f + 0.65f * s;
                c = {base[0] * k, base[1] * k, base[2] * k};
            } else {
                const float g = 0.30f + 0.55f * s;
                c = {g, g, g};
            }
            picture.set(px, py, c);
        }
    std::vector<std::size_t> counts(biome.species.size(), 0);
    for (const auto& t : trees)
        if (t.speciesId >= 0 && static_cast<std::size_t>(t.speciesId) < counts.size()) ++counts[static_cast<std::size_t>(t.speciesId)];
    std::vector<std::pair<std::string, Rgb>> entries;
    for (std::size_t s = 0; s < counts.size(); ++s)
        if (counts[s] > 0)
            entries.emplace_back(biome.species[s].name + " (" + std::to_string(counts[s]) + ")",
                                 categoryColour(static_cast<int>(s)));
    entries.emplace_back("ground (hillshade)", Rgb{0.6f, 0.6f, 0.6f});
    const std::string heading = title + " (" + std::to_string(trees.size()) + ")";
    withLegend(mapFrame(picture, gridPictureExtent(terrainM, factor, pw, ph)).canvas, heading, entries).writePng(path);
}

}  // namespace eco::synth
