// eco canopy: canopy trees from a canopy height model (paper §5): species map with optional
// target proportions, then iterative positioning (synth/species_map, synth/canopy_placer).
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "canopy_placer.h"
#include "reporter.h"
#include "stage_common.h"

namespace eco::pipeline {

struct CanopyOptions {
    std::string terrain, chm;
    std::string biome;     ///< biome TOML; "" = the embedded Sonoma biome
    std::string abiotics;  ///< abiotics of the terrain; "" = computed with default parameters
    std::string out;       ///< HDF5 output (atomic)
    std::string pngDir, csv;  ///< optional outputs ("" = none)
    std::string gpkg;         ///< optional: the trees as a GeoPackage in the CHM's (else the terrain's) CRS
    std::string geotiffDir;   ///< optional: the file's grids (species map, CHM, terrain) as GeoTIFFs
    std::string mask;         ///< grey image: where the targets apply
    std::string config;       ///< TOML of placer parameters, applied before the overrides below
    std::vector<std::string> targets;  ///< "SPECIES=FRACTION", met one after another
    TerrainReadFlags terrainRead;      ///< the cell size applies to an image CHM too
    double chmVerticalScale = 1, chmVerticalOffsetM = 0;  ///< image CHM only
    std::string chmGaps = "fill";  ///< nodata cells of the CHM: fill, zero or fail (core/terrain_io.h)
    double chmFillMaxM = 2.0;      ///< fill: how far from data a gap is filled, metres
    bool resampleTerrain = false;  ///< a terrain on other cells than the CHM's is resampled onto them (bilinear)
    /// Placer parameters set over `config` (else the defaults), by key of
    /// synth::canopyParamFields(); on the command line as the flags of canopyParamFlags().
    ParamOverrides<synth::CanopyParams> params;
};
/// The placer parameters eco canopy takes as flags: flag and key, the seed first.
const std::vector<ParamFlagName>& canopyParamFlags();
struct CanopyStageResult {
    synth::CanopyResult placement;  ///< the trees and the iteration statistics
    std::vector<std::string> written;
};
CanopyStageResult canopyStage(const CanopyOptions& options, Reporter& reporter);
/// The stage's settings checked without reading its inputs: the placer configuration file and
/// overrides, the biome, the targets' species. ValidationError naming the file and key.
void checkCanopyOptions(const CanopyOptions& options);
std::vector<std::string> commandLine(const CanopyOptions& options);

}  // namespace eco::pipeline
