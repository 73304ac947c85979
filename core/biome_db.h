// The biome database: statistics of simulated (or surveyed) undergrowth per region, written
// by the analyser (analysis/) and read by the synthesizer (synth/) and `eco inspect`.
// The HDF5 schema (every group, dataset, shape and unit) is documented in
// docs/database.md; kBiomeDbSchemaVersion changes whenever it does.
//
// Vocabulary:
//   * combination: bitmask of the canopy sub-biomes whose trees seed a cell (bit b-1 for
//     sub-biome b), 1 .. 2^nSubBiomes - 1; 0 = seeded by no canopy tree.
//   * region: (combination, cluster): a k-means cluster of the annual-mean abiotics of the
//     cells of one combination.
//   * category: a species in a layer, c = layer * nSpecies + species, layer 0 =
//     undergrowth, 1 = canopy (the same species can be both a canopy tree and a sapling).
//   * features: the annual-mean abiotics, one per factor in the order of kFactors (factors.h).
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "canopy_context.h"
#include "factors.h"
#include "point_pattern.h"

namespace eco {

/// 5: a fifth feature column, wind (factors.h), and /features/weights: 1 for a factor in the
///    clustering distance, 0 for one no species of the biome responds to (left out);
/// 4: the creation date moved from the root attribute created_utc to /provenance
///    (docs/hdf5.md; left out with eco --no-provenance), so that two analyses of the same
///    inputs write the same bytes;
/// 3: canopy context per region (density of each species by depth under the canopy cover,
///    heights under crowns, cell pairs by context for the context part of g(r));
/// 2: region features use the canopy-shaded annual sun (1: the terrain's own sun).
/// Version 2, 3 and 4 files are still read (version 2 without the context statistics:
/// hasContext() false; before 5 with four feature columns: the wind gets weight 0, mean 0,
/// std 1, so that their regions are found as before).
/// A factor added later (a row of kFactors) does not change the version: the feature
/// columns are read by their names (/features/names); a file without an optional factor
/// gets it with weight 0 as above, one without a required factor is refused naming it
/// (docs/factors.md).
constexpr int kBiomeDbSchemaVersion = 5;
constexpr int kBiomeDbOldestReadableVersion = 2;
constexpr const char* kBiomeDbFormat = "eco-biome-db";

enum class Layer : int { Undergrowth = 0, Canopy = 1 };

/// Provenance of one analysed input (a simulation or a field survey).
struct DbInput {
    std::string path;          ///< simulation file (or a label for in-memory inputs)
    std::string abioticsPath;  ///< abiotics file used
    std::string terrainPath;   ///< as recorded by the simulation, may be empty
    std::string canopyPath;    ///< as recorded by the simulation, may be empty
    std::uint64_t seed = 0;    ///< the simulation's seed
    int year = -1;             ///< snapshot year analysed (-1: not a simulation)
    RectWindow window;         ///< analysed window, world metres
    std::int64_t undergrowthPlants = 0;  ///< undergrowth plants in the window
    std::int64_t canopyTrees = 0;        ///< canopy trees in the window
    /// Plants in the window but in no region (not analysed): in cells seeded by no canopy
    /// tree, or in edge cells whose centre lies outside the window.
    std::int64_t unlabelledPlants = 0;
    double unlabelledAreaM2 = 0;         ///< area of the cells seeded by no canopy tree
    std::string parameters;    ///< the input's own parameters as text (e.g. the simulation's), may be empty
};

/// Per combination: the clustering that splits it into regions.
struct DbCombination {
    int mask = 0;                       ///< sub-biome bitmask
    int k = 0;                          ///< clusters chosen
    int firstRegion = 0;                ///< its regions are firstRegion .. firstRegion + k - 1
    double areaM2 = 0;                  ///< total area of its cells over all inputs
    std::int64_t cellCount = 0;
    Features featureMean{};             ///< normalisation: z = (value - mean) / std
    Features featureStd{};
    /// Selection score of each k = 1..kMax tried (index k - 1): mean silhouette; NaN where
    /// not defined (k = 1) or not tried (too few cells).
    std::vector<double> silhouette;
};

/// A histogram with its edges (edges.size() == counts.size() + 1); counts are raw numbers
/// of plants (whole numbers stored as double), never renormalised.
struct DbHistogram {
    std::vector<double> edges;
    std::vector<double> counts;
    double overflow = 0;  ///< values at or above the last edge (clamped into no bin)
};

/// Statistics of one ordered category pair (source i -> target j) in one region.
struct DbPairStats {
    int source = 0;  ///< category
    int target = 0;  ///< category
    // Pair correlation (both plants in the region; distance bins of BiomeDatabase::pcfBins).
    std::vector<double> pairCount;          ///< raw ordered pairs per bin
    std::vector<double> translateWeighted;  ///< sum of |W| / |W n (W + u)| per bin
    double normalisation = 0;               ///< sum over windows of n_i (n_j - [i == j]) / |W|, 1/m^2
    std::vector<double> g;                  ///< translateWeighted / (annulus area * normalisation)
    // Disk separation (source in the region, target anywhere; separation bins of
    // BiomeDatabase::separationBins; sources closer to the input window's edge than the
    // search distance are left out, so no neighbour is missed).
    std::vector<double> separationCount;    ///< raw (source, target) pairs per separation bin
    double separationUnderflow = 0;         ///< pairs with separation below the first edge
    double separationSources = 0;           ///< source plants that were counted (interior)
    /// Mean number of targets per source plant in separation bin k (0 if no sources).
    double separationPerSource(int k) const {
        return separationSources > 0 ? separationCount[static_cast<std::size_t>(k)] / separationSources : 0.0;
    }
};

struct DbRegion {
    int combination = 0;
    int cluster = 0;                 ///< 0 .. k - 1 within the combination
    Features centroidNormalised{};   ///< in the combination's normalised units
    Features centroidRaw{};          ///< in feature units
    double areaM2 = 0;
    std::int64_t cellCount = 0;
    double undergrowthCount = 0;     ///< plants
    double canopyCount = 0;          ///< trees
    double densityPerM2 = 0;         ///< undergrowth plants per m^2
    /// [inputs] area of the region's cells in each analysed input (m^2; they sum to areaM2):
    /// how many simulations stand behind the region (replicates()). Empty when read from a
    /// file written before it was recorded.
    std::vector<double> inputAreaM2;
    /// Inputs with cells in the region; -1 when inputAreaM2 was not recorded.
    int replicates() const;
    std::vector<double> speciesCount;        ///< [nSpecies] undergrowth plants
    std::vector<double> speciesProportion;   ///< [nSpecies] speciesCount / undergrowthCount
    std::vector<double> canopySpeciesCount;  ///< [nSpecies] canopy trees
    std::vector<DbHistogram> height;         ///< [nSpecies] undergrowth height, m
    std::vector<DbHistogram> crownRadius;    ///< [nSpecies] undergrowth crown radius, m
    std::vector<DbPairStats> pairs;          ///< sorted by (source, target)
    // Canopy context (schema 3; empty in version 2 files). C = contextBins.count().
    std::vector<double> contextAreaM2;         ///< [C] area of the region's cells in each context bin
    std::vector<double> contextSpeciesCount;   ///< [nSpecies][C] undergrowth plants by species and context of their cell
    std::vector<DbHistogram> heightCovered;    ///< [nSpecies] heights of the plants under a crown (edges of `height`)
    /// [C][C][pcf bins] cell pairs (both in the region, same input) by the contexts of the two
    /// cells and the distance of their centres: the context part of g(r) (docs/database.md).
    std::vector<double> contextCellPairs;

    /// Pair statistics of source -> target, or nullptr when that pair did not occur.
    const DbPairStats* pair(int source, int target) const;
};

/// "1+3 (Conifer, Valley Oak)": a combination mask (bit b-1 for sub-biome b) by its sub-biomes.
std::string combinationName(const std::vector<std::string>& subBiomeNames, int mask);

struct BiomeDatabase {
    int schemaVersion = kBiomeDbSchemaVersion;
    std::string codeVersion;
    std::string createdUtc;   ///< ISO 8601 (provenance); "" when not recorded
    std::string biomeName;
    std::string biomeToml;    ///< the biome the inputs were made with
    std::vector<std::string> speciesNames;    ///< biome order
    std::vector<std::string> subBiomeNames;   ///< sub-biome b at index b - 1
    /// Per species: sub-biome bitmask a canopy tree of that species seeds (0 if it cannot
    /// be a canopy tree). The synthesizer labels its cells with the same masks.
    std::vector<int> canopySubBiomeMask;
    double seedingRadiusFactor = 12;          ///< a tree seeds cells within factor * crown radius
    /// Per factor (factors.h order): 1 when the factor enters the normalised distance of the
    /// clustering and of nearestRegion, 0 when it is left out (the analyser gives 0 to a
    /// factor no species of the biome responds to, so that such a factor changes no region;
    /// docs/database.md). Only 0 and 1 are stored. Default (a database built in code): 1 for
    /// the factors every biome gives (FactorInfo::responseRequired), 0 for the optional ones.
    Features featureWeights = [] {
        Features w{};
        for (std::size_t f = 0; f < kFactorCount; ++f) w[f] = kFactors[f].responseRequired ? 1.0 : 0.0;
        return w;
    }();
    DistanceBins pcfBins;
    SeparationBins separationBins;
    /// Bins of the signed depth under the canopy cover (core/canopy_context.h); schema 3.
    CanopyContextBins contextBins;
    /// True when every region carries the canopy-context statistics (schema 3 files; a
    /// database built in code without them, or read from a version 2 file, has none).
    bool hasContext() const;
    /// Every analysis parameter, as (name, value text); docs/database.md lists them.
    std::vector<std::pair<std::string, std::string>> parameters;
    std::vector<DbInput> inputs;
    std::vector<DbCombination> combinations;  ///< ascending mask; only those that occur
    std::vector<DbRegion> regions;            ///< grouped by combination, cluster order

    int speciesCount() const { return static_cast<int>(speciesNames.size()); }
    int categoryCount() const { return 2 * speciesCount(); }
    /// "Toyon" for undergrowth, "Toyon (canopy)" for a canopy category.
    std::string categoryName(int category) const;
    static Layer layerOf(int category, int nSpecies) { return category >= nSpecies ? Layer::Canopy : Layer::Undergrowth; }
    /// "1+3 (Conifer, Valley Oak)".
    std::string combinationName(int mask) const;
    /// Index into combinations of a mask, or -1.
    int combinationIndex(int mask) const;

    /// Region for a cell of the given combination and annual-mean abiotics x (factors.h
    /// order and units): the nearest centroid in the
    /// combination's normalised units. When the combination did not occur in the analysed
    /// inputs, the stored combination sharing the most sub-biomes (then differing in the
    /// fewest, then the lowest mask) stands in for it. -1 when the combination is 0 or
    /// shares no sub-biome with any stored one.
    int nearestRegion(int combination, const Features& x) const;
    /// The stored combination nearestRegion() uses for `combination`, or -1.
    int standInCombination(int combination) const;
    /// Region of the stored combination combinations[combinationIdx] whose centroid is
    /// nearest in the combination's normalised units, over the factors of weight 1 (the
    /// second step of nearestRegion).
    int nearestRegionOf(std::size_t combinationIdx, const Features& x) const;
};

/// Write a database atomically (temporary file, then rename). IoError on failure.
void writeBiomeDatabase(const std::string& path, const BiomeDatabase& db);

/// Read a database. IoError naming the file and the dataset or attribute when it is not
/// an eco-biome-db file, has another schema_version (the message gives the found and the
/// expected version), or a dataset is missing or has the wrong shape.
BiomeDatabase readBiomeDatabase(const std::string& path);

}  // namespace eco
