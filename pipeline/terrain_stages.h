// Stages that make or convert height fields: eco terrain generate | convert, eco chm generate.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "generate.h"
#include "grid.h"
#include "reporter.h"
#include "stage_common.h"

namespace eco::pipeline {

/// eco terrain generate: a procedural terrain written to `out` (.asc, .h5, .png, .tif, .exr).
struct TerrainGenerateOptions {
    std::string out;
    std::string pngDir;  ///< "" = no pictures; else terrain_elevation.png, terrain_hillshade.png
    TerrainGenParams params;
    /// Image outputs: metres per stored unit and metres subtracted (unset: chosen and printed).
    std::optional<double> verticalScale, verticalOffsetM;
};
struct TerrainResult {
    Grid<float> terrain;  ///< elevation, metres
    std::vector<std::string> written;
};
TerrainResult generateTerrainStage(const TerrainGenerateOptions& options, Reporter& reporter);
/// The eco command line of the stage (without "eco").
std::vector<std::string> commandLine(const TerrainGenerateOptions& options);

/// eco terrain convert IN OUT: between formats, chosen by extension.
struct TerrainConvertOptions {
    std::string in, out;
    std::optional<double> cellSizeM;
    /// The encoding of the image side (both sides when both are images).
    std::optional<double> verticalScale, verticalOffsetM;
};
TerrainResult convertTerrainStage(const TerrainConvertOptions& options, Reporter& reporter);

/// eco chm generate: a canopy height model on a terrain's grid from a density sketch.
struct ChmGenerateOptions {
    std::string terrain, out;
    std::string sketchImage;  ///< painted sketch; "" = generated from `sketch`
    std::string pngDir;       ///< "" = no pictures; else chm.png, sketch.png
    TerrainReadFlags terrainRead;  ///< vertical flags apply only to an image terrain
    SketchParams sketch;
    bool sketchSeedGiven = false;  ///< --sketch-seed on the command line
    ChmGenParams chm;
};
struct ChmResult {
    Grid<float> chm;  ///< metres above ground
    std::size_t trees = 0;
    std::vector<std::string> written;
};
ChmResult generateChmStage(const ChmGenerateOptions& options, Reporter& reporter);
std::vector<std::string> commandLine(const ChmGenerateOptions& options);

}  // namespace eco::pipeline
