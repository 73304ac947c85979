// eco terrain generate | convert, eco chm generate: parsing and reporting only; the work is
// in core/terrain_io and core/generate.
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <memory>
#include <sstream>
#include <string>

#include "atomic_file.h"
#include "cli_common.h"
#include "error.h"
#include "generate.h"
#include "h5io.h"
#include "image_out.h"
#include "terrain_io.h"
#include "text_format.h"

namespace eco::cli {

namespace {

std::string num(double v) { return formatNumber(v, 6); }

/// A round number >= maxValue - offset, so 16-bit PNG levels cover the data with a little room.
double niceScaleAbove(double range) {
    if (!(range > 0)) return 1.0;
    const double step = std::pow(10.0, std::floor(std::log10(range))) / 2.0;
    return std::ceil(range / step) * step;
}

/// How to encode heights in an image file: chosen automatically unless the user gave it.
struct ImageEncoding {
    TerrainWriteOptions write;
    bool automatic = false;
};

ImageEncoding chooseEncoding(const std::string& path, const Grid<float>& g, const CLI::Option* scaleOpt,
                             double userScale, const CLI::Option* offsetOpt, double userOffset) {
    ImageEncoding enc;
    const bool haveScale = scaleOpt && scaleOpt->count() > 0;
    const bool haveOffset = offsetOpt && offsetOpt->count() > 0;
    enc.write.verticalScale = haveScale ? userScale : 1.0;
    enc.write.verticalOffsetM = haveOffset ? userOffset : 0.0;
    if (fileExtension(path) == ".png") {
        // 16-bit fixed point: the values must fit in [offset, offset + scale].
        const double lo = g.minValue(), hi = g.maxValue();
        if (!haveOffset && lo < 0) {
            const double step = niceScaleAbove(std::max(hi - lo, 1.0)) / 10.0;
            enc.write.verticalOffsetM = std::floor(lo / step) * step;
        }
        if (!haveScale) {
            enc.write.verticalScale = niceScaleAbove(hi - enc.write.verticalOffsetM);
            enc.automatic = true;
        }
        long clipped = 0;
        for (float v : g.data()) {
            const double s = (v - enc.write.verticalOffsetM) / enc.write.verticalScale;
            if (s < 0 || s > 1) ++clipped;
        }
        if (clipped > 0)
            info("warning: " + std::to_string(clipped) + " cells of " + path + " lie outside [" +
                 num(enc.write.verticalOffsetM) + ", " + num(enc.write.verticalOffsetM + enc.write.verticalScale) +
                 "] m and are clipped; choose --vertical-scale / --vertical-offset to cover " + num(g.minValue()) +
                 " .. " + num(g.maxValue()) + " m");
    }
    return enc;
}

/// The flags a reader of an image output must give back.
std::string readBackHint(const std::string& path, const Grid<float>& g, const TerrainWriteOptions& w) {
    if (!isTerrainImageExtension(fileExtension(path))) return "";
    std::string hint = "  read it back with: --cell-size " + num(g.cellSizeM()) + " --vertical-scale " +
                       num(w.verticalScale);
    if (w.verticalOffsetM != 0) hint += " --vertical-offset " + num(w.verticalOffsetM);
    if (g.originX() != 0 || g.originY() != 0)
        hint += "  (images do not store the origin " + num(g.originX()) + ", " + num(g.originY()) + ")";
    return hint;
}

std::string describe(const Grid<float>& g, const std::string& units) {
    return std::to_string(g.width()) + " x " + std::to_string(g.height()) + " cells of " + num(g.cellSizeM()) +
           " m, " + num(g.minValue()) + " .. " + num(g.maxValue()) + " " + units;
}

// ------------------------------------------------------------------ terrain generate

struct TerrainGenerateArgs {
    std::string out;
    std::string pngDir;
    TerrainGenParams params;
    double verticalScale = 1, verticalOffset = 0;
    CLI::Option* scaleOpt = nullptr;
    CLI::Option* offsetOpt = nullptr;
};

void writeTerrainPictures(const std::string& dir, const Grid<float>& terrain) {
    ensureDirectory(dir);
    const std::string elevation = (std::filesystem::path(dir) / "terrain_elevation.png").string();
    const std::string shade = (std::filesystem::path(dir) / "terrain_hillshade.png").string();
    writeMapPng(elevation, terrain, "Elevation", "m", Colormap::Terrain);
    writeMapPng(shade, hillshade(terrain), "Hillshade (sun from the north-west, 45 deg)", "relative",
                Colormap::Greys, 0.0, 1.0);
    std::cout << "wrote picture: " << elevation << "\n" << "wrote picture: " << shade << "\n";
}

void runTerrainGenerate(const TerrainGenerateArgs& a) {
    const std::string ext = fileExtension(a.out);
    if (ext.empty() || (ext != ".asc" && ext != ".h5" && ext != ".hdf5" && !isTerrainImageExtension(ext)))
        throw ValidationError(a.out + ": unknown terrain format '" + ext + "'; supported: " +
                              supportedTerrainExtensions());
    const Grid<float> terrain = generateTerrain(a.params);
    const ImageEncoding enc = chooseEncoding(a.out, terrain, a.scaleOpt, a.verticalScale, a.offsetOpt,
                                             a.verticalOffset);
    writeTerrain(a.out, terrain, enc.write);
    std::cout << "wrote terrain: " << a.out << " (" << describe(terrain, "m") << ", seed " << a.params.seed
              << ")\n";
    const std::string hint = readBackHint(a.out, terrain, enc.write);
    if (!hint.empty()) std::cout << hint << "\n";
    if (!a.pngDir.empty()) writeTerrainPictures(a.pngDir, terrain);
}

// ------------------------------------------------------------------ terrain convert

struct TerrainConvertArgs {
    std::string in, out;
    double cellSize = 0, verticalScale = 1, verticalOffset = 0;
    CLI::Option* scaleOpt = nullptr;
    CLI::Option* offsetOpt = nullptr;
};

void runTerrainConvert(const TerrainConvertArgs& a) {
    const std::string inExt = fileExtension(a.in), outExt = fileExtension(a.out);
    const bool inImage = isTerrainImageExtension(inExt), outImage = isTerrainImageExtension(outExt);
    if (outExt != ".asc" && outExt != ".h5" && outExt != ".hdf5" && !outImage)
        throw ValidationError(a.out + ": unknown terrain format '" + outExt + "'; supported: " +
                              supportedTerrainExtensions());
    const bool verticalGiven = a.scaleOpt->count() > 0 || a.offsetOpt->count() > 0;
    if (verticalGiven && !inImage && !outImage)
        throw ValidationError("--vertical-scale / --vertical-offset describe image encodings, but neither " + a.in +
                              " nor " + a.out + " is an image");
    // The vertical encoding describes whichever side is an image (both when both are).
    TerrainReadOptions ro;
    ro.cellSizeM = a.cellSize;
    if (inImage) {
        ro.verticalScale = a.verticalScale;
        ro.verticalOffsetM = a.verticalOffset;
    }
    const Grid<float> terrain = readTerrain(a.in, ro);
    ImageEncoding enc;
    if (outImage) enc = chooseEncoding(a.out, terrain, a.scaleOpt, a.verticalScale, a.offsetOpt, a.verticalOffset);
    writeTerrain(a.out, terrain, enc.write);
    std::cout << "wrote terrain: " << a.out << " (" << describe(terrain, "m") << ")\n";
    const std::string hint = readBackHint(a.out, terrain, enc.write);
    if (!hint.empty()) std::cout << hint << "\n";
}

// ------------------------------------------------------------------ chm generate

struct ChmGenerateArgs {
    std::string terrain, out, sketchImage, pngDir;
    double cellSize = 0, verticalScale = 1, verticalOffset = 0;
    SketchParams sketch;
    ChmGenParams chm;
    CLI::Option* sketchSeedOpt = nullptr;
};

std::string withoutExtension(const std::string& path) {
    const std::string ext = fileExtension(path);
    return ext.empty() ? path : path.substr(0, path.size() - ext.size());
}

void writeChmH5(const std::string& path, const Grid<float>& chm, const Grid<std::int32_t>& sketch,
                const std::vector<GeneratedTree>& trees, const ChmGenerateArgs& a) {
    AtomicOutput out(path);
    {
        h5::File f = h5::File::create(out.tempPath());
        f.writeGrid("/chm/height", chm, "m above ground");
        f.writeGridI32("/chm/sketch", sketch, "density level: 0 empty, 1 sparse, 2 dense");
        f.setAttr("/chm", "generator",
                  std::string("eco procedural CHM: a stand-in for the paper's learned (conditional GAN) CHM; "
                              "sphere crowns placed by dart throwing from the density sketch"));
        f.setAttr("/chm", "seed", static_cast<std::int64_t>(a.chm.seed));
        f.setAttr("/chm", "dense_spacing_m", a.chm.denseSpacingM);
        f.setAttr("/chm", "sparse_spacing_m", a.chm.sparseSpacingM);
        f.setAttr("/chm", "min_height_m", a.chm.minHeightM);
        f.setAttr("/chm", "max_height_m", a.chm.maxHeightM);
        f.setAttr("/chm", "crown_allometry_a", a.chm.crownA);
        f.setAttr("/chm", "crown_allometry_b", a.chm.crownB);
        f.setAttr("/chm", "height_field_wavelength_m", a.chm.heightFieldWavelengthM);
        f.setAttr("/chm", "tree_height_spread", a.chm.treeHeightSpread);
        f.setAttr("/chm", "sparse_height_factor", a.chm.sparseHeightFactor);
        f.setAttr("/chm", "dense_gap_fraction", a.chm.denseGapFraction);
        f.setAttr("/chm", "gap_size_m", a.chm.gapSizeM);
        if (a.sketchImage.empty()) {
            f.setAttr("/chm/sketch", "source", std::string("generated"));
            f.setAttr("/chm/sketch", "seed", static_cast<std::int64_t>(a.sketch.seed));
            f.setAttr("/chm/sketch", "feature_size_m", a.sketch.featureSizeM);
            f.setAttr("/chm/sketch", "empty_fraction", a.sketch.emptyFraction);
            f.setAttr("/chm/sketch", "dense_fraction", a.sketch.denseFraction);
        } else {
            f.setAttr("/chm/sketch", "source", a.sketchImage);
        }
        // The trees behind the CHM: ground truth for canopy placement.
        std::vector<double> x, y, hgt, r;
        for (const auto& t : trees) {
            x.push_back(t.x);
            y.push_back(t.y);
            hgt.push_back(t.heightM);
            r.push_back(t.crownRadiusM);
        }
        const std::vector<hsize_t> dims{static_cast<hsize_t>(trees.size())};
        f.writeF64("/chm/trees/x_m", x, dims);
        f.writeF64("/chm/trees/y_m", y, dims);
        f.writeF64("/chm/trees/height_m", hgt, dims);
        f.writeF64("/chm/trees/crown_radius_m", r, dims);
        f.setAttr("/chm/trees", "description",
                  std::string("trees the CHM was rasterised from (world metres; height above ground)"));
    }
    out.commit();
}

void runChmGenerate(const ChmGenerateArgs& a) {
    const std::string outExt = fileExtension(a.out);
    if (outExt != ".asc" && outExt != ".h5" && outExt != ".hdf5" && !isTerrainImageExtension(outExt))
        throw ValidationError(a.out + ": unknown output format '" + outExt + "'; supported: " +
                              supportedTerrainExtensions());
    TerrainReadOptions ro;
    ro.cellSizeM = a.cellSize;
    if (isTerrainImageExtension(fileExtension(a.terrain))) {
        ro.verticalScale = a.verticalScale;
        ro.verticalOffsetM = a.verticalOffset;
    }
    const Grid<float> terrain = readTerrain(a.terrain, ro);
    const Grid<std::int32_t> sketch = a.sketchImage.empty() ? generateDensitySketch(terrain, a.sketch)
                                                            : readDensitySketch(a.sketchImage, terrain);
    std::vector<GeneratedTree> trees;
    const Grid<float> chm = generateChm(sketch, a.chm, trees);

    if (outExt == ".h5" || outExt == ".hdf5") {
        writeChmH5(a.out, chm, sketch, trees, a);
        std::cout << "wrote CHM: " << a.out << " (/chm/height, /chm/sketch, /chm/trees; " << describe(chm, "m above ground")
                  << ", " << trees.size() << " trees)\n";
    } else {
        TerrainWriteOptions wo;
        if (outExt == ".png") wo.verticalScale = niceScaleAbove(std::max<double>(chm.maxValue(), a.chm.maxHeightM));
        writeTerrain(a.out, chm, wo);
        std::cout << "wrote CHM: " << a.out << " (" << describe(chm, "m above ground") << ", " << trees.size()
                  << " trees)\n";
        const std::string hint = readBackHint(a.out, chm, wo);
        if (!hint.empty()) std::cout << hint << "\n";
        const std::string sketchPath = withoutExtension(a.out) + "_sketch.png";
        writeDensitySketch(sketchPath, sketch);
        std::cout << "wrote density sketch: " << sketchPath << " (black empty, grey sparse, white dense)\n";
    }
    if (!a.pngDir.empty()) {
        ensureDirectory(a.pngDir);
        const std::string chmPng = (std::filesystem::path(a.pngDir) / "chm.png").string();
        const std::string sketchPng = (std::filesystem::path(a.pngDir) / "sketch.png").string();
        writeMapPng(chmPng, chm, "Canopy height model (generated)", "m above ground", Colormap::Viridis, 0.0,
                    std::max<double>(chm.maxValue(), 1.0));
        writeCategoryPng(sketchPng, sketch, "Density sketch", {"empty", "sparse", "dense"});
        std::cout << "wrote picture: " << chmPng << "\n" << "wrote picture: " << sketchPng << "\n";
    }
}

void addTerrainReadOptions(CLI::App* cmd, double& cellSize, double& scale, double& offset) {
    cmd->add_option("--cell-size", cellSize,
                    "Metres per cell. Required when the terrain is an image; for .asc/.h5 it is read from "
                    "the file and, if given, must agree")
        ->check(positiveNumber());
    cmd->add_option("--vertical-scale", scale,
                    "Image terrains only: metres per stored unit (16-bit PNG values are 0..1), "
                    "elevation = value * scale + offset")
        ->check(positiveNumber());
    cmd->add_option("--vertical-offset", offset, "Image terrains only: metres added after scaling");
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
        gen->add_option("--out", a->out, "Output terrain: .asc, .h5, .png (16-bit), .tif or .exr (float)")
            ->required();
        gen->add_option("--width", a->params.width, "Columns (cells along x, east)")->check(CLI::Range(2, 1 << 16))
            ->capture_default_str();
        gen->add_option("--height", a->params.height, "Rows (cells along y, north)")->check(CLI::Range(2, 1 << 16))
            ->capture_default_str();
        gen->add_option("--cell-size", a->params.cellSizeM, "Metres per cell")->check(positiveNumber())
            ->capture_default_str();
        gen->add_option("--seed", a->params.seed, "Random seed")->capture_default_str();
        gen->add_option("--relief", a->params.reliefM, "Height range of the hills above the valley rim (m)")
            ->check(nonNegativeNumber())->capture_default_str();
        gen->add_option("--valley-depth", a->params.valleyDepthM, "Depth of the valley below the lowest hills (m)")
            ->check(positiveNumber())->capture_default_str();
        a->scaleOpt = gen->add_option("--vertical-scale", a->verticalScale,
                                      "Image outputs: metres per stored unit (default: PNG a round number above "
                                      "the highest elevation, TIFF/EXR 1). Printed; give it back when reading")
                          ->check(positiveNumber());
        a->offsetOpt = gen->add_option("--vertical-offset", a->verticalOffset,
                                       "Image outputs: metres subtracted before scaling (default 0)");
        gen->add_option("--png", a->pngDir, "Also write elevation and hillshade pictures into this directory");
        gen->callback([a] { runTerrainGenerate(*a); });
    }
    {
        auto a = std::make_shared<TerrainConvertArgs>();
        CLI::App* conv = terrain->add_subcommand(
            "convert",
            "Convert a terrain between formats (.asc, .h5, .png, .tif, .exr), chosen by extension. The vertical "
            "scale/offset describe the image side (both sides when both are images).");
        conv->add_option("IN", a->in, "Input terrain")->required();
        conv->add_option("OUT", a->out, "Output terrain (written atomically)")->required();
        conv->add_option("--cell-size", a->cellSize,
                         "Metres per cell: required for image inputs; checked against .asc/.h5 inputs")
            ->check(positiveNumber());
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
        gen->add_option("--terrain", a->terrain, "Terrain whose grid the CHM takes (.asc, .h5, .png, .tif, .exr)")
            ->required();
        gen->add_option("--out", a->out,
                        "Output CHM: .h5 (/chm/height, /chm/sketch, /chm/trees) or .asc/.png/.tif/.exr (sketch "
                        "then written beside it as <name>_sketch.png)")
            ->required();
        addTerrainReadOptions(gen, a->cellSize, a->verticalScale, a->verticalOffset);
        auto* sketchOpt = gen->add_option("--sketch", a->sketchImage,
                                          "Painted density sketch: grey image of the terrain's size, black empty "
                                          "(< 1/3), grey sparse (< 2/3), white dense");
        a->sketchSeedOpt = gen->add_option("--sketch-seed", a->sketch.seed, "Seed of the generated density sketch")
                               ->capture_default_str();
        sketchOpt->excludes(a->sketchSeedOpt);
        gen->add_option("--empty-fraction", a->sketch.emptyFraction, "Generated sketch: share of Empty cells")
            ->check(CLI::Range(0.0, 1.0))->capture_default_str()->excludes(sketchOpt);
        gen->add_option("--dense-fraction", a->sketch.denseFraction, "Generated sketch: share of Dense cells")
            ->check(CLI::Range(0.0, 1.0))->capture_default_str()->excludes(sketchOpt);
        gen->add_option("--seed", a->chm.seed, "Seed of the tree placement and heights")->capture_default_str();
        gen->add_option("--dense-spacing", a->chm.denseSpacingM, "Typical tree spacing in Dense areas (m)")
            ->check(positiveNumber())->capture_default_str();
        gen->add_option("--sparse-spacing", a->chm.sparseSpacingM, "Typical tree spacing in Sparse areas (m)")
            ->check(positiveNumber())->capture_default_str();
        gen->add_option("--min-height", a->chm.minHeightM, "Shortest canopy tree (m)")->check(positiveNumber())
            ->capture_default_str();
        gen->add_option("--max-height", a->chm.maxHeightM, "Tallest canopy tree (m)")->check(positiveNumber())
            ->capture_default_str();
        gen->add_option("--png", a->pngDir, "Also write pictures of the CHM and the sketch into this directory");
        gen->callback([a] { runChmGenerate(*a); });
    }
}

}  // namespace eco::cli
