// eco abiotics: the monthly abiotic maps of a terrain (the models are in core/abiotics).
#pragma once

#include <string>
#include <vector>

#include "abiotics.h"
#include "reporter.h"
#include "stage_common.h"

namespace eco::pipeline {

struct AbioticsOptions {
    std::string terrain;
    std::string biome;   ///< biome TOML; "" = the embedded Sonoma biome
    std::string out;     ///< HDF5 output (atomic)
    std::string pngDir;  ///< "" = no pictures; else one PNG per map and month
    std::string geotiffDir;  ///< "" = none; else every map as a GeoTIFF (12 bands for the monthly ones)
    std::string canopy;  ///< canopy file whose crowns shade the sun maps; "" = open sky
    TerrainReadFlags terrainRead;
    double sunStepMinutes = 10;  ///< sampling interval of the sun path
};
struct AbioticsResult {
    Abiotics maps;
    std::vector<std::string> written;
};
AbioticsResult abioticsStage(const AbioticsOptions& options, Reporter& reporter);
std::vector<std::string> commandLine(const AbioticsOptions& options);

}  // namespace eco::pipeline
