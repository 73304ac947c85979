// Regions: combination labels from the canopy, k-means on the annual-mean abiotics, and the
// silhouette criterion that picks k.
#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>

#include "analysis.h"
#include "error.h"
#include "rng.h"

namespace eco::analysis {

namespace {

double dist2(const Features& a, const Features& b) {
    double d = 0;
    for (std::size_t f = 0; f < kFactorCount; ++f) d += (a[f] - b[f]) * (a[f] - b[f]);
    return d;
}

int nearest(const Features& p, const std::vector<Features>& centroids, double* d2out = nullptr) {
    int best = 0;
    double bestD = std::numeric_limits<double>::infinity();
    for (std::size_t c = 0; c < centroids.size(); ++c) {
        const double d = dist2(p, centroids[c]);
        if (d < bestD) {
            bestD = d;
            best = static_cast<int>(c);
        }
    }
    if (d2out) *d2out = bestD;
    return best;
}

/// Draw an index with probability proportional to weights (total > 0).
std::size_t drawWeighted(const std::vector<double>& weights, double total, RandomStream& rng) {
    const double target = rng.uniform() * total;
    double acc = 0;
    for (std::size_t i = 0; i < weights.size(); ++i) {
        acc += weights[i];
        if (target < acc) return i;
    }
    // Rounding: the last index with a positive weight.
    for (std::size_t i = weights.size(); i-- > 0;)
        if (weights[i] > 0) return i;
    return 0;
}

KMeansResult lloyd(const std::vector<Features>& points, std::vector<Features> centroids, int maxIterations) {
    const std::size_t n = points.size();
    const std::size_t k = centroids.size();
    KMeansResult r;
    r.assignment.assign(n, -1);
    for (int it = 0; it < std::max(1, maxIterations); ++it) {
        bool changed = false;
        for (std::size_t i = 0; i < n; ++i) {
            const int c = nearest(points[i], centroids);
            if (c != r.assignment[i]) {
                r.assignment[i] = c;
                changed = true;
            }
        }
        if (!changed && it > 0) break;
        std::vector<Features> sum(k, Features{});
        std::vector<std::size_t> count(k, 0);
        for (std::size_t i = 0; i < n; ++i) {
            const std::size_t c = static_cast<std::size_t>(r.assignment[i]);
            ++count[c];
            for (std::size_t f = 0; f < kFactorCount; ++f) sum[c][f] += points[i][f];
        }
        for (std::size_t c = 0; c < k; ++c) {
            if (count[c] == 0) {
                // Empty cluster: move it to the point farthest from its centroid (deterministic).
                std::size_t far = 0;
                double farD = -1;
                for (std::size_t i = 0; i < n; ++i) {
                    const double d = dist2(points[i], centroids[static_cast<std::size_t>(r.assignment[i])]);
                    if (d > farD) {
                        farD = d;
                        far = i;
                    }
                }
                centroids[c] = points[far];
                changed = true;
                continue;
            }
            for (std::size_t f = 0; f < kFactorCount; ++f) centroids[c][f] = sum[c][f] / static_cast<double>(count[c]);
        }
    }
    // Final assignment against the final centroids.
    r.inertia = 0;
    for (std::size_t i = 0; i < n; ++i) {
        double d = 0;
        r.assignment[i] = nearest(points[i], centroids, &d);
        r.inertia += d;
    }
    r.centroids = std::move(centroids);
    return r;
}

}  // namespace

const char* toString(CanopyMembership m) {
    switch (m) {
        case CanopyMembership::SubBiomeCanopyLists: return "sub_biome_canopy_lists";
        case CanopyMembership::SpeciesSubBiomes: return "species_sub_biomes";
    }
    return "?";
}

Features clusteringWeights(const Biome& biome) {
    Features w{};
    for (const Species& s : biome.species)
        for (std::size_t f = 0; f < kFactorCount; ++f)
            if (!s.responses[f].isIndifferent()) w[f] = 1.0;
    return w;
}

std::vector<int> canopySubBiomeMasks(const Biome& biome, CanopyMembership membership) {
    if (biome.subBiomes.size() > 30)
        throw ValidationError("biome '" + biome.name + "': at most 30 sub-biomes can be analysed, found " +
                              std::to_string(biome.subBiomes.size()));
    std::vector<int> masks(biome.species.size(), 0);
    for (std::size_t s = 0; s < biome.species.size(); ++s) {
        const Species& sp = biome.species[s];
        if (!sp.canopy) continue;
        int m = 0;
        if (membership == CanopyMembership::SubBiomeCanopyLists) {
            for (const SubBiome& sb : biome.subBiomes)
                if (std::find(sb.canopySpecies.begin(), sb.canopySpecies.end(), sp.name) != sb.canopySpecies.end())
                    m |= 1 << (sb.number - 1);
        } else {
            for (int b : sp.subBiomes) m |= 1 << (b - 1);
        }
        masks[s] = m;
    }
    return masks;
}

KMeansResult kmeans(const std::vector<Features>& points, int k, std::uint64_t seed, std::uint64_t stream,
                    int restarts, int maxIterations) {
    const std::size_t n = points.size();
    if (k < 1 || static_cast<std::size_t>(k) > n)
        throw ValidationError("k-means: k = " + std::to_string(k) + " needs 1..number of points (" + std::to_string(n) + ")");
    KMeansResult best;
    best.inertia = std::numeric_limits<double>::infinity();
    for (int rs = 0; rs < std::max(1, restarts); ++rs) {
        RandomStream rng(seed, mixStream(stream, static_cast<std::uint64_t>(rs)));
        // k-means++: first centre uniform, then with probability proportional to D^2.
        std::vector<Features> centroids;
        centroids.push_back(points[rng.below(static_cast<std::uint32_t>(n))]);
        std::vector<double> d2(n);
        for (std::size_t i = 0; i < n; ++i) d2[i] = dist2(points[i], centroids[0]);
        while (centroids.size() < static_cast<std::size_t>(k)) {
            const double total = std::accumulate(d2.begin(), d2.end(), 0.0);
            // All remaining points coincide with a centre: take the next point in order.
            const std::size_t pick = total > 0 ? drawWeighted(d2, total, rng) : centroids.size() % n;
            centroids.push_back(points[pick]);
            for (std::size_t i = 0; i < n; ++i) d2[i] = std::min(d2[i], dist2(points[i], centroids.back()));
        }
        KMeansResult r = lloyd(points, std::move(centroids), maxIterations);
        if (r.inertia < best.inertia) best = std::move(r);
    }
    return best;
}

double meanSilhouette(const std::vector<Features>& points, const std::vector<int>& assignment, int k) {
    const std::size_t n = points.size();
    if (k < 2 || n < 2) return std::numeric_limits<double>::quiet_NaN();
    std::vector<std::size_t> size(static_cast<std::size_t>(k), 0);
    for (int a : assignment) ++size[static_cast<std::size_t>(a)];
    std::vector<double> s(n, 0.0);
    const std::ptrdiff_t nn = static_cast<std::ptrdiff_t>(n);
#pragma omp parallel
    {
        std::vector<double> sumTo(static_cast<std::size_t>(k));
#pragma omp for schedule(dynamic, 64)
        for (std::ptrdiff_t i = 0; i < nn; ++i) {
            const std::size_t ci = static_cast<std::size_t>(assignment[static_cast<std::size_t>(i)]);
            if (size[ci] <= 1) continue;  // alone in its cluster: 0
            std::fill(sumTo.begin(), sumTo.end(), 0.0);
            for (std::size_t j = 0; j < n; ++j)
                sumTo[static_cast<std::size_t>(assignment[j])] += std::sqrt(dist2(points[static_cast<std::size_t>(i)], points[j]));
            const double a = sumTo[ci] / static_cast<double>(size[ci] - 1);
            double b = std::numeric_limits<double>::infinity();
            for (std::size_t c = 0; c < static_cast<std::size_t>(k); ++c)
                if (c != ci && size[c] > 0) b = std::min(b, sumTo[c] / static_cast<double>(size[c]));
            if (!std::isfinite(b)) continue;
            const double m = std::max(a, b);
            s[static_cast<std::size_t>(i)] = m > 0 ? (b - a) / m : 0.0;
        }
    }
    // Summed in index order: identical for any thread count.
    return std::accumulate(s.begin(), s.end(), 0.0) / static_cast<double>(n);
}

KSelection selectK(const std::vector<Features>& points, int kLimit, const AnalysisParams& params, std::uint64_t stream) {
    KSelection sel;
    const std::size_t n = points.size();
    const double nan = std::numeric_limits<double>::quiet_NaN();
    sel.silhouette.assign(static_cast<std::size_t>(std::max(1, params.kMax)), nan);
    if (n == 0) return sel;

    // Seeded sample (partial Fisher-Yates) when there are too many points; its first
    // silhouetteSampleCells entries are themselves a uniform sample for silhouettes.
    std::vector<std::size_t> idx(n);
    std::iota(idx.begin(), idx.end(), std::size_t{0});
    const std::size_t m = std::min(n, static_cast<std::size_t>(params.kmeansSampleCells));
    RandomStream rng(params.seed, mixStream(stream, 0x5A3D1Eull));
    for (std::size_t i = 0; i < m && m < n; ++i) {
        const std::size_t j = i + rng.below(static_cast<std::uint32_t>(n - i));
        std::swap(idx[i], idx[j]);
    }
    std::vector<Features> sample(m);
    for (std::size_t i = 0; i < m; ++i) sample[i] = points[idx[i]];
    const std::size_t ms = std::min(m, static_cast<std::size_t>(params.silhouetteSampleCells));
    const std::vector<Features> silSample(sample.begin(), sample.begin() + static_cast<std::ptrdiff_t>(ms));

    // Distinct points bound k.
    std::vector<Features> distinct = sample;
    std::sort(distinct.begin(), distinct.end());
    distinct.erase(std::unique(distinct.begin(), distinct.end()), distinct.end());
    const int limit = std::min({kLimit, params.kMax, static_cast<int>(distinct.size()), static_cast<int>(ms)});

    KMeansResult one = kmeans(sample, 1, params.seed, mixStream(stream, 1), 1, params.kmeansMaxIterations);
    sel.centroids = one.centroids;
    double bestS = -2;
    int bestK = 1;
    std::vector<Features> bestCentroids;
    for (int k = 2; k <= limit; ++k) {
        KMeansResult r = kmeans(sample, k, params.seed, mixStream(stream, static_cast<std::uint64_t>(k)),
                                params.kmeansRestarts, params.kmeansMaxIterations);
        std::vector<int> silAssign(ms);
        for (std::size_t i = 0; i < ms; ++i) silAssign[i] = nearest(silSample[i], r.centroids);
        const double s = meanSilhouette(silSample, silAssign, k);
        sel.silhouette[static_cast<std::size_t>(k - 1)] = s;
        if (s > bestS) {
            bestS = s;
            bestK = k;
            bestCentroids = r.centroids;
        }
    }
    if (bestK >= 2 && bestS >= params.silhouetteThreshold) {
        sel.k = bestK;
        sel.centroids = std::move(bestCentroids);
    }
    // Canonical order: by centroid, feature by feature (sun first).
    std::sort(sel.centroids.begin(), sel.centroids.end());
    return sel;
}

}  // namespace eco::analysis
