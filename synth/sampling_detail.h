// Pieces shared by the synthesizer's samplers (synth/undergrowth.cpp: the dart sampler and
// refinement; synth/structured_sampler.cpp: the structured sampler). Private to synth/.
#pragma once

#include <omp.h>

#include <algorithm>
#include <chrono>
#include <ctime>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <limits>
#include <memory>
#include <new>
#include <type_traits>
#include <vector>

#ifdef __linux__
#include <sys/mman.h>
#endif

#include "biome.h"
#include "grid.h"
#include "memory.h"
#include "plants.h"
#include "point_pattern.h"
#include "rng.h"
#include "undergrowth.h"

namespace eco::synth::detail {

/// Wall and process-CPU seconds of a sampler's phases: each call closes the phase called
/// `name` (adding to it when a pass repeats it) and starts the next.
class PhaseTimer {
public:
    explicit PhaseTimer(std::vector<UndergrowthSample::Phase>& phases)
        : phases_(phases), mark_(std::chrono::steady_clock::now()), cpuMark_(std::clock()) {}
    void operator()(const char* name) {
        const auto now = std::chrono::steady_clock::now();
        const std::clock_t cpu = std::clock();
        const double wall = std::chrono::duration<double>(now - mark_).count();
        const double cpuS = static_cast<double>(cpu - cpuMark_) / CLOCKS_PER_SEC;
        mark_ = now;
        cpuMark_ = cpu;
        for (UndergrowthSample::Phase& p : phases_)
            if (p.name == name) {
                p.wallS += wall;
                p.cpuS += cpuS;
                return;
            }
        phases_.push_back(UndergrowthSample::Phase{name, wall, cpuS});
    }
    /// Starts the next phase now, recording nothing (time already accounted otherwise).
    void restart() {
        mark_ = std::chrono::steady_clock::now();
        cpuMark_ = std::clock();
    }

private:
    std::vector<UndergrowthSample::Phase>& phases_;
    std::chrono::steady_clock::time_point mark_;
    std::clock_t cpuMark_;
};

/// Asks the kernel for transparent huge pages (2 MB) over the whole 2 MB pages inside
/// [p, p + bytes), where it offers them on request (Linux, THP mode "madvise"): the
/// samplers' large arrays are written once, and on this project's virtual machines a
/// fresh 4 kB page fault cost 10-30 us (a 2 MB one about as much as 50 small ones), which
/// made page faults a large share of the sampler at 3072^2 (docs/synth.md, Performance).
/// A hint only: nothing changes but the time.
inline void adviseHugePages(void* p, std::size_t bytes) {
#if defined(__linux__) && defined(MADV_HUGEPAGE)
    constexpr std::uintptr_t kHuge = std::uintptr_t{1} << 21;
    const std::uintptr_t a = (reinterpret_cast<std::uintptr_t>(p) + kHuge - 1) & ~(kHuge - 1);
    const std::uintptr_t b = (reinterpret_cast<std::uintptr_t>(p) + bytes) & ~(kHuge - 1);
    if (b > a) madvise(reinterpret_cast<void*>(a), b - a, MADV_HUGEPAGE);
#else
    (void)p;
    (void)bytes;
#endif
}

/// An uninitialised array of trivially copyable items (a std::vector clears its items on
/// one thread first; here the threads that fill it touch its pages), on huge pages when it
/// is large (adviseHugePages).
template <typename T>
class RawArray {
    static_assert(std::is_trivially_copyable<T>::value && std::is_trivially_default_constructible<T>::value,
                  "RawArray holds plain items");
    struct Free {
        void operator()(T* q) const { std::free(q); }
    };

public:
    RawArray() = default;
    explicit RawArray(std::size_t count) : n_(count) {
        if (count == 0) return;
        constexpr std::size_t kHuge = std::size_t{1} << 21;
        const std::size_t bytes = count * sizeof(T);
        const bool large = bytes >= 2 * kHuge;
        const std::size_t align = large ? kHuge : 64;
        void* q = std::aligned_alloc(align, (bytes + align - 1) / align * align);
        if (q == nullptr) throw std::bad_alloc();
        if (large) adviseHugePages(q, bytes);
        p_.reset(static_cast<T*>(q));
    }
    T* data() { return p_.get(); }
    const T* data() const { return p_.get(); }
    std::size_t size() const { return n_; }
    T& operator[](std::size_t i) { return p_.get()[i]; }
    const T& operator[](std::size_t i) const { return p_.get()[i]; }

private:
    std::unique_ptr<T, Free> p_;
    std::size_t n_ = 0;
};

/// Per species: the bitmask of its own sub-biomes (Table 3 column); a seed package of
/// combination m can hold species s when mask[s] & m != 0 (the simulator's rule).
inline std::vector<int> speciesSubBiomeMasks(const Biome& biome) {
    std::vector<int> m(biome.species.size(), 0);
    for (std::size_t s = 0; s < biome.species.size(); ++s)
        for (int b : biome.species[s].subBiomes)
            if (b >= 1 && b <= 30) m[s] |= 1 << (b - 1);
    return m;
}

/// Distinct values of an int grid, ascending. Rows in parallel, merged in row order.
inline std::vector<std::int32_t> distinctValues(const Grid<std::int32_t>& g) {
    const int h = g.height(), w = g.width();
    std::vector<std::vector<std::int32_t>> rows(static_cast<std::size_t>(h));
#pragma omp parallel for schedule(static)
    for (int iy = 0; iy < h; ++iy) {
        auto& v = rows[static_cast<std::size_t>(iy)];
        std::int32_t last = std::numeric_limits<std::int32_t>::min();
        for (int ix = 0; ix < w; ++ix) {
            const std::int32_t x = g(ix, iy);
            if (x == last) continue;
            last = x;
            if (std::find(v.begin(), v.end(), x) == v.end()) v.push_back(x);
        }
    }
    std::vector<std::int32_t> all;
    for (auto& r : rows) all.insert(all.end(), r.begin(), r.end());
    std::sort(all.begin(), all.end());
    all.erase(std::unique(all.begin(), all.end()), all.end());
    return all;
}

/// Trunks as a point grid, for the exclusion discs.
struct TrunkIndex {
    PointGrid grid;
    std::vector<double> radius2;  ///< per sorted point: exclusion radius^2
    double maxRadius = 0;

    TrunkIndex(const std::vector<Plant>& canopy, double factor) {
        if (!(factor > 0) || canopy.empty()) return;
        std::vector<double> x, y, r2;
        x.reserve(canopy.size());  // no copies left behind by growth: fresh pages cost
        y.reserve(canopy.size());
        r2.reserve(canopy.size());
        for (const auto& t : canopy) {
            x.push_back(t.xM);
            y.push_back(t.yM);
            const double r = factor * t.crownRadiusM;
            r2.push_back(r * r);
            maxRadius = std::max(maxRadius, r);
        }
        if (!(maxRadius > 0)) return;
        grid = PointGrid(x, y, std::max(1.0, 2.0 * maxRadius));
        radius2 = grid.permuted(r2);
    }
    bool onTrunk(double x, double y) const {
        if (!(maxRadius > 0)) return false;
        bool hit = false;
        grid.forEachWithin(x, y, maxRadius, [&](std::size_t s, double, double, double d2) {
            if (d2 < radius2[s]) hit = true;
        });
        return hit;
    }
};

/// Poisson(lambda) for lambda <= 100 by inversion of the uniform u, given exp(-lambda);
/// at most `cap`. poissonCount's step, also for callers that draw u in a batch: for
/// 0 < lambda <= 100, poissonInvert(u, lambda, std::exp(-lambda), cap) with u the stream's
/// next uniform is poissonCount(stream, lambda, cap) (and uses that one uniform only).
inline int poissonInvert(double u, double lambda, double expNegLambda, int cap) {
    double p = expNegLambda, cdf = p;
    int k = 0;
    while (u > cdf && k < cap) {
        ++k;
        p *= lambda / k;
        cdf += p;
        if (p < 1e-300 && k > lambda) break;  // numerically exhausted
    }
    return k;
}

/// Poisson(lambda) by inversion, one uniform per piece of at most 100 of the mean (so that
/// exp(-lambda) never underflows); capped at `cap`.
inline int poissonCount(RandomStream& rs, double lambda, int cap, double expNegLambda = -1) {
    if (expNegLambda >= 0 && lambda <= 100.0) return poissonInvert(rs.uniform(), lambda, expNegLambda, cap);  // exp(-lambda) given
    int n = 0;
    while (lambda > 0 && n < cap) {
        const double piece = std::min(lambda, 100.0);
        lambda -= piece;
        const double u = rs.uniform();
        n += poissonInvert(u, piece, std::exp(-piece), cap);
    }
    return std::min(n, cap);
}


/// Where cumulative share u in [0, 1) of a histogram falls: bin k and the fraction t in
/// [0, 1) of that bin's count below it. -1: the histogram is empty (or malformed); 0: u falls
/// in the overflow; 1: found.
inline int histogramLocate(const DbHistogram& h, double u, std::size_t& bin, double& t) {
    double total = h.overflow;
    for (double c : h.counts) total += c;
    if (!(total > 0) || h.edges.size() != h.counts.size() + 1) return -1;
    const double target = u * total;
    double cum = 0;
    for (std::size_t k = 0; k < h.counts.size(); ++k) {
        const double c = h.counts[k];
        if (c > 0 && cum + c > target) {
            bin = k;
            t = (target - cum) / c;
            return 1;
        }
        cum += c;
    }
    return 0;
}

/// Per species: its histograms (height, or crown radius when `radius`) of every region added
/// up, on the first region's edges: the fallback of a region without plants of a species.
inline std::vector<DbHistogram> pooledSizeHistograms(const BiomeDatabase& db, bool radius) {
    std::vector<DbHistogram> pooled(static_cast<std::size_t>(db.speciesCount()));
    for (const auto& reg : db.regions)
        for (std::size_t s = 0; s < pooled.size(); ++s) {
            const DbHistogram& src = radius ? reg.crownRadius[s] : reg.height[s];
            DbHistogram& dst = pooled[s];
            if (dst.edges.empty()) {
                dst.edges = src.edges;
                dst.counts.assign(src.counts.size(), 0.0);
            }
            if (dst.counts.size() != src.counts.size()) continue;
            for (std::size_t k = 0; k < src.counts.size(); ++k) dst.counts[k] += src.counts[k];
            dst.overflow += src.overflow;
        }
    return pooled;
}

/// Cells that a trunk's exclusion disc may reach: only candidates there need the trunk query.
inline Grid<std::uint8_t> nearTrunkCells(const Grid<float>& geometry, const std::vector<Plant>& canopy, double factor) {
    Grid<std::uint8_t> near = Grid<std::uint8_t>::like(geometry, 0);
    if (!(factor > 0)) return near;
    const int w = geometry.width(), h = geometry.height();
    // Each thread marks the cells of its own share of the rows, from every tree.
#pragma omp parallel
    {
        const long long nt = omp_get_num_threads(), t0 = omp_get_thread_num();
        const int rowLo = static_cast<int>(h * t0 / nt), rowHi = static_cast<int>(h * (t0 + 1) / nt) - 1;
        for (const Plant& t : canopy) {
            const double re = factor * t.crownRadiusM;
            const int x0 = std::max(0, geometry.cellX(t.xM - re)), x1 = std::min(w - 1, geometry.cellX(t.xM + re));
            const int y0 = std::max(rowLo, geometry.cellY(t.yM - re)), y1 = std::min(rowHi, geometry.cellY(t.yM + re));
            for (int iy = y0; iy <= y1; ++iy)
                for (int ix = x0; ix <= x1; ++ix) near(ix, iy) = 1;
        }
    }
    return near;
}

/// A candidate plant (the samplers' compact form before sizes are drawn).
struct Candidate {
    std::uint64_t key;   ///< random priority: each (region, species) keeps its lowest keys; keys the size draw
    float dx, dy;        ///< position relative to the terrain origin, m
    std::uint32_t cell;  ///< cell index of the position
    std::uint16_t species;
    std::uint16_t pass;
};

/// Per (region r, species s, canopy-context bin c), flattened as (r * nSpecies + s) * nCtx + c:
/// the database's density of s (plants per m^2) in context c of region r; nCtx is the
/// database's number of context bins, or 1 (the region's density x the species' share) for a
/// database without context statistics. 0 for a species the region does not hold.
std::vector<double> speciesContextDensities(const BiomeDatabase& db);

/// Sizes of the accepted plants (docs/synth.md 2a "Sizes"): height from the region's
/// histogram of the plant's context (under a crown or in the open), truncated below the
/// lowest crown above; crown radius by allometry. Fills out.plants, out.plantRegion and
/// out.heightsLimitedByCrown in the order of `accepted`. Parallel over plants, each keyed by
/// its own random key (Candidate::key). Every candidate's cell must lie in a region.
/// Defined in synth/structured_sampler.cpp; the structured and Deussen samplers use it.
/// The plants are accepted[order[i]] for i < count (accepted[i] when order is null).
void drawSizes(const BiomeDatabase& db, const Biome& biome, const std::vector<Plant>& canopy, const ClusterMap& map,
               const Grid<float>& terrainM, const SynthParams& params, bool withContext, const Candidate* accepted,
               const std::uint32_t* order, std::size_t count, UndergrowthSample& out);
inline void drawSizes(const BiomeDatabase& db, const Biome& biome, const std::vector<Plant>& canopy, const ClusterMap& map,
                      const Grid<float>& terrainM, const SynthParams& params, bool withContext,
                      const std::vector<Candidate>& accepted, UndergrowthSample& out) {
    drawSizes(db, biome, canopy, map, terrainM, params, withContext, accepted.data(), nullptr, accepted.size(), out);
}

}  // namespace eco::synth::detail

namespace eco::synth {
/// The structured sampler (synth/structured_sampler.cpp); sampleUndergrowth calls it after
/// checking the inputs when params.method is Structured.
UndergrowthSample sampleStructured(const BiomeDatabase& db, const Biome& biome, const std::vector<Plant>& canopy,
                                   const ClusterMap& map, const Grid<float>& terrainM, const SynthParams& params);
/// The Deussen 1998 sampler (synth/deussen_sampler.cpp); sampleUndergrowth calls it after
/// checking the inputs when params.method is Deussen. densityImage may be null.
UndergrowthSample sampleDeussen(const BiomeDatabase& db, const Biome& biome, const std::vector<Plant>& canopy,
                                const ClusterMap& map, const Grid<float>& terrainM, const SynthParams& params,
                                const Grid<float>* densityImage);
/// The Xu 2015 sampler (synth/xu2015_sampler.cpp); sampleUndergrowth calls it after checking
/// the inputs when params.method is Xu2015.
UndergrowthSample sampleXu2015(const BiomeDatabase& db, const Biome& biome, const std::vector<Plant>& canopy,
                               const ClusterMap& map, const Grid<float>& terrainM, const SynthParams& params,
                               const XuExemplar& exemplar);
}  // namespace eco::synth
