// A synthesized scene (canopy + undergrowth + forest floor) and what is done with it: the
// scene file (HDF5, docs/synth.md), the plant CSV, the PDB plant list of the paper's
// authors' tools (SPEC §7b), top-down pictures, and the comparison of a scene with the
// database it was synthesized from (`eco compare`).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "biome.h"
#include "biome_db.h"
#include "forest_floor.h"
#include "grid.h"
#include "plants.h"
#include "point_pattern.h"
#include "undergrowth.h"

namespace eco::synth {

constexpr int kSceneSchemaVersion = 1;
constexpr const char* kSceneFormat = "eco-scene";

// ------------------------------------------------------------------------- scene file

/// Everything `eco synth` records.
struct SceneRecord {
    std::vector<Plant> canopy;
    std::vector<Plant> undergrowth;
    ClusterMap clusterMap;
    ForestFloor floor;
    Grid<float> terrainM;
    SynthParams params;
    ForestFloorParams floorParams;
    UndergrowthSample sampling;     ///< its regions, passes and dart counts (plants are in `undergrowth`)
    bool refined = false;
    RefineParams refineParams;
    RefineResult refineResult;
    std::string databasePath, terrainSource, canopySource, abioticsSource;
    std::string databaseCreatedUtc, databaseCodeVersion;
    /// Deussen method: the density image read ("" = the database's density map).
    std::string densityImageSource;
    /// Xu 2015 method: the exemplar read (file and snapshot).
    std::string exemplarSource;
};

/// Write a scene file atomically. Layout (docs/synth.md):
///   /canopy, /undergrowth      plant groups (core/plants.h), attribute layer
///   /forest_floor/grass, /forest_floor/litter   float grids, density [0, 1]
///   /cluster_map               int32 grid: database region, -1 none
///   /combination_map           int32 grid: sub-biome bitmask of the seeding canopy, 0 none
///   /terrain/elevation         float grid, m
///   /regions/...               per database region: cells, area, target and placed counts
///   /refinement                attributes (and objective per sweep) when refined
///   /provenance                created_utc, sampling_seconds, refinement_seconds,
///                              database_created_utc (core/provenance.h; not with --no-provenance)
///   /regions attributes with the Deussen method: per species in placement order its
///                              half-toning cell, minimum distance, dots, drops, Clark-Evans R
///   root attributes: format = "eco-scene", schema_version = 1, code_version,
///   seed, every parameter by key (deussen_density_image, xu_exemplar with those methods), database_path, terrain_source, canopy_source,
///   abiotics_source, biome_name, biome_toml, units.
void writeSceneFile(const std::string& path, const SceneRecord& scene, const Biome& biome,
                    const BiomeDatabase& db);

/// What `eco compare` and other readers take from a scene file.
struct SceneData {
    std::vector<Plant> canopy, undergrowth;  ///< species mapped by name onto the given biome
    Grid<std::int32_t> clusterMap;
    Grid<std::int32_t> combinationMap;
    Grid<float> terrainM;
    Grid<float> grass, litter;
    std::uint64_t seed = 0;
    std::string databasePath;
    std::string biomeName;
};

/// Read a scene file. IoError naming the file and the object when it is not an eco-scene
/// file of schema version 1 or misses a dataset; ValidationError for a species not in `biome`.
SceneData readSceneFile(const std::string& path, const Biome& biome);

/// All plants as CSV (atomic): layer,species_id,species,x_m,y_m,ground_z_m,height_m,
/// crown_radius_m, canopy first (the columns of writePlantsCsv with a layer).
void writeScenePlantsCsv(const std::string& path, const std::vector<Plant>& canopy,
                         const std::vector<Plant>& undergrowth, const Biome& biome);

// ------------------------------------------------------------------------- PDB plant lists

/// One species block of a PDB plant list.
struct PdbSpecies {
    int speciesId = 0;
    double minHeightM = 0, maxHeightM = 0;
    double meanRadiusToHeight = 0;
    std::vector<Plant> plants;  ///< x, y, ground z, height, crown radius (speciesId set)
};

/// Write the plants in the PDB plant-list text format (SPEC §7b), atomically: the number of
/// species, then per species present (ascending biome index) a line `id min_height
/// max_height mean_radius_to_height_ratio`, a line with the count n and n lines `x y z
/// height crown_radius` (metres, world coordinates, z = ground elevation). x, y, z with 4
/// decimals; heights and radii fixed-point with at least 4 decimals and 4 significant digits
/// (seedlings of a fraction of a millimetre stay nonzero). One layer alone: pass {} for the other.
void writePdb(const std::string& path, const std::vector<Plant>& canopy, const std::vector<Plant>& undergrowth);

/// Read a PDB plant list. IoError "FILE:LINE: ..." for a malformed or truncated file.
std::vector<PdbSpecies> readPdb(const std::string& path);

// ------------------------------------------------------------------------- pictures

/// Symbolic top-down picture (as the paper's Fig. 14): every plant a disc of its crown in its
/// species' categoryColour (undergrowth opaque, canopy crowns translucent over it, trunks as
/// dots) over the ground tinted by grass (green) and litter (brown) when the maps are given,
/// else a hillshade; a legend of species with counts. `crop` (world metres) limits the view;
/// the longer side gets maxSidePx pixels. Atomic PNG.
void writeScenePng(const std::string& path, const std::vector<Plant>& canopy, const std::vector<Plant>& undergrowth,
                   const Grid<float>& terrainM, const ForestFloor* floor, const Biome& biome, const std::string& title,
                   const RectWindow* crop = nullptr, int maxSidePx = 1024);

/// The default zoomed crop: a square of `sideM` metres (clamped to the terrain) centred on the
/// terrain's centre.
RectWindow defaultZoomWindow(const Grid<float>& terrainM, double sideM = 60.0);

// ------------------------------------------------------------------------- comparison

/// A scene region against its database region.
struct RegionComparison {
    int region = 0;
    std::string name;                   ///< "1+3 (Conifer, Valley Oak) / cluster 0"
    std::int64_t cells = 0;
    double areaM2 = 0;
    std::int64_t plants = 0;            ///< undergrowth plants in the region
    double targetDensityPerM2 = 0;
    double densityPerM2 = 0;
    double densityRelativeError = 0;    ///< (density - target) / target (0 when the target is 0)
    std::vector<double> proportion;     ///< [species] undergrowth share in the scene
    double proportionMaxDifference = 0; ///< max over species of |share - target share|
    double heightDistance = 0;          ///< total-variation distance of the height histograms, mean over species weighted by plants
    double radiusDistance = 0;          ///< same for crown radius
    double pcfDistance = 0;             ///< pcfDistance() inside the region
};

struct SceneComparison {
    std::vector<RegionComparison> regions;  ///< database order; regions absent from the scene have cells = 0
    double pcfDistance = 0;                 ///< over all regions
    ScenePairStats pairs;                   ///< the scene's pair sums (for plots)
};

/// Re-analyse a scene against the database: per region of the scene's cluster map (cells
/// whose centre lies in `window` when given, plants inside it) density, species
/// proportions, size histograms (the database's bin edges) and pair correlation (the
/// estimator of core/point_pattern.h, with at most maxSourcesPerRegion undergrowth sources
/// per region, 0 = all; see scenePairStatistics). ValidationError when the cluster map names
/// regions the database does not have.
SceneComparison compareScene(const std::vector<Plant>& canopy, const std::vector<Plant>& undergrowth,
                             const Grid<std::int32_t>& clusterMap, const BiomeDatabase& db,
                             const RectWindow* window = nullptr, std::size_t maxSourcesPerRegion = 20000);

/// The comparison as a Markdown table (one row per region present in the scene).
std::string comparisonTable(const SceneComparison& c, const BiomeDatabase& db);

/// Picture of the comparison: per region (largest first, at most 12) the pair correlation of
/// all undergrowth pooled, scene against database, with densities in the panel's title.
void writeComparisonPng(const std::string& path, const SceneComparison& c, const BiomeDatabase& db);

/// Pooled undergrowth g of a database region per bin (all undergrowth categories as one).
std::vector<double> pooledUndergrowthG(const DbRegion& r, const BiomeDatabase& db);
/// Same for a scene region.
std::vector<double> pooledUndergrowthG(const ScenePairStats& s, int region, int nSpecies);

}  // namespace eco::synth
