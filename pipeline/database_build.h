// eco database build (issue 27 item 2): a complete biome database from one command. Plans an
// ensemble (pipeline/ensemble.h) whose canopies realise every combination of the biome's
// sub-biomes on several generated terrains, and reports which combination x cluster the
// database then covers, with how much simulated area, plants and replicates behind each.
#pragma once

#include <string>
#include <utility>
#include <vector>

#include "biome.h"
#include "biome_db.h"

namespace eco::pipeline {

struct DatabaseBuildOptions {
    std::string biome;       ///< biome TOML; "" = the embedded Sonoma biome
    std::string out;         ///< the database
    std::string workDir;     ///< the ensemble's folder (its specification, members, manifest)
    std::string simConfig;   ///< simulation configuration (model constants)
    int terrains = 2;        ///< generated terrains (replicates) per combination
    /// Terrains the user gives (any format eco terrain reads; images need their cell size in
    /// the file): every combination is simulated on each too, on a plot centred in it.
    std::vector<std::string> terrainFiles;
    /// Generated terrain t of N spreads its valley depth and base elevation over these ranges
    /// (first to last; one terrain takes the generator's defaults), so that the members'
    /// slopes, moisture routing, sun on aspects and temperatures (the lapse rate) differ.
    /// (The hills' relief was tried first: on terrains of a few hundred metres the valley's
    /// walls set the slopes, and relief 35 or 140 m gave the same abiotics.)
    double valleyDepthMinM = 8, valleyDepthMaxM = 60;
    double baseElevationMinM = 0, baseElevationMaxM = 600;
    int terrainCells = 160;  ///< terrain width and height in cells of 0.914 m
    double plotM = 100;      ///< side of the simulated plot, centred on the terrain
    int years = 150;
    int kMax = 6;
    int membersAtOnce = 1;
    std::uint64_t seed = 1;
};

/// The canopy mix of a combination (bitmask of sub-biomes, bit b-1 for sub-biome b): 90 % of
/// the forested area shared equally by the combination's sub-biomes and, within one, by its
/// canopy species; every other canopy species 0. "SPECIES=FRACTION" targets of eco canopy.
std::vector<std::string> combinationTargets(const Biome& biome, int mask);

/// Writes OPTIONS.workDir/ensemble.toml: one member per combination the biome allows (every
/// non-empty set of sub-biomes with canopy species) and terrain; returns its path.
/// ValidationError for settings out of range or a biome without canopy sub-biomes.
std::string writeDatabaseBuildSpec(const DatabaseBuildOptions& options);

/// One row per combination the biome allows and cluster the database has for it (or one row
/// saying it is missing and what stands in): simulated area, plants, replicates.
struct CoverageRow {
    int combination = 0;
    std::string name;
    int cluster = -1;        ///< -1: the combination is not in the database
    double areaM2 = 0;
    double plants = 0;
    int replicates = -1;     ///< simulations with cells in the region (-1: not recorded)
    Features centroid{};     ///< the region's mean abiotic conditions (factor units)
    std::string standIn;     ///< for a missing combination: whose statistics synthesis uses
};
std::vector<CoverageRow> coverage(const BiomeDatabase& db, const Biome& biome);
/// The table as text (printed) and as CSV (stored beside the database).
std::string coverageText(const std::vector<CoverageRow>& rows);
std::string coverageCsv(const std::vector<CoverageRow>& rows);

/// Valley depth and base elevation (m) of generated terrain `t` (1-based) of `n` in a build.
std::pair<double, double> generatedTerrainShape(const DatabaseBuildOptions& options, int t, int n);

}  // namespace eco::pipeline
