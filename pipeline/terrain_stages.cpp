#include "terrain_stages.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <ostream>

#include "atomic_file.h"
#include "eco_version.h"
#include "provenance.h"
#include "error.h"
#include "h5io.h"
#include "image_out.h"
#include "geo_raster.h"
#include "terrain_io.h"
#include "text_format.h"

namespace eco::pipeline {

namespace {

std::string num(double v) { return formatNumber(v, 6); }

/// A round number >= maxValue - offset, so 16-bit PNG levels cover the data with a little room.
double niceScaleAbove(double range) {
    if (!(range > 0)) return 1.0;
    const double step = std::pow(10.0, std::floor(std::log10(range))) / 2.0;
    return std::ceil(range / step) * step;
}

/// How to encode heights in an image file: chosen automatically unless the user gave it.
TerrainWriteOptions chooseEncoding(const std::string& path, const Grid<float>& g, const std::optional<double>& userScale,
                                   const std::optional<double>& userOffset, Reporter& reporter) {
    TerrainWriteOptions w;
    w.verticalScale = userScale ? *userScale : 1.0;
    w.verticalOffsetM = userOffset ? *userOffset : 0.0;
    if (fileExtension(path) == ".png") {
        // 16-bit fixed point: the values must fit in [offset, offset + scale].
        const double lo = g.minValue(), hi = g.maxValue();
        if (!userOffset && lo < 0) {
            const double step = niceScaleAbove(std::max(hi - lo, 1.0)) / 10.0;
            w.verticalOffsetM = std::floor(lo / step) * step;
        }
        if (!userScale) w.verticalScale = niceScaleAbove(hi - w.verticalOffsetM);
        long clipped = 0;
        for (float v : g.data()) {
            const double s = (v - w.verticalOffsetM) / w.verticalScale;
            if (s < 0 || s > 1) ++clipped;
        }
        if (clipped > 0)
            reporter.info("warning: " + std::to_string(clipped) + " cells of " + path + " lie outside [" +
                          num(w.verticalOffsetM) + ", " + num(w.verticalOffsetM + w.verticalScale) +
                          "] m and are clipped; choose --vertical-scale / --vertical-offset to cover " + num(g.minValue()) +
                          " .. " + num(g.maxValue()) + " m");
    }
    return w;
}

/// The flags a reader of an image output must give back.
std::string readBackHint(const std::string& path, const Grid<float>& g, const TerrainWriteOptions& w) {
    if (!isTerrainImageExtension(fileExtension(path))) return "";
    std::string hint = "  read it back with: --cell-size " + num(g.cellSizeM()) + " --vertical-scale " +
                       num(w.verticalScale);
    if (w.verticalOffsetM != 0) hint += " --vertical-offset " + num(w.verticalOffsetM);
    if (g.originX() != 0 || g.originY() != 0)
        hint += "  (images do not store the origin " + formatNumber(g.originX(), 10) + ", " + formatNumber(g.originY(), 10) + ")";
    return hint;
}

/// A warning when `path`'s format stores no CRS (an ESRI ASCII grid, a plain image) but the
/// grid has one: GIS software would open the file without it.
void warnCrsDropped(const std::string& path, const Grid<float>& g, Reporter& reporter) {
    const std::string ext = fileExtension(path);
    if (g.crsWkt().empty() || ext == ".h5" || ext == ".hdf5") return;
    reporter.info("warning: " + path + ": " + (ext == ".asc" ? "an ESRI ASCII grid" : "a plain image") +
                  " stores no CRS, so " + crsDisplayName(g.crsWkt()) +
                  " is not in the file (write .tif or .h5 to keep it; eco takes the other input's CRS for a file without one)");
}

/// True when a .tif/.tiff output of `g`, read from `input`, is written as a GeoTIFF (its
/// geotransform and CRS) rather than a plain image: the grid has a CRS or the input a
/// geotransform, and no image encoding was asked for.
bool writesGeoTiff(const std::string& outExt, const Grid<float>& g, const std::string& input, bool verticalGiven) {
    return (outExt == ".tif" || outExt == ".tiff") && !verticalGiven && (!g.crsWkt().empty() || hasGeotransform(input));
}

std::string describe(const Grid<float>& g, const std::string& units) {
    return std::to_string(g.width()) + " x " + std::to_string(g.height()) + " cells of " + num(g.cellSizeM()) +
           " m, " + num(g.minValue()) + " .. " + num(g.maxValue()) + " " + units;
}

bool isTerrainOutput(const std::string& ext) {
    return ext == ".asc" || ext == ".h5" || ext == ".hdf5" || isTerrainImageExtension(ext);
}

void writeTerrainPictures(const std::string& dir, const Grid<float>& terrain, std::ostream& out,
                          std::vector<std::string>& written) {
    prepareOutputDirectory(dir);
    const std::string elevation = (std::filesystem::path(dir) / "terrain_elevation.png").string();
    const std::string shade = (std::filesystem::path(dir) / "terrain_hillshade.png").string();
    writeMapPng(elevation, terrain, "Elevation", "m", Colormap::Terrain);
    writeMapPng(shade, hillshade(terrain), "Hillshade (sun from the north-west, 45 deg)", "relative",
                Colormap::Greys, 0.0, 1.0);
    out << "wrote picture: " << elevation << "\n" << "wrote picture: " << shade << "\n";
    written.insert(written.end(), {elevation, shade});
}

std::string withoutExtension(const std::string& path) {
    const std::string ext = fileExtension(path);
    return ext.empty() ? path : path.substr(0, path.size() - ext.size());
}

void writeChmH5(const std::string& path, const Grid<float>& chm, const Grid<std::int32_t>& sketch,
                const std::vector<GeneratedTree>& trees, const ChmGenerateOptions& a) {
    AtomicOutput out(path);
    {
        h5::File f = h5::File::create(out.tempPath());
        f.writeGrid("/chm/height", chm, "m");
        f.setAttr("/chm/height", "long_name", std::string("canopy height above ground"));
        f.writeGridI32("/chm/sketch", sketch, "1");
        f.setAttr("/chm/sketch", "long_name", std::string("density level: 0 empty, 1 sparse, 2 dense"));
        // The root attributes every file of ours carries (docs/hdf5.md); readers of a CHM take
        // any file with /chm/height, so older files stay readable.
        f.setAttr("/", "format", std::string("eco-chm"));
        f.setAttr("/", "schema_version", std::int64_t{1});
        f.setAttr("/", "code_version", std::string(ECO_VERSION_STRING));
        writeProvenance(f, {});  // what identifies the run: nothing measured
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
        f.writeF64("/chm/trees/x_m", x, dims, "m");
        f.writeF64("/chm/trees/y_m", y, dims, "m");
        f.writeF64("/chm/trees/height_m", hgt, dims, "m");
        f.writeF64("/chm/trees/crown_radius_m", r, dims, "m");
        f.setAttr("/chm/trees", "description",
                  std::string("trees the CHM was rasterised from (world metres; height above ground)"));
    }
    out.commit();
}

}  // namespace

TerrainResult generateTerrainStage(const TerrainGenerateOptions& a, Reporter& reporter) {
    const std::string ext = fileExtension(a.out);
    if (ext.empty() || !isTerrainOutput(ext))
        throw ValidationError(a.out + ": unknown terrain format '" + ext + "'; supported: " +
                              supportedTerrainExtensions());
    TerrainResult result;
    result.terrain = generateTerrain(a.params);
    const Grid<float>& terrain = result.terrain;
    const TerrainWriteOptions enc = chooseEncoding(a.out, terrain, a.verticalScale, a.verticalOffsetM, reporter);
    AtomicOutputSet outputs;  // the terrain and its pictures together
    writeTerrain(a.out, terrain, enc);
    result.written.push_back(a.out);
    std::ostream& out = reporter.out();
    out << "wrote terrain: " << a.out << " (" << describe(terrain, "m") << ", seed " << a.params.seed << ")\n";
    const std::string hint = readBackHint(a.out, terrain, enc);
    if (!hint.empty()) out << hint << "\n";
    if (!a.pngDir.empty()) writeTerrainPictures(a.pngDir, terrain, out, result.written);
    outputs.commit();
    return result;
}

std::vector<std::string> commandLine(const TerrainGenerateOptions& a) {
    const TerrainGenParams defaults;
    std::vector<std::string> args = {"terrain", "generate", "--out", a.out,
                                     "--width", std::to_string(a.params.width),
                                     "--height", std::to_string(a.params.height),
                                     "--cell-size", argNumber(a.params.cellSizeM),
                                     "--seed", std::to_string(a.params.seed)};
    if (a.params.reliefM != defaults.reliefM) args.insert(args.end(), {"--relief", argNumber(a.params.reliefM)});
    if (a.params.valleyDepthM != defaults.valleyDepthM)
        args.insert(args.end(), {"--valley-depth", argNumber(a.params.valleyDepthM)});
    if (a.params.baseElevationM != defaults.baseElevationM)
        args.insert(args.end(), {"--base-elevation", argNumber(a.params.baseElevationM)});
    if (a.verticalScale) args.insert(args.end(), {"--vertical-scale", argNumber(*a.verticalScale)});
    if (a.verticalOffsetM) args.insert(args.end(), {"--vertical-offset", argNumber(*a.verticalOffsetM)});
    if (!a.pngDir.empty()) args.insert(args.end(), {"--png", a.pngDir});
    return args;
}

TerrainResult convertTerrainStage(const TerrainConvertOptions& a, Reporter& reporter) {
    requireOutputsNotInputs({{"OUT", a.out}}, {a.in});
    const std::string inExt = fileExtension(a.in), outExt = fileExtension(a.out);
    const bool inImage = isTerrainImageExtension(inExt), outImage = isTerrainImageExtension(outExt);
    if (!isTerrainOutput(outExt))
        throw ValidationError(a.out + ": unknown terrain format '" + outExt + "'; supported: " +
                              supportedTerrainExtensions());
    const bool verticalGiven = a.verticalScale || a.verticalOffsetM;
    if (verticalGiven && !inImage && !outImage)
        throw ValidationError("--vertical-scale / --vertical-offset describe image encodings, but neither " + a.in +
                              " nor " + a.out + " is an image");
    // The vertical encoding describes whichever side is an image (both when both are).
    TerrainReadOptions ro;
    if (a.cellSizeM) ro.cellSizeM = *a.cellSizeM;
    if (inImage) {
        if (a.verticalScale) ro.verticalScale = *a.verticalScale;
        if (a.verticalOffsetM) ro.verticalOffsetM = *a.verticalOffsetM;
    }
    TerrainResult result;
    result.terrain = readTerrain(a.in, ro);
    const Grid<float>& terrain = result.terrain;
    std::ostream& out = reporter.out();
    // A georeferenced input (a GeoTIFF, or our HDF5 of one, which keeps its CRS) written as
    // .tif stays a GeoTIFF in metres with its geotransform and CRS (a vertical encoding asked
    // for gives the plain image, as before).
    if (writesGeoTiff(outExt, terrain, a.in, verticalGiven)) {
        writeGeoTiff(a.out, terrain, "m");
        result.written.push_back(a.out);
        out << "wrote terrain: " << a.out << " (GeoTIFF" << (terrain.crsWkt().empty() ? "" : ", the input's CRS") << "; "
            << describe(terrain, "m") << ")\n";
        return result;
    }
    TerrainWriteOptions enc;
    if (outImage) enc = chooseEncoding(a.out, terrain, a.verticalScale, a.verticalOffsetM, reporter);
    writeTerrain(a.out, terrain, enc);
    result.written.push_back(a.out);
    out << "wrote terrain: " << a.out << " (" << describe(terrain, "m") << ")\n";
    const std::string hint = readBackHint(a.out, terrain, enc);
    if (!hint.empty()) out << hint << "\n";
    warnCrsDropped(a.out, terrain, reporter);
    return result;
}

ChmResult generateChmStage(const ChmGenerateOptions& a, Reporter& reporter) {
    requireOutputsNotInputs({{"--out", a.out}}, {a.terrain, a.sketchImage});
    const std::string outExt = fileExtension(a.out);
    if (!isTerrainOutput(outExt))
        throw ValidationError(a.out + ": unknown output format '" + outExt + "'; supported: " +
                              supportedTerrainExtensions());
    TerrainReadOptions ro;
    if (a.terrainRead.cellSizeM) ro.cellSizeM = *a.terrainRead.cellSizeM;
    if (isTerrainImageExtension(fileExtension(a.terrain))) {
        const TerrainReadOptions given = a.terrainRead.options();
        ro.verticalScale = given.verticalScale;
        ro.verticalOffsetM = given.verticalOffsetM;
    }
    const Grid<float> terrain = readTerrain(a.terrain, ro);
    const Grid<std::int32_t> sketch = a.sketchImage.empty() ? generateDensitySketch(terrain, a.sketch)
                                                            : readDensitySketch(a.sketchImage, terrain);
    std::vector<GeneratedTree> trees;
    ChmResult result;
    result.chm = generateChm(sketch, a.chm, trees);
    result.trees = trees.size();
    const Grid<float>& chm = result.chm;

    std::ostream& out = reporter.out();
    AtomicOutputSet outputs;  // the CHM, its sketch and pictures together
    if (outExt == ".h5" || outExt == ".hdf5") {
        writeChmH5(a.out, chm, sketch, trees, a);
        result.written.push_back(a.out);
        out << "wrote CHM: " << a.out << " (/chm/height, /chm/sketch, /chm/trees; " << describe(chm, "m above ground")
            << ", " << trees.size() << " trees)\n";
    } else {
        if (writesGeoTiff(outExt, chm, a.terrain, false)) {
            // A georeferenced terrain gives a GeoTIFF CHM on its cells, as eco terrain convert
            // does: a plain TIFF had no cell size or origin, and eco canopy refused it.
            writeGeoTiff(a.out, chm, "m");
            result.written.push_back(a.out);
            out << "wrote CHM: " << a.out << " (GeoTIFF" << (chm.crsWkt().empty() ? "" : ", the terrain's CRS") << "; "
                << describe(chm, "m above ground") << ", " << trees.size() << " trees)\n";
        } else {
            TerrainWriteOptions wo;
            if (outExt == ".png") wo.verticalScale = niceScaleAbove(std::max<double>(chm.maxValue(), a.chm.maxHeightM));
            writeTerrain(a.out, chm, wo);
            result.written.push_back(a.out);
            out << "wrote CHM: " << a.out << " (" << describe(chm, "m above ground") << ", " << trees.size() << " trees)\n";
            const std::string hint = readBackHint(a.out, chm, wo);
            if (!hint.empty()) out << hint << "\n";
            warnCrsDropped(a.out, chm, reporter);
        }
        const std::string sketchPath = withoutExtension(a.out) + "_sketch.png";
        writeDensitySketch(sketchPath, sketch);
        result.written.push_back(sketchPath);
        out << "wrote density sketch: " << sketchPath << " (black empty, grey sparse, white dense)\n";
    }
    if (!a.pngDir.empty()) {
        prepareOutputDirectory(a.pngDir);
        const std::string chmPng = (std::filesystem::path(a.pngDir) / "chm.png").string();
        const std::string sketchPng = (std::filesystem::path(a.pngDir) / "sketch.png").string();
        writeMapPng(chmPng, chm, "Canopy height model (generated)", "m above ground", Colormap::Viridis, 0.0,
                    std::max<double>(chm.maxValue(), 1.0));
        writeCategoryPng(sketchPng, sketch, "Density sketch", {"empty", "sparse", "dense"});
        result.written.insert(result.written.end(), {chmPng, sketchPng});
        out << "wrote picture: " << chmPng << "\n" << "wrote picture: " << sketchPng << "\n";
    }
    outputs.commit();
    return result;
}

std::vector<std::string> commandLine(const ChmGenerateOptions& a) {
    const SketchParams sketchDefaults;
    const ChmGenParams chmDefaults;
    std::vector<std::string> args = {"chm", "generate", "--terrain", a.terrain, "--out", a.out,
                                     "--seed", std::to_string(a.chm.seed)};
    if (!a.pngDir.empty()) args.insert(args.end(), {"--png", a.pngDir});
    a.terrainRead.appendArgs(args);
    if (!a.sketchImage.empty()) args.insert(args.end(), {"--sketch", a.sketchImage});
    if (a.sketchSeedGiven) args.insert(args.end(), {"--sketch-seed", std::to_string(a.sketch.seed)});
    if (a.sketch.emptyFraction != sketchDefaults.emptyFraction)
        args.insert(args.end(), {"--empty-fraction", argNumber(a.sketch.emptyFraction)});
    if (a.sketch.denseFraction != sketchDefaults.denseFraction)
        args.insert(args.end(), {"--dense-fraction", argNumber(a.sketch.denseFraction)});
    if (a.chm.denseSpacingM != chmDefaults.denseSpacingM)
        args.insert(args.end(), {"--dense-spacing", argNumber(a.chm.denseSpacingM)});
    if (a.chm.sparseSpacingM != chmDefaults.sparseSpacingM)
        args.insert(args.end(), {"--sparse-spacing", argNumber(a.chm.sparseSpacingM)});
    if (a.chm.minHeightM != chmDefaults.minHeightM) args.insert(args.end(), {"--min-height", argNumber(a.chm.minHeightM)});
    if (a.chm.maxHeightM != chmDefaults.maxHeightM) args.insert(args.end(), {"--max-height", argNumber(a.chm.maxHeightM)});
    return args;
}

}  // namespace eco::pipeline
