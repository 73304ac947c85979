// The structured undergrowth sampler (docs/synth.md section 2): plants placed conditioned on
// the canopy (density of each species by its depth under the canopy cover) and on each
// other (a clustered Cox process whose pair correlation is fitted to the database's), sizes
// drawn by context below the crown above, crown radius by allometry.
//
// Model of a region, species s, point u:
//   lambda_s(u) = m_s rho_s(ctx(u)) w(u) x [ (1 - sum_k a_sk) + sum_k a_sk Lambda_k(u) ],
//   Lambda_k(u) = (1 / kappa_k) sum over parents c of field k of N(u - c; sigma_k^2 I),
// rho_s(c) the database density of s in context bin c, w the seeding kernel, m_s the scale
// that gives the region's count, parents Poisson(kappa_k) shared by every species. Its pair
// correlation is g_context(r) x (1 + sum_k a_sk a_tk B_k exp(-r^2 / 4 sigma_k^2)),
// B_k = 1 / (4 pi kappa_k sigma_k^2), so (sigma_k, B_k) are fitted to the pooled g of the
// region divided by its context part, and a_sk to each species' own g.
//
// Sampling: in a first pass each cell throws Poisson darts for the free part and Poisson
// parents for the cluster fields; each parent throws offspring of each attached species
// (Gaussian displacement), thinned by lambda_s at the landing point. Every candidate carries a
// random key; each (region, species) keeps its lowest keys up to its quota. Later passes
// throw free darts for what is still missing. Everything is keyed by (seed, pass, cell,
// dart): identical for any thread count.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <ctime>
#include <limits>
#include <memory>
#include <numeric>
#include <unordered_map>

#include <omp.h>

#include "canopy_context.h"
#include "error.h"
#include "rng.h"
#include "sampling_detail.h"
#include "undergrowth.h"

namespace eco::synth {

using namespace detail;

namespace {

constexpr std::uint64_t kFreeStream = 0x5354465245454453ull;       // "STFREEDS"
constexpr std::uint64_t kParentStream = 0x5354504152454e54ull;     // "STPARENT"
constexpr std::uint64_t kOffspringStream = 0x53544f4646535052ull;  // "STOFFSPR"
constexpr std::uint64_t kSizeStream = 0x5354534953495a45ull;       // "STSISIZE"
constexpr double kPi = 3.14159265358979323846;

using Clock = std::chrono::steady_clock;

/// Values of g at bins where the weights are 0 filled by linear interpolation between the
/// nearest defined bins (constant beyond them); 1 everywhere when none is defined.
std::vector<double> fillUndefined(std::vector<double> v, const std::vector<char>& defined) {
    const std::size_t n = v.size();
    std::vector<std::size_t> idx;
    for (std::size_t i = 0; i < n; ++i)
        if (defined[i]) idx.push_back(i);
    if (idx.empty()) return std::vector<double>(n, 1.0);
    for (std::size_t i = 0; i < n; ++i) {
        if (defined[i]) continue;
        const auto it = std::lower_bound(idx.begin(), idx.end(), i);
        if (it == idx.begin())
            v[i] = v[idx.front()];
        else if (it == idx.end())
            v[i] = v[idx.back()];
        else {
            const std::size_t hi = *it, lo = *(it - 1);
            const double t = double(i - lo) / double(hi - lo);
            v[i] = v[lo] * (1 - t) + v[hi] * t;
        }
    }
    return v;
}

/// Per context bin: density (plants per m^2) of species s (or pooled when s < 0).
std::vector<double> contextDensity(const BiomeDatabase& db, const DbRegion& r, int species) {
    const std::size_t nc = static_cast<std::size_t>(db.contextBins.count());
    const std::size_t ns = static_cast<std::size_t>(db.speciesCount());
    std::vector<double> rho(nc, 0.0);
    for (std::size_t c = 0; c < nc; ++c) {
        if (!(r.contextAreaM2[c] > 0)) continue;
        double n = 0;
        for (std::size_t s = 0; s < ns; ++s)
            if (species < 0 || s == static_cast<std::size_t>(species)) n += r.contextSpeciesCount[s * nc + c];
        rho[c] = n / r.contextAreaM2[c];
    }
    return rho;
}

/// Observed g of the region: pooled undergrowth (species < 0) or species s with itself.
/// Empty when the database lacks it.
std::vector<double> observedPcf(const BiomeDatabase& db, const DbRegion& r, int species) {
    const int ns = db.speciesCount();
    const std::size_t nb = static_cast<std::size_t>(db.pcfBins.count);
    if (species >= 0) {
        const DbPairStats* p = r.pair(species, species);
        if (p == nullptr || !(p->normalisation > 0)) return {};
        return p->g;
    }
    std::vector<double> tw(nb, 0.0);
    double norm = 0;
    for (const DbPairStats& p : r.pairs) {
        if (p.source >= ns || p.target >= ns) continue;
        for (std::size_t b = 0; b < nb; ++b) tw[b] += p.translateWeighted[b];
        norm += p.normalisation;
    }
    if (!(norm > 0)) return {};
    for (std::size_t b = 0; b < nb; ++b) tw[b] = annulusPcf(tw[b], db.pcfBins.annulusAreaM2(static_cast<int>(b)), norm);
    return tw;
}

struct Fit {
    double amp[2] = {0, 0};
    double sse = std::numeric_limits<double>::infinity();
};

/// Least squares of y ~ sum_k amp_k x_k with amp >= 0 over two (or one) basis vectors.
Fit nonNegativeFit(const std::vector<double>& y, const std::vector<double>& x0, const std::vector<double>* x1) {
    auto sseOf = [&](double a0, double a1) {
        double e = 0;
        for (std::size_t b = 0; b < y.size(); ++b) {
            const double d = y[b] - a0 * x0[b] - (x1 ? a1 * (*x1)[b] : 0.0);
            e += d * d;
        }
        return e;
    };
    Fit best;
    auto consider = [&](double a0, double a1) {
        if (!(a0 >= 0) || !(a1 >= 0)) return;
        const double e = sseOf(a0, a1);
        if (e < best.sse) {
            best.sse = e;
            best.amp[0] = a0;
            best.amp[1] = a1;
        }
    };
    double s00 = 0, s11 = 0, s01 = 0, t0 = 0, t1 = 0;
    for (std::size_t b = 0; b < y.size(); ++b) {
        s00 += x0[b] * x0[b];
        t0 += x0[b] * y[b];
        if (x1) {
            s11 += (*x1)[b] * (*x1)[b];
            s01 += x0[b] * (*x1)[b];
            t1 += (*x1)[b] * y[b];
        }
    }
    consider(0, 0);
    if (s00 > 0) consider(std::max(0.0, t0 / s00), 0);
    if (x1 && s11 > 0) consider(0, std::max(0.0, t1 / s11));
    if (x1) {
        const double det = s00 * s11 - s01 * s01;
        if (std::abs(det) > 1e-12 * std::max(1e-300, s00 * s11)) consider((t0 * s11 - t1 * s01) / det, (t1 * s00 - t0 * s01) / det);
    }
    return best;
}

}  // namespace

std::vector<double> detail::speciesContextDensities(const BiomeDatabase& db) {
    const bool withContext = db.hasContext();
    const std::size_t nR = db.regions.size(), nS = static_cast<std::size_t>(db.speciesCount());
    const std::size_t nCtx = withContext ? static_cast<std::size_t>(db.contextBins.count()) : 1;
    std::vector<double> rho(nR * nS * nCtx, 0.0);
    for (std::size_t r = 0; r < nR; ++r) {
        const DbRegion& reg = db.regions[r];
        for (std::size_t s = 0; s < nS; ++s) {
            if (!(reg.speciesCount[s] > 0)) continue;
            if (withContext) {
                const std::vector<double> d = contextDensity(db, reg, static_cast<int>(s));
                // Context bins the region's cells never reached: the species' mean density.
                for (std::size_t c = 0; c < nCtx; ++c)
                    rho[(r * nS + s) * nCtx + c] = reg.contextAreaM2[c] > 0 ? d[c] : reg.speciesCount[s] / std::max(reg.areaM2, 1e-300);
            } else {
                rho[(r * nS + s) * nCtx] = reg.densityPerM2 * reg.speciesProportion[s];
            }
        }
    }
    return rho;
}

std::vector<double> contextPcf(const BiomeDatabase& db, int region, int species) {
    const std::size_t nb = static_cast<std::size_t>(db.pcfBins.count);
    if (!db.hasContext() || region < 0 || static_cast<std::size_t>(region) >= db.regions.size())
        return std::vector<double>(nb, 1.0);
    const DbRegion& r = db.regions[static_cast<std::size_t>(region)];
    const std::size_t nc = static_cast<std::size_t>(db.contextBins.count());
    const std::vector<double> rho = contextDensity(db, r, species);
    double area = 0, n = 0;
    for (std::size_t c = 0; c < nc; ++c) {
        area += r.contextAreaM2[c];
        n += rho[c] * r.contextAreaM2[c];
    }
    if (!(area > 0) || !(n > 0)) return std::vector<double>(nb, 1.0);
    const double mean = n / area;
    std::vector<double> g(nb, 1.0);
    std::vector<char> defined(nb, 0);
    for (std::size_t b = 0; b < nb; ++b) {
        double num = 0, den = 0;
        for (std::size_t c1 = 0; c1 < nc; ++c1)
            for (std::size_t c2 = 0; c2 < nc; ++c2) {
                const double p = r.contextCellPairs[(c1 * nc + c2) * nb + b];
                num += p * rho[c1] * rho[c2];
                den += p;
            }
        if (den > 0) {
            g[b] = num / den / (mean * mean);
            defined[b] = 1;
        }
    }
    return fillUndefined(g, defined);
}

RegionStructure fitRegionStructure(const BiomeDatabase& db, int region, const SynthParams& params) {
    const std::size_t nb = static_cast<std::size_t>(db.pcfBins.count);
    const std::size_t ns = static_cast<std::size_t>(db.speciesCount());
    const DbRegion& r = db.regions.at(static_cast<std::size_t>(region));
    RegionStructure st;
    st.region = region;
    st.attachment.assign(ns * 2, 0.0);
    // Inhibition per species pair: leading bins with g below hardCoreG where a Poisson
    // pattern would have had enough pairs for that to be no accident.
    {
        std::vector<double> hc(ns * ns, 0.0);
        bool any = false;
        for (const DbPairStats& p : r.pairs) {
            if (p.source >= static_cast<int>(ns) || p.target >= static_cast<int>(ns) || !(p.normalisation > 0)) continue;
            double d = 0;
            for (std::size_t b = 0; b < nb; ++b) {
                const double expectedPairs = db.pcfBins.annulusAreaM2(static_cast<int>(b)) * p.normalisation;
                if (!(p.g[b] < params.hardCoreG) || expectedPairs < params.hardCoreMinExpectedPairs) break;
                d = db.pcfBins.hiM(static_cast<int>(b));
            }
            if (d > 0) {
                const std::size_t i = static_cast<std::size_t>(p.source), j = static_cast<std::size_t>(p.target);
                hc[i * ns + j] = std::max(hc[i * ns + j], d);
                hc[j * ns + i] = std::max(hc[j * ns + i], d);
                any = true;
            }
        }
        if (any) st.hardCoreM = std::move(hc);
    }
    const std::vector<double> gPool = observedPcf(db, r, -1);
    if (gPool.size() != nb || !(r.undergrowthCount >= 2)) return st;
    const std::vector<double> ctxPool = contextPcf(db, region, -1);
    for (std::size_t b = 0; b < nb; ++b) {
        const double d = gPool[b] - ctxPool[b];
        st.pooledContextRms += d * d;
    }
    st.pooledContextRms = std::sqrt(st.pooledContextRms / double(nb));

    // Scales: a log grid; fit the pooled g = g_ctx (1 + B1 f1 + B2 f2), f = exp(-r^2 / 4 sigma^2).
    constexpr int kGrid = 24;
    std::vector<double> sigmas(kGrid);
    for (int i = 0; i < kGrid; ++i)
        sigmas[static_cast<std::size_t>(i)] =
            params.clusterSigmaMinM * std::pow(params.clusterSigmaMaxM / params.clusterSigmaMinM, double(i) / (kGrid - 1));
    auto basis = [&](double sigma, const std::vector<double>& ctx) {
        std::vector<double> f(nb);
        for (std::size_t b = 0; b < nb; ++b) {
            const double rm = db.pcfBins.midM(static_cast<int>(b));
            f[b] = ctx[b] * std::exp(-rm * rm / (4 * sigma * sigma));
        }
        return f;
    };
    std::vector<double> yPool(nb);
    for (std::size_t b = 0; b < nb; ++b) yPool[b] = gPool[b] - ctxPool[b];
    Fit best;
    double bestS[2] = {0, 0};
    for (int i = 0; i < kGrid; ++i) {
        const auto f1 = basis(sigmas[static_cast<std::size_t>(i)], ctxPool);
        const Fit one = nonNegativeFit(yPool, f1, nullptr);
        if (one.sse < best.sse * (1 - 1e-12)) {
            best = one;
            bestS[0] = sigmas[static_cast<std::size_t>(i)];
            bestS[1] = 0;
        }
        for (int j = i + 2; j < kGrid; ++j) {  // the second scale at least two grid steps larger
            const auto f2 = basis(sigmas[static_cast<std::size_t>(j)], ctxPool);
            const Fit two = nonNegativeFit(yPool, f1, &f2);
            if (two.sse < best.sse * (1 - 1e-9)) {
                best = two;
                bestS[0] = sigmas[static_cast<std::size_t>(i)];
                bestS[1] = sigmas[static_cast<std::size_t>(j)];
            }
        }
    }
    st.pooledFitRms = std::sqrt(best.sse / double(nb));
    // Keep the fields with an amplitude; field 0 is the finer.
    for (int k = 0; k < 2; ++k)
        if (best.amp[k] > 1e-6 && bestS[k] > 0) {
            st.sigmaM[st.scales] = bestS[k];
            st.pooledAmplitude[st.scales] = best.amp[k];
            ++st.scales;
        }
    if (st.scales == 0) return st;

    // Species amplitudes at the chosen scales (their own g over their own context part).
    std::vector<double> c(ns * 2, 0.0);
    std::vector<double> share(ns, 0.0);
    for (std::size_t s = 0; s < ns; ++s) share[s] = r.undergrowthCount > 0 ? r.speciesCount[s] / r.undergrowthCount : 0.0;
    for (std::size_t s = 0; s < ns; ++s) {
        if (!(r.speciesCount[s] > 0)) continue;
        const std::vector<double> gs = observedPcf(db, r, static_cast<int>(s));
        double amp[2] = {st.pooledAmplitude[0], st.pooledAmplitude[1]};
        if (r.speciesCount[s] >= params.clusterMinPlants && gs.size() == nb) {
            const std::vector<double> ctx = contextPcf(db, region, static_cast<int>(s));
            std::vector<double> y(nb);
            for (std::size_t b = 0; b < nb; ++b) y[b] = gs[b] - ctx[b];
            const auto f1 = basis(st.sigmaM[0], ctx);
            if (st.scales == 2) {
                const auto f2 = basis(st.sigmaM[1], ctx);
                const Fit fs = nonNegativeFit(y, f1, &f2);
                amp[0] = fs.amp[0];
                amp[1] = fs.amp[1];
            } else {
                amp[0] = nonNegativeFit(y, f1, nullptr).amp[0];
            }
        }
        for (int k = 0; k < st.scales; ++k) c[s * 2 + static_cast<std::size_t>(k)] = std::sqrt(std::max(0.0, amp[k]));
    }
    // Scale the species so that the pooled amplitude is met: (sum_s p_s a_sk)^2 B_k = P_k.
    double gamma[2] = {0, 0};
    for (int k = 0; k < st.scales; ++k) {
        double sum = 0;
        for (std::size_t s = 0; s < ns; ++s) sum += share[s] * c[s * 2 + static_cast<std::size_t>(k)];
        gamma[k] = sum > 0 ? std::sqrt(st.pooledAmplitude[k]) / sum : 0.0;
    }
    // Field amplitudes B_k = m_k^2 and attachments a_sk = gamma_k c_sk / m_k. The model's g
    // does not depend on the m_k (a_sk a_tk B_k = gamma_k^2 c_sk c_tk), only how many parents
    // carry it (kappa_k = 1 / (4 pi sigma_k^2 m_k^2)): a field of few parents makes one
    // realisation's g swing (a wide field in a small region may have a dozen). So the m_k
    // give the field with fewer parents as many as possible (max over m of min_k kappa_k),
    // subject to every species' a_s1 + a_s2 <= 1 (its free share >= 0). Measured over 12
    // synthesis seeds on three fidelity scenes it beat one shared amplitude and a weighted
    // sum of 1 / kappa_k (docs/synth.md). One field: m_1 = max_s gamma_1 c_s1.
    double lo[2] = {0, 0};
    for (int k = 0; k < st.scales; ++k)
        for (std::size_t s = 0; s < ns; ++s) lo[k] = std::max(lo[k], gamma[k] * c[s * 2 + static_cast<std::size_t>(k)]);
    double shared = 0;  // the single amplitude of both fields that the sum bound allows
    for (std::size_t s = 0; s < ns; ++s) {
        double t = 0;
        for (int k = 0; k < st.scales; ++k) t += gamma[k] * c[s * 2 + static_cast<std::size_t>(k)];
        shared = std::max(shared, t);
    }
    if (!(shared > 0)) {
        st.scales = 0;
        return st;
    }
    double mField[2] = {shared, shared};
    if (st.scales == 2 && lo[0] > 0 && lo[1] > 0) {
        // m_2 on a log grid above its bound; m_1 the least that keeps every species within 1.
        auto m1For = [&](double m2) {
            double m1 = 0;
            for (std::size_t s = 0; s < ns; ++s) {
                const double rest = 1.0 - gamma[1] * c[s * 2 + 1] / m2;
                const double need = gamma[0] * c[s * 2];
                if (need > 0) m1 = std::max(m1, need / rest);
            }
            return m1;
        };
        // 1 / kappa_k up to a constant: the area per parent of field k.
        auto cost = [&](double m1, double m2) {
            return std::max(st.sigmaM[0] * st.sigmaM[0] * m1 * m1, st.sigmaM[1] * st.sigmaM[1] * m2 * m2);
        };
        // The shared amplitude is one feasible point: never do worse than it.
        double bestCost = cost(shared, shared);
        constexpr int kSteps = 400;
        for (int i = 1; i <= kSteps; ++i) {
            const double m2 = lo[1] * std::pow(1e4, double(i) / kSteps);  // from just above the bound to 10^4 x it
            const double m1 = m1For(m2);
            const double cst = cost(m1, m2);
            if (cst < bestCost) {
                bestCost = cst;
                mField[0] = m1;
                mField[1] = m2;
            }
        }
    }
    for (int k = 0; k < st.scales; ++k) {
        const double m = mField[k];
        st.parentsPerM2[k] = 1.0 / (4 * kPi * st.sigmaM[k] * st.sigmaM[k] * m * m);
        for (std::size_t s = 0; s < ns; ++s)
            st.attachment[s * 2 + static_cast<std::size_t>(k)] = gamma[k] * c[s * 2 + static_cast<std::size_t>(k)] / m;
    }
    return st;
}

namespace {


/// Below this many items a loop over candidates runs on one thread: the later passes handle
/// a few per cent of the plants, and a parallel region's barriers cost more than they save
/// (much more when other processes hold the cores).
constexpr std::size_t kParallelMin = std::size_t{1} << 16;

/// A counting sort of items into buckets, in parallel: each thread counts, then places, a
/// contiguous share [lo, hi) of the items (forRange(lo, hi, f) calls f(item) on them in
/// order), so a bucket holds its items in input order for any number of threads.
/// bucketOf(item) is in [0, nBuckets]; nBuckets leaves the item out. place(item, p) puts the
/// item at position p. Returns the buckets' starts (nBuckets + 1).
template <typename ForRange, typename BucketOf, typename Place>
std::vector<std::size_t> scatterRanges(std::size_t n, std::size_t nBuckets, ForRange forRange, BucketOf bucketOf, Place place) {
    const std::size_t maxThreads = static_cast<std::size_t>(omp_get_max_threads());
    std::vector<std::size_t> next(maxThreads * (nBuckets + 1), 0);  // [thread][bucket]: count, then position
    std::vector<std::size_t> start(nBuckets + 1, 0);
#pragma omp parallel if (n >= kParallelMin)
    {
        const std::size_t t = static_cast<std::size_t>(omp_get_thread_num()), nt = static_cast<std::size_t>(omp_get_num_threads());
        const std::size_t lo = n * t / nt, hi = n * (t + 1) / nt;
        std::size_t* mine = &next[t * (nBuckets + 1)];
        forRange(lo, hi, [&](const auto& item) { ++mine[bucketOf(item)]; });
#pragma omp barrier
#pragma omp single
        {
            std::size_t at = 0;
            for (std::size_t b = 0; b < nBuckets; ++b) {
                start[b] = at;
                for (std::size_t u = 0; u < nt; ++u) {
                    std::size_t& c = next[u * (nBuckets + 1) + b];
                    const std::size_t k = c;
                    c = at;
                    at += k;
                }
            }
            start[nBuckets] = at;
        }
        forRange(lo, hi, [&](const auto& item) {
            const std::size_t b = bucketOf(item);
            if (b < nBuckets) place(item, mine[b]++);
        });
    }
    return start;
}

/// scatterRanges over the items 0 .. n-1 (bucketOf(i), place(i, p)).
template <typename BucketOf, typename Place>
std::vector<std::size_t> scatterByBucket(std::size_t n, std::size_t nBuckets, BucketOf bucketOf, Place place) {
    auto indices = [](std::size_t lo, std::size_t hi, const auto& f) {
        for (std::size_t i = lo; i < hi; ++i) f(i);
    };
    return scatterRanges(n, nBuckets, indices, bucketOf, place);
}

/// The candidates of a pass as the rows made them: item i of the whole is item
/// i - rowStart[y] of row y (at rowPtr[y]). forRange visits a range of them in order without
/// copying them into one array (at 3072^2 that copy was half a gigabyte of fresh pages).
struct RowCandidates {
    const std::vector<const Candidate*>& rowPtr;
    const std::vector<std::size_t>& rowStart;  ///< rowPtr.size() + 1
    template <typename F>
    void operator()(std::size_t lo, std::size_t hi, const F& f) const {
        if (lo >= hi) return;
        std::size_t y = static_cast<std::size_t>(std::upper_bound(rowStart.begin(), rowStart.end(), lo) - rowStart.begin()) - 1;
        std::size_t i = lo;
        while (i < hi) {
            const std::size_t end = std::min(hi, rowStart[y + 1]);
            const Candidate* row = rowPtr[y];
            for (std::size_t j = i - rowStart[y]; i < end; ++i, ++j) f(row[j]);
            ++y;
        }
    }
};

/// A thread's store of candidate rows: blocks of a million candidates (24 MB, on huge
/// pages), each row copied whole into one.
struct CandidateArena {
    static constexpr std::size_t kBlock = std::size_t{1} << 20;
    std::vector<RawArray<Candidate>> blocks;
    std::size_t used = 0;  ///< in the last block
    const Candidate* append(const Candidate* src, std::size_t n) {
        if (n == 0) return nullptr;
        if (blocks.empty() || used + n > blocks.back().size()) {
            blocks.emplace_back(std::max(n, kBlock));
            used = 0;
        }
        Candidate* dst = blocks.back().data() + used;
        std::copy(src, src + n, dst);
        used += n;
        return dst;
    }
};

/// The order of v[0 .. n-1] by `less`, as indices: a counting pass into buckets (bucketOf
/// must not decrease along `less`), then each bucket sorted on its own, in parallel (equal
/// items by index). The same for any thread count.
template <typename BucketOf, typename Less>
RawArray<std::uint32_t> orderInBuckets(const Candidate* v, std::size_t n, std::size_t nBuckets, BucketOf bucketOf, Less less) {
    RawArray<std::uint32_t> order(n);
    const std::vector<std::size_t> start = scatterByBucket(
        n, nBuckets, [&](std::size_t i) { return bucketOf(v[i]); },
        [&](std::size_t i, std::size_t p) { order[p] = static_cast<std::uint32_t>(i); });
#pragma omp parallel for schedule(dynamic, 256) if (n >= kParallelMin)
    for (std::int64_t b = 0; b < static_cast<std::int64_t>(nBuckets); ++b) {
        const std::size_t lo = start[static_cast<std::size_t>(b)], hi = start[static_cast<std::size_t>(b) + 1];
        if (hi - lo > 1)
            std::sort(order.data() + lo, order.data() + hi, [&](std::uint32_t a, std::uint32_t c) {
                if (less(v[a], v[c])) return true;
                if (less(v[c], v[a])) return false;
                return a < c;
            });
    }
    return order;
}

/// Per (region, mask index, context): cumulative weights over species (the roulette of the
/// free darts) of rate_s = factor_rs x rho_rs(ctx), restricted to the species of the mask.
struct RateTable {
    std::size_t nMasks = 0, nCtx = 0, nSpecies = 0;
    std::vector<double> cumulative;  ///< [region][mask][ctx][species]
    const double* row(std::size_t r, std::size_t m, std::size_t c) const {
        return &cumulative[((r * nMasks + m) * nCtx + c) * nSpecies];
    }
    double total(std::size_t r, std::size_t m, std::size_t c) const { return row(r, m, c)[nSpecies - 1]; }
    int pick(std::size_t r, std::size_t m, std::size_t c, double u) const {
        const double* cum = row(r, m, c);
        const double t = cum[nSpecies - 1];
        if (!(t > 0)) return -1;
        int s = static_cast<int>(std::upper_bound(cum, cum + nSpecies, u * t) - cum);
        if (s >= static_cast<int>(nSpecies)) s = static_cast<int>(nSpecies) - 1;
        while (s > 0 && cum[s] == cum[s - 1]) --s;
        return s;
    }
};

/// A histogram with its cumulative counts, for the per-plant size draws in O(log bins).
/// The sums are added in the order of histogramLocate's scan, so every result has the same
/// bits as the linear scans (histogramLocate, histogramQuantile and a bin-by-bin CDF); a
/// histogram with a negative count or unsorted edges falls back to those scans.
struct CumulativeHistogram {
    const DbHistogram* h = nullptr;
    double total = 0;         ///< overflow + counts, added in histogramLocate's order
    std::vector<double> cum;  ///< cum[k] = counts[0] + ... + counts[k - 1], added in order
    bool scan = false;        ///< negative counts or unsorted edges: the linear scans

    CumulativeHistogram() = default;
    explicit CumulativeHistogram(const DbHistogram& hist) : h(&hist) {
        total = hist.overflow;
        for (double c : hist.counts) total += c;
        cum.assign(hist.counts.size() + 1, 0.0);
        for (std::size_t k = 0; k < hist.counts.size(); ++k) {
            cum[k + 1] = cum[k] + hist.counts[k];
            if (!(hist.counts[k] >= 0)) scan = true;
        }
        for (std::size_t k = 0; k + 1 < hist.edges.size(); ++k)
            if (!(hist.edges[k] <= hist.edges[k + 1])) scan = true;
    }
    bool hasMass() const { return h != nullptr && total > 0; }
    /// histogramLocate.
    int locate(double u, std::size_t& bin, double& t) const {
        if (scan) return histogramLocate(*h, u, bin, t);
        if (!(total > 0) || h->edges.size() != h->counts.size() + 1) return -1;
        const double target = u * total;
        // The scan stops at the first bin k with counts[k] > 0 and cum[k + 1] > target; with
        // no negative count that is the first k with cum[k + 1] > target.
        const auto it = std::upper_bound(cum.begin() + 1, cum.end(), target);
        if (it == cum.end()) return 0;
        bin = static_cast<std::size_t>(it - cum.begin()) - 1;
        t = (target - cum[bin]) / h->counts[bin];
        return 1;
    }
    /// histogramQuantile.
    double quantile(double u) const {
        std::size_t k = 0;
        double t = 0;
        const int found = locate(u, k, t);
        if (found < 0) return -1;
        if (found == 0) return h->edges.back();
        return h->edges[k] + t * (h->edges[k + 1] - h->edges[k]);
    }
    /// Share of the histogram below x (linear inside a bin).
    double below(double x) const {
        if (!(total > 0)) return 0.0;
        const std::vector<double>& e = h->edges;
        const std::size_t n = h->counts.size();
        if (scan || e.size() != n + 1) {
            double b = 0;
            for (std::size_t k = 0; k < n; ++k) {
                const double lo = e[k], hi = e[k + 1];
                if (x >= hi)
                    b += h->counts[k];
                else if (x > lo)
                    b += h->counts[k] * (x - lo) / (hi - lo);
            }
            return b / total;
        }
        // Bins with x >= their upper edge add their counts (cum of the first k), the bin
        // holding x its part.
        const std::size_t k = static_cast<std::size_t>(
            std::upper_bound(e.begin() + 1, e.end(), x, [](double v, double edge) { return !(v >= edge); }) - (e.begin() + 1));
        double b = cum[k];
        if (k < n && x > e[k]) b += h->counts[k] * (x - e[k]) / (e[k + 1] - e[k]);
        return b / total;
    }
};

/// The height draw of one (region, species, context): a height histogram and, for the shape
/// inside its bins, the region's crown-radius histogram through the species' allometry.
/// Height at cumulative share u: inside a bin the height is not spread linearly: the bin's
/// crown radii (allometry of its edges) are spread as the radius histogram spreads them, and
/// mapped back to heights. The simulator's radius is the allometry of its height, so the
/// radius histogram carries the shape of the heights inside the (coarser at small sizes)
/// height bins. Linear inside the bin without it.
struct HeightDraw {
    CumulativeHistogram height;
    const CumulativeHistogram* radius = nullptr;  ///< null: linear inside bins
    const Allometry* allometry = nullptr;
    std::vector<double> fa, fb;  ///< per height bin: the radius histogram's mass below its edges' radii
    double rTotal = 0;

    HeightDraw(const DbHistogram& heightHist, const CumulativeHistogram* radiusHist, const Allometry& allo)
        : height(heightHist), radius(radiusHist), allometry(&allo) {
        if (radius == nullptr) return;
        const DbHistogram& rh = *radius->h;
        const std::size_t nb = heightHist.counts.size();
        fa.assign(nb, 0.0);
        fb.assign(nb, 0.0);
        for (std::size_t k = 0; k < nb && k + 1 < heightHist.edges.size(); ++k) {
            double total = rh.overflow, a0 = 0, b0 = 0;
            const double ra = allo.crownRadiusM(heightHist.edges[k]), rb = allo.crownRadiusM(heightHist.edges[k + 1]);
            for (std::size_t j = 0; j < rh.counts.size(); ++j) {
                const double a = rh.edges[j], b = rh.edges[j + 1], n = rh.counts[j];
                auto part = [&](double x) { return x >= b ? n : (x > a ? n * (x - a) / (b - a) : 0.0); };
                a0 += part(ra);
                b0 += part(rb);
                total += n;
            }
            fa[k] = a0;
            fb[k] = b0;
            rTotal = total;
        }
    }
    double quantile(double u) const {
        std::size_t k = 0;
        double t = 0;
        const int found = height.locate(u, k, t);
        if (found < 0) return -1;
        const std::vector<double>& e = height.h->edges;
        if (found == 0) return e.back();
        const double lo = e[k], hi = e[k + 1];
        if (radius != nullptr && rTotal > 0 && fb[k] - fa[k] > 1e-12 * rTotal) {
            const double hq = allometry->heightForCrownRadiusM(radius->quantile((fa[k] + t * (fb[k] - fa[k])) / rTotal));
            if (hq >= lo && hq <= hi) return hq;
        }
        return lo + t * (hi - lo);
    }
};

/// Random blocks made in one batch (randomBlocksBatch): requests (stream, counter) added in
/// order, then made at once; word k of request i is word[k][i].
struct BlockBatch {
    std::vector<std::uint64_t> stream, counter;
    std::vector<std::uint32_t> word[4];
    void clear() {
        stream.clear();
        counter.clear();
    }
    void add(std::uint64_t s, std::uint64_t c) {
        stream.push_back(s);
        counter.push_back(c);
    }
    void make(std::uint64_t seed) {
        const std::size_t n = stream.size();
        for (auto& v : word)
            if (v.size() < n) v.resize(std::max(n, 2 * v.size()));
        randomBlocksBatch(seed, stream.data(), counter.data(), n, word[0].data(), word[1].data(), word[2].data(), word[3].data());
    }
    /// The uniform of words k, k + 1 of request i (RandomStream::uniform's bits).
    double unit(std::size_t i, int k) const { return bitsToUnit(word[k][i], word[k + 1][i]); }
};

/// A cell of a row that throws free darts (the structured sampler's candidates).
struct DartCell {
    int ix;
    std::uint32_t cell;
    int region;
    std::uint32_t mask, ctx;
    double lambda;        ///< expected darts
    double total;         ///< later passes: the sum of the species' rates
    double expNeg;        ///< exp(-lambda) when lambda <= 100, else -1 (a count of several pieces)
    std::size_t rates;    ///< later passes: where its cumulative species rates start in RowScratch::rates
    std::uint32_t nRates; ///< later passes: how many (the species still missing plants in its tile)
    std::uint64_t stream; ///< its darts' stream
    int n = 0;            ///< darts
};

/// A cluster parent's offspring of one species.
struct Brood {
    double px, py, sigma, lmax, lambda;
    std::uint32_t species;
    int n;                     ///< offspring
    int lead;                  ///< words of the count's block left after the count
    std::uint32_t leadWord[4];
    std::size_t firstBlock;    ///< its first block in RowScratch::blocks, then its first word in RowScratch::words
};

/// A thread's scratch for the rows it makes.
struct RowScratch {
    std::vector<Candidate> cand;
    std::vector<DartCell> cells;
    std::vector<double> rates, cum;
    std::vector<std::uint16_t> rateSpecies;  ///< the species of each entry of rates
    std::vector<std::uint32_t> words;        ///< the broods' words, each brood's in order
    std::vector<Brood> broods;
    BlockBatch counts, blocks;
};

/// Random sequential adsorption with hard cores: in ascending key order, a candidate of a
/// pass is dropped when a plant already placed (earlier passes, or this pass's admitted
/// candidates of lower key) is nearer than their pair's hard-core distance (the matrix of
/// the candidate's region). A candidate of a species without a hard core is always admitted
/// (and inhibits others).
///
/// The sequential rule has one result (the greedy independent set in key order), found here
/// without sorting by key and mostly in parallel: only the candidates a hard core concerns
/// take part (a species inhibited in its region, or one that some hard core keeps others
/// away from; the rest, half of them on the benchmark scenes, are admitted and inhibit no
/// one). Those are grouped by buckets of the hard-core range (in the order they come, rows),
/// each one's neighbours of lower key within its hard cores listed in parallel (one near a
/// plant of an earlier pass is dropped there and then), then each candidate decided after
/// the neighbours it depends on (a depth-first walk in bucket order, local in memory):
/// admitted unless one of them was. Placed plants of earlier passes that inhibit others sit
/// in a bucket grid (linked lists through them).
struct HardCore {
    const std::vector<RegionStructure>& structure;
    std::size_t nSpecies;
    double maxM = 0, bucketM = 1;
    int nx = 0, ny = 0;
    std::vector<std::int32_t> head;  ///< [ny][nx] last placed plant of each bucket, -1 none
    std::vector<std::int32_t> next;  ///< per placed plant
    std::vector<Candidate> placed;
    std::vector<char> speciesInhibited;  ///< [region][species]: some pair of it has a hard core
    std::vector<char> speciesInhibits;   ///< [species]: some region's hard core keeps others from it

    HardCore(const std::vector<RegionStructure>& st, std::size_t ns, double extentX, double extentY)
        : structure(st), nSpecies(ns) {
        speciesInhibited.assign(st.size() * ns, 0);
        speciesInhibits.assign(ns, 0);
        for (std::size_t r = 0; r < st.size(); ++r)
            for (std::size_t i = 0; i < st[r].hardCoreM.size(); ++i)
                if (st[r].hardCoreM[i] > 0) {
                    maxM = std::max(maxM, st[r].hardCoreM[i]);
                    speciesInhibited[r * ns + i / ns] = 1;
                    speciesInhibits[i % ns] = 1;
                }
        if (!(maxM > 0)) return;
        bucketM = std::max(maxM, 2.0);  // not finer: the buckets are counted and cleared every pass
        nx = std::max(1, static_cast<int>(std::ceil(extentX / bucketM)));
        ny = std::max(1, static_cast<int>(std::ceil(extentY / bucketM)));
        head.assign(static_cast<std::size_t>(nx) * static_cast<std::size_t>(ny), -1);
    }
    int bucketX(float dx) const { return std::clamp(static_cast<int>(dx / bucketM), 0, nx - 1); }
    int bucketY(float dy) const { return std::clamp(static_cast<int>(dy / bucketM), 0, ny - 1); }
    std::size_t bucketOf(const Candidate& c) const {
        return static_cast<std::size_t>(bucketY(c.dy)) * static_cast<std::size_t>(nx) + static_cast<std::size_t>(bucketX(c.dx));
    }
    static bool conflict(const Candidate& c, const Candidate& q, const double* hc) {
        const double d = hc[q.species];
        if (!(d > 0)) return false;
        const double ddx = double(q.dx) - double(c.dx), ddy = double(q.dy) - double(c.dy);
        return ddx * ddx + ddy * ddy < d * d;
    }
    /// True when a plant of an earlier pass is nearer to c than their hard core.
    bool nearPlaced(const Candidate& c, const double* hc) const {
        const int bx = bucketX(c.dx), by = bucketY(c.dy);
        for (int y = std::max(0, by - 1); y <= std::min(ny - 1, by + 1); ++y)
            for (int x = std::max(0, bx - 1); x <= std::min(nx - 1, bx + 1); ++x)
                for (std::int32_t o = head[static_cast<std::size_t>(y) * static_cast<std::size_t>(nx) + static_cast<std::size_t>(x)];
                     o >= 0; o = next[static_cast<std::size_t>(o)])
                    if (conflict(c, placed[static_cast<std::size_t>(o)], hc)) return true;
        return false;
    }
    /// Removes the dropped candidates of a pass from cand[0 .. count - 1] (the admitted keep
    /// their order, moved to the front) and appends them to `dropped`; the admitted ones that
    /// inhibit others are placed. Returns how many are admitted.
    std::size_t select(Candidate* cand, std::size_t count, const std::int32_t* regionOfCell, std::vector<Candidate>& dropped) {
        const std::size_t nb = head.size();
        auto inhibited = [&](const Candidate& c) {
            return speciesInhibited[static_cast<std::size_t>(regionOfCell[c.cell]) * nSpecies + c.species] != 0;
        };
        auto concerned = [&](const Candidate& c) { return speciesInhibits[c.species] != 0 || inhibited(c); };
        // The concerned candidates by bucket, in the order they came inside a bucket: position p;
        // origin[p] its index in cand.
        RawArray<std::uint32_t> concernedBucket(count);
        std::size_t n = 0;
#pragma omp parallel for schedule(static) reduction(+ : n) if (count >= kParallelMin)
        for (std::int64_t ii = 0; ii < static_cast<std::int64_t>(count); ++ii) {
            const Candidate& c = cand[static_cast<std::size_t>(ii)];
            const bool in = concerned(c);
            concernedBucket[static_cast<std::size_t>(ii)] = static_cast<std::uint32_t>(in ? bucketOf(c) : nb);
            n += in;
        }
        RawArray<Candidate> cb(n);
        RawArray<std::uint32_t> origin(n);
        const std::vector<std::size_t> start = scatterByBucket(
            count, nb, [&](std::size_t i) { return concernedBucket[i]; },
            [&](std::size_t i, std::size_t p) {
                cb[p] = cand[i];
                origin[p] = static_cast<std::uint32_t>(i);
            });
        // q (position) comes before c (position p) in the sequential order: lower key, then
        // lower cell, then earlier position.
        auto before = [&](std::size_t q, std::size_t p) {
            const Candidate &a = cb[q], &c = cb[p];
            if (a.key != c.key) return a.key < c.key;
            if (a.cell != c.cell) return a.cell < c.cell;
            return q < p;
        };
        // state: 0 undecided, 1 admitted, 2 dropped. Per chunk of positions: the earlier
        // neighbours within hard cores of each.
        constexpr std::size_t kChunk = 4096;
        const std::size_t nChunks = (n + kChunk - 1) / kChunk;
        std::vector<std::uint8_t> state(n, 0);
        std::vector<std::vector<std::uint32_t>> deps(nChunks), depEnd(nChunks);
#pragma omp parallel for schedule(dynamic, 1) if (n >= kParallelMin)
        for (std::int64_t k = 0; k < static_cast<std::int64_t>(nChunks); ++k) {
            const std::size_t lo = static_cast<std::size_t>(k) * kChunk, hi = std::min(n, lo + kChunk);
            auto& dk = deps[static_cast<std::size_t>(k)];
            auto& ek = depEnd[static_cast<std::size_t>(k)];
            ek.reserve(hi - lo);
            for (std::size_t p = lo; p < hi; ++p) {
                const Candidate& c = cb[p];
                const std::size_t region = static_cast<std::size_t>(regionOfCell[c.cell]);
                if (!speciesInhibited[region * nSpecies + c.species]) {
                    state[p] = 1;
                } else {
                    const double* hc = structure[region].hardCoreM.data() + c.species * nSpecies;
                    if (!placed.empty() && nearPlaced(c, hc)) {
                        state[p] = 2;
                    } else {
                        const int bx = bucketX(c.dx), by = bucketY(c.dy);
                        for (int y = std::max(0, by - 1); y <= std::min(ny - 1, by + 1); ++y)
                            for (int x = std::max(0, bx - 1); x <= std::min(nx - 1, bx + 1); ++x) {
                                const std::size_t b = static_cast<std::size_t>(y) * static_cast<std::size_t>(nx) + static_cast<std::size_t>(x);
                                for (std::size_t q = start[b]; q < start[b + 1]; ++q)
                                    if (q != p && conflict(c, cb[q], hc) && before(q, p)) dk.push_back(static_cast<std::uint32_t>(q));
                            }
                    }
                }
                ek.push_back(static_cast<std::uint32_t>(dk.size()));
            }
        }
        // Each candidate decided after the earlier neighbours it depends on.
        auto depRange = [&](std::size_t p, const std::uint32_t*& b, const std::uint32_t*& e) {
            const std::size_t k = p / kChunk, i = p % kChunk;
            b = deps[k].data() + (i == 0 ? 0 : depEnd[k][i - 1]);
            e = deps[k].data() + depEnd[k][i];
        };
        std::vector<std::uint32_t> stack;
        for (std::size_t root = 0; root < n; ++root) {
            if (state[root] != 0) continue;
            stack.push_back(static_cast<std::uint32_t>(root));
            while (!stack.empty()) {
                const std::uint32_t p = stack.back();
                if (state[p] != 0) {
                    stack.pop_back();
                    continue;
                }
                const std::uint32_t *b, *e;
                depRange(p, b, e);
                std::uint8_t decided = 1;
                for (; b != e; ++b) {
                    if (state[*b] == 1) {
                        decided = 2;
                        break;
                    }
                    if (state[*b] == 0) {
                        decided = 0;
                        stack.push_back(*b);
                        break;
                    }
                }
                if (decided != 0) {
                    state[p] = decided;
                    stack.pop_back();
                }
            }
        }
        // Admitted ones that inhibit others placed; the dropped ones moved out of cand (in
        // place: a copy would be one more large array to fault in).
        std::vector<std::uint8_t> drop(count, 0);
        for (std::size_t p = 0; p < n; ++p) {
            if (state[p] != 1) {
                drop[origin[p]] = 1;
                continue;
            }
            if (!speciesInhibits[cb[p].species]) continue;
            const std::size_t b = bucketOf(cb[p]);
            next.push_back(head[b]);
            head[b] = static_cast<std::int32_t>(placed.size());
            placed.push_back(cb[p]);
        }
        std::size_t k = 0;
        for (std::size_t i = 0; i < count; ++i) {
            if (drop[i])
                dropped.push_back(cand[i]);
            else
                cand[k++] = cand[i];
        }
        return k;
    }
};

}  // namespace

// Sizes (declared in sampling_detail.h).
void detail::drawSizes(const BiomeDatabase& db, const Biome& biome, const std::vector<Plant>& canopy, const ClusterMap& map,
               const Grid<float>& terrainM, const SynthParams& params, bool withContext,
               const Candidate* accepted, const std::uint32_t* order, std::size_t count, UndergrowthSample& out) {
    const std::size_t nR = db.regions.size(), nS = static_cast<std::size_t>(db.speciesCount());
    const double ox = terrainM.originX(), oy = terrainM.originY();
    const std::vector<DbHistogram> pooledHeight = pooledSizeHistograms(db, false);
    // Open-ground histograms: all heights less those under crowns.
    std::vector<DbHistogram> openHeight;
    if (withContext)
        for (std::size_t r = 0; r < nR; ++r)
            for (std::size_t s = 0; s < nS; ++s) {
                DbHistogram o = db.regions[r].height[s];
                const DbHistogram& cov = db.regions[r].heightCovered[s];
                for (std::size_t k = 0; k < o.counts.size() && k < cov.counts.size(); ++k) o.counts[k] = std::max(0.0, o.counts[k] - cov.counts[k]);
                o.overflow = std::max(0.0, o.overflow - cov.overflow);
                openHeight.push_back(std::move(o));
            }
    const CanopyCover cover(canopy);
    // The height draw of every (region, species, covered): the context's histogram when it
    // has plants, else the region's, else the species' pooled one; none (-1) without plants.
    std::vector<CumulativeHistogram> radiusTables;
    radiusTables.reserve(nR * nS);
    for (std::size_t r = 0; r < nR; ++r)
        for (std::size_t s = 0; s < nS; ++s) radiusTables.emplace_back(db.regions[r].crownRadius[s]);
    std::vector<HeightDraw> draws;
    std::vector<int> drawOf(nR * nS * 2, -1);
    for (std::size_t r = 0; r < nR; ++r)
        for (std::size_t s = 0; s < nS; ++s)
            for (int covered = 0; covered < 2; ++covered) {
                const DbHistogram* hist = nullptr;
                if (withContext) {
                    const DbHistogram& ctxH = covered ? db.regions[r].heightCovered[s] : openHeight[r * nS + s];
                    if (CumulativeHistogram(ctxH).hasMass()) hist = &ctxH;
                }
                if (hist == nullptr && CumulativeHistogram(db.regions[r].height[s]).hasMass()) hist = &db.regions[r].height[s];
                if (hist == nullptr && CumulativeHistogram(pooledHeight[s]).hasMass()) hist = &pooledHeight[s];
                if (hist == nullptr) continue;
                const CumulativeHistogram* radius = radiusTables[r * nS + s].hasMass() ? &radiusTables[r * nS + s] : nullptr;
                drawOf[(r * nS + s) * 2 + static_cast<std::size_t>(covered)] = static_cast<int>(draws.size());
                draws.emplace_back(*hist, radius, biome.species[s].allometry);
            }
    const std::int64_t nPlants = static_cast<std::int64_t>(count);
    out.plants.reserve(count);
    out.plantRegion.reserve(count);
    adviseHugePages(out.plants.data(), count * sizeof(Plant));
    adviseHugePages(out.plantRegion.data(), count * sizeof(int));
    // The plants' fresh pages faulted in by every thread (430 MB at 3072^2): the resize below
    // runs on one thread, and its page faults were a large serial part of this phase.
    prepareLargeBuffer(out.plants.data(), count * sizeof(Plant));
    prepareLargeBuffer(out.plantRegion.data(), count * sizeof(int));
    out.plants.resize(count);
    out.plantRegion.resize(count);
    std::int64_t limited = 0;
    // Chunks of plants, each plant's size uniform (block 0 of its key's stream) made for the
    // whole chunk at once (randomBitsBatch: the same bits as RandomStream::uniform).
    constexpr std::int64_t kChunk = 256;
    const std::int64_t nChunks = (nPlants + kChunk - 1) / kChunk;
#pragma omp parallel reduction(+ : limited)
    {
        std::uint64_t sizeStream[kChunk];
        std::uint32_t w0[kChunk], w1[kChunk];
#pragma omp for schedule(static)
        for (std::int64_t chunk = 0; chunk < nChunks; ++chunk) {
            const std::int64_t lo = chunk * kChunk, hi = std::min(nPlants, lo + kChunk);
            for (std::int64_t i = lo; i < hi; ++i) {
                // The plants come in cell order, read through the permutation from the pass
                // order: the candidate some plants ahead fetched early (its cache miss was a
                // quarter of this loop). The second loop finds the chunk's candidates in cache.
                constexpr std::int64_t kAhead = 16;
                if (order != nullptr && i + kAhead < nPlants) __builtin_prefetch(&accepted[order[i + kAhead]]);
                sizeStream[i - lo] = mixStream(kSizeStream, accepted[order != nullptr ? order[i] : static_cast<std::size_t>(i)].key);
            }
            randomBitsBatch(params.seed, sizeStream, 0, static_cast<std::size_t>(hi - lo), w0, w1);
            for (std::int64_t i = lo; i < hi; ++i) {
                const Candidate& cnd = accepted[order != nullptr ? order[i] : static_cast<std::size_t>(i)];
                const std::size_t s = cnd.species;
                const int r = map.region.data()[cnd.cell];
                Plant p;
                p.speciesId = static_cast<int>(s);
                p.xM = ox + static_cast<double>(cnd.dx);
                p.yM = oy + static_cast<double>(cnd.dy);
                p.groundZM = terrainM.sampleBilinear(p.xM, p.yM);
                const double limit = cover.lowestCrownAboveM(p.xM, p.yM);
                const bool covered = limit < CanopyCover::kNone;
                const int d = drawOf[(static_cast<std::size_t>(r) * nS + s) * 2 + (covered ? 1 : 0)];
                const double u = bitsToUnit(w0[i - lo], w1[i - lo]);
                double height;
                if (d >= 0) {
                    const HeightDraw& draw = draws[static_cast<std::size_t>(d)];
                    const double top = covered ? draw.height.below(limit) : 1.0;
                    if (top > 0) {
                        height = draw.quantile(u * top);
                        if (covered && !(height < limit)) height = draw.height.quantile(u * top);
                        if (covered && top < 1.0) ++limited;
                    } else {
                        height = u * limit;  // the species never grew this low: below the crown, uniformly
                        ++limited;
                    }
                } else {
                    height = 0.5 * biome.species[s].maxHeightM;
                    if (covered) height = std::min(height, u * limit);
                }
                if (covered && !(height < limit)) height = std::nextafter(limit, 0.0);
                p.heightM = std::max(0.0, height);
                p.crownRadiusM = biome.species[s].allometry.crownRadiusM(p.heightM);
                out.plants[static_cast<std::size_t>(i)] = p;
                out.plantRegion[static_cast<std::size_t>(i)] = r;
            }
        }
    }
    out.heightsLimitedByCrown = limited;
}

UndergrowthSample sampleStructured(const BiomeDatabase& db, const Biome& biome, const std::vector<Plant>& canopy,
                                   const ClusterMap& map, const Grid<float>& terrainM, const SynthParams& params) {
    const auto t0 = Clock::now();
    UndergrowthSample out;
    // Wall time of each phase, summed over the passes (the benchmark's breakdown).
    detail::PhaseTimer phase(out.phases);
    const int w = terrainM.width(), h = terrainM.height();
    const double cs = terrainM.cellSizeM(), cellArea = cs * cs;
    const std::size_t nR = db.regions.size();
    const std::size_t nS = static_cast<std::size_t>(db.speciesCount());
    const bool withContext = db.hasContext();
    if (!withContext)
        out.warnings.push_back("the database (schema " + std::to_string(db.schemaVersion) +
                               ") has no canopy-context statistics: densities do not follow the depth under the canopy, "
                               "heights are not split under crowns and open, and clustering is fitted to g without its "
                               "context part (re-run eco analyse for schema " + std::to_string(kBiomeDbSchemaVersion) + ")");
    const CanopyContextBins bins = withContext ? db.contextBins : CanopyContextBins{{}};
    const std::size_t nCtx = withContext ? static_cast<std::size_t>(bins.count()) : 1;
    Grid<std::uint8_t> ctx = withContext ? canopyContextMap(canopyDepthMap(terrainM, canopy), bins)
                                         : Grid<std::uint8_t>::like(terrainM, 0);

    // Per region: the fitted structure and the per-context densities rho[r][s][c].
    out.structure.resize(nR);
    const std::vector<double> rho = speciesContextDensities(db);
    std::vector<double> rhoMax(nR * nS, 0.0);
    for (std::size_t r = 0; r < nR; ++r) {
        out.structure[r] = fitRegionStructure(db, static_cast<int>(r), params);
        for (std::size_t s = 0; s < nS; ++s)
            for (std::size_t c = 0; c < nCtx; ++c) rhoMax[r * nS + s] = std::max(rhoMax[r * nS + s], rho[(r * nS + s) * nCtx + c]);
    }

    phase("model fit and canopy context");
    // Masks (combinations) and which species each admits.
    const std::vector<std::int32_t> masks = distinctValues(map.combination);
    const std::vector<int> subMask = speciesSubBiomeMasks(biome);
    auto maskIndex = [&](std::int32_t m) {
        const auto it = std::lower_bound(masks.begin(), masks.end(), m);
        return (it != masks.end() && *it == m) ? static_cast<std::size_t>(it - masks.begin()) : std::size_t(-1);
    };
    Grid<std::uint16_t> maskIdx = Grid<std::uint16_t>::like(terrainM, 0);
    if (masks.size() > 65535) throw ValidationError("undergrowth sampling: more than 65535 sub-biome combinations");
#pragma omp parallel for schedule(static)
    for (int iy = 0; iy < h; ++iy)
        for (int ix = 0; ix < w; ++ix) maskIdx(ix, iy) = static_cast<std::uint16_t>(maskIndex(map.combination(ix, iy)));
    auto admits = [&](std::size_t m, std::size_t s) { return (subMask[s] & masks[m]) != 0; };
    // Per mask index: the species it admits, ascending.
    std::vector<std::uint16_t> maskSpecies;
    std::vector<std::uint32_t> maskSpeciesStart(masks.size() + 1, 0);
    for (std::size_t m = 0; m < masks.size(); ++m) {
        for (std::size_t s = 0; s < nS; ++s)
            if (admits(m, s)) maskSpecies.push_back(static_cast<std::uint16_t>(s));
        maskSpeciesStart[m + 1] = static_cast<std::uint32_t>(maskSpecies.size());
    }

    // Cells of each region; rows in parallel, added in row order.
    std::vector<std::int64_t> rowCells(static_cast<std::size_t>(h) * nR, 0);
#pragma omp parallel for schedule(static)
    for (int iy = 0; iy < h; ++iy)
        for (int ix = 0; ix < w; ++ix) {
            const int r = map.region(ix, iy);
            if (r < 0 || static_cast<std::size_t>(r) >= nR) continue;
            ++rowCells[static_cast<std::size_t>(iy) * nR + static_cast<std::size_t>(r)];
        }
    // Quota tiles: each (region, species, tile) gets its expected count, so the plants of a
    // species follow its per-context densities tile by tile and not only over the whole
    // region (a clustered pattern's count in a window varies far more than a Poisson one's).
    const double tileM = params.quotaTileM > 0 ? params.quotaTileM : std::max(terrainM.extentX(), terrainM.extentY());
    const int nTx = std::max(1, static_cast<int>(std::ceil(terrainM.extentX() / tileM)));
    const int nTy = std::max(1, static_cast<int>(std::ceil(terrainM.extentY() / tileM)));
    const std::size_t nTiles = static_cast<std::size_t>(nTx) * static_cast<std::size_t>(nTy);
    std::vector<int> tileX(static_cast<std::size_t>(w)), tileY(static_cast<std::size_t>(h));
    for (int ix = 0; ix < w; ++ix) tileX[static_cast<std::size_t>(ix)] = std::min(nTx - 1, static_cast<int>((ix + 0.5) * cs / tileM));
    for (int iy = 0; iy < h; ++iy) tileY[static_cast<std::size_t>(iy)] = std::min(nTy - 1, static_cast<int>((iy + 0.5) * cs / tileM));
    // The quota tile of every cell (a lookup instead of a division per candidate).
    RawArray<std::uint32_t> tileOfCell(static_cast<std::size_t>(w) * static_cast<std::size_t>(h));
#pragma omp parallel for schedule(static)
    for (int iy = 0; iy < h; ++iy)
        for (int ix = 0; ix < w; ++ix)
            tileOfCell[terrainM.index(ix, iy)] = static_cast<std::uint32_t>(tileY[static_cast<std::size_t>(iy)] * nTx + tileX[static_cast<std::size_t>(ix)]);
    auto groupOf = [&](std::size_t cell, std::size_t s) {
        return (static_cast<std::size_t>(map.region.data()[cell]) * nS + s) * nTiles + tileOfCell[cell];
    };
    const std::size_t nGroups = nR * nS * nTiles;
    // Expected counts per group: one tile row per task, cells in a fixed order.
    std::vector<double> expectedG(nGroups, 0.0);
#pragma omp parallel for schedule(dynamic, 1)
    for (int ty = 0; ty < nTy; ++ty)
        for (int iy = 0; iy < h; ++iy) {
            if (tileY[static_cast<std::size_t>(iy)] != ty) continue;
            for (int ix = 0; ix < w; ++ix) {
                const int r = map.region(ix, iy);
                if (r < 0 || static_cast<std::size_t>(r) >= nR || !(map.seedWeight(ix, iy) > 0)) continue;
                const std::size_t cell = terrainM.index(ix, iy), m = maskIdx.data()[cell], c = ctx.data()[cell];
                const std::size_t tile = tileOfCell[cell];
                for (std::uint32_t k = maskSpeciesStart[m]; k < maskSpeciesStart[m + 1]; ++k) {
                    const std::size_t s = maskSpecies[k];
                    expectedG[(static_cast<std::size_t>(r) * nS + s) * nTiles + tile] += rho[(static_cast<std::size_t>(r) * nS + s) * nCtx + c] * cellArea;
                }
            }
        }
    std::vector<std::int64_t> quotaG(nGroups, 0), placedG(nGroups, 0);
    for (std::size_t g = 0; g < nGroups; ++g) quotaG[g] = static_cast<std::int64_t>(std::llround(expectedG[g]));
    std::vector<double> expected(nR * nS, 0.0);
    out.regions.resize(nR);
    std::vector<std::int64_t> quota(nR * nS, 0);
    for (std::size_t r = 0; r < nR; ++r) {
        RegionSampling& rs = out.regions[r];
        rs.region = static_cast<int>(r);
        for (int iy = 0; iy < h; ++iy) rs.cells += rowCells[static_cast<std::size_t>(iy) * nR + r];
        rs.areaM2 = static_cast<double>(rs.cells) * cellArea;
        // Quotas: the expected count of each species at its per-context densities over the
        // cells here that admit it (the region's mean density when the target has the
        // database's mix of contexts, more plants where it has more of the dense contexts).
        std::int64_t n = 0;
        for (std::size_t s = 0; s < nS; ++s) {
            for (std::size_t t = 0; t < nTiles; ++t) {
                expected[r * nS + s] += expectedG[(r * nS + s) * nTiles + t];
                quota[r * nS + s] += quotaG[(r * nS + s) * nTiles + t];
            }
            n += quota[r * nS + s];
        }
        rs.targetCount = n;
        rs.targetDensityPerM2 = rs.areaM2 > 0 ? double(n) / rs.areaM2 : 0.0;
    }

    const TrunkIndex trunks(canopy, params.trunkExclusionFactor);
    const Grid<std::uint8_t> nearTrunk = nearTrunkCells(terrainM, canopy, params.trunkExclusionFactor);
    const double ox = terrainM.originX(), oy = terrainM.originY();
    auto onTrunk = [&](std::size_t cell, double x, double y) { return nearTrunk.data()[cell] != 0 && trunks.onTrunk(x, y); };
    // Target intensity of species s at a cell (per m^2), before the oversampling factor.
    std::vector<double> scale(nR * nS, 0.0);
    for (std::size_t i = 0; i < nR * nS; ++i) scale[i] = expected[i] > 0 ? double(quota[i]) / expected[i] : 0.0;
    auto intensity = [&](std::size_t cell, std::size_t s) -> double {
        const int r = map.region.data()[cell];
        if (r < 0 || !admits(maskIdx.data()[cell], s)) return 0.0;
        if (!(map.seedWeight.data()[cell] > 0)) return 0.0;
        return scale[static_cast<std::size_t>(r) * nS + s] * rho[(static_cast<std::size_t>(r) * nS + s) * nCtx + ctx.data()[cell]];
    };

    HardCore hardCore(out.structure, nS, terrainM.extentX(), terrainM.extentY());
    phase("masks, quotas, trunks");
    // No group takes more than its quota (and the hard cores' drops leave the array): one
    // allocation for every pass's plants, filled in pass order.
    RawArray<Candidate> accepted(static_cast<std::size_t>(std::accumulate(quotaG.begin(), quotaG.end(), std::int64_t{0})));
    std::size_t nAccepted = 0;
    for (int pass = 0; pass < params.maxPasses; ++pass) {
        // Rate factor per (region, species): the oversampling times the share of its quota
        // still missing. Every pass draws from the same model: the free part, and offspring
        // of the same cluster parents (their streams do not depend on the pass), so the
        // plants of all passes together are one thinned realisation of it, conditioned on
        // one parent field (a later pass with parents of its own would dilute the clustering).
        std::vector<double> passFactor(nR * nS, 0.0), freeFactor(nR * nS, 0.0);
        bool any = false;
        for (std::size_t r = 0; r < nR; ++r)
            for (std::size_t s = 0; s < nS; ++s) {
                const std::size_t i = r * nS + s;
                std::int64_t missing = 0;
                for (std::size_t t = 0; t < nTiles; ++t)
                    missing += std::max<std::int64_t>(0, quotaG[i * nTiles + t] - placedG[i * nTiles + t]);
                if (missing <= 0 || !(expected[i] > 0)) continue;
                any = true;
                // Later passes oversample more (the few plants still missing would otherwise
                // take many passes to find darts).
                passFactor[i] = params.candidateOversample * std::min(64.0, std::pow(2.0, pass)) * double(missing) / double(quota[i]);
                double attached = 0;
                for (int k = 0; k < out.structure[r].scales; ++k) attached += out.structure[r].attachment[s * 2 + static_cast<std::size_t>(k)];
                freeFactor[i] = passFactor[i] * scale[i] * std::max(0.0, 1.0 - attached);
            }
        if (!any) break;
        out.passes = pass + 1;
        std::vector<double> groupFactor;
        std::vector<char> tileActive;
        std::vector<std::uint16_t> tileSpecies;
        std::vector<std::uint32_t> tileSpeciesStart;
        if (pass > 0) {
            groupFactor.assign(nGroups, 0.0);
            tileActive.assign(nR * nTiles, 0);
            const double boost = params.candidateOversample * std::min(64.0, std::pow(2.0, pass));
            for (std::size_t g = 0; g < nGroups; ++g) {
                const std::int64_t missing = quotaG[g] - placedG[g];
                if (missing <= 0) continue;
                const std::size_t i = g / nTiles;
                groupFactor[g] = boost * scale[i] * double(missing) / std::max(1e-300, expectedG[g]);
                tileActive[(i / nS) * nTiles + g % nTiles] = 1;
            }
            // Per (region, tile): its species with a rate factor, ascending.
            tileSpeciesStart.assign(nR * nTiles + 1, 0);
            for (std::size_t r = 0; r < nR; ++r)
                for (std::size_t t = 0; t < nTiles; ++t) {
                    for (std::size_t sp = 0; sp < nS; ++sp)
                        if (groupFactor[(r * nS + sp) * nTiles + t] > 0) tileSpecies.push_back(static_cast<std::uint16_t>(sp));
                    tileSpeciesStart[r * nTiles + t + 1] = static_cast<std::uint32_t>(tileSpecies.size());
                }
        }
        std::vector<char> activeRegion(nR, 0);
        for (std::size_t i = 0; i < nR * nS; ++i)
            if (passFactor[i] > 0) activeRegion[i / nS] = 1;
        RateTable table;
        table.nMasks = masks.size();
        table.nCtx = nCtx;
        table.nSpecies = nS;
        table.cumulative.assign(nR * masks.size() * nCtx * nS, 0.0);
        for (std::size_t r = 0; r < nR; ++r)
            for (std::size_t m = 0; m < masks.size(); ++m)
                for (std::size_t c = 0; c < nCtx; ++c) {
                    double acc = 0;
                    double* row = &table.cumulative[((r * masks.size() + m) * nCtx + c) * nS];
                    for (std::size_t s = 0; s < nS; ++s) {
                        if (admits(m, s)) acc += freeFactor[r * nS + s] * rho[(r * nS + s) * nCtx + c];
                        row[s] = acc;
                    }
                }

        // exp(-lambda) of the free darts of a cell, per (region, mask, context): one exp per
        // table entry instead of one per cell.
        std::vector<double> expFree(nR * masks.size() * nCtx);
        for (std::size_t r = 0; r < nR; ++r)
            for (std::size_t m = 0; m < masks.size(); ++m)
                for (std::size_t c = 0; c < nCtx; ++c)
                    expFree[(r * masks.size() + m) * nCtx + c] = std::exp(-std::min(100.0, table.total(r, m, c) * cellArea));
        // Per row its candidates, made in a buffer of the thread and copied whole into the
        // thread's arena (large blocks on huge pages: growing a vector per row cost a page
        // fault per 4 kB, hundreds of MB at 3072^2); the rows are then read in row order.
        const std::size_t maxThreads = static_cast<std::size_t>(omp_get_max_threads());
        std::vector<const Candidate*> rowPtr(static_cast<std::size_t>(h), nullptr);
        std::vector<std::size_t> rowCount(static_cast<std::size_t>(h), 0);
        std::vector<CandidateArena> arenas(maxThreads);
        std::vector<RowScratch> scratch(maxThreads);
        std::vector<std::int64_t> rowThrown(static_cast<std::size_t>(h), 0), rowOnTrunk(static_cast<std::size_t>(h), 0);
        const std::uint64_t freeStream = mixStream(kFreeStream, static_cast<std::uint64_t>(pass));
        // The row's random blocks are made in batches (randomBlocksBatch, eight at a time:
        // the same bits as the streams' one block at a time): first every dart count of the
        // row, then every dart's two blocks, then the same for the cluster offspring.
        auto rowBody = [&](const int iy, RowScratch& sc) {
            std::vector<Candidate>& cand = sc.cand;
            // A candidate off the trunks joins the row's list.
            auto keep = [&](double x, double y, std::size_t cell, std::size_t s, std::uint64_t key) {
                if (onTrunk(cell, x, y)) {
                    ++rowOnTrunk[static_cast<std::size_t>(iy)];
                    return;
                }
                cand.push_back(Candidate{key, static_cast<float>(x - ox), static_cast<float>(y - oy), static_cast<std::uint32_t>(cell),
                                         static_cast<std::uint16_t>(s), static_cast<std::uint16_t>(pass)});
            };
            // Free darts. The cells that throw them: pass 0 at the model's free rate (table by
            // region, mask, context); later passes at each (region, species, tile)'s own missing
            // share, in the tiles that still miss plants (a few per cent of the plants; the
            // tiles' quotas keep the density where it is due), the species' cumulative rates kept.
            sc.cells.clear();
            sc.rates.clear();
            sc.rateSpecies.clear();
            sc.counts.clear();
            for (int ix = 0; ix < w; ++ix) {
                const int r = map.region(ix, iy);
                if (r < 0) continue;
                const std::size_t cell = terrainM.index(ix, iy);
                const float wgt = map.seedWeight.data()[cell];
                if (!(wgt > 0)) continue;
                const std::size_t m = maskIdx.data()[cell], c = ctx.data()[cell];
                DartCell dc{ix, static_cast<std::uint32_t>(cell), r, static_cast<std::uint32_t>(m), static_cast<std::uint32_t>(c), 0, 0, -1, 0, 0, 0};
                if (pass == 0) {
                    dc.lambda = table.total(static_cast<std::size_t>(r), m, c) * cellArea;
                    if (!(dc.lambda > 0)) continue;
                    if (dc.lambda <= 100) dc.expNeg = expFree[(static_cast<std::size_t>(r) * masks.size() + m) * nCtx + c];
                } else {
                    const std::size_t tile = static_cast<std::size_t>(tileY[static_cast<std::size_t>(iy)]) * static_cast<std::size_t>(nTx) +
                                             static_cast<std::size_t>(tileX[static_cast<std::size_t>(ix)]);
                    if (!tileActive[static_cast<std::size_t>(r) * nTiles + tile]) continue;
                    // The species' rates added in species order; those of a species that no
                    // longer misses plants in the tile are 0 and leave the sums as they are, so
                    // only the tile's missing species are listed (with their cumulative rate).
                    const std::size_t at = sc.rates.size();
                    const std::size_t rt = static_cast<std::size_t>(r) * nTiles + tile;
                    double total = 0;
                    for (std::uint32_t k = tileSpeciesStart[rt]; k < tileSpeciesStart[rt + 1]; ++k) {
                        const std::size_t s = tileSpecies[k];
                        const std::size_t g = (static_cast<std::size_t>(r) * nS + s) * nTiles + tile;
                        const double f = admits(m, s) ? groupFactor[g] * rho[(static_cast<std::size_t>(r) * nS + s) * nCtx + c] : 0.0;
                        total += f;
                        sc.rates.push_back(total);
                        sc.rateSpecies.push_back(static_cast<std::uint16_t>(s));
                    }
                    if (!(total > 0)) {
                        sc.rates.resize(at);
                        sc.rateSpecies.resize(at);
                        continue;
                    }
                    dc.total = total;
                    dc.lambda = total * cellArea;
                    if (dc.lambda <= 100) dc.expNeg = std::exp(-dc.lambda);
                    dc.rates = at;
                    dc.nRates = static_cast<std::uint32_t>(sc.rates.size() - at);
                }
                dc.stream = mixStream(freeStream, cell);
                sc.counts.add(mixStream(dc.stream, kParentStream), 0);  // the cell's count: block 0 of its own stream
                sc.cells.push_back(dc);
            }
            sc.counts.make(params.seed);
            sc.blocks.clear();
            for (std::size_t i = 0; i < sc.cells.size(); ++i) {
                DartCell& dc = sc.cells[i];
                if (dc.expNeg >= 0) {
                    dc.n = poissonInvert(sc.counts.unit(i, 0), dc.lambda, dc.expNeg, 65535);
                } else {
                    RandomStream counter(params.seed, sc.counts.stream[i], 0);
                    dc.n = poissonCount(counter, dc.lambda, 65535);
                }
                // Dart j: blocks 2j and 2j + 1 of the cell's stream (8 words).
                for (int j = 0; j < dc.n; ++j) {
                    sc.blocks.add(dc.stream, 2 * static_cast<std::uint64_t>(j));
                    sc.blocks.add(dc.stream, 2 * static_cast<std::uint64_t>(j) + 1);
                }
            }
            sc.blocks.make(params.seed);
            std::size_t q = 0;
            for (const DartCell& dc : sc.cells)
                for (int j = 0; j < dc.n; ++j, q += 2) {
                    const double x = ox + (dc.ix + sc.blocks.unit(q, 0)) * cs, y = oy + (iy + sc.blocks.unit(q, 2)) * cs;
                    const std::uint64_t key = (static_cast<std::uint64_t>(sc.blocks.word[2][q + 1]) << 32) | sc.blocks.word[3][q + 1];
                    ++rowThrown[static_cast<std::size_t>(iy)];
                    if (pass == 0) {
                        const int s = table.pick(static_cast<std::size_t>(dc.region), dc.mask, dc.ctx, sc.blocks.unit(q + 1, 0));
                        if (s >= 0) keep(x, y, dc.cell, static_cast<std::size_t>(s), key);
                    } else {
                        // The first species whose cumulative rate exceeds u; the last one when
                        // none does (the linear search over all species, which stopped there).
                        const double u = sc.blocks.unit(q + 1, 0) * dc.total;
                        const double* rates = sc.rates.data() + dc.rates;
                        std::size_t k = 0;
                        while (k < dc.nRates && rates[k] <= u) ++k;
                        keep(x, y, dc.cell, k < dc.nRates ? sc.rateSpecies[dc.rates + k] : nS - 1, key);
                    }
                }
            if (pass != 0) return;
            // Cluster parents of each field (the same in every pass): per row a Poisson number
            // at the row's total rate kappa x area, each in a cell drawn by its rate; then
            // their offspring of each attached species.
            std::vector<double>& cum = sc.cum;
            cum.resize(static_cast<std::size_t>(w));
            for (int k = 0; k < 2; ++k) {
                double total = 0;
                for (int ix = 0; ix < w; ++ix) {
                    const int r = map.region(ix, iy);
                    if (r >= 0 && map.seedWeight(ix, iy) > 0 && out.structure[static_cast<std::size_t>(r)].scales > k)
                        total += out.structure[static_cast<std::size_t>(r)].parentsPerM2[k] * cellArea;
                    cum[static_cast<std::size_t>(ix)] = total;
                }
                if (!(total > 0)) continue;
                RandomStream prs(params.seed, mixStream(mixStream(kParentStream, static_cast<std::uint64_t>(k)), static_cast<std::uint64_t>(iy)), 0);
                const int nParents = poissonCount(prs, total, 1 << 30);
                // The broods (a parent's offspring of one species) in order, each with its
                // count drawn from block 0 of its stream.
                sc.broods.clear();
                sc.counts.clear();
                for (int j = 0; j < nParents; ++j) {
                    const double u = prs.uniform() * total;
                    int ix = static_cast<int>(std::upper_bound(cum.begin(), cum.end(), u) - cum.begin());
                    ix = std::min(ix, w - 1);
                    const double px = ox + (ix + prs.uniform()) * cs, py = oy + (iy + prs.uniform()) * cs;
                    const int r = map.region(ix, iy);
                    if (!activeRegion[static_cast<std::size_t>(r)]) continue;
                    const RegionStructure& st = out.structure[static_cast<std::size_t>(r)];
                    for (std::size_t s = 0; s < nS; ++s) {
                        const double a = st.attachment[s * 2 + static_cast<std::size_t>(k)];
                        const std::size_t i = static_cast<std::size_t>(r) * nS + s;
                        const double lmax = scale[i] * rhoMax[i];
                        if (!(a > 0) || !(lmax > 0) || !(passFactor[i] > 0)) continue;
                        const std::uint64_t oStream = mixStream(
                            mixStream(mixStream(mixStream(kOffspringStream, static_cast<std::uint64_t>(pass)), static_cast<std::uint64_t>(k)),
                                      static_cast<std::uint64_t>(iy)),
                            static_cast<std::uint64_t>(j) * nS + s);
                        Brood br{};
                        br.px = px;
                        br.py = py;
                        br.sigma = st.sigmaM[k];
                        br.lmax = lmax;
                        br.lambda = passFactor[i] * a * lmax / st.parentsPerM2[k];
                        br.species = static_cast<std::uint32_t>(s);
                        sc.counts.add(oStream, 0);
                        sc.broods.push_back(br);
                    }
                }
                sc.counts.make(params.seed);
                // Offspring o of a brood: its stream's words 8o .. 8o + 7 after the count
                // (the count's block's words left over, then the blocks after it).
                sc.blocks.clear();
                for (std::size_t g = 0; g < sc.broods.size(); ++g) {
                    Brood& br = sc.broods[g];
                    const std::uint64_t oStream = sc.counts.stream[g];
                    std::uint64_t nextBlock;
                    if (br.lambda > 0 && br.lambda <= 100) {
                        br.n = poissonInvert(sc.counts.unit(g, 0), br.lambda, std::exp(-br.lambda), 65535);
                        br.lead = 2;
                        br.leadWord[0] = sc.counts.word[2][g];
                        br.leadWord[1] = sc.counts.word[3][g];
                        nextBlock = 1;
                    } else {
                        RandomStream ors(params.seed, oStream, 0);
                        br.n = poissonCount(ors, br.lambda, 65535);
                        br.lead = 0;
                        for (int u = ors.usedWords(); u < 4; ++u) br.leadWord[br.lead++] = ors.buffered()[static_cast<std::size_t>(u)];
                        nextBlock = ors.nextBlock();
                    }
                    br.firstBlock = sc.blocks.stream.size();
                    const std::int64_t words = 8 * static_cast<std::int64_t>(br.n) - br.lead;
                    for (std::int64_t b = 0; b < (words + 3) / 4; ++b) sc.blocks.add(oStream, nextBlock + static_cast<std::uint64_t>(b));
                }
                sc.blocks.make(params.seed);
                // Each brood's words in stream order (its count's leftovers, then its blocks).
                sc.words.clear();
                for (Brood& br : sc.broods) {
                    const std::size_t begin = sc.words.size();
                    for (int u = 0; u < br.lead; ++u) sc.words.push_back(br.leadWord[u]);
                    const std::size_t nWords = 8 * static_cast<std::size_t>(br.n);
                    for (std::size_t b = br.firstBlock; sc.words.size() - begin < nWords; ++b)
                        for (int k = 0; k < 4; ++k) sc.words.push_back(sc.blocks.word[k][b]);
                    br.firstBlock = begin;  // now: where its words start in sc.words
                }
                for (const Brood& br : sc.broods) {
                    const std::uint32_t* wd = sc.words.data() + br.firstBlock;
                    auto word = [&](std::size_t t) { return wd[t]; };
                    const std::size_t s = br.species;
                    for (std::size_t o = 0; o < static_cast<std::size_t>(br.n); ++o) {
                        const std::size_t t = 8 * o;
                        // Gaussian displacement: both coordinates of one Box-Muller pair.
                        const double u1 = 1.0 - bitsToUnit(word(t), word(t + 1)), u2 = bitsToUnit(word(t + 2), word(t + 3));
                        const double radius = br.sigma * std::sqrt(-2.0 * std::log(u1)), angle = 2.0 * kPi * u2;
                        const double x = br.px + radius * std::cos(angle), y = br.py + radius * std::sin(angle);
                        const double uThin = bitsToUnit(word(t + 4), word(t + 5));
                        const std::uint64_t key = (static_cast<std::uint64_t>(word(t + 6)) << 32) | word(t + 7);
                        ++rowThrown[static_cast<std::size_t>(iy)];
                        const int cx = terrainM.cellX(x), cy = terrainM.cellY(y);
                        if (!terrainM.inside(cx, cy)) continue;
                        const std::size_t oc = terrainM.index(cx, cy);
                        if (uThin * br.lmax < intensity(oc, s)) keep(x, y, oc, s, key);
                    }
                }
            }
        };
#pragma omp parallel for schedule(dynamic, 8)
        for (int iy = 0; iy < h; ++iy) {
            const std::size_t t = static_cast<std::size_t>(omp_get_thread_num());
            RowScratch& sc = scratch[t];
            sc.cand.clear();
            rowBody(iy, sc);
            rowCount[static_cast<std::size_t>(iy)] = sc.cand.size();
            rowPtr[static_cast<std::size_t>(iy)] = arenas[t].append(sc.cand.data(), sc.cand.size());
        }
        std::vector<RowScratch>().swap(scratch);
        phase("candidates");
        std::vector<std::size_t> rowStart(static_cast<std::size_t>(h) + 1, 0);
        for (int iy = 0; iy < h; ++iy) {
            out.darts += rowThrown[static_cast<std::size_t>(iy)];
            out.dartsOnTrunks += rowOnTrunk[static_cast<std::size_t>(iy)];
            rowStart[static_cast<std::size_t>(iy) + 1] = rowStart[static_cast<std::size_t>(iy)] + rowCount[static_cast<std::size_t>(iy)];
        }
        const std::size_t nCand = rowStart[static_cast<std::size_t>(h)];
        const RowCandidates rows{rowPtr, rowStart};
        auto groupOfCand = [&](const Candidate& c) { return groupOf(c.cell, c.species); };
        // Each (region, species, tile) keeps its lowest keys up to what it still misses: the
        // keys of each group gathered in one array (straight from the rows' lists, in row
        // order), each group's threshold found by nth_element in parallel (the k-th smallest
        // key does not depend on the order).
        RawArray<std::uint64_t> keys(nCand);
        const std::vector<std::size_t> groupStart =
            scatterRanges(nCand, nGroups, rows, groupOfCand, [&](const Candidate& c, std::size_t p) { keys[p] = c.key; });
        std::vector<std::uint64_t> threshold(nGroups, std::numeric_limits<std::uint64_t>::max());
        std::vector<std::int64_t> equalQuota(nGroups, std::numeric_limits<std::int64_t>::max());
#pragma omp parallel for schedule(dynamic, 64) if (nCand >= kParallelMin)
        for (std::int64_t gi = 0; gi < static_cast<std::int64_t>(nGroups); ++gi) {
            const std::size_t i = static_cast<std::size_t>(gi);
            const std::int64_t missing = quotaG[i] - placedG[i];
            if (missing <= 0) {
                threshold[i] = 0;
                equalQuota[i] = 0;
                continue;
            }
            std::uint64_t* b = keys.data() + groupStart[i];
            std::uint64_t* e = keys.data() + groupStart[i + 1];
            placedG[i] += std::min<std::int64_t>(missing, e - b);  // less those the hard cores drop, below
            if (e - b <= missing) continue;
            std::nth_element(b, b + (missing - 1), e);
            threshold[i] = b[missing - 1];
            std::int64_t less = 0;
            for (auto it = b; it != e; ++it) less += *it < threshold[i];
            equalQuota[i] = missing - less;
        }
        keys = RawArray<std::uint64_t>();
        // Below the threshold: taken; at it: the first equalQuota[g] in candidate order (a
        // key drawn twice), decided in order between the parallel count and the copy. Each
        // thread takes a contiguous share of the candidates, so the accepted ones come in
        // candidate order, appended to `accepted`, for any number of threads.
        const std::size_t passFirst = nAccepted;
        {
            std::vector<std::size_t> taken(maxThreads + 1, 0);
            std::vector<std::vector<std::uint8_t>> tieTaken(maxThreads);
            std::vector<std::vector<std::uint32_t>> tieGroup(maxThreads);
#pragma omp parallel if (nCand >= kParallelMin)
            {
                const std::size_t t = static_cast<std::size_t>(omp_get_thread_num()), nt = static_cast<std::size_t>(omp_get_num_threads());
                const std::size_t lo = nCand * t / nt, hi = nCand * (t + 1) / nt;
                std::size_t below = 0;
                rows(lo, hi, [&](const Candidate& c) {
                    const std::size_t g = groupOfCand(c);
                    if (c.key < threshold[g])
                        ++below;
                    else if (c.key == threshold[g])
                        tieGroup[t].push_back(static_cast<std::uint32_t>(g));
                });
                taken[t] = below;
#pragma omp barrier
#pragma omp single
                {
                    std::size_t at = passFirst;
                    for (std::size_t u = 0; u < nt; ++u) {
                        for (const std::uint32_t g : tieGroup[u]) {
                            const bool take = equalQuota[g]-- > 0;
                            tieTaken[u].push_back(take ? 1 : 0);
                            taken[u] += take;
                        }
                        const std::size_t k = taken[u];
                        taken[u] = at;
                        at += k;
                    }
                    nAccepted = at;
                }
                std::size_t at = taken[t], tie = 0;
                rows(lo, hi, [&](const Candidate& c) {
                    const std::uint64_t th = threshold[groupOfCand(c)];
                    if (c.key < th || (c.key == th && tieTaken[t][tie++])) accepted[at++] = c;
                });
            }
        }
        std::vector<CandidateArena>().swap(arenas);
        phase("quota selection");
        // Inhibition: in ascending key order, a candidate closer than the hard-core distance
        // to a plant already placed is dropped (random sequential adsorption); later passes
        // throw darts for what is missing.
        if (hardCore.maxM > 0) {
            std::vector<Candidate> dropped;
            nAccepted = passFirst + hardCore.select(accepted.data() + passFirst, nAccepted - passFirst, map.region.data().data(), dropped);
            for (const Candidate& c : dropped) --placedG[groupOf(c.cell, c.species)];
            out.dartsInhibited += static_cast<std::int64_t>(dropped.size());
        }
        phase("hard core");
    }
    const RawArray<std::uint32_t> order = orderInBuckets(
        accepted.data(), nAccepted, (static_cast<std::size_t>(w) * static_cast<std::size_t>(h) + 15) / 16,
        [](const Candidate& c) { return static_cast<std::size_t>(c.cell) / 16; },
        [](const Candidate& a, const Candidate& b) {
            if (a.cell != b.cell) return a.cell < b.cell;
            if (a.key != b.key) return a.key < b.key;
            return a.pass < b.pass;
        });
    for (std::size_t r = 0; r < nR; ++r)
        for (std::size_t s = 0; s < nS; ++s)
            for (std::size_t t = 0; t < nTiles; ++t) out.regions[r].placed += placedG[(r * nS + s) * nTiles + t];

    phase("final sort");
    drawSizes(db, biome, canopy, map, terrainM, params, withContext, accepted.data(), order.data(), nAccepted, out);
    phase("sizes");
    out.seconds = std::chrono::duration<double>(Clock::now() - t0).count();
    return out;
}

}  // namespace eco::synth
