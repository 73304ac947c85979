// The fidelity protocol (issue 24, docs/fidelity.md): how close a synthesized scene comes to a
// held-out simulation of the same plot, measured against two reference levels.
//
//   d(scene, B)  the scene against simulation B (another seed; the database came from A)
//   d(A, B)      replicate level: two simulations of the same plot, the best attainable
//   d(CSR, B)    no-structure level: B's plants at uniform random positions in the plot's
//                seeded cells (off trunks), crown radii shuffled within species
//   score = (d(scene, B) - d(A, B)) / (d(CSR, B) - d(A, B))   0 = replicate, 1 = CSR
//
// Every figure (pair correlation pooled and per species pair, canopy -> undergrowth cross g,
// Ripley's L, under-crown shares, density by light class, radius / allometric radius,
// heights against the canopy, density, species shares, Xu et al. 2015's PCT.DEV) is a
// function of one pattern summary; this file computes them from plants in memory (no files,
// no simulation, no synthesis), so tests feed it constructed layouts. The command
// `eco fidelity` (validate/fidelity_protocol.h) produces the patterns.
//
// Determinism: serial code, plus scenePairStatistics and countPairs, which are
// identical for any number of OpenMP threads; the CSR pattern is Philox keyed by
// (seed, plant).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "param_desc.h"
#include "biome.h"
#include "grid.h"
#include "plants.h"
#include "point_pattern.h"

namespace eco::validate {

/// Every parameter of the protocol's measures (recorded in the CSV; docs/fidelity.md).
struct FidelityParams {
    RectWindow window{100.0, 60.0, 220.0, 180.0};  ///< the plot (world metres)
    DistanceBins bins{10.0, 40};                   ///< g(r) and L(r): 0.25 m bins to 10 m
    double edgeBandM = 2.0;          ///< gap edge: within this distance of the crown-cover edge, either side
    double coverRasterM = 0.2;       ///< raster of the crown cover for the light classes
    double trunkExclusionFactor = 0.1;  ///< CSR: no plant within this x crown radius of a trunk
    double chmThresholdM = 3.0;      ///< heights against the CHM only where it is at least this tall (the simulator's canopy_threshold_m)
    std::uint64_t csrSeed = 1;
    /// A score is given only when d(CSR, B) - d(A, B) exceeds this share of d(CSR, B) and
    /// 1e-9: otherwise the figure does not tell structure from none (n/a).
    double scoreGuardFraction = 0.05;

    /// ValidationError naming the field when one is out of range (fidelityParamFields).
    void validate() const;
    /// (key, value text) of every parameter, as the report records them: the window and bins,
    /// then fidelityParamFields() in order.
    std::vector<std::pair<std::string, std::string>> asParameters() const;
};
/// The one description of FidelityParams' scalar keys (core/param_desc.h): validation, the
/// recorded parameters and docs/fidelity.md's table (eco config describe fidelity).
const std::vector<ParamDesc<FidelityParams>>& fidelityParamFields();

/// The plot's fixed context, shared by every pattern compared.
struct FidelityContext {
    const Biome* biome = nullptr;
    std::vector<Plant> canopy;            ///< canopy trees (all of them; those near the plot matter)
    Grid<std::int32_t> regionMap;         ///< region label per cell (-1 = no undergrowth allowed)
    int nRegions = 0;
    std::vector<std::string> regionNames; ///< [nRegions], for the report
    Grid<float> chmM;                     ///< canopy height model; empty = no CHM figure
};

/// Which class of light a point is in (docs/fidelity.md): under crown cover at least
/// edgeBand from its edge, within edgeBand of the edge on either side, or outside the cover
/// at least edgeBand from it.
enum class LightClass : int { Deep = 0, Edge = 1, Clearing = 2 };

/// Everything the figures need about one pattern, per scope (0 = the whole plot, 1 + k =
/// region k).
struct PatternSummary {
    std::string name;
    struct Scope {
        double seededAreaM2 = 0;                  ///< cells with a region, inside the plot
        std::vector<std::int64_t> count;          ///< [species] undergrowth plants
        std::vector<std::int64_t> underCrown;     ///< [species] inside some canopy crown disc
        std::vector<std::vector<double>> radiusRatio;  ///< [species] crown radius / allometric radius, sorted
        double classAreaM2[3] = {0, 0, 0};        ///< LightClass areas (seeded)
        std::int64_t classCount[3] = {0, 0, 0};   ///< plants per LightClass
        std::int64_t tallerThanCrown = 0;         ///< under a crown and taller than the tallest crown covering it
        std::int64_t tallerThanChm = 0;           ///< taller than the CHM at its cell (where CHM >= threshold)
        std::vector<double> pooledG;              ///< [bin] pooled undergrowth g (region windows; overall: empty)
        std::int64_t total() const;
        double density() const { return seededAreaM2 > 0 ? static_cast<double>(total()) / seededAreaM2 : 0.0; }
        double classDensity(LightClass c) const;
    };
    std::vector<Scope> scopes;          ///< [1 + nRegions]
    /// Pair statistics per region (categories: undergrowth species 0..S-1, canopy S..2S-1).
    struct RegionPairs {
        double areaM2 = 0;
        std::vector<std::int64_t> count;  ///< [category]
        std::vector<double> g;            ///< [i][j][bin]
    };
    std::vector<RegionPairs> pairs;     ///< [nRegions]
    std::vector<double> lMinusR;        ///< [bin] L(r) - r at the bin's upper edge, pooled undergrowth, plot rectangle
    std::vector<double> gRect;          ///< [bin] pooled undergrowth g in the plot rectangle
    double ripleyIndex = 0;             ///< mean of L(r) - r over the bins (Xu et al.'s aggregation index, our reading)
};

/// Undergrowth of one pattern inside the plot (on cells with a region) summarised.
PatternSummary summarisePattern(const std::string& name, const std::vector<Plant>& undergrowth,
                                const FidelityContext& ctx, const FidelityParams& params);

/// The CSR reference: the plants of `reference` inside the plot on region cells, each moved
/// to a uniform random position in the plot's region cells (cell drawn uniformly, position
/// uniform in the cell and in the plot; redrawn on a trunk's exclusion disc); heights kept,
/// crown radii permuted at random among plants of the same species.
std::vector<Plant> csrPattern(const std::vector<Plant>& reference, const FidelityContext& ctx,
                              const FidelityParams& params);

/// Score (d - dRep) / (dCsr - dRep); `scored` false (and NaN returned) when the guard fails.
double fidelityScore(double dScene, double dReplicate, double dCsr, double guardFraction, bool& scored);

/// One row of the report: a figure in one scope at the three levels.
struct FidelityFigure {
    std::string figure;      ///< e.g. "g pooled undergrowth (RMS)"
    std::string scope;       ///< "overall" or the region's name
    std::string unit;
    double scene = 0, replicate = 0, csr = 0;  ///< distances to B: d(scene, B), d(A, B), d(CSR, B)
    double score = 0;
    bool scored = false;
};

/// A per-species value at every pattern (for the tables of shares and radius ratios).
struct SpeciesRow {
    std::string quantity;    ///< "under-crown share", "radius ratio median", ...
    std::string species;
    double scene = 0, reference = 0, replicate = 0, csr = 0;  ///< values of scene, A, B, CSR
    std::int64_t countB = 0;
};

/// A raw value per pattern (densities, ratios, counts, indices).
struct ValueRow {
    std::string quantity, scope;
    double scene = 0, reference = 0, replicate = 0, csr = 0;
};

struct FidelityReport {
    std::vector<FidelityFigure> figures;
    std::vector<SpeciesRow> species;
    std::vector<ValueRow> values;
    std::vector<double> binUpperM;                 ///< for the curves
    std::vector<double> gScene, gA, gB, gCsr;      ///< pooled g, plot rectangle
    std::vector<double> lScene, lA, lB, lCsr;      ///< L(r) - r, plot rectangle
    FidelityParams params;
};

/// Distance figures between `x` and the held-out `b` (docs/fidelity.md gives each formula).
struct FigureDistances {
    std::vector<std::pair<std::string, double>> overall;  ///< (figure, distance)
    std::vector<std::vector<std::pair<std::string, double>>> perRegion;
};
FigureDistances figureDistances(const PatternSummary& x, const PatternSummary& b, const FidelityContext& ctx);

/// The whole protocol on patterns in memory: scene, reference A (the database's source),
/// held-out replicate B; the CSR pattern is made from B.
FidelityReport evaluateFidelity(const std::vector<Plant>& scene, const std::vector<Plant>& referenceA,
                                const std::vector<Plant>& replicateB, const FidelityContext& ctx,
                                const FidelityParams& params);

/// The report as Markdown (figure | scene | replicate | CSR | score, then the species tables).
std::string fidelityMarkdown(const FidelityReport& r, const std::string& heading);
/// Every figure and value as CSV (atomic): kind,quantity,scope,species,scene,reference_a,replicate_b,csr,score.
void writeFidelityCsv(const std::string& path, const FidelityReport& r);

// Pieces, exposed for tests.

/// RMS difference of two curves (equal length; the mean of squared differences, square-rooted).
double rmsDifference(const std::vector<double>& a, const std::vector<double>& b);
/// L(r) - r at each bin's upper edge from pair sums of one type (translation correction):
/// K(r) = sum over bins up to r of S / N, L = sqrt(K / pi).
std::vector<double> ripleyLMinusR(const PairSums& sums);
/// q-quantile (0..1) of sorted values, linear between order statistics; NaN when empty.
double sortedQuantile(const std::vector<double>& sorted, double q);
/// Xu et al. 2015's PCT.DEV: |I_synthesis - I_sample| / |I_sample| x 100 (NaN when I_sample is 0).
double pctDev(double synthesis, double sample);

}  // namespace eco::validate
