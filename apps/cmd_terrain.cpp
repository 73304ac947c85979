// eco terrain generate | convert, eco chm generate: parsing only; the stages are in
// pipeline/terrain_stages (the work in core/terrain_io and core/generate).
#include <memory>
#include <optional>
#include <string>

#include "cli_common.h"
#include "text_format.h"
#include "terrain_stages.h"

namespace eco::cli {

namespace {

struct TerrainGenerateArgs {
    pipeline::TerrainGenerateOptions options;
    double verticalScale = 1, verticalOffset = 0;
    CLI::Option* scaleOpt = nullptr;
    CLI::Option* offsetOpt = nullptr;
};

struct TerrainConvertArgs {
    std::string in, out;
    double cellSize = 0, verticalScale = 1, verticalOffset = 0;
    CLI::Option* cellOpt = nullptr;
    CLI::Option* scaleOpt = nullptr;
    CLI::Option* offsetOpt = nullptr;
};

struct ChmGenerateArgs {
    pipeline::ChmGenerateOptions options;
    double cellSize = 0, verticalScale = 1, verticalOffset = 0;
    CLI::Option* cellOpt = nullptr;
    CLI::Option* scaleOpt = nullptr;
    CLI::Option* offsetOpt = nullptr;
    CLI::Option* sketchSeedOpt = nullptr;
};

std::optional<double> given(const CLI::Option* opt, double value) {
    return opt && opt->count() > 0 ? std::optional<double>(value) : std::nullopt;
}

void runTerrainGenerate(TerrainGenerateArgs& a) {
    a.options.verticalScale = given(a.scaleOpt, a.verticalScale);
    a.options.verticalOffsetM = given(a.offsetOpt, a.verticalOffset);
    CliReporter reporter;
    pipeline::generateTerrainStage(a.options, reporter);
}

void runTerrainConvert(const TerrainConvertArgs& a) {
    pipeline::TerrainConvertOptions o;
    o.in = a.in;
    o.out = a.out;
    o.cellSizeM = given(a.cellOpt, a.cellSize);
    o.verticalScale = given(a.scaleOpt, a.verticalScale);
    o.verticalOffsetM = given(a.offsetOpt, a.verticalOffset);
    CliReporter reporter;
    pipeline::convertTerrainStage(o, reporter);
}

void runChmGenerate(ChmGenerateArgs& a) {
    a.options.terrainRead.cellSizeM = given(a.cellOpt, a.cellSize);
    a.options.terrainRead.verticalScale = given(a.scaleOpt, a.verticalScale);
    a.options.terrainRead.verticalOffsetM = given(a.offsetOpt, a.verticalOffset);
    a.options.sketchSeedGiven = a.sketchSeedOpt->count() > 0;
    CliReporter reporter;
    pipeline::generateChmStage(a.options, reporter);
}

void addTerrainReadOptions(CLI::App* cmd, ChmGenerateArgs& a) {
    a.cellOpt = cmd->add_option("--cell-size", a.cellSize,
                    "Metres per cell. Required when the terrain is an image; for .asc/.h5 it is read from "
                    "the file and, if given, must agree")
        ->check(cellSizeRange());
    a.scaleOpt = cmd->add_option("--vertical-scale", a.verticalScale,
                    "Image terrains only: metres per stored unit (16-bit PNG values are 0..1), "
                    "elevation = value * scale + offset")
        ->check(positiveNumber());
    a.offsetOpt = cmd->add_option("--vertical-offset", a.verticalOffset, "Image terrains only: metres added after scaling");
}

}  // namespace

void registerTerrainCommands(CLI::App& app) {
    // ---------------------------------------------------------------- eco terrain
    CLI::App* terrain = app.add_subcommand(
        "terrain", "Terrain (digital elevation model) tools: generate the default terrain, convert formats");
    terrain->require_subcommand(1);

    {
        auto a = std::make_shared<TerrainGenerateArgs>();
        CLI::App* gen = terrain->add_subcommand(
            "generate",
            "Generate a procedural terrain: ridged hills cut by a meandering valley whose creek drains out of the "
            "domain (coastal California scale, elevations about 50-300 m). Deterministic for a seed, whatever "
            "the thread count.");
        gen->add_option("--out", a->options.out, "Output terrain: .asc, .h5, .png (16-bit), .tif or .exr (float)")
            ->required();
        gen->add_option("--width", a->options.params.width, "Columns (cells along x, east)")->check(CLI::Range(2, 1 << 16))
            ->capture_default_str();
        gen->add_option("--height", a->options.params.height, "Rows (cells along y, north)")->check(CLI::Range(2, 1 << 16))
            ->capture_default_str();
        gen->add_option("--cell-size", a->options.params.cellSizeM, "Metres per cell")->check(cellSizeRange())
            ->capture_default_str();
        gen->add_option("--seed", a->options.params.seed, "Random seed")->capture_default_str();
        gen->add_option("--relief", a->options.params.reliefM, "Height range of the hills above the valley rim (m)")
            ->check(nonNegativeNumber())->capture_default_str();
        gen->add_option("--valley-depth", a->options.params.valleyDepthM, "Depth of the valley below the lowest hills (m)")
            ->check(positiveNumber())->capture_default_str();
        gen->add_option("--base-elevation", a->options.params.baseElevationM,
                        "Elevation of the creek bed where it leaves the domain (m): shifts the whole terrain, and with "
                        "it the temperature (the biome's lapse rate)")
            ->check(CLI::Range(-500.0, 9000.0))->capture_default_str();
        a->scaleOpt = gen->add_option("--vertical-scale", a->verticalScale,
                                      "Image outputs: metres per stored unit (default: PNG a round number above "
                                      "the highest elevation, TIFF/EXR 1). Printed; give it back when reading")
                          ->check(positiveNumber());
        a->offsetOpt = gen->add_option("--vertical-offset", a->verticalOffset,
                                       "Image outputs: metres subtracted before scaling (default 0)");
        gen->add_option("--png", a->options.pngDir, "Also write elevation and hillshade pictures into this directory");
        gen->callback([a] { runTerrainGenerate(*a); });
    }
    {
        auto a = std::make_shared<TerrainConvertArgs>();
        CLI::App* conv = terrain->add_subcommand(
            "convert",
            "Convert a terrain between formats (.asc, .h5, .png, .tif, .exr; GeoTIFF, .img and .vrt read through GDAL with "
            "their geotransform), chosen by extension. The vertical "
            "scale/offset describe the image side (both sides when both are images).");
        conv->add_option("IN", a->in, "Input terrain")->required();
        conv->add_option("OUT", a->out, "Output terrain (written atomically)")->required();
        a->cellOpt = conv->add_option("--cell-size", a->cellSize,
                         "Metres per cell: required for plain image inputs; checked against .asc/.h5 and georeferenced inputs")
            ->check(cellSizeRange());
        a->scaleOpt = conv->add_option("--vertical-scale", a->verticalScale,
                                       "Metres per stored image unit: elevation = value * scale + offset "
                                       "(PNG output default: chosen and printed)")
                          ->check(positiveNumber());
        a->offsetOpt = conv->add_option("--vertical-offset", a->verticalOffset, "Metres added after scaling");
        conv->callback([a] { runTerrainConvert(*a); });
    }

    // ---------------------------------------------------------------- eco chm
    CLI::App* chm = app.add_subcommand("chm", "Canopy height model (CHM) tools");
    chm->require_subcommand(1);
    {
        auto a = std::make_shared<ChmGenerateArgs>();
        CLI::App* gen = chm->add_subcommand(
            "generate",
            "Generate a canopy height model (metres above ground) on a terrain's grid from a density sketch "
            "(empty / sparse / dense). This procedural generator stands in for the paper's learned CHM "
            "(a conditional GAN trained on lidar), for which no training data is available; a real CHM can be "
            "used directly wherever a CHM is read.");
        gen->add_option("--terrain", a->options.terrain, "Terrain whose grid the CHM takes (.asc, .h5, .png, .tif, .exr)")
            ->required();
        gen->add_option("--out", a->options.out,
                        "Output CHM: .h5 (/chm/height, /chm/sketch, /chm/trees) or .asc/.png/.tif/.exr (sketch "
                        "then written beside it as <name>_sketch.png)")
            ->required();
        addTerrainReadOptions(gen, *a);
        auto* sketchOpt = gen->add_option("--sketch", a->options.sketchImage,
                                          "Painted density sketch: grey image of the terrain's size, black empty "
                                          "(< 1/3), grey sparse (< 2/3), white dense");
        a->sketchSeedOpt = gen->add_option("--sketch-seed", a->options.sketch.seed, "Seed of the generated density sketch")
                               ->capture_default_str();
        sketchOpt->excludes(a->sketchSeedOpt);
        gen->add_option("--empty-fraction", a->options.sketch.emptyFraction, "Generated sketch: share of Empty cells")
            ->check(CLI::Range(0.0, 1.0))->capture_default_str()->excludes(sketchOpt);
        gen->add_option("--dense-fraction", a->options.sketch.denseFraction, "Generated sketch: share of Dense cells")
            ->check(CLI::Range(0.0, 1.0))->capture_default_str()->excludes(sketchOpt);
        gen->add_option("--seed", a->options.chm.seed, "Seed of the tree placement and heights")->capture_default_str();
        gen->add_option("--dense-spacing", a->options.chm.denseSpacingM, "Typical tree spacing in Dense areas (m)")
            ->check(positiveNumber())->capture_default_str();
        gen->add_option("--sparse-spacing", a->options.chm.sparseSpacingM, "Typical tree spacing in Sparse areas (m)")
            ->check(positiveNumber())->capture_default_str();
        // Trees of 0.1 .. 200 m (the tallest trees on Earth are about 116 m; 1e9 was accepted).
        gen->add_option("--min-height", a->options.chm.minHeightM, "Shortest canopy tree (m)")->check(numberIn(0.1, 200))
            ->capture_default_str();
        gen->add_option("--max-height", a->options.chm.maxHeightM, "Tallest canopy tree (m)")->check(numberIn(0.1, 200))
            ->capture_default_str();
        gen->add_option("--png", a->options.pngDir, "Also write pictures of the CHM and the sketch into this directory");
        gen->callback([a] {
            if (a->options.chm.minHeightM > a->options.chm.maxHeightM)
                usageError("--min-height, --max-height", "the shortest tree (" + formatNumber(a->options.chm.minHeightM) +
                                                             " m) must not be taller than the tallest (" +
                                                             formatNumber(a->options.chm.maxHeightM) + " m)");
            if (a->options.sketchImage.empty() && a->options.sketch.emptyFraction + a->options.sketch.denseFraction > 1 + 1e-12)
                usageError("--empty-fraction, --dense-fraction",
                           "the shares add up to " +
                               formatNumber(a->options.sketch.emptyFraction + a->options.sketch.denseFraction) +
                               "; together they must not exceed 1");
            runChmGenerate(*a);
        });
    }
}

}  // namespace eco::cli
