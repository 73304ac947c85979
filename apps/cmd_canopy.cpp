// eco canopy: parsing only; the stage is in pipeline/canopy_stage (the science in
// synth/species_map and synth/canopy_placer, docs/canopy.md).
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "canopy_stage.h"
#include "canopy_placer.h"
#include "cli_common.h"
#include "memory.h"

namespace eco::cli {

namespace {

struct CanopyArgs {
    pipeline::CanopyOptions options;
    double cellSizeM = 0, verticalScale = 1, verticalOffsetM = 0;
    CLI::Option *cellOpt = nullptr, *scaleOpt = nullptr, *offsetOpt = nullptr;
    // The placer parameters' flags (pipeline::canopyParamFlags) write into `flags`; those
    // given become overrides, applied after --config.
    synth::CanopyParams flags;
    std::vector<std::pair<std::string, CLI::Option*>> paramOpts;  // key, option
};

template <class T>
std::optional<T> given(const CLI::Option* opt, T value) {
    return opt->count() ? std::optional<T>(value) : std::nullopt;
}

void runCanopy(CanopyArgs& a) {
    retainFreedMemory();  // the iterations and stages recycle memory (core/memory.h)
    pipeline::CanopyOptions& o = a.options;
    o.terrainRead.cellSizeM = given(a.cellOpt, a.cellSizeM);
    o.terrainRead.verticalScale = given(a.scaleOpt, a.verticalScale);
    o.terrainRead.verticalOffsetM = given(a.offsetOpt, a.verticalOffsetM);
    setGivenParams(o.params, a.paramOpts, a.flags, synth::canopyParamFields());
    CliReporter reporter;
    pipeline::canopyStage(o, reporter);
}

}  // namespace

void registerCanopyCommand(CLI::App& app) {
    auto args = std::make_shared<CanopyArgs>();
    pipeline::CanopyOptions& o = args->options;
    CLI::App* cmd = app.add_subcommand(
        "canopy",
        "Canopy trees from a canopy height model (paper §5): a species map from the abiotics (with optional "
        "target proportions), then iterative tree positioning; written to one HDF5 file");
    cmd->add_option("--terrain", o.terrain, "Terrain (.asc, .h5, .png, .tif, .exr), elevations in metres")->required();
    cmd->add_option("--chm", o.chm,
                    "Canopy height model, metres above ground (.asc, .h5 from 'eco chm generate', images); must "
                    "cover the terrain's cells")
        ->required();
    cmd->add_option("--biome", o.biome, "Biome TOML (default: the embedded Sonoma biome)");
    cmd->add_option("--abiotics", o.abiotics,
                    "Abiotics file from 'eco abiotics' (default: computed from the terrain with default parameters)");
    cmd->add_option("--target", o.targets,
                    "SPECIES=FRACTION: share of the forested area for a canopy species, e.g. 'Redwood=0.4'; "
                    "repeatable, met one after another")
        ->take_all();
    cmd->add_option("--mask", o.mask,
                    "Grey image of the CHM's pixel size: the targets apply inside its white part (a brush)");
    cmd->add_option("--out", o.out, "Output HDF5 file, e.g. canopy.h5 (written atomically)")->required();
    cmd->add_option("--png", o.pngDir, "Also write canopy.png, species_map.png and chm.png into this directory");
    cmd->add_option("--csv", o.csv, "Also write the trees as CSV");
    cmd->add_option("--gpkg", o.gpkg, "Also write the trees as a GeoPackage point layer, in the CHM's (else the terrain's) CRS");
    cmd->add_option("--geotiff", o.geotiffDir,
                    "Also write the canopy file's grids (species map, CHM, terrain) as GeoTIFFs into this directory, "
                    "with the inputs' geotransform and CRS");
    cmd->add_option("--config", o.config,
                    "TOML with placer parameters ([canopy] table or top-level keys; unknown keys are errors)");
    // The placer parameters' flags from their descriptions (synth/canopy_placer.cpp).
    const auto& fields = synth::canopyParamFields();
    synth::CanopyParams& flags = args->flags;
    args->paramOpts = addParamOptions(cmd, pipeline::canopyParamFlags(), flags, fields);
    args->cellOpt = cmd->add_option("--cell-size", args->cellSizeM, "Metres per cell (required for plain images; georeferenced rasters carry it)")
        ->check(cellSizeRange());
    args->scaleOpt = cmd->add_option("--vertical-scale", args->verticalScale, "Image terrain only: metres per stored unit")
        ->capture_default_str();
    args->offsetOpt = cmd->add_option("--vertical-offset", args->verticalOffsetM, "Image terrain only: metres added after scaling")
        ->capture_default_str();
    cmd->add_option("--chm-gaps", o.chmGaps,
                    "Nodata cells of the CHM: fill (from their neighbours, up to --chm-fill-max from data; the rest 0), "
                    "zero (non-forest) or fail")
        ->check(oneOf({"fill", "zero", "fail"}))
        ->capture_default_str();
    cmd->add_option("--chm-fill-max", o.chmFillMaxM, "fill: how far from data a gap is filled, metres")
        ->capture_default_str()
        ->check(nonNegativeNumber());
    cmd->add_flag("--resample-terrain", o.resampleTerrain,
                  "A terrain on other cells than the CHM's (e.g. a 10 m DEM under a 1 m lidar CHM) is resampled bilinearly "
                  "onto the CHM's cells (it must cover them); without it such inputs are refused");
    cmd->add_option("--chm-vertical-scale", o.chmVerticalScale, "Image CHM only: metres per stored unit")
        ->capture_default_str();
    cmd->add_option("--chm-vertical-offset", o.chmVerticalOffsetM, "Image CHM only: metres added after scaling")
        ->capture_default_str();
    cmd->callback([args] { runCanopy(*args); });
}

}  // namespace eco::cli
