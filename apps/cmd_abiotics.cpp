// eco abiotics: parsing only; the stage is in pipeline/abiotics_stage (the models in
// core/abiotics).
#include <memory>
#include <string>

#include "abiotics.h"
#include "abiotics_stage.h"
#include "cli_common.h"

namespace eco::cli {

namespace {

struct AbioticsArgs {
    pipeline::AbioticsOptions options;
    double cellSizeM = 0, verticalScale = 1, verticalOffsetM = 0;
    CLI::Option *cellOpt = nullptr, *scaleOpt = nullptr, *offsetOpt = nullptr;
};

void runAbiotics(AbioticsArgs& a) {
    if (a.cellOpt->count()) a.options.terrainRead.cellSizeM = a.cellSizeM;
    if (a.scaleOpt->count()) a.options.terrainRead.verticalScale = a.verticalScale;
    if (a.offsetOpt->count()) a.options.terrainRead.verticalOffsetM = a.verticalOffsetM;
    CliReporter reporter;
    pipeline::abioticsStage(a.options, reporter);
}

}  // namespace

void registerAbioticsCommand(CLI::App& app) {
    auto args = std::make_shared<AbioticsArgs>();
    pipeline::AbioticsOptions& o = args->options;
    // The maps listed from kAbioticMaps (core/abiotics.h), so that a new map needs no line here.
    std::string maps;
    for (const AbioticMapInfo& m : kAbioticMaps)
        maps += std::string(maps.empty() ? "" : "; ") + m.name + " (" + m.unit + (m.isMonthly() ? ", monthly" : "") + "): " +
                m.description;
    CLI::App* cmd = app.add_subcommand("abiotics", "Abiotic maps of a terrain, written to one HDF5 file with its elevation: " +
                                                       maps);
    cmd->add_option("--terrain", o.terrain, "Terrain (.asc, .h5, .png, .tif, .exr), elevations in metres")
        ->required();
    cmd->add_option("--biome", o.biome, "Biome TOML (default: the embedded Sonoma biome)");
    cmd->add_option("--out", o.out, "Output HDF5 file, e.g. abiotics.h5 (written atomically)")->required();
    cmd->add_option("--png", o.pngDir, "Also write one PNG per map and month into this directory");
    cmd->add_option("--geotiff", o.geotiffDir,
                    "Also write every map as a GeoTIFF into this directory (<out stem>_sun.tif etc., 12 bands for the "
                    "monthly maps, with the terrain's geotransform and CRS) for GIS software");
    cmd->add_option("--canopy", o.canopy,
                    "Canopy file from 'eco canopy' on this terrain: shade the sun maps under its crowns (each crown "
                    "x (1 - alpha)); for looking at the light under the canopy. eco simulate, analyse and synth "
                    "shade with their canopy themselves and want the unshaded file");
    args->cellOpt = cmd->add_option("--cell-size", args->cellSizeM,
                    "Metres per cell (required for image terrains; checked against .asc / .h5)")
        ->check(cellSizeRange());
    args->scaleOpt = cmd->add_option("--vertical-scale", args->verticalScale, "Image terrains only: metres per stored unit")
        ->capture_default_str();
    args->offsetOpt = cmd->add_option("--vertical-offset", args->verticalOffsetM, "Image terrains only: metres added after scaling")
        ->capture_default_str();
    addParamOption(cmd, "--sun-step", o.sunStepMinutes, sunParamFields(), "sun_step_minutes");
    cmd->callback([args] { runAbiotics(*args); });
}

}  // namespace eco::cli
