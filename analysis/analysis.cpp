// The analyser's driver: labels and regions for every input, then per-region statistics.
#include "analysis.h"

#include <omp.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>

#include "eco_version.h"
#include "error.h"
#include "provenance.h"
#include "text_format.h"

namespace eco::analysis {

namespace {

// The database records reals with twelve significant digits.
constexpr int kRecordDigits = 12;

std::string num(double v) { return formatNumber(v, kRecordDigits); }

/// Sources per work item of the pair loop. Fixed, never derived from the thread count, so
/// that the floating-point sums (per item, then added in item order) are reproducible.
constexpr std::size_t kSourcesPerItem = 1024;

/// Cell value used for cells outside the analysed window or with a non-finite abiotic.
constexpr std::int32_t kOutside = -1;

struct PreparedInput {
    Grid<std::int32_t> combination;  ///< mask, 0 = seeded by none, kOutside = not analysed
    Grid<std::int32_t> region;       ///< region index, -1 = none
    RectWindow window;               ///< clipped to the grid
};


void validateInputs(const std::vector<AnalysisInput>& inputs) {
    if (inputs.empty()) throw ValidationError("analyse: no inputs");
    for (std::size_t i = 0; i < inputs.size(); ++i) {
        const AnalysisInput& in = inputs[i];
        const std::string what = "analyse: input " + std::to_string(i) + " (" + in.provenance.path + ")";
        if (!in.biome) throw ValidationError(what + ": no biome");
        if (in.biome->species.size() != inputs[0].biome->species.size())
            throw ValidationError(what + ": biome has " + std::to_string(in.biome->species.size()) +
                                  " species, the first input's has " + std::to_string(inputs[0].biome->species.size()) +
                                  "; inputs analysed together must share their species");
        for (std::size_t s = 0; s < in.biome->species.size(); ++s)
            if (in.biome->species[s].name != inputs[0].biome->species[s].name)
                throw ValidationError(what + ": species " + std::to_string(s) + " is '" + in.biome->species[s].name +
                                      "', the first input's is '" + inputs[0].biome->species[s].name + "'");
        if (in.biome->subBiomes.size() != inputs[0].biome->subBiomes.size())
            throw ValidationError(what + ": the biome's sub-biomes differ from the first input's");
        if (in.features.geometry().empty()) throw ValidationError(what + ": empty abiotic grids");
        for (std::size_t f = 1; f < kFactorCount; ++f)
            if (!in.features.maps[f].sameGeometry(in.features.geometry()))
                throw ValidationError(what + ": the " + std::string(kFactors[f].key) +
                                      " grid differs in geometry from the " + kFactors[0].key + " grid");
        in.window.validate(what);
        for (const auto* list : {&in.canopy, &in.undergrowth})
            for (std::size_t p = 0; p < list->size(); ++p) {
                const Plant& pl = (*list)[p];
                if (pl.speciesId < 0 || static_cast<std::size_t>(pl.speciesId) >= in.biome->species.size())
                    throw ValidationError(what + ": " + (list == &in.canopy ? "canopy" : "undergrowth") + " plant " +
                                          std::to_string(p) + " has species id " + std::to_string(pl.speciesId) +
                                          " outside the biome's " + std::to_string(in.biome->species.size()) + " species");
                if (!std::isfinite(pl.xM) || !std::isfinite(pl.yM) || !std::isfinite(pl.heightM) ||
                    !std::isfinite(pl.crownRadiusM) || pl.crownRadiusM < 0 || pl.heightM < 0)
                    throw ValidationError(what + ": " + (list == &in.canopy ? "canopy" : "undergrowth") + " plant " +
                                          std::to_string(p) + " has a non-finite or negative value");
            }
    }
}

/// Histogram of one species' sizes (edges 0 .. top in `bins` bins).
DbHistogram emptyHistogram(double top, int bins) {
    DbHistogram h;
    if (!(top > 0.0) || !std::isfinite(top)) top = 1.0;
    for (int b = 0; b <= bins; ++b) h.edges.push_back(top * b / bins);
    h.counts.assign(static_cast<std::size_t>(bins), 0.0);
    return h;
}

void addToHistogram(DbHistogram& h, double v) {
    const std::size_t bins = h.counts.size();
    const double top = h.edges.back();
    if (v > top) {
        h.overflow += 1;
        return;
    }
    std::size_t b = static_cast<std::size_t>(v / top * static_cast<double>(bins));
    if (b >= bins) b = bins - 1;  // v == top: the last bin includes its upper edge
    h.counts[b] += 1;
}

/// One layer of one input's plants, sorted into a neighbour grid.
struct LayerPoints {
    PointGrid grid;
    std::vector<double> radius;    ///< crown radius, sorted order
    std::vector<int> category;     ///< compact category, sorted order
    std::vector<int> region;       ///< region or -1, sorted order
    double maxRadius = 0;
};

/// Pooled (over inputs) sums of one region, compact categories.
struct RegionSums {
    std::vector<double> pairCount, translate;  // [nc][nc][nb]
    std::vector<double> normalisation;         // [nc][nc]
    std::vector<double> sepCount;              // [nc][nc][nsep]
    std::vector<double> sepUnder, sepSources;  // [nc][nc]
    std::vector<double> categoryCount;         // [nc] plants of each category in the region
};

struct WorkItem {
    int region;
    std::size_t begin, end;  ///< range in the sources array
};

struct Source {
    int layer;
    std::uint32_t sorted;
};

/// Pair-correlation and separation sums of one input, added to `sums` (regions x categories).
void pairStatistics(const AnalysisInput& in, const PreparedInput& prep, int nRegions, int nc,
                    const std::vector<int>& compactOfCategory, const AnalysisParams& params,
                    std::vector<RegionSums>& sums) {
    const int ns = static_cast<int>(in.biome->species.size());
    const DistanceBins& pb = params.pcfBins;
    const SeparationBins& sb = params.separationBins;
    const std::size_t nb = static_cast<std::size_t>(pb.count), nsep = static_cast<std::size_t>(sb.count);
    const std::size_t ncc = static_cast<std::size_t>(nc) * static_cast<std::size_t>(nc);
    const Grid<std::int32_t>& regionGrid = prep.region;
    const RectWindow& window = prep.window;

    // Plants of both layers inside the window, with their region (-1 outside every region).
    LayerPoints layers[2];
    for (int layer = 0; layer < 2; ++layer) {
        const std::vector<Plant>& plants = layer == 0 ? in.undergrowth : in.canopy;
        std::vector<double> x, y, r;
        std::vector<int> cat, reg;
        for (const Plant& p : plants) {
            if (!window.contains(p.xM, p.yM)) continue;
            const int ix = regionGrid.cellX(p.xM), iy = regionGrid.cellY(p.yM);
            x.push_back(p.xM);
            y.push_back(p.yM);
            r.push_back(p.crownRadiusM);
            cat.push_back(compactOfCategory[static_cast<std::size_t>(layer * ns + p.speciesId)]);
            reg.push_back(regionGrid.inside(ix, iy) ? regionGrid(ix, iy) : -1);
        }
        LayerPoints& L = layers[layer];
        for (double v : r) L.maxRadius = std::max(L.maxRadius, v);
        const double searchTypical = std::max(pb.rMaxM, sb.maxM + 2.0 * L.maxRadius);
        L.grid = PointGrid(x, y, 0.5 * searchTypical);
        L.radius = L.grid.permuted(r);
        L.category = L.grid.permuted(cat);
        L.region = L.grid.permuted(reg);
    }
    // Largest crown radius of each target category (border of the separation histograms).
    std::vector<double> maxRadiusOfCategory(static_cast<std::size_t>(nc), 0.0);
    for (const LayerPoints& L : layers)
        for (std::size_t s = 0; s < L.radius.size(); ++s) {
            double& m = maxRadiusOfCategory[static_cast<std::size_t>(L.category[s])];
            m = std::max(m, L.radius[s]);
        }

    // Category counts per region and the intensity normalisation of each window.
    const std::vector<CellWindow> windows = CellWindow::fromLabels(regionGrid, nRegions, pb.rMaxM);
    std::vector<double> count(static_cast<std::size_t>(nRegions) * static_cast<std::size_t>(nc), 0.0);
    for (const LayerPoints& L : layers)
        for (std::size_t s = 0; s < L.region.size(); ++s)
            if (L.region[s] >= 0)
                count[static_cast<std::size_t>(L.region[s]) * static_cast<std::size_t>(nc) +
                      static_cast<std::size_t>(L.category[s])] += 1;
    for (int k = 0; k < nRegions; ++k) {
        const double area = windows[static_cast<std::size_t>(k)].areaM2();
        RegionSums& R = sums[static_cast<std::size_t>(k)];
        const double* n = count.data() + static_cast<std::size_t>(k) * static_cast<std::size_t>(nc);
        for (int i = 0; i < nc; ++i) R.categoryCount[static_cast<std::size_t>(i)] += n[i];
        if (!(area > 0)) continue;
        for (int i = 0; i < nc; ++i)
            for (int j = 0; j < nc; ++j)
                R.normalisation[static_cast<std::size_t>(i * nc + j)] += pairNormalisation(n[i], n[j], i == j, area);
    }

    // Sources grouped by region; work items of at most kSourcesPerItem sources.
    std::vector<Source> sources;
    std::vector<std::size_t> regionStart(static_cast<std::size_t>(nRegions) + 1, 0);
    for (const LayerPoints& L : layers)
        for (int reg : L.region)
            if (reg >= 0) ++regionStart[static_cast<std::size_t>(reg) + 1];
    for (int k = 0; k < nRegions; ++k) regionStart[static_cast<std::size_t>(k) + 1] += regionStart[static_cast<std::size_t>(k)];
    sources.resize(regionStart.back());
    {
        std::vector<std::size_t> fill(regionStart.begin(), regionStart.end() - 1);
        for (int layer = 0; layer < 2; ++layer)
            for (std::size_t s = 0; s < layers[layer].region.size(); ++s) {
                const int reg = layers[layer].region[s];
                if (reg >= 0) sources[fill[static_cast<std::size_t>(reg)]++] = Source{layer, static_cast<std::uint32_t>(s)};
            }
    }
    std::vector<WorkItem> items;
    for (int k = 0; k < nRegions; ++k)
        for (std::size_t b = regionStart[static_cast<std::size_t>(k)]; b < regionStart[static_cast<std::size_t>(k) + 1];
             b += kSourcesPerItem)
            items.push_back(WorkItem{k, b, std::min(b + kSourcesPerItem, regionStart[static_cast<std::size_t>(k) + 1])});

    struct Local {
        std::vector<std::int64_t> count, sep, under, sepSources;
        std::vector<double> trans;
    };
    const std::size_t batch = static_cast<std::size_t>(std::max(1, omp_get_max_threads())) * 8;
    std::vector<Local> locals(std::min(batch, std::max<std::size_t>(items.size(), 1)));
    for (Local& l : locals) {
        l.count.resize(ncc * nb);
        l.trans.resize(ncc * nb);
        l.sep.resize(ncc * nsep);
        l.under.resize(ncc);
        l.sepSources.resize(ncc);
    }
    const double binsPerM = static_cast<double>(nb) / pb.rMaxM;
    const double sepBinsPerM = static_cast<double>(nsep) / (sb.maxM - sb.minM);
    const double rPcf = pb.rMaxM;
    for (std::size_t first = 0; first < items.size(); first += batch) {
        const std::size_t last = std::min(items.size(), first + batch);
#pragma omp parallel for schedule(dynamic, 1)
        for (std::size_t it = first; it < last; ++it) {
            const WorkItem& item = items[it];
            Local& Lc = locals[it - first];
            std::fill(Lc.count.begin(), Lc.count.end(), 0);
            std::fill(Lc.trans.begin(), Lc.trans.end(), 0.0);
            std::fill(Lc.sep.begin(), Lc.sep.end(), 0);
            std::fill(Lc.under.begin(), Lc.under.end(), 0);
            std::fill(Lc.sepSources.begin(), Lc.sepSources.end(), 0);
            const int k = item.region;
            const CellWindow& cw = windows[static_cast<std::size_t>(k)];
            std::vector<char> interior(static_cast<std::size_t>(nc));
            for (std::size_t si = item.begin; si < item.end; ++si) {
                const Source src = sources[si];
                const LayerPoints& S = layers[src.layer];
                const double px = S.grid.xs()[src.sorted], py = S.grid.ys()[src.sorted];
                const double ri = S.radius[src.sorted];
                const std::size_t ci = static_cast<std::size_t>(S.category[src.sorted]);
                const double edge = window.distanceToEdgeM(px, py);
                for (int j = 0; j < nc; ++j) {
                    // Every target of category j within the separation range lies inside the window.
                    interior[static_cast<std::size_t>(j)] = edge >= sb.maxM + ri + maxRadiusOfCategory[static_cast<std::size_t>(j)];
                    Lc.sepSources[ci * static_cast<std::size_t>(nc) + static_cast<std::size_t>(j)] += interior[static_cast<std::size_t>(j)];
                }
                std::int64_t* countRow = Lc.count.data() + ci * static_cast<std::size_t>(nc) * nb;
                double* transRow = Lc.trans.data() + ci * static_cast<std::size_t>(nc) * nb;
                std::int64_t* sepRow = Lc.sep.data() + ci * static_cast<std::size_t>(nc) * nsep;
                std::int64_t* underRow = Lc.under.data() + ci * static_cast<std::size_t>(nc);
                for (int layer = 0; layer < 2; ++layer) {
                    const LayerPoints& T = layers[layer];
                    if (T.grid.size() == 0) continue;
                    const double radius = std::max(rPcf, sb.maxM + ri + T.maxRadius);
                    const bool sameLayer = layer == src.layer;
                    // Pair correlation counts each unordered pair once (its translation weight
                    // is symmetric): within a layer from the lower sorted index, across layers
                    // from the undergrowth plant. The sums are mirrored when finalised.
                    const bool crossFromHere = !sameLayer && src.layer == 0;
                    const int* tRegion = T.region.data();
                    const int* tCategory = T.category.data();
                    const double* tRadius = T.radius.data();
                    T.grid.forEachWithin(px, py, radius, [&](std::size_t t, double dx, double dy, double d2) {
                        if (sameLayer && t == src.sorted) return;
                        const double d = std::sqrt(d2);
                        const std::size_t cj = static_cast<std::size_t>(tCategory[t]);
                        if (d < rPcf && (sameLayer ? t > src.sorted : crossFromHere) && tRegion[t] == k) {
                            std::size_t b = static_cast<std::size_t>(d * binsPerM);
                            if (b >= nb) b = nb - 1;
                            ++countRow[cj * nb + b];
                            transRow[cj * nb + b] += cw.translationWeight(dx, dy);
                        }
                        if (interior[cj]) {
                            const double sep = d - ri - tRadius[t];
                            if (sep < sb.minM) {
                                ++underRow[cj];
                            } else if (sep < sb.maxM) {
                                std::size_t s = static_cast<std::size_t>((sep - sb.minM) * sepBinsPerM);
                                if (s >= nsep) s = nsep - 1;
                                ++sepRow[cj * nsep + s];
                            }
                        }
                    });
                }
            }
        }
        for (std::size_t it = first; it < last; ++it) {  // item order: reproducible sums
            const Local& Lc = locals[it - first];
            RegionSums& R = sums[static_cast<std::size_t>(items[it].region)];
            for (std::size_t i = 0; i < ncc * nb; ++i) {
                R.pairCount[i] += static_cast<double>(Lc.count[i]);
                R.translate[i] += Lc.trans[i];
            }
            for (std::size_t i = 0; i < ncc * nsep; ++i) R.sepCount[i] += static_cast<double>(Lc.sep[i]);
            for (std::size_t i = 0; i < ncc; ++i) {
                R.sepUnder[i] += static_cast<double>(Lc.under[i]);
                R.sepSources[i] += static_cast<double>(Lc.sepSources[i]);
            }
        }
    }
}

/// Cell pairs of each region by (context of the first cell, context of the second,
/// distance bin of their centres), both cells in the region and the same input. Source
/// cells: every k-th cell of the region (k = ceil(cells / contextPairSampleCells)), in input
/// then cell order; every cell within rmax is a target. Integer counts: identical for any
/// thread count.
void contextCellPairs(const std::vector<PreparedInput>& prep, const std::vector<Grid<std::uint8_t>>& contextOf,
                      const AnalysisParams& params, std::vector<DbRegion>& regions) {
    const std::size_t nR = regions.size();
    const std::size_t nCtx = static_cast<std::size_t>(params.contextBins.count());
    const std::size_t nb = static_cast<std::size_t>(params.pcfBins.count);
    const std::size_t perRegion = nCtx * nCtx * nb;
    for (DbRegion& r : regions) r.contextCellPairs.assign(perRegion, 0.0);
    if (nR == 0) return;
    std::vector<std::int64_t> stride(nR), seen(nR, 0);
    for (std::size_t k = 0; k < nR; ++k)
        stride[k] = std::max<std::int64_t>(1, (regions[k].cellCount + params.contextPairSampleCells - 1) /
                                                  params.contextPairSampleCells);
    for (std::size_t i = 0; i < prep.size(); ++i) {
        const Grid<std::int32_t>& reg = prep[i].region;
        const Grid<std::uint8_t>& ctx = contextOf[i];
        const double cs = reg.cellSizeM();
        const int lag = static_cast<int>(std::ceil(params.pcfBins.rMaxM / cs));
        struct Lag {
            int dx, dy, bin;
        };
        std::vector<Lag> lags;
        for (int dy = -lag; dy <= lag; ++dy)
            for (int dx = -lag; dx <= lag; ++dx) {
                const int b = params.pcfBins.binOf(cs * std::sqrt(double(dx) * dx + double(dy) * dy));
                if (b >= 0) lags.push_back({dx, dy, b});
            }
        std::vector<std::uint32_t> sources;
        for (std::size_t c = 0; c < reg.data().size(); ++c) {
            const std::int32_t k = reg.data()[c];
            if (k >= 0 && seen[static_cast<std::size_t>(k)]++ % stride[static_cast<std::size_t>(k)] == 0)
                sources.push_back(static_cast<std::uint32_t>(c));
        }
        const int w = reg.width(), h = reg.height();
        const std::ptrdiff_t nSrc = static_cast<std::ptrdiff_t>(sources.size());
        std::vector<std::int64_t> total(nR * perRegion, 0);
#pragma omp parallel
        {
            std::vector<std::int64_t> local(nR * perRegion, 0);
#pragma omp for schedule(static)
            for (std::ptrdiff_t j = 0; j < nSrc; ++j) {
                const std::uint32_t c = sources[static_cast<std::size_t>(j)];
                const int ix = static_cast<int>(c % static_cast<std::uint32_t>(w)), iy = static_cast<int>(c / static_cast<std::uint32_t>(w));
                const std::int32_t k = reg.data()[c];
                std::int64_t* row = local.data() + static_cast<std::size_t>(k) * perRegion +
                                    static_cast<std::size_t>(ctx.data()[c]) * nCtx * nb;
                for (const Lag& l : lags) {
                    const int x = ix + l.dx, y = iy + l.dy;
                    if (x < 0 || y < 0 || x >= w || y >= h || reg(x, y) != k) continue;
                    ++row[static_cast<std::size_t>(ctx(x, y)) * nb + static_cast<std::size_t>(l.bin)];
                }
            }
#pragma omp critical(eco_context_pairs)
            for (std::size_t q = 0; q < local.size(); ++q) total[q] += local[q];
        }
        for (std::size_t k = 0; k < nR; ++k)
            for (std::size_t q = 0; q < perRegion; ++q)
                regions[k].contextCellPairs[q] += static_cast<double>(total[k * perRegion + q]);
    }
}

}  // namespace

// ---------------------------------------------------------------------------------------

const std::vector<AnalysisParamField>& analysisParamFields() {
    using K = AnalysisParamField::Kind;
    using R = ParamRange;
    using P = AnalysisParams;
    static const std::vector<AnalysisParamField> fields = {
        {"seeding_radius_factor", "canopy trees seed cells within this radius (`eco analyse`: the simulation's when it records one, else this default)", "crown radii",
         K::Real, &P::seedingRadiusFactor, nullptr, R::above(0), nullptr, "must be positive"},
        {"kmax", "largest number of k-means clusters tried per combination", "", K::Integer, nullptr, &P::kMax, R::closed(1, 64)},
        {"silhouette_threshold", "best mean silhouette below this: k = 1", "", K::Real, &P::silhouetteThreshold, nullptr,
         R::closed(-1, 1)},
        {"min_cluster_area_m2", "k <= combination area / this", "m^2", K::Real, &P::minClusterAreaM2, nullptr,
         R::atLeast(0)},
        {"kmeans_sample_cells", "k-means runs on at most this many cells (seeded sample)", "cells", K::Integer, nullptr,
         &P::kmeansSampleCells, R::atLeast(1)},
        {"silhouette_sample_cells", "silhouettes on at most this many of those (O(n^2))", "cells", K::Integer, nullptr,
         &P::silhouetteSampleCells, R::atLeast(2)},
        {"kmeans_restarts", "k-means++ restarts; the lowest inertia wins", "", K::Integer, nullptr, &P::kmeansRestarts,
         R::atLeast(1)},
        {"kmeans_max_iterations", "Lloyd iterations per restart", "", K::Integer, nullptr, &P::kmeansMaxIterations,
         R::atLeast(1)},
        {"seed", "seed of k-means++ and the samples", "", K::Seed, nullptr, nullptr, R::any(), &P::seed},
        {"height_bins", "height histogram bins per species, 0 .. its tallest undergrowth plant", "", K::Integer, nullptr,
         &P::heightBins, R::closed(1, 10000)},
        {"radius_bins", "crown radius histogram bins per species, 0 .. its widest undergrowth crown", "", K::Integer,
         nullptr, &P::radiusBins, R::closed(1, 10000)},
        {"context_pair_sample_cells", "context cell pairs: at most this many source cells per region", "cells", K::Integer,
         nullptr, &P::contextPairSampleCells, R::atLeast(1)},
    };
    return fields;
}

void AnalysisParams::validate() const {
    validateParams(*this, analysisParamFields(), "analysis parameter");
    pcfBins.validate("analysis parameter pcf bins");
    separationBins.validate("analysis parameter separation bins");
    contextBins.validate("analysis parameter context_edges_m");
}

std::vector<std::pair<std::string, std::string>> AnalysisParams::asParameters() const {
    // The database's /parameters in the order files have them: each field of the table,
    // followed by the choices, bins and descriptions recorded after it.
    std::string edges;
    for (double e : contextBins.edgesM) edges += (edges.empty() ? "" : ",") + num(e);
    const std::vector<std::pair<std::string, std::vector<std::pair<std::string, std::string>>>> after = {
        {"seeding_radius_factor", {{"canopy_membership", toString(membership)}}},
        {"kmax", {{"k_criterion", "max mean silhouette over k = 2..kmax; k = 1 when it is below silhouette_threshold"}}},
        {"seed",
         {{"feature_normalisation", "per combination: z = (value - mean) / std over its cells, all inputs"},
          {"pcf_rmax_m", num(pcfBins.rMaxM)},
          {"pcf_bins", std::to_string(pcfBins.count)},
          {"pcf_estimator", "annulus; translation edge correction, exact set covariance of the region's cells"},
          {"separation_min_m", num(separationBins.minM)},
          {"separation_max_m", num(separationBins.maxM)},
          {"separation_bins", std::to_string(separationBins.count)},
          {"separation_edge_rule",
           "sources nearer the input window's edge than separation_max + r_source + max r_target are left out"}}},
        {"radius_bins",
         {{"context_edges_m", edges},
          {"context_depth",
           "signed distance (m) from a cell centre to the canopy cover edge, + under cover (core/canopy_context.h)"}}},
    };
    std::vector<std::pair<std::string, std::string>> out;
    for (const auto& f : analysisParamFields()) {
        out.emplace_back(f.key, paramText(f, *this, kRecordDigits));
        for (const auto& [key, entries] : after)
            if (key == f.key) out.insert(out.end(), entries.begin(), entries.end());
    }
    return out;
}

BiomeDatabase analyse(const std::vector<AnalysisInput>& inputs, const AnalysisParams& params,
                      const AnalysisProgress& progress) {
    params.validate();
    validateInputs(inputs);
    auto report = [&](const std::string& stage, double f) {
        if (progress) progress(stage, f);
    };
    const Biome& biome = *inputs[0].biome;
    const int ns = static_cast<int>(biome.species.size());
    const std::vector<int> speciesMask = canopySubBiomeMasks(biome, params.membership);

    BiomeDatabase db;
    db.codeVersion = ECO_VERSION_STRING;
    db.createdUtc = utcTimestamp();
    db.biomeName = biome.name;
    db.biomeToml = biomeToToml(biome);
    for (const Species& s : biome.species) db.speciesNames.push_back(s.name);
    for (const SubBiome& sb : biome.subBiomes) db.subBiomeNames.push_back(sb.name);
    db.canopySubBiomeMask = speciesMask;
    db.seedingRadiusFactor = params.seedingRadiusFactor;
    db.pcfBins = params.pcfBins;
    db.separationBins = params.separationBins;
    db.contextBins = params.contextBins;
    db.parameters = params.asParameters();
    // A factor counts when a species responds to it in the biome of any input.
    db.featureWeights = Features{};
    for (const AnalysisInput& in : inputs) {
        const Features w = clusteringWeights(*in.biome);
        for (std::size_t f = 0; f < kFactorCount; ++f) db.featureWeights[f] = std::max(db.featureWeights[f], w[f]);
    }

    // Pairs farther apart than half a window's shorter side are too few (and the edge
    // correction too large) for a pair correlation; far beyond it every bin would be 0.
    // Checked before any work.
    for (std::size_t i = 0; i < inputs.size(); ++i) {
        const AnalysisInput& in = inputs[i];
        const Grid<float>& g = in.features.geometry();
        const double wx = std::min(in.window.x1, g.originX() + g.extentX()) - std::max(in.window.x0, g.originX());
        const double wy = std::min(in.window.y1, g.originY() + g.extentY()) - std::max(in.window.y0, g.originY());
        const double halfShorter = 0.5 * std::min(wx, wy);
        if (wx > 0 && wy > 0 && params.pcfBins.rMaxM > halfShorter)
            throw ValidationError("analyse: input " + std::to_string(i) + " (" + in.provenance.path + "): the pair-correlation "
                                  "range (--rmax / pcf_rmax_m) " + num(params.pcfBins.rMaxM) + " m is more than half the shorter side "
                                  "of its window (" + num(wx) + " x " + num(wy) + " m); use at most " + num(halfShorter) + " m");
    }

    // 1. Combination labels of every analysed cell.
    report("labels", 0.0);
    std::vector<PreparedInput> prep(inputs.size());
    for (std::size_t i = 0; i < inputs.size(); ++i) {
        const AnalysisInput& in = inputs[i];
        const Grid<float>& g = in.features.geometry();
        RectWindow w = in.window;
        w.x0 = std::max(w.x0, g.originX());
        w.y0 = std::max(w.y0, g.originY());
        w.x1 = std::min(w.x1, g.originX() + g.extentX());
        w.y1 = std::min(w.y1, g.originY() + g.extentY());
        if (!(w.x0 < w.x1) || !(w.y0 < w.y1))
            throw ValidationError("analyse: input " + std::to_string(i) + " (" + in.provenance.path +
                                  "): the window does not overlap the abiotic grid");
        prep[i].window = w;
        prep[i].combination = seedingLabels(g, in.canopy, speciesMask, params.seedingRadiusFactor);
        for (int iy = 0; iy < g.height(); ++iy)
            for (int ix = 0; ix < g.width(); ++ix) {
                const std::size_t c = g.index(ix, iy);
                const Features f = in.features.at(c);
                bool finite = true;
                for (double v : f) finite = finite && std::isfinite(v);
                if (!finite || !w.contains(g.cellCentreX(ix), g.cellCentreY(iy)))
                    prep[i].combination.data()[c] = kOutside;
            }
        report("labels", static_cast<double>(i + 1) / static_cast<double>(inputs.size()));
    }

    // 2. Per combination (ascending mask): normalisation, k, centroids; cells -> regions.
    const int maxMask = (1 << biome.subBiomes.size()) - 1;
    std::vector<std::vector<std::pair<std::uint32_t, std::uint32_t>>> cellsOf(static_cast<std::size_t>(maxMask) + 1);
    for (std::size_t i = 0; i < inputs.size(); ++i) {
        const auto& comb = prep[i].combination.data();
        for (std::size_t c = 0; c < comb.size(); ++c)
            if (comb[c] > 0 && comb[c] <= maxMask)
                cellsOf[static_cast<std::size_t>(comb[c])].emplace_back(static_cast<std::uint32_t>(i), static_cast<std::uint32_t>(c));
        prep[i].region = Grid<std::int32_t>::like(prep[i].combination, -1);
    }
    int nMasksPresent = 0;
    for (int m = 1; m <= maxMask; ++m) nMasksPresent += !cellsOf[static_cast<std::size_t>(m)].empty();
    int masksDone = 0;
    report("clusters", 0.0);
    for (int m = 1; m <= maxMask; ++m) {
        const auto& cells = cellsOf[static_cast<std::size_t>(m)];
        if (cells.empty()) continue;
        DbCombination comb;
        comb.mask = m;
        comb.cellCount = static_cast<std::int64_t>(cells.size());
        std::vector<Features> raw(cells.size());
        for (std::size_t j = 0; j < cells.size(); ++j) {
            const AnalysisInput& in = inputs[cells[j].first];
            raw[j] = in.features.at(cells[j].second);
            const double cs = in.features.geometry().cellSizeM();
            comb.areaM2 += cs * cs;
        }
        for (std::size_t f = 0; f < kFactorCount; ++f) {
            double sum = 0;
            for (const Features& v : raw) sum += v[f];
            const double mean = sum / static_cast<double>(raw.size());
            double ss = 0;
            for (const Features& v : raw) ss += (v[f] - mean) * (v[f] - mean);
            double sd = std::sqrt(ss / static_cast<double>(raw.size()));
            // A constant feature carries no information: unit scale keeps z finite.
            if (!(sd > 1e-9 * std::max(1.0, std::abs(mean)))) sd = 1.0;
            comb.featureMean[f] = mean;
            comb.featureStd[f] = sd;
        }
        // A factor of weight 0 (no species responds to it) is 0 in every normalised vector: it
        // adds exactly 0 to every distance, so k-means, the silhouette and the assignment see
        // the other factors only, bit for bit as without it (docs/database.md).
        std::vector<Features> z(raw.size());
        for (std::size_t j = 0; j < raw.size(); ++j)
            for (std::size_t f = 0; f < kFactorCount; ++f)
                z[j][f] = db.featureWeights[f] == 0 ? 0.0 : (raw[j][f] - comb.featureMean[f]) / comb.featureStd[f];
        const int kLimit = params.minClusterAreaM2 > 0
                               ? std::max(1, static_cast<int>(std::floor(comb.areaM2 / params.minClusterAreaM2)))
                               : params.kMax;
        const KSelection sel = selectK(z, kLimit, params, static_cast<std::uint64_t>(m));
        comb.k = sel.k;
        comb.silhouette = sel.silhouette;
        comb.firstRegion = static_cast<int>(db.regions.size());
        for (int c = 0; c < sel.k; ++c) {
            DbRegion r;
            r.combination = m;
            r.cluster = c;
            r.inputAreaM2.assign(inputs.size(), 0.0);
            r.centroidNormalised = sel.centroids[static_cast<std::size_t>(c)];
            for (std::size_t f = 0; f < kFactorCount; ++f)
                r.centroidRaw[f] = comb.featureMean[f] + comb.featureStd[f] * r.centroidNormalised[f];
            db.regions.push_back(std::move(r));
        }
        // Exact nearest-centroid assignment of every cell (ties: lower cluster).
        const std::ptrdiff_t nCells = static_cast<std::ptrdiff_t>(cells.size());
#pragma omp parallel for schedule(static)
        for (std::ptrdiff_t j = 0; j < nCells; ++j) {
            int best = 0;
            double bestD = std::numeric_limits<double>::infinity();
            for (int c = 0; c < sel.k; ++c) {
                double d = 0;
                for (std::size_t f = 0; f < kFactorCount; ++f) {
                    const double e = z[static_cast<std::size_t>(j)][f] - sel.centroids[static_cast<std::size_t>(c)][f];
                    d += e * e;
                }
                if (d < bestD) {
                    bestD = d;
                    best = c;
                }
            }
            const auto& cell = cells[static_cast<std::size_t>(j)];
            prep[cell.first].region.data()[cell.second] = comb.firstRegion + best;
        }
        for (std::size_t j = 0; j < cells.size(); ++j) {
            const auto& cell = cells[j];
            DbRegion& r = db.regions[static_cast<std::size_t>(prep[cell.first].region.data()[cell.second])];
            const double cs = inputs[cell.first].features.geometry().cellSizeM();
            r.areaM2 += cs * cs;
            r.inputAreaM2[cell.first] += cs * cs;
            ++r.cellCount;
        }
        db.combinations.push_back(std::move(comb));
        report("clusters", static_cast<double>(++masksDone) / std::max(1, nMasksPresent));
    }
    if (db.combinations.empty()) report("clusters", 1.0);
    report("statistics", 0.0);

    // 3. Counts, proportions and size histograms.
    const int nRegions = static_cast<int>(db.regions.size());
    const std::size_t nCtx = static_cast<std::size_t>(params.contextBins.count());
    // Histogram ranges per species: 0 .. the largest value of that species in any input
    // (undergrowth plants are small: the species' maximum would waste the bins), the same
    // edges in every region; a species absent everywhere gets its maximum height.
    std::vector<double> topHeight(static_cast<std::size_t>(ns), 0.0), topRadius(static_cast<std::size_t>(ns), 0.0);
    for (const AnalysisInput& in : inputs)
        for (const Plant& pl : in.undergrowth) {
            const std::size_t s = static_cast<std::size_t>(pl.speciesId);
            topHeight[s] = std::max(topHeight[s], pl.heightM);
            topRadius[s] = std::max(topRadius[s], pl.crownRadiusM);
        }
    for (int s = 0; s < ns; ++s) {
        const Species& sp = biome.species[static_cast<std::size_t>(s)];
        double& th = topHeight[static_cast<std::size_t>(s)];
        double& tr = topRadius[static_cast<std::size_t>(s)];
        if (!(th > 0)) th = sp.maxHeightM;
        if (!(tr > 0)) tr = sp.allometry.crownRadiusM(sp.maxHeightM);
    }
    for (DbRegion& r : db.regions) {
        r.speciesCount.assign(static_cast<std::size_t>(ns), 0.0);
        r.canopySpeciesCount.assign(static_cast<std::size_t>(ns), 0.0);
        for (int s = 0; s < ns; ++s) {
            r.height.push_back(emptyHistogram(topHeight[static_cast<std::size_t>(s)], params.heightBins));
            r.crownRadius.push_back(emptyHistogram(topRadius[static_cast<std::size_t>(s)], params.radiusBins));
        }
        r.heightCovered = r.height;
        r.contextAreaM2.assign(nCtx, 0.0);
        r.contextSpeciesCount.assign(static_cast<std::size_t>(ns) * nCtx, 0.0);
    }
    std::vector<Grid<std::uint8_t>> contextOf(inputs.size());
    for (std::size_t i = 0; i < inputs.size(); ++i) {
        contextOf[i] = canopyContextMap(canopyDepthMap(inputs[i].features.geometry(), inputs[i].canopy), params.contextBins);
        const double cellArea = inputs[i].features.geometry().cellSizeM() * inputs[i].features.geometry().cellSizeM();
        const auto& reg = prep[i].region.data();
        for (std::size_t c = 0; c < reg.size(); ++c)
            if (reg[c] >= 0) db.regions[static_cast<std::size_t>(reg[c])].contextAreaM2[contextOf[i].data()[c]] += cellArea;
    }
    contextCellPairs(prep, contextOf, params, db.regions);
    std::vector<char> categoryPresent(static_cast<std::size_t>(2 * ns), 0);
    for (std::size_t i = 0; i < inputs.size(); ++i) {
        const AnalysisInput& in = inputs[i];
        const PreparedInput& p = prep[i];
        const CanopyCover cover(in.canopy);
        DbInput prov = in.provenance;
        prov.window = p.window;
        prov.undergrowthPlants = prov.canopyTrees = prov.unlabelledPlants = 0;
        prov.unlabelledAreaM2 = 0;
        for (std::int32_t c : p.combination.data())
            if (c == 0) prov.unlabelledAreaM2 += in.features.geometry().cellSizeM() * in.features.geometry().cellSizeM();
        for (int layer = 0; layer < 2; ++layer)
            for (const Plant& pl : layer == 0 ? in.undergrowth : in.canopy) {
                if (!p.window.contains(pl.xM, pl.yM)) continue;
                (layer == 0 ? prov.undergrowthPlants : prov.canopyTrees) += 1;
                const int ix = p.region.cellX(pl.xM), iy = p.region.cellY(pl.yM);
                const int reg = p.region.inside(ix, iy) ? p.region(ix, iy) : -1;
                if (reg < 0) {
                    ++prov.unlabelledPlants;
                    continue;
                }
                categoryPresent[static_cast<std::size_t>(layer * ns + pl.speciesId)] = 1;
                DbRegion& r = db.regions[static_cast<std::size_t>(reg)];
                const std::size_t s = static_cast<std::size_t>(pl.speciesId);
                if (layer == 1) {
                    r.canopyCount += 1;
                    r.canopySpeciesCount[s] += 1;
                    continue;
                }
                r.undergrowthCount += 1;
                r.speciesCount[s] += 1;
                addToHistogram(r.height[s], pl.heightM);
                addToHistogram(r.crownRadius[s], pl.crownRadiusM);
                r.contextSpeciesCount[s * nCtx + contextOf[i](ix, iy)] += 1;
                if (cover.covered(pl.xM, pl.yM)) addToHistogram(r.heightCovered[s], pl.heightM);
            }
        db.inputs.push_back(std::move(prov));
    }
    for (DbRegion& r : db.regions) {
        r.densityPerM2 = r.areaM2 > 0 ? r.undergrowthCount / r.areaM2 : 0.0;
        r.speciesProportion.assign(static_cast<std::size_t>(ns), 0.0);
        if (r.undergrowthCount > 0)
            for (int s = 0; s < ns; ++s)
                r.speciesProportion[static_cast<std::size_t>(s)] = r.speciesCount[static_cast<std::size_t>(s)] / r.undergrowthCount;
    }

    // 4. Pair correlation and separation, pooled over inputs (compact categories: those
    // present in some region; separation targets outside every region are still counted).
    for (std::size_t i = 0; i < inputs.size(); ++i)
        for (int layer = 0; layer < 2; ++layer)
            for (const Plant& pl : layer == 0 ? inputs[i].undergrowth : inputs[i].canopy)
                if (prep[i].window.contains(pl.xM, pl.yM))
                    categoryPresent[static_cast<std::size_t>(layer * ns + pl.speciesId)] = 1;
    std::vector<int> compactOf(static_cast<std::size_t>(2 * ns), -1), categoryOf;
    for (int c = 0; c < 2 * ns; ++c)
        if (categoryPresent[static_cast<std::size_t>(c)]) {
            compactOf[static_cast<std::size_t>(c)] = static_cast<int>(categoryOf.size());
            categoryOf.push_back(c);
        }
    const int nc = static_cast<int>(categoryOf.size());
    const std::size_t ncc = static_cast<std::size_t>(nc) * static_cast<std::size_t>(nc);
    const std::size_t nb = static_cast<std::size_t>(params.pcfBins.count);
    const std::size_t nsep = static_cast<std::size_t>(params.separationBins.count);
    std::vector<RegionSums> sums(static_cast<std::size_t>(nRegions));
    for (RegionSums& R : sums) {
        R.pairCount.assign(ncc * nb, 0.0);
        R.translate.assign(ncc * nb, 0.0);
        R.normalisation.assign(ncc, 0.0);
        R.sepCount.assign(ncc * nsep, 0.0);
        R.sepUnder.assign(ncc, 0.0);
        R.sepSources.assign(ncc, 0.0);
        R.categoryCount.assign(static_cast<std::size_t>(nc), 0.0);
    }
    for (std::size_t i = 0; i < inputs.size(); ++i) {
        if (nRegions > 0) pairStatistics(inputs[i], prep[i], nRegions, nc, compactOf, params, sums);
        report("statistics", static_cast<double>(i + 1) / static_cast<double>(inputs.size()));
    }
    for (int k = 0; k < nRegions; ++k) {
        RegionSums& R = sums[static_cast<std::size_t>(k)];
        // Unordered pair sums -> ordered: H[i][j] + H[j][i] (twice H[i][i] on the diagonal).
        for (std::size_t i = 0; i < static_cast<std::size_t>(nc); ++i)
            for (std::size_t j = i; j < static_cast<std::size_t>(nc); ++j)
                for (std::size_t b = 0; b < nb; ++b) {
                    const std::size_t x = (i * static_cast<std::size_t>(nc) + j) * nb + b;
                    const std::size_t y = (j * static_cast<std::size_t>(nc) + i) * nb + b;
                    const double c = R.pairCount[x] + R.pairCount[y], w = R.translate[x] + R.translate[y];
                    R.pairCount[x] = R.pairCount[y] = c;
                    R.translate[x] = R.translate[y] = w;
                }
        DbRegion& region = db.regions[static_cast<std::size_t>(k)];
        for (int i = 0; i < nc; ++i) {
            if (!(R.categoryCount[static_cast<std::size_t>(i)] > 0)) continue;  // source absent from the region
            for (int j = 0; j < nc; ++j) {
                const std::size_t pi = static_cast<std::size_t>(i * nc + j);
                double sepTotal = R.sepUnder[pi];
                for (std::size_t b = 0; b < nsep; ++b) sepTotal += R.sepCount[pi * nsep + b];
                if (!(R.categoryCount[static_cast<std::size_t>(j)] > 0) && !(sepTotal > 0)) continue;
                DbPairStats ps;
                ps.source = categoryOf[static_cast<std::size_t>(i)];
                ps.target = categoryOf[static_cast<std::size_t>(j)];
                ps.pairCount.assign(R.pairCount.begin() + static_cast<std::ptrdiff_t>(pi * nb),
                                    R.pairCount.begin() + static_cast<std::ptrdiff_t>((pi + 1) * nb));
                ps.translateWeighted.assign(R.translate.begin() + static_cast<std::ptrdiff_t>(pi * nb),
                                            R.translate.begin() + static_cast<std::ptrdiff_t>((pi + 1) * nb));
                ps.normalisation = R.normalisation[pi];
                ps.g.resize(nb);
                for (std::size_t b = 0; b < nb; ++b)
                    ps.g[b] = annulusPcf(ps.translateWeighted[b], params.pcfBins.annulusAreaM2(static_cast<int>(b)),
                                         ps.normalisation);
                ps.separationCount.assign(R.sepCount.begin() + static_cast<std::ptrdiff_t>(pi * nsep),
                                          R.sepCount.begin() + static_cast<std::ptrdiff_t>((pi + 1) * nsep));
                ps.separationUnderflow = R.sepUnder[pi];
                ps.separationSources = R.sepSources[pi];
                region.pairs.push_back(std::move(ps));
            }
        }
        std::sort(region.pairs.begin(), region.pairs.end(), [](const DbPairStats& a, const DbPairStats& b) {
            return std::make_pair(a.source, a.target) < std::make_pair(b.source, b.target);
        });
    }
    return db;
}

}  // namespace eco::analysis
