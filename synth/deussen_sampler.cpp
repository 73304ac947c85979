// The Deussen et al. 1998 undergrowth sampler (SynthMethod::Deussen; docs/synth.md section 2c):
// "Given an image that specifies the distribution of densities of a plant species, positions
// of individual plants are generated using a half-toning algorithm [Floyd-Steinberg] ... a
// relaxation method that iteratively moves each plant position towards the center of mass
// of its Voronoi polygon" (§4.1).
//
// 1. Density map. Species s at terrain cell c: the database's density of s in the cell's
//    region and canopy context (speciesContextDensities, as the structured sampler uses it)
//    where the cell's seeding sub-biomes admit s, else 0. A user density image d (relative
//    density of the whole undergrowth) reshapes it: lambda_s(c) = base_s(c) d(c) K, K =
//    sum over s and c of base_s / sum of base_s d, so the undergrowth keeps the database's
//    total over the terrain and darker cells get fewer plants of every species.
// 2. Half-toning. Per species, each terrain cell is split into k x k half-toning cells (k the
//    smallest with at most `halftoneFill` expected plants in a half-toning cell where the
//    species is densest); Floyd-Steinberg error diffusion in serpentine order, each tile of
//    `halftoneTileM` on its own; a cell gives round(value + diffused error) dots, each
//    jittered uniformly inside it. The error goes only to cells where the species may grow
//    (weights renormalised), so mass is kept up to half a plant per tile.
// 3. Minimum distances, in the species' priority order (largest mean height first): a dot
//    closer than its minimum distance to a plant already kept (its own species: the larger
//    of `minDistanceFactor` x its mean crown radius and the database's hard core; another
//    species: their hard core), or on a canopy trunk's exclusion disc, is jittered again in
//    its half-toning cell (8 tries), else dropped.
// 4. Lloyd relaxation, `lloydIterations` times: each plant moves to the centroid of its
//    Voronoi cell (among its own species), weighted by the density squared (the points of a
//    centroidal Voronoi tessellation settle at a density proportional to the square root of
//    its weight in 2-D, Gersho 1979: so the plants keep their density classes), estimated
//    from the centres of an m x m lattice on a square around the plant; canopy trunks'
//    exclusion discs and cells where the species may not grow weigh nothing (obstacles). A
//    move is refused when it lands where the species may not grow, on a trunk, or nearer
//    than a minimum distance to another plant's previous position; then moves that
//    conflict with each other are undone (both), so no pair ends closer than its minimum
//    distance. Plants of earlier species and canopy trees never move.
// 5. Sizes: drawSizes, the structured sampler's (height from the region's histogram by
//    canopy context, below the crown above; radius by allometry).
//
// Determinism: dots are keyed by (seed, species, half-toning cell), re-jitters by (seed,
// species, dot); the tiles and the per-plant steps are independent, and every sum runs in a
// fixed order, so the result is bit-identical for any thread count.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <ctime>
#include <limits>
#include <numeric>

#include <omp.h>

#include "canopy_context.h"
#include "error.h"
#include "image_in.h"
#include "rng.h"
#include "sampling_detail.h"
#include "text_format.h"
#include "undergrowth.h"

namespace eco::synth {

using namespace detail;

namespace {

constexpr std::uint64_t kDotStream = 0x4445555353444f54ull;    // "DEUSSDOT"
constexpr std::uint64_t kRetryStream = 0x4445555352455452ull;  // "DEUSRETR"
/// Re-jitters of a dot that lands too near a plant before it is dropped.
constexpr int kJitterTries = 8;
/// Largest split of a terrain cell per side (a density image with one bright pixel would ask
/// for more; the half-toning cell then holds several plants).
constexpr int kMaxSplit = 16;

using Clock = std::chrono::steady_clock;

/// Density of every species per terrain cell (step 1).
struct DensityMap {
    const ClusterMap& map;
    const Grid<std::uint8_t>& ctx;
    const Grid<float>* image = nullptr;
    std::vector<double> rho;  ///< speciesContextDensities
    std::size_t nR = 0, nS = 0, nCtx = 1;
    std::vector<int> subMask;        ///< per species: its sub-biome bits
    std::vector<double> imageScale;  ///< per species: K_s (1 without an image)

    /// Plants per m^2 of species s in cell `cell`.
    double operator()(std::size_t s, std::size_t cell) const {
        const int r = map.region.data()[cell];
        if (r < 0 || static_cast<std::size_t>(r) >= nR || !(map.seedWeight.data()[cell] > 0) ||
            (subMask[s] & map.combination.data()[cell]) == 0)
            return 0.0;
        const double v = rho[(static_cast<std::size_t>(r) * nS + s) * nCtx + ctx.data()[cell]];
        return image == nullptr ? v : v * imageScale[s] * static_cast<double>(image->data()[cell]);
    }
};

struct Dot {
    double x, y;           ///< world metres
    std::uint64_t key;     ///< keys the size draw and the output order
    std::uint32_t gx, gy;  ///< half-toning cell, for re-jitters
};

/// Points of one species or more in buckets that can grow (the kept dots of step 3).
struct GrowingGrid {
    double ox = 0, oy = 0, cell = 1;
    int nx = 1, ny = 1;
    std::vector<std::int32_t> head, next;
    std::vector<double> xs, ys;
    GrowingGrid(double originX, double originY, double extentX, double extentY, double cellM)
        : ox(originX), oy(originY), cell(std::max(cellM, 1e-3)) {
        nx = std::max(1, static_cast<int>(std::ceil(extentX / cell)));
        ny = std::max(1, static_cast<int>(std::ceil(extentY / cell)));
        head.assign(static_cast<std::size_t>(nx) * static_cast<std::size_t>(ny), -1);
    }
    int bx(double x) const { return std::clamp(static_cast<int>(std::floor((x - ox) / cell)), 0, nx - 1); }
    int by(double y) const { return std::clamp(static_cast<int>(std::floor((y - oy) / cell)), 0, ny - 1); }
    void add(double x, double y) {
        const std::size_t b = static_cast<std::size_t>(by(y)) * static_cast<std::size_t>(nx) + static_cast<std::size_t>(bx(x));
        next.push_back(head[b]);
        head[b] = static_cast<std::int32_t>(xs.size());
        xs.push_back(x);
        ys.push_back(y);
    }
    /// True when a point lies nearer than d to (x, y).
    bool anyWithin(double x, double y, double d) const {
        if (!(d > 0)) return false;
        const int x0 = bx(x - d), x1 = bx(x + d), y0 = by(y - d), y1 = by(y + d);
        for (int j = y0; j <= y1; ++j)
            for (int i = x0; i <= x1; ++i)
                for (std::int32_t p = head[static_cast<std::size_t>(j) * static_cast<std::size_t>(nx) + static_cast<std::size_t>(i)]; p >= 0;
                     p = next[static_cast<std::size_t>(p)]) {
                    const double dx = xs[static_cast<std::size_t>(p)] - x, dy = ys[static_cast<std::size_t>(p)] - y;
                    if (dx * dx + dy * dy < d * d) return true;
                }
        return false;
    }
};

/// Clark-Evans R of a pattern of n points on `areaM2` (no edge correction): mean
/// nearest-neighbour distance over 0.5 / sqrt(density). 0 for fewer than 2 points.
double clarkEvans(const std::vector<double>& x, const std::vector<double>& y, double areaM2) {
    const std::size_t n = x.size();
    if (n < 2 || !(areaM2 > 0)) return 0.0;
    const double spacing = std::sqrt(areaM2 / static_cast<double>(n));
    const PointGrid grid(x, y, spacing);
    const std::vector<std::uint32_t>& order = grid.order();
    std::vector<double> nn(n, 0.0);
    // Sorted index of each original point, to skip the point itself.
    std::vector<std::size_t> sortedOf(n);
    for (std::size_t s = 0; s < n; ++s) sortedOf[order[s]] = s;
#pragma omp parallel for schedule(static)
    for (std::int64_t ii = 0; ii < static_cast<std::int64_t>(n); ++ii) {
        const std::size_t i = static_cast<std::size_t>(ii);
        double radius = 2.0 * spacing, best = std::numeric_limits<double>::infinity();
        for (int tries = 0; tries < 40 && !(best < radius * radius); ++tries, radius *= 2)
            grid.forEachWithin(x[i], y[i], radius, [&](std::size_t s, double, double, double d2) {
                if (s != sortedOf[i] && d2 < best) best = d2;
            });
        nn[i] = std::isfinite(best) ? std::sqrt(best) : 0.0;
    }
    double sum = 0;
    for (double d : nn) sum += d;
    return (sum / static_cast<double>(n)) / (0.5 * spacing);
}

}  // namespace

Grid<float> readDensityImage(const std::string& path, const Grid<float>& like) {
    const ImagePixels image = readImagePixels(path, "density image", 0, [&](int w, int h, int) {
        if (w != like.width() || h != like.height())
            throw ValidationError(path + ": density image is " + std::to_string(w) + " x " + std::to_string(h) +
                                  " pixels but the terrain is " + std::to_string(like.width()) + " x " +
                                  std::to_string(like.height()) +
                                  " cells; resample the image to the terrain's size (it is not resampled automatically)");
    });
    const int w = image.width, h = image.height, nch = image.channels;
    const int colour = nch >= 3 ? 3 : 1;  // alpha (the 2nd of 2, the 4th) ignored
    Grid<float> out = Grid<float>::like(like, 0.0f);
    double total = 0;
    for (int row = 0; row < h; ++row) {
        const int iy = h - 1 - row;  // image row 0 = north
        for (int ix = 0; ix < w; ++ix) {
            const std::size_t k = (static_cast<std::size_t>(row) * static_cast<std::size_t>(w) + static_cast<std::size_t>(ix)) *
                                  static_cast<std::size_t>(nch);
            double grey = 0;
            for (int c = 0; c < colour; ++c) grey += image.values[k + static_cast<std::size_t>(c)];
            grey /= colour;
            if (!std::isfinite(grey) || grey < 0)
                throw ValidationError(path + ": density image value " + formatNumber(grey, 6) + " at column " +
                                      std::to_string(ix + 1) + ", row " + std::to_string(row + 1) +
                                      " is not a relative density (finite, >= 0)");
            out(ix, iy) = static_cast<float>(grey);
            total += grey;
        }
    }
    if (!(total > 0))
        throw ValidationError(path + ": density image is 0 everywhere: no plant could be placed (white = densest, black = none)");
    return out;
}

UndergrowthSample sampleDeussen(const BiomeDatabase& db, const Biome& biome, const std::vector<Plant>& canopy,
                                const ClusterMap& map, const Grid<float>& terrainM, const SynthParams& params,
                                const Grid<float>* densityImage) {
    const auto t0 = Clock::now();
    UndergrowthSample out;
    detail::PhaseTimer phase(out.phases);
    const DeussenParams& dp = params.deussen;
    const int w = terrainM.width(), h = terrainM.height();
    const double cs = terrainM.cellSizeM(), cellArea = cs * cs;
    const double ox = terrainM.originX(), oy = terrainM.originY();
    const std::size_t nR = db.regions.size(), nS = static_cast<std::size_t>(db.speciesCount());
    const bool withContext = db.hasContext();
    if (!withContext)
        out.warnings.push_back("the database (schema " + std::to_string(db.schemaVersion) +
                               ") has no canopy-context statistics: the density map is each region's mean density "
                               "and heights are not split under crowns and open");
    const Grid<std::uint8_t> ctx = withContext ? canopyContextMap(canopyDepthMap(terrainM, canopy), db.contextBins)
                                               : Grid<std::uint8_t>::like(terrainM, 0);

    DensityMap density{map, ctx, densityImage, speciesContextDensities(db), nR, nS,
                       withContext ? static_cast<std::size_t>(db.contextBins.count()) : 1, speciesSubBiomeMasks(biome),
                       std::vector<double>(nS, 1.0)};
    // Per species: sum of the database density (and of it times the image) over the terrain,
    // rows in parallel, added in row order.
    std::vector<double> rowBase(static_cast<std::size_t>(h) * nS, 0.0), rowImage(static_cast<std::size_t>(h) * nS, 0.0);
    {
        DensityMap base = density;
        base.image = nullptr;
#pragma omp parallel for schedule(static)
        for (int iy = 0; iy < h; ++iy)
            for (int ix = 0; ix < w; ++ix) {
                const std::size_t cell = terrainM.index(ix, iy);
                for (std::size_t s = 0; s < nS; ++s) {
                    const double b = base(s, cell);
                    if (!(b > 0)) continue;
                    rowBase[static_cast<std::size_t>(iy) * nS + s] += b;
                    if (densityImage != nullptr) rowImage[static_cast<std::size_t>(iy) * nS + s] += b * densityImage->data()[cell];
                }
            }
    }
    std::vector<double> baseSum(nS, 0.0), imageSum(nS, 0.0);
    for (int iy = 0; iy < h; ++iy)
        for (std::size_t s = 0; s < nS; ++s) {
            baseSum[s] += rowBase[static_cast<std::size_t>(iy) * nS + s];
            imageSum[s] += rowImage[static_cast<std::size_t>(iy) * nS + s];
        }
    if (densityImage != nullptr) {
        // One factor for all species: the image is the relative density of the whole
        // undergrowth, and the undergrowth keeps the database's total over the terrain.
        double allBase = 0, allImage = 0;
        for (std::size_t s = 0; s < nS; ++s) {
            allBase += baseSum[s];
            allImage += imageSum[s];
        }
        const double k = allImage > 0 ? allBase / allImage : 0.0;
        if (!(allImage > 0) && allBase > 0)
            throw ValidationError("the density image is 0 wherever the database places undergrowth: nothing to place");
        for (std::size_t s = 0; s < nS; ++s) {
            density.imageScale[s] = k;
            if (baseSum[s] > 0 && !(imageSum[s] > 0))
                out.warnings.push_back("the density image is 0 wherever the database places " + biome.species[s].name +
                                       " (about " + formatNumber(baseSum[s] * cellArea, 4) + " plants without it): none placed");
        }
    }
    // Per species: densest cell and the area where it may grow.
    std::vector<double> maxDensity(nS, 0.0), speciesAreaM2(nS, 0.0);
    {
        std::vector<double> rowMax(static_cast<std::size_t>(h) * nS, 0.0), rowCount(static_cast<std::size_t>(h) * nS, 0.0);
#pragma omp parallel for schedule(static)
        for (int iy = 0; iy < h; ++iy)
            for (int ix = 0; ix < w; ++ix) {
                const std::size_t cell = terrainM.index(ix, iy);
                for (std::size_t s = 0; s < nS; ++s) {
                    const double v = density(s, cell);
                    if (!(v > 0)) continue;
                    double& m = rowMax[static_cast<std::size_t>(iy) * nS + s];
                    m = std::max(m, v);
                    rowCount[static_cast<std::size_t>(iy) * nS + s] += 1;
                }
            }
        for (int iy = 0; iy < h; ++iy)
            for (std::size_t s = 0; s < nS; ++s) {
                maxDensity[s] = std::max(maxDensity[s], rowMax[static_cast<std::size_t>(iy) * nS + s]);
                speciesAreaM2[s] += rowCount[static_cast<std::size_t>(iy) * nS + s] * cellArea;
            }
    }

    // Priority: largest mean height in the database first (Deussen's larger plants first).
    const std::vector<DbHistogram> pooledHeight = pooledSizeHistograms(db, false);
    const std::vector<DbHistogram> pooledRadius = pooledSizeHistograms(db, true);
    auto histogramMean = [](const DbHistogram& hist) {
        double n = 0, sum = 0;
        for (std::size_t k = 0; k < hist.counts.size() && k + 1 < hist.edges.size(); ++k) {
            n += hist.counts[k];
            sum += hist.counts[k] * 0.5 * (hist.edges[k] + hist.edges[k + 1]);
        }
        return n > 0 ? sum / n : 0.0;
    };
    std::vector<std::size_t> order;
    for (std::size_t s = 0; s < nS; ++s)
        if (maxDensity[s] > 0) order.push_back(s);
    std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
        return histogramMean(pooledHeight[a]) > histogramMean(pooledHeight[b]);
    });
    // Minimum distances: hard cores (the largest over the regions, both orders) and the
    // species' own spacing.
    std::vector<double> minDist(nS * nS, 0.0);
    for (std::size_t r = 0; r < nR; ++r) {
        const RegionStructure st = fitRegionStructure(db, static_cast<int>(r), params);
        if (st.hardCoreM.size() != nS * nS) continue;
        for (std::size_t a = 0; a < nS; ++a)
            for (std::size_t b = 0; b < nS; ++b) {
                const double d = std::max(st.hardCoreM[a * nS + b], st.hardCoreM[b * nS + a]);
                minDist[a * nS + b] = std::max(minDist[a * nS + b], d);
            }
    }
    for (std::size_t s = 0; s < nS; ++s)
        minDist[s * nS + s] = std::max(minDist[s * nS + s], dp.minDistanceFactor * histogramMean(pooledRadius[s]));

    const TrunkIndex trunks(canopy, params.trunkExclusionFactor);
    const Grid<std::uint8_t> nearTrunk = nearTrunkCells(terrainM, canopy, params.trunkExclusionFactor);
    auto cellOf = [&](double x, double y) -> std::int64_t {
        const int cx = terrainM.cellX(x), cy = terrainM.cellY(y);
        if (!terrainM.inside(cx, cy)) return -1;
        return static_cast<std::int64_t>(terrainM.index(cx, cy));
    };
    auto onTrunk = [&](std::size_t cell, double x, double y) { return nearTrunk.data()[cell] && trunks.onTrunk(x, y); };
    phase("density map");

    // ------------------------------------------------------------------ 2. half-toning
    std::vector<int> split(nS, 1);
    for (std::size_t s : order)
        split[s] = std::clamp(static_cast<int>(std::ceil(cs * std::sqrt(maxDensity[s] / dp.halftoneFill) - 1e-9)), 1, kMaxSplit);
    // Half-toning cells whose centre is on a trunk's exclusion disc get no plant; each species'
    // half-toned density is raised by the share it loses there, so that its total is kept.
    std::vector<double> trunkScale(nS, 1.0);
    {
        std::vector<double> rowLost(static_cast<std::size_t>(h) * nS, 0.0);
#pragma omp parallel for schedule(dynamic, 16)
        for (int iy = 0; iy < h; ++iy)
            for (int ix = 0; ix < w; ++ix) {
                const std::size_t cell = terrainM.index(ix, iy);
                if (!nearTrunk.data()[cell]) continue;
                for (std::size_t s : order) {
                    const double v = density(s, cell);
                    if (!(v > 0)) continue;
                    const int k = split[s];
                    const double hc = cs / k;
                    int on = 0;
                    for (int b = 0; b < k; ++b)
                        for (int a = 0; a < k; ++a)
                            on += trunks.onTrunk(ox + (static_cast<double>(ix) * k + a + 0.5) * hc, oy + (static_cast<double>(iy) * k + b + 0.5) * hc);
                    rowLost[static_cast<std::size_t>(iy) * nS + s] += v * on / (k * k);
                }
            }
        for (std::size_t s : order) {
            double lost = 0;
            for (int iy = 0; iy < h; ++iy) lost += rowLost[static_cast<std::size_t>(iy) * nS + s];
            // The density map's sum of the species.
            const double total = densityImage != nullptr ? density.imageScale[s] * imageSum[s] : baseSum[s];
            if (total > lost && lost > 0) trunkScale[s] = total / (total - lost);
        }
    }
    const int tileCells = std::max(1, static_cast<int>(std::lround(dp.halftoneTileM / cs)));
    const int nTx = (w + tileCells - 1) / tileCells, nTy = (h + tileCells - 1) / tileCells;
    const std::size_t tilesPerSpecies = static_cast<std::size_t>(nTx) * static_cast<std::size_t>(nTy);
    std::vector<std::vector<Dot>> tileDots(order.size() * tilesPerSpecies);
#pragma omp parallel for schedule(dynamic, 1)
    for (std::int64_t task = 0; task < static_cast<std::int64_t>(tileDots.size()); ++task) {
        const std::size_t si = static_cast<std::size_t>(task) / tilesPerSpecies, tile = static_cast<std::size_t>(task) % tilesPerSpecies;
        const std::size_t s = order[si];
        const int k = split[s];
        const double hc = cs / k, hcArea = hc * hc * trunkScale[s];
        const int cx0 = static_cast<int>(tile % static_cast<std::size_t>(nTx)) * tileCells;
        const int cy0 = static_cast<int>(tile / static_cast<std::size_t>(nTx)) * tileCells;
        const int cx1 = std::min(w, cx0 + tileCells), cy1 = std::min(h, cy0 + tileCells);
        const int W = (cx1 - cx0) * k, H = (cy1 - cy0) * k;
        std::vector<double> valCur(static_cast<std::size_t>(W)), valNext(static_cast<std::size_t>(W));
        std::vector<double> errCur(static_cast<std::size_t>(W), 0.0), errNext(static_cast<std::size_t>(W), 0.0);
        // Expected plants of each half-toning cell of row j (0 outside the species' area and
        // where the cell's centre is on a trunk).
        auto rowValues = [&](int j, std::vector<double>& v) {
            const int cy = cy0 + j / k;
            const double yc = oy + (static_cast<double>(cy0) * k + j + 0.5) * hc;
            for (int i = 0; i < W; ++i) {
                const int cx = cx0 + i / k;
                const std::size_t cell = terrainM.index(cx, cy);
                double val = density(s, cell) * hcArea;
                if (val > 0 && nearTrunk.data()[cell] && trunks.onTrunk(ox + (static_cast<double>(cx0) * k + i + 0.5) * hc, yc)) val = 0;
                v[static_cast<std::size_t>(i)] = val;
            }
        };
        std::vector<Dot>& dots = tileDots[static_cast<std::size_t>(task)];
        const std::uint64_t speciesStream = mixStream(kDotStream, s);
        const std::uint64_t rowCells = static_cast<std::uint64_t>(w) * static_cast<std::uint64_t>(k);
        double carry = 0;
        if (H > 0) rowValues(0, valCur);
        for (int j = 0; j < H; ++j) {
            const bool last = j + 1 >= H;
            if (!last) rowValues(j + 1, valNext);
            const int dir = (j % 2 == 0) ? 1 : -1;
            const std::uint32_t gy = static_cast<std::uint32_t>(cy0 * k + j);
            for (int t = 0; t < W; ++t) {
                const int i = dir > 0 ? t : W - 1 - t;
                const double v = valCur[static_cast<std::size_t>(i)];
                if (!(v > 0)) continue;
                const double acc = v + errCur[static_cast<std::size_t>(i)] + carry;
                carry = 0;
                const int n = acc >= 0.5 ? static_cast<int>(std::floor(acc + 0.5)) : 0;
                const double e = acc - n;
                const std::uint32_t gx = static_cast<std::uint32_t>(cx0 * k + i);
                for (int m = 0; m < n; ++m) {
                    RandomStream rs(params.seed, mixStream(speciesStream, static_cast<std::uint64_t>(gy) * rowCells + gx), 2 * static_cast<std::uint64_t>(m));
                    const double u = rs.uniform(), uy = rs.uniform();
                    const std::uint64_t key = (static_cast<std::uint64_t>(rs.nextU32()) << 32) | rs.nextU32();
                    dots.push_back(Dot{ox + (gx + u) * hc, oy + (gy + uy) * hc, key, gx, gy});
                }
                // Floyd-Steinberg weights 7 (ahead), 3 (below behind), 5 (below), 1 (below
                // ahead), over the neighbours where the species may grow.
                const int ahead = i + dir, behind = i - dir;
                auto okCur = [&](int x) { return x >= 0 && x < W && valCur[static_cast<std::size_t>(x)] > 0; };
                auto okNext = [&](int x) { return !last && x >= 0 && x < W && valNext[static_cast<std::size_t>(x)] > 0; };
                const double w7 = okCur(ahead) ? 7 : 0, w3 = okNext(behind) ? 3 : 0, w5 = okNext(i) ? 5 : 0, w1 = okNext(ahead) ? 1 : 0;
                const double wsum = w7 + w3 + w5 + w1;
                if (!(wsum > 0)) {
                    carry = e;  // to the next cell of the species' area in scan order
                    continue;
                }
                if (w7 > 0) errCur[static_cast<std::size_t>(ahead)] += e * w7 / wsum;
                if (w3 > 0) errNext[static_cast<std::size_t>(behind)] += e * w3 / wsum;
                if (w5 > 0) errNext[static_cast<std::size_t>(i)] += e * w5 / wsum;
                if (w1 > 0) errNext[static_cast<std::size_t>(ahead)] += e * w1 / wsum;
            }
            std::swap(valCur, valNext);
            std::swap(errCur, errNext);
            std::fill(errNext.begin(), errNext.end(), 0.0);
        }
    }
    phase("half-toning");

    // ------------------------------------------------------------------ 3, 4. per species
    struct Placed {
        double x, y;
        std::uint64_t key;
        std::uint32_t cell;
        std::uint16_t species;
    };
    std::vector<Placed> placed;
    double lloydSeconds = 0, spacingSeconds = 0;
    for (std::size_t si = 0; si < order.size(); ++si) {
        const std::size_t s = order[si];
        auto tSpecies = Clock::now();
        const int k = split[s];
        const double hc = cs / k;
        const double dSelf = minDist[s * nS + s];
        UndergrowthSample::DeussenSpecies report;
        report.species = static_cast<int>(s);
        report.halftoneCellM = hc;
        report.minDistanceM = dSelf;
        // The species' density on every cell (one lookup per Voronoi sample).
        std::vector<double> lambda(static_cast<std::size_t>(w) * static_cast<std::size_t>(h));
#pragma omp parallel for schedule(static)
        for (int iy = 0; iy < h; ++iy)
            for (int ix = 0; ix < w; ++ix) {
                const std::size_t cell = terrainM.index(ix, iy);
                lambda[cell] = density(s, cell);
            }
        // Plants of earlier species this one keeps a hard core from.
        std::vector<double> ox2, oy2, od;
        double otherMax = 0;
        for (const Placed& p : placed) {
            const double d = minDist[s * nS + p.species];
            if (!(d > 0)) continue;
            ox2.push_back(p.x);
            oy2.push_back(p.y);
            od.push_back(d);
            otherMax = std::max(otherMax, d);
        }
        const PointGrid others = ox2.empty() ? PointGrid() : PointGrid(ox2, oy2, std::max(1.0, 2.0 * otherMax));
        const std::vector<double> othersD = ox2.empty() ? std::vector<double>() : others.permuted(od);
        auto nearOther = [&](double x, double y) {
            if (ox2.empty()) return false;
            bool hit = false;
            others.forEachWithin(x, y, otherMax, [&](std::size_t q, double, double, double d2) {
                if (d2 < othersD[q] * othersD[q]) hit = true;
            });
            return hit;
        };
        // Where a plant of s may stand (its area, off the trunks, away from earlier species).
        auto allowed = [&](double x, double y, std::int64_t& cellOut) {
            const std::int64_t cell = cellOf(x, y);
            if (cell < 0 || !(lambda[static_cast<std::size_t>(cell)] > 0)) return false;
            if (onTrunk(static_cast<std::size_t>(cell), x, y) || nearOther(x, y)) return false;
            cellOut = cell;
            return true;
        };

        // Step 3: the dots in tile and scan order; a dot too near is jittered again, then dropped.
        std::vector<double> X, Y;
        std::vector<std::uint64_t> keys;
        GrowingGrid kept(ox, oy, terrainM.extentX(), terrainM.extentY(), std::max(dSelf, 4.0 * hc));
        std::int64_t dotIndex = 0;
        for (std::size_t tile = 0; tile < tilesPerSpecies; ++tile)
            for (const Dot& d : tileDots[si * tilesPerSpecies + tile]) {
                ++report.dots;
                double x = d.x, y = d.y;
                std::int64_t cell = -1;
                bool ok = allowed(x, y, cell) && !kept.anyWithin(x, y, dSelf);
                for (int tr = 0; !ok && tr < kJitterTries; ++tr) {
                    RandomStream rs(params.seed, mixStream(mixStream(kRetryStream, s), static_cast<std::uint64_t>(dotIndex)), static_cast<std::uint64_t>(tr));
                    x = ox + (d.gx + rs.uniform()) * hc;
                    y = oy + (d.gy + rs.uniform()) * hc;
                    ok = allowed(x, y, cell) && !kept.anyWithin(x, y, dSelf);
                }
                ++dotIndex;
                if (!ok) {
                    ++report.dropped;
                    continue;
                }
                kept.add(x, y);
                X.push_back(x);
                Y.push_back(y);
                keys.push_back(d.key);
            }
        const std::size_t n = X.size();
        report.clarkEvansBefore = clarkEvans(X, Y, speciesAreaM2[s]);
        spacingSeconds += std::chrono::duration<double>(Clock::now() - tSpecies).count();
        tSpecies = Clock::now();

        // Step 4: Lloyd relaxation (Jacobi: every plant from the previous positions).
        const double meanDensity = speciesAreaM2[s] > 0 ? baseSum[s] * cellArea / speciesAreaM2[s] : 1.0;
        const int m = dp.voronoiSamples;
        std::vector<double> NX(n), NY(n);
        std::vector<std::uint8_t> moved(n);
        for (int it = 0; it < dp.lloydIterations && n > 0; ++it) {
            const PointGrid grid(X, Y, std::max(0.05, 1.0 / std::sqrt(std::max(meanDensity, 1e-12))));
            const std::vector<std::uint32_t>& gorder = grid.order();
            const std::vector<double>& gx = grid.xs();
            const std::vector<double>& gy = grid.ys();
            std::int64_t refused = 0;
#pragma omp parallel reduction(+ : refused)
            {
                std::vector<std::pair<double, std::uint32_t>> nb;  // (distance^2 to the plant, sorted index)
#pragma omp for schedule(static)
                for (std::int64_t ii = 0; ii < static_cast<std::int64_t>(n); ++ii) {
                    const std::size_t i = static_cast<std::size_t>(ii);
                    const double xi = X[i], yi = Y[i];
                    NX[i] = xi;
                    NY[i] = yi;
                    moved[i] = 0;
                    const std::int64_t ci = cellOf(xi, yi);
                    double lam = ci >= 0 ? lambda[static_cast<std::size_t>(ci)] : 0.0;
                    if (!(lam > 0)) lam = meanDensity;
                    const double R = dp.voronoiRadiusFactor / std::sqrt(lam);
                    nb.clear();
                    grid.forEachWithin(xi, yi, 2.0 * std::sqrt(2.0) * R, [&](std::size_t q, double, double, double d2) {
                        if (gorder[q] != i) nb.emplace_back(d2, static_cast<std::uint32_t>(q));
                    });
                    std::sort(nb.begin(), nb.end());
                    // Samples at the centres of an m x m lattice on the square: a fixed rule, so
                    // that the relaxation settles (random samples keep plants jittering).
                    // The lattice's columns and rows and their cells, once per plant.
                    double offX[64], offY[64];
                    int cellXs[64], cellYs[64];
                    for (int a = 0; a < m; ++a) {
                        offX[a] = offY[a] = R * (-1.0 + (2.0 * a + 1.0) / m);
                        cellXs[a] = terrainM.cellX(xi + offX[a]);
                        cellYs[a] = terrainM.cellY(yi + offY[a]);
                    }
                    double sw = 0, sx = 0, sy = 0;
                    for (int a = 0; a < m; ++a)
                        for (int b = 0; b < m; ++b) {
                            const double dx = offX[a], dy = offY[b];
                            const double px = xi + dx, py = yi + dy;
                            if (!terrainM.inside(cellXs[a], cellYs[b])) continue;
                            const std::size_t pc = terrainM.index(cellXs[a], cellYs[b]);
                            const double wgt = lambda[pc];
                            if (!(wgt > 0) || onTrunk(pc, px, py)) continue;
                            const double d0 = dx * dx + dy * dy;
                            bool own = true;
                            for (const auto& [di2, q] : nb) {
                                if (di2 > 4.0 * d0) break;  // farther than 2 |sample - plant|: cannot be nearer
                                const double ex = gx[q] - px, ey = gy[q] - py;
                                if (ex * ex + ey * ey < d0) {
                                    own = false;
                                    break;
                                }
                            }
                            if (!own) continue;
                            // Weight density^2: the points of a centroidal Voronoi tessellation
                            // with weight f settle at a density proportional to f^(1/2) in 2-D
                            // (Gersho 1979), so density^2 keeps the plants' density classes.
                            const double f = wgt * wgt;
                            sw += f;
                            sx += f * dx;
                            sy += f * dy;
                        }
                    if (!(sw > 0)) continue;
                    const double cx = xi + sx / sw, cy = yi + sy / sw;
                    std::int64_t cell = -1;
                    bool ok = allowed(cx, cy, cell);
                    if (ok && dSelf > 0)
                        grid.forEachWithin(cx, cy, dSelf, [&](std::size_t q, double, double, double) {
                            if (gorder[q] != i) ok = false;
                        });
                    if (!ok) {
                        ++refused;
                        continue;
                    }
                    NX[i] = cx;
                    NY[i] = cy;
                    moved[i] = 1;
                }
            }
            // Moves that conflict with each other are undone, both: every remaining pair then
            // had one side checked against the other's position.
            std::vector<std::uint8_t> undo(n, 0);
            if (dSelf > 0) {
                const PointGrid after(NX, NY, std::max(0.05, 2.0 * dSelf));
                const std::vector<std::uint32_t>& aorder = after.order();
#pragma omp parallel for schedule(static) reduction(+ : refused)
                for (std::int64_t ii = 0; ii < static_cast<std::int64_t>(n); ++ii) {
                    const std::size_t i = static_cast<std::size_t>(ii);
                    if (!moved[i]) continue;
                    bool clash = false;
                    after.forEachWithin(NX[i], NY[i], dSelf, [&](std::size_t q, double, double, double) {
                        const std::uint32_t j = aorder[q];
                        if (j != i && moved[j]) clash = true;
                    });
                    if (clash) {
                        undo[i] = 1;
                        ++refused;
                    }
                }
            }
            double moveSum = 0;
            for (std::size_t i = 0; i < n; ++i) {
                if (undo[i]) continue;
                moveSum += std::hypot(NX[i] - X[i], NY[i] - Y[i]);
                X[i] = NX[i];
                Y[i] = NY[i];
            }
            report.meanMoveM.push_back(moveSum / static_cast<double>(n));
            report.refused.push_back(refused);
        }
        report.clarkEvansAfter = clarkEvans(X, Y, speciesAreaM2[s]);
        for (std::size_t i = 0; i < n; ++i) {
            const std::int64_t cell = cellOf(X[i], Y[i]);
            placed.push_back(Placed{X[i], Y[i], keys[i], static_cast<std::uint32_t>(cell), static_cast<std::uint16_t>(s)});
        }
        out.darts += report.dots;
        out.dartsInhibited += report.dropped;
        out.deussen.push_back(std::move(report));
        lloydSeconds += std::chrono::duration<double>(Clock::now() - tSpecies).count();
    }
    out.phases.push_back(UndergrowthSample::Phase{"minimum distances", spacingSeconds, 0});
    out.phases.push_back(UndergrowthSample::Phase{"Lloyd relaxation", lloydSeconds, 0});
    phase.restart();

    // ------------------------------------------------------------------ 5. sizes, report
    std::vector<Candidate> accepted(placed.size());
    for (std::size_t i = 0; i < placed.size(); ++i) {
        const Placed& p = placed[i];
        Candidate c{p.key, static_cast<float>(p.x - ox), static_cast<float>(p.y - oy), p.cell, p.species, 0};
        // The stored (float) position decides the cell when it still lies in the species' area.
        const std::int64_t fc = cellOf(ox + static_cast<double>(c.dx), oy + static_cast<double>(c.dy));
        if (fc >= 0 && density(p.species, static_cast<std::size_t>(fc)) > 0) c.cell = static_cast<std::uint32_t>(fc);
        accepted[i] = c;
    }
    std::sort(accepted.begin(), accepted.end(), [](const Candidate& a, const Candidate& b) {
        if (a.cell != b.cell) return a.cell < b.cell;
        if (a.key != b.key) return a.key < b.key;
        return a.species < b.species;
    });
    drawSizes(db, biome, canopy, map, terrainM, params, withContext, accepted, out);
    phase("sizes");

    // Regions: cells, expected plants (the density map's sum) and plants placed.
    out.regions.resize(nR);
    std::vector<double> rowExpected(static_cast<std::size_t>(h) * nR, 0.0);
    std::vector<std::int64_t> rowCells(static_cast<std::size_t>(h) * nR, 0);
#pragma omp parallel for schedule(static)
    for (int iy = 0; iy < h; ++iy)
        for (int ix = 0; ix < w; ++ix) {
            const std::size_t cell = terrainM.index(ix, iy);
            const int r = map.region.data()[cell];
            if (r < 0 || static_cast<std::size_t>(r) >= nR) continue;
            const std::size_t i = static_cast<std::size_t>(iy) * nR + static_cast<std::size_t>(r);
            ++rowCells[i];
            for (std::size_t s = 0; s < nS; ++s) rowExpected[i] += density(s, cell) * cellArea;
        }
    for (std::size_t r = 0; r < nR; ++r) {
        RegionSampling& rs = out.regions[r];
        rs.region = static_cast<int>(r);
        double expected = 0;
        for (int iy = 0; iy < h; ++iy) {
            rs.cells += rowCells[static_cast<std::size_t>(iy) * nR + r];
            expected += rowExpected[static_cast<std::size_t>(iy) * nR + r];
        }
        rs.areaM2 = static_cast<double>(rs.cells) * cellArea;
        rs.targetDensityPerM2 = rs.areaM2 > 0 ? expected / rs.areaM2 : 0.0;
        rs.targetCount = std::llround(expected);
    }
    for (const std::int32_t r : out.plantRegion)
        if (r >= 0 && static_cast<std::size_t>(r) < nR) ++out.regions[static_cast<std::size_t>(r)].placed;
    out.passes = 1;
    out.seconds = std::chrono::duration<double>(Clock::now() - t0).count();
    return out;
}

}  // namespace eco::synth
