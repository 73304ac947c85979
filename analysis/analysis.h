// The analyser (paper §6.2 "Analysis", SPEC §6): turns simulated (or surveyed) plant
// patterns into a biome database (core/biome_db.h): regions = sub-biome combination x
// k-means cluster of the annual-mean abiotics; per region the area, density, species
// proportions, size histograms, pair correlation (translation edge correction) and disk
// separation histograms. docs/analysis.md explains each step and its parameters.
//
// Every function is deterministic: for the same inputs and parameters the database is
// bit-identical whatever the number of OpenMP threads. No function here touches a file;
// analysis/sim_input.h reads simulation files into AnalysisInput.
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <utility>
#include <vector>

#include "biome.h"
#include "biome_db.h"
#include "canopy_context.h"
#include "grid.h"
#include "param_desc.h"
#include "plants.h"
#include "point_pattern.h"
#include "seeding.h"

namespace eco::analysis {

/// Which sub-biomes a canopy tree of a species seeds.
enum class CanopyMembership {
    /// Sub-biomes whose `canopy` list names the species (default; the simulator's seed
    /// packages use the same rule). A canopy-capable species no list names seeds nothing.
    SubBiomeCanopyLists,
    /// The species' own `sub_biomes` (Table 3's column).
    SpeciesSubBiomes,
};
const char* toString(CanopyMembership m);

/// Every parameter of the analysis; all are recorded in the database (/parameters).
struct AnalysisParams {
    double seedingRadiusFactor = 12.0;  ///< a canopy tree seeds cells within factor * crown radius
    CanopyMembership membership = CanopyMembership::SubBiomeCanopyLists;
    // Clustering
    int kMax = 6;                       ///< largest k tried per combination
    double silhouetteThreshold = 0.25;  ///< best mean silhouette below this: k = 1 (no structure)
    double minClusterAreaM2 = 2500.0;   ///< k <= combination area / this, so regions keep enough plants
    int kmeansSampleCells = 20000;      ///< k-means runs on at most this many cells (seeded sample)
    int silhouetteSampleCells = 2000;   ///< silhouettes on at most this many of those
    int kmeansRestarts = 4;             ///< k-means++ restarts; the lowest inertia wins
    int kmeansMaxIterations = 100;      ///< Lloyd iterations per restart
    std::uint64_t seed = 1;             ///< k-means++ and sampling
    // Statistics
    DistanceBins pcfBins{10.0, 40};          ///< pair correlation: 0..10 m in 0.25 m annuli
    SeparationBins separationBins{-12.0, 4.0, 64};  ///< disk separation: -12..4 m in 0.25 m bins
    int heightBins = 20;                ///< per species, 0 .. its tallest undergrowth plant in any input
    int radiusBins = 20;                ///< per species, 0 .. its widest undergrowth crown in any input
    // Canopy context (core/canopy_context.h)
    CanopyContextBins contextBins;      ///< bins of the signed depth under the canopy cover
    /// Context cell pairs: at most this many source cells per region (every k-th cell).
    int contextPairSampleCells = 20000;

    /// ValidationError naming the parameter and value when one is out of range
    /// (analysisParamFields, then the bins).
    void validate() const;
    /// (name, value) of every parameter, as recorded in the database: analysisParamFields()
    /// in order, with the membership, the bins and descriptions of the method between them.
    std::vector<std::pair<std::string, std::string>> asParameters() const;
};

/// One numeric parameter of AnalysisParams (core/param_desc.h): its key in the database's
/// /parameters and docs/analysis.md's table, its doc line and its range.
using AnalysisParamField = ParamDesc<AnalysisParams>;
/// The numeric parameters of AnalysisParams that are fields of it (the bins are their own
/// structs), in record order: the one description of them.
const std::vector<AnalysisParamField>& analysisParamFields();

/// One analysed pattern: a simulation's last snapshot, or a field survey.
struct AnalysisInput {
    const Biome* biome = nullptr;     ///< every input of one analysis must share the species
    std::vector<Plant> canopy;        ///< canopy trees (sources of seeding and of pairs)
    std::vector<Plant> undergrowth;   ///< the analysed plants
    // Annual means per factor (factors.h), one geometry (grid.h conventions). The sun is under
    // the canopy (applyCanopyShade with `canopy`), as readSimulation (sim_input.h) makes it and
    // as the synthesizer shades its target terrain.
    FactorGrids features;
    RectWindow window;                ///< analysed area; cells whose centre lies inside it
    DbInput provenance;               ///< path, seed, year ... (counts are filled in)
};

/// Progress: stage ("labels", "clusters", "statistics") and fraction done in [0, 1].
using AnalysisProgress = std::function<void(const std::string& stage, double fraction)>;

/// Analyse the inputs into one database (regions pooled over all inputs). ValidationError
/// for inconsistent inputs (other species, grids of different geometry, a window outside
/// the grid) or parameters. The database's creation date and code version are filled in.
BiomeDatabase analyse(const std::vector<AnalysisInput>& inputs, const AnalysisParams& params,
                      const AnalysisProgress& progress = {});

// ---------------------------------------------------------------------------------------
// The steps, exposed for tests and for the synthesizer's own use.

/// Per species: the sub-biome bitmask (bit b-1 for sub-biome b) a canopy tree of that
/// species seeds; 0 for species that cannot be canopy trees.
std::vector<int> canopySubBiomeMasks(const Biome& biome, CanopyMembership membership);

/// Weight of each factor (factors.h order) in the clustering distance and in the database's
/// nearestRegion: 1 when at least one species of the biome responds to it, 0 when every
/// species is indifferent (an optional factor such as wind that the biome leaves out), so
/// that a factor no species uses changes no region. (A constant map of a factor in use keeps
/// weight 1: analyse() gives it unit scale, so its normalised values are about 0.)
Features clusteringWeights(const Biome& biome);

/// Combination labels: seedingLabels (core/seeding.h), the same the synthesizer uses.

struct KMeansResult {
    std::vector<Features> centroids;
    std::vector<int> assignment;  ///< per point
    double inertia = 0;           ///< sum of squared distances to the assigned centroid
};

/// Lloyd's k-means with k-means++ initialisation from RandomStream(seed, stream), best of
/// `restarts`. Deterministic; ties go to the lower centroid index. k <= points.size().
KMeansResult kmeans(const std::vector<Features>& points, int k, std::uint64_t seed, std::uint64_t stream,
                    int restarts, int maxIterations);

/// Mean silhouette width of a partition (Rousseeuw 1987), in [-1, 1]; a point alone in its
/// cluster scores 0. Needs k >= 2.
double meanSilhouette(const std::vector<Features>& points, const std::vector<int>& assignment, int k);

struct KSelection {
    int k = 1;
    std::vector<double> silhouette;   ///< [kTried], index k-1; NaN for k = 1 and untried k
    std::vector<Features> centroids;  ///< k centroids in the points' units
};

/// Choose k in 1..kLimit: the k >= 2 of the highest mean silhouette (ties: smaller k),
/// or k = 1 when that silhouette is below params.silhouetteThreshold. Uses at most
/// params.kmeansSampleCells points (a seeded sample) and params.silhouetteSampleCells of
/// them for silhouettes. `stream` keys the randomness (one per combination).
KSelection selectK(const std::vector<Features>& points, int kLimit, const AnalysisParams& params, std::uint64_t stream);

}  // namespace eco::analysis
