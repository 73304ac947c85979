#include "terrain_io.h"


#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstdint>
#include <fstream>
#include <limits>
#include <map>
#include <sstream>
#include <vector>

#include "atomic_file.h"
#include "eco_version.h"
#include "provenance.h"
#include "error.h"
#include "h5io.h"
#include "geo_raster.h"
#include "image_codec.h"
#include "image_in.h"
#include "memory.h"
#include "text_format.h"

namespace eco {

namespace {

constexpr const char* kTerrainDataset = "/terrain/elevation";
constexpr const char* kChmDataset = "/chm/height";

std::string lower(std::string s) {
    std::transform(s.begin(), s.end(), s.begin(),
                   [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
    return s;
}

/// Shortest text that reads back to exactly the same double.
std::string exactText(double v) {
    char buf[64];
    const auto res = std::to_chars(buf, buf + sizeof buf, v);
    return std::string(buf, res.ptr);
}

std::string numberText(double v) { return formatNumber(v); }

void requireReadable(const std::string& path) {
    std::FILE* f = std::fopen(path.c_str(), "rb");
    if (!f) throw IoError(path + ": cannot open file (missing or unreadable)");
    std::fclose(f);
}

/// Throws IoError naming the first NaN / infinite cell (in the file's order: images and
/// ASCII grids store the northern row first), at its position of cellText.
void requireFinite(const Grid<float>& g, const std::string& path, bool fileRowsNorthFirst) {
    const int w = g.width(), h = g.height();
    for (int fileRow = 0; fileRow < h; ++fileRow) {
        const int iy = fileRowsNorthFirst ? h - 1 - fileRow : fileRow;
        for (int ix = 0; ix < w; ++ix) {
            const float v = g(ix, iy);
            if (std::isfinite(v)) continue;
            const std::string what = std::isnan(v) ? "NaN" : "infinite";
            throw IoError(path + ": " + what + " elevation at " + cellText(g, ix, iy) + "; fill gaps before use");
        }
    }
}

void requireFiniteForWrite(const Grid<float>& g, const std::string& path) {
    for (int iy = 0; iy < g.height(); ++iy)
        for (int ix = 0; ix < g.width(); ++ix)
            if (!std::isfinite(g(ix, iy)))
                throw ValidationError(path + ": cannot write a non-finite value (cell ix=" +
                                      std::to_string(ix) + ", iy=" + std::to_string(iy) + ")");
}

void requireNonEmpty(const Grid<float>& g, const std::string& path) {
    if (g.empty()) throw ValidationError(path + ": cannot write an empty grid");
}

void checkReadOptions(const std::string& path, const TerrainReadOptions& o) {
    if (!(o.cellSizeM >= 0) || !std::isfinite(o.cellSizeM))
        throw ValidationError(path + ": cell size (--cell-size) must be positive, got " +
                              numberText(o.cellSizeM));
    if (!(o.verticalScale > 0) || !std::isfinite(o.verticalScale))
        throw ValidationError(path + ": vertical scale (--vertical-scale) must be positive, got " +
                              numberText(o.verticalScale));
    if (!std::isfinite(o.verticalOffsetM) || !std::isfinite(o.originX) || !std::isfinite(o.originY))
        throw ValidationError(path + ": vertical offset and origin must be finite");
}

/// .asc and .h5 store metres: a vertical scale or offset would silently change them.
void requireMetricFormat(const std::string& path, const TerrainReadOptions& o, const char* format) {
    if (o.verticalScale != 1.0 || o.verticalOffsetM != 0.0)
        throw ValidationError(path + ": --vertical-scale / --vertical-offset apply to image terrains "
                              "only; " + format + " files store metres");
}

void checkCellSize(const std::string& path, double fileCellM, const TerrainReadOptions& o) {
    if (o.cellSizeM > 0 && std::abs(o.cellSizeM - fileCellM) > 1e-6 * std::max(1.0, fileCellM))
        throw ValidationError(path + ": wrong cell size: the file says " + numberText(fileCellM) +
                              " m but --cell-size gives " + numberText(o.cellSizeM) +
                              " m (leave --cell-size out for this file)");
}

void checkWriteOptions(const std::string& path, const TerrainWriteOptions& o) {
    if (!(o.verticalScale > 0) || !std::isfinite(o.verticalScale))
        throw ValidationError(path + ": vertical scale (--vertical-scale) must be positive, got " +
                              numberText(o.verticalScale));
    if (!std::isfinite(o.verticalOffsetM))
        throw ValidationError(path + ": vertical offset (--vertical-offset) must be finite");
}

std::string readWholeFile(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    if (!in) throw IoError(path + ": cannot open file (missing or unreadable)");
    noteInputFile(path);  // recorded in /provenance with its hash
    std::ostringstream ss;
    ss << in.rdbuf();
    if (in.bad()) throw IoError(path + ": read error");
    return ss.str();
}

/// Whitespace-separated tokens of a text buffer, one at a time.
class Tokenizer {
public:
    explicit Tokenizer(const std::string& text) : p_(text.data()), end_(text.data() + text.size()) {}
    /// Next token, or false at the end.
    bool next(const char*& begin, const char*& end) {
        while (p_ < end_ && std::isspace(static_cast<unsigned char>(*p_))) {
            if (*p_ == '\n') ++line_;
            ++p_;
        }
        if (p_ >= end_) return false;
        begin = p_;
        while (p_ < end_ && !std::isspace(static_cast<unsigned char>(*p_))) ++p_;
        end = p_;
        return true;
    }
    int line() const { return line_; }

private:
    const char* p_;
    const char* end_;
    int line_ = 1;
};

template <typename T>
bool parseNumber(const char* b, const char* e, T& out) {
    if (b < e && *b == '+') ++b;
    const auto res = std::from_chars(b, e, out);
    return res.ec == std::errc() && res.ptr == e;
}

SampleType storageFor(const std::string& ext) { return ext == ".png" ? SampleType::UInt16 : SampleType::Float; }

/// OIIO format name for an extension: the temporary file's name has no usable extension.
std::string oiioFormat(const std::string& ext) {
    if (ext == ".png") return "png";
    if (ext == ".tif" || ext == ".tiff") return "tiff";
    return "openexr";
}

}  // namespace

std::string fileExtension(const std::string& path) {
    const auto slash = path.find_last_of('/');
    const auto dot = path.find_last_of('.');
    if (dot == std::string::npos || (slash != std::string::npos && dot < slash)) return "";
    return lower(path.substr(dot));
}

bool isTerrainImageExtension(const std::string& ext) {
    return ext == ".png" || ext == ".tif" || ext == ".tiff" || ext == ".exr";
}

std::string supportedTerrainExtensions() {
    return "'.asc' (ESRI ASCII grid), '.tif', '.tiff' (GeoTIFF, or a plain image), '.img', '.vrt' (through GDAL), "
           "'.png', '.exr' (images), '.h5', '.hdf5' (eco HDF5)";
}

namespace {

bool isGdalOnlyExtension(const std::string& ext) { return ext == ".img" || ext == ".vrt"; }

/// A georeferenced raster as a height grid: geometry from the file (a cell size given must
/// agree), the vertical options applied; nodata cells stay NaN.
Grid<float> readGeoHeights(const std::string& path, const TerrainReadOptions& options, std::int64_t& nodataCells) {
    checkReadOptions(path, options);
    GeoRaster r = readGeoRaster(path);
    checkCellSize(path, r.grid.cellSizeM(), options);
    nodataCells = r.nodataCells;
    if (options.verticalScale != 1 || options.verticalOffsetM != 0)
        for (float& v : r.grid.data()) v = static_cast<float>(v * options.verticalScale + options.verticalOffsetM);
    return std::move(r.grid);
}

}  // namespace

// ---------------------------------------------------------------------------- ESRI ASCII

namespace {

/// readAsc; with allowNodata, NODATA_value cells become NaN and are counted.
Grid<float> readAscImpl(const std::string& path, const TerrainReadOptions& options, bool allowNodata,
                        std::int64_t& nodataCells) {
    checkReadOptions(path, options);
    requireMetricFormat(path, options, "ESRI ASCII (.asc)");
    const std::string text = readWholeFile(path);
    Tokenizer tok(text);

    static const char* const kKeys[] = {"ncols", "nrows", "xllcorner", "xllcenter", "yllcorner",
                                        "yllcenter", "cellsize", "nodata_value"};
    std::map<std::string, double> header;
    const char* b = nullptr;
    const char* e = nullptr;
    bool haveToken = tok.next(b, e);
    while (haveToken) {
        const std::string key = lower(std::string(b, e));
        if (std::find(std::begin(kKeys), std::end(kKeys), key) == std::end(kKeys)) break;
        const int keyLine = tok.line();
        if (header.count(key)) throw IoError(path + ": header key '" + key + "' appears twice");
        if (!tok.next(b, e) || tok.line() != keyLine)
            throw IoError(path + ": header key '" + key + "' (line " + std::to_string(keyLine) +
                          ") has no value");
        double v = 0;
        if (!parseNumber(b, e, v) || !std::isfinite(v))
            throw IoError(path + ": header key '" + key + "' has non-numeric value '" + std::string(b, e) + "'");
        header[key] = v;
        haveToken = tok.next(b, e);
    }

    auto require = [&](const char* key) {
        if (!header.count(key))
            throw IoError(path + ": ESRI ASCII header is missing '" + std::string(key) + "'");
        return header.at(key);
    };
    auto requireEither = [&](const char* corner, const char* centre) -> std::pair<double, bool> {
        if (header.count(corner) && header.count(centre))
            throw IoError(path + ": ESRI ASCII header has both '" + std::string(corner) + "' and '" +
                          centre + "'");
        if (header.count(corner)) return {header.at(corner), false};
        if (header.count(centre)) return {header.at(centre), true};
        throw IoError(path + ": ESRI ASCII header is missing '" + std::string(corner) + "' (or '" +
                      centre + "')");
    };
    const double ncolsD = require("ncols");
    const double nrowsD = require("nrows");
    const double cell = require("cellsize");
    const auto [xll, xIsCentre] = requireEither("xllcorner", "xllcenter");
    const auto [yll, yIsCentre] = requireEither("yllcorner", "yllcenter");
    for (const auto& [key, v] : {std::pair<const char*, double>{"ncols", ncolsD}, {"nrows", nrowsD}}) {
        if (v < 1 || v != std::floor(v))
            throw IoError(path + ": " + key + " must be a positive whole number, got " + numberText(v));
        if (v > 1e7) throw IoError(path + ": " + key + " = " + numberText(v) + " is larger than eco reads (at most 10000000 a side)");
    }
    requireMemory(8.0 * ncolsD * nrowsD, path + ": a grid of " + formatNumber(ncolsD, 10) + " x " + formatNumber(nrowsD, 10) + " cells",
                  "crop or resample it first, e.g. gdal_translate -srcwin / gdalwarp -tr");
    if (!cellSizeInRange(cell)) throw IoError(path + ": cellsize " + numberText(cell) + " " + cellSizeRangeText());
    checkCellSize(path, cell, options);

    const int ncols = static_cast<int>(ncolsD), nrows = static_cast<int>(nrowsD);
    const double originX = xIsCentre ? xll - 0.5 * cell : xll;
    const double originY = yIsCentre ? yll - 0.5 * cell : yll;
    const bool hasNodata = header.count("nodata_value") > 0;
    const float nodata = hasNodata ? static_cast<float>(header.at("nodata_value")) : 0.f;

    Grid<float> g(ncols, nrows, cell, originX, originY);
    const std::size_t expected = static_cast<std::size_t>(ncols) * static_cast<std::size_t>(nrows);
    std::size_t count = 0;
    for (; haveToken; haveToken = tok.next(b, e), ++count) {
        if (count >= expected) continue;  // counted, reported below
        const int col = static_cast<int>(count % static_cast<std::size_t>(ncols));
        const int fileRow = static_cast<int>(count / static_cast<std::size_t>(ncols));
        float v = 0;
        if (!parseNumber(b, e, v))
            throw IoError(path + ": line " + std::to_string(tok.line()) + ": value '" + std::string(b, e) +
                          "' at column " + std::to_string(col + 1) + ", row " + std::to_string(fileRow + 1) +
                          " is not a number (or is out of range)");
        if (hasNodata && v == nodata) {
            if (!allowNodata)
                throw IoError(path + ": NODATA value " + numberText(header.at("nodata_value")) + " at " +
                              cellText(g, col, nrows - 1 - fileRow) + ": the terrain must have no gaps; fill them before use");
            v = std::numeric_limits<float>::quiet_NaN();
            ++nodataCells;
        } else if (!std::isfinite(v)) {
            throw IoError(path + ": " + (std::isnan(v) ? "NaN" : "infinite") + " elevation at " +
                          cellText(g, col, nrows - 1 - fileRow) + "; fill gaps before use");
        }
        g(col, nrows - 1 - fileRow) = v;
    }
    if (count != expected)
        throw IoError(path + ": the header says " + std::to_string(ncols) + " x " + std::to_string(nrows) +
                      " = " + std::to_string(expected) + " values but the file has " + std::to_string(count));
    return g;
}

}  // namespace

Grid<float> readAsc(const std::string& path, const TerrainReadOptions& options) {
    std::int64_t nodata = 0;
    return readAscImpl(path, options, false, nodata);
}

void writeAsc(const std::string& path, const Grid<float>& g) {
    requireNonEmpty(g, path);
    requireFiniteForWrite(g, path);
    AtomicOutput out(path);
    std::string text;
    text.reserve(g.size() * 10 + 200);
    text += "ncols " + std::to_string(g.width()) + "\n";
    text += "nrows " + std::to_string(g.height()) + "\n";
    text += "xllcorner " + exactText(g.originX()) + "\n";
    text += "yllcorner " + exactText(g.originY()) + "\n";
    text += "cellsize " + exactText(g.cellSizeM()) + "\n";
    char buf[32];
    for (int iy = g.height() - 1; iy >= 0; --iy) {  // first row written = northern edge
        for (int ix = 0; ix < g.width(); ++ix) {
            // Shortest text that parses back to the same float: the round trip is exact.
            const auto res = std::to_chars(buf, buf + sizeof buf, g(ix, iy));
            if (ix) text += ' ';
            text.append(buf, res.ptr);
        }
        text += '\n';
    }
    std::FILE* f = std::fopen(out.tempPath().c_str(), "wb");
    if (!f) throw IoError(path + ": cannot create file");
    const bool ok = std::fwrite(text.data(), 1, text.size(), f) == text.size();
    const bool closed = std::fclose(f) == 0;
    if (!ok || !closed) throw IoError(path + ": write failed (disk full?)");
    out.commit();
}

// ---------------------------------------------------------------------------- images

Grid<float> readTerrainImage(const std::string& path, const TerrainReadOptions& options) {
    checkReadOptions(path, options);
    requireReadable(path);
    if (!(options.cellSizeM > 0))
        throw ValidationError(path + ": an image terrain has no cell size: give it with --cell-size (metres per pixel)");
    // Channel 0 only. The pixels as float, then the grid: 8 bytes a cell (the header alone
    // can claim any size).
    const ImagePixels image = readImagePixels(path, "image", 1, [&](int w, int h, int) {
        requireMemory(8.0 * w * h, path + ": an image of " + std::to_string(w) + " x " + std::to_string(h) + " pixels",
                      "crop or resample it first");
    });
    const int w = image.width, h = image.height;
    const std::vector<float>& px = image.values;
    Grid<float> g(w, h, options.cellSizeM, options.originX, options.originY);
    for (int row = 0; row < h; ++row) {  // image row 0 = northern edge
        const int iy = h - 1 - row;
        for (int ix = 0; ix < w; ++ix) {
            const double v = px[static_cast<std::size_t>(row) * w + ix];
            g(ix, iy) = static_cast<float>(v * options.verticalScale + options.verticalOffsetM);
        }
    }
    requireFinite(g, path, true);
    return g;
}

void writeTerrainImage(const std::string& path, const Grid<float>& g, const TerrainWriteOptions& options) {
    const std::string ext = fileExtension(path);
    if (!isTerrainImageExtension(ext))
        throw IoError(path + ": not an image extension; supported: " + supportedTerrainExtensions());
    checkWriteOptions(path, options);
    requireNonEmpty(g, path);
    requireFiniteForWrite(g, path);
    const int w = g.width(), h = g.height();
    const auto base = storageFor(ext);
    ImageWriteSpec spec;
    spec.format = oiioFormat(ext);
    spec.width = w;
    spec.height = h;
    spec.channels = 1;
    spec.stored = base;
    spec.attributes.emplace_back("ImageDescription",
                   "eco terrain: cell_size_m=" + exactText(g.cellSizeM()) + " origin_x_m=" +
                       exactText(g.originX()) + " origin_y_m=" + exactText(g.originY()) +
                       " z_m = value * " + exactText(options.verticalScale) + " + " +
                       exactText(options.verticalOffsetM) + "; row 0 = north");
    if (ext != ".png") spec.attributes.emplace_back("compression", "zip");
    // OpenImageIO stamps TIFF and EXR files with the current time unless DateTime is given:
    // an empty one keeps the same terrain giving the same bytes.
    spec.attributes.emplace_back("DateTime", "");

    std::vector<float> f32;
    std::vector<std::uint16_t> u16;
    if (base == SampleType::UInt16) u16.resize(g.size());
    else f32.resize(g.size());
    for (int row = 0; row < h; ++row) {
        const int iy = h - 1 - row;
        for (int ix = 0; ix < w; ++ix) {
            const double v = (static_cast<double>(g(ix, iy)) - options.verticalOffsetM) / options.verticalScale;
            const std::size_t k = static_cast<std::size_t>(row) * w + ix;
            if (base == SampleType::UInt16)
                u16[k] = static_cast<std::uint16_t>(std::lround(std::clamp(v, 0.0, 1.0) * 65535.0));
            else
                f32[k] = static_cast<float>(v);
        }
    }

    AtomicOutput out(path);
    // The temporary file's name ends in ".tmp<pid>", so name the format explicitly.
    const ImageWriteResult r = base == SampleType::UInt16 ? writeImageFile(out.tempPath(), spec, base, u16.data())
                                                          : writeImageFile(out.tempPath(), spec, base, f32.data());
    using Step = ImageWriteResult::Step;
    if (r.step == Step::Create) throw IoError(path + ": cannot create image writer: " + r.reason);
    if (r.step == Step::Open) throw IoError(path + ": cannot create image: " + r.reason);
    if (r.step == Step::Write) throw IoError(path + ": cannot write image: " + r.reason);
    if (r.step == Step::Close) throw IoError(path + ": cannot finish image: " + r.reason);
    out.commit();
}

// ---------------------------------------------------------------------------- HDF5

Grid<float> readTerrainH5(const std::string& path, const TerrainReadOptions& options) {
    checkReadOptions(path, options);
    requireMetricFormat(path, options, "HDF5");
    const h5::File f = h5::File::openRead(path);
    std::string dataset;
    if (f.exists(kTerrainDataset)) dataset = kTerrainDataset;
    else if (f.exists(kChmDataset)) dataset = kChmDataset;
    else
        throw IoError(path + ": no height raster found: looked for " + std::string(kTerrainDataset) +
                      " (terrain) and " + kChmDataset + " (canopy height model)");
    Grid<float> g = f.readGrid(dataset);
    checkCellSize(path, g.cellSizeM(), options);
    requireFinite(g, path + ": " + dataset, false);
    return g;
}

void writeTerrainH5(const std::string& path, const Grid<float>& g) {
    requireNonEmpty(g, path);
    requireFiniteForWrite(g, path);
    AtomicOutput out(path);
    {
        h5::File f = h5::File::create(out.tempPath());
        f.writeGrid(kTerrainDataset, g, "m");
        f.setAttr(kTerrainDataset, "description",
                  std::string("ground elevation (digital elevation model), metres"));
        // The root attributes every file of ours carries (docs/hdf5.md); readers of a
        // terrain take any file with /terrain/elevation, so older files stay readable.
        f.setAttr("/", "format", std::string("eco-terrain"));
        f.setAttr("/", "schema_version", std::int64_t{1});
        f.setAttr("/", "code_version", std::string(ECO_VERSION_STRING));
        writeProvenance(f, {});  // what identifies the run: nothing measured
    }  // closed before the rename
    out.commit();
}

// ---------------------------------------------------------------------------- dispatch

Grid<float> readTerrain(const std::string& path, const TerrainReadOptions& options) {
    noteInputFile(path);  // any format (GeoTIFF through GDAL too): recorded in /provenance with its hash
    const std::string ext = fileExtension(path);
    const bool known = ext == ".asc" || ext == ".h5" || ext == ".hdf5" || isTerrainImageExtension(ext) || isGdalOnlyExtension(ext);
    if (!known)
        throw IoError(path + ": unknown terrain format '" + ext + "'; supported: " + supportedTerrainExtensions());
    requireReadable(path);
    if (ext == ".asc") return readAsc(path, options);
    if (ext == ".h5" || ext == ".hdf5") return readTerrainH5(path, options);
    if (isGdalOnlyExtension(ext) || ((ext == ".tif" || ext == ".tiff") && hasGeotransform(path))) {
        std::int64_t nodata = 0;
        Grid<float> g = readGeoHeights(path, options, nodata);
        if (nodata > 0)
            for (int iy = 0; iy < g.height(); ++iy)
                for (int ix = 0; ix < g.width(); ++ix)
                    if (std::isnan(g(ix, iy)))
                        throw IoError(path + ": " + std::to_string(nodata) + " nodata cell(s), the first at " + cellText(g, ix, iy) +
                                      ": a terrain must have no gaps; fill them first (gdal_fillnodata.py IN OUT)");
        return g;
    }
    return readTerrainImage(path, options);
}

ChmGapRule parseChmGapRule(const std::string& text, const std::string& what) {
    if (text == "fill") return ChmGapRule::Fill;
    if (text == "zero") return ChmGapRule::Zero;
    if (text == "fail") return ChmGapRule::Fail;
    throw ValidationError(what + ": unknown gap rule '" + text + "'; use fill, zero or fail");
}

std::string ChmRead::summary(const std::string& path) const {
    std::string s;
    if (nodataCells > 0)
        s += path + ": " + std::to_string(nodataCells) + " nodata cell(s): " + std::to_string(filledCells) +
             " filled from their neighbours, " + std::to_string(zeroedCells) + " set to 0 m (non-forest)";
    if (negativeCells > 0)
        s += (s.empty() ? "" : "\n") + path + ": " + std::to_string(negativeCells) + " cell(s) below 0 m (lowest " +
             formatNumber(mostNegativeM) + " m) clamped to 0";
    return s;
}

ChmRead readChm(const std::string& path, const ChmReadOptions& options) {
    if (!(options.fillMaxM >= 0) || !std::isfinite(options.fillMaxM))
        throw ValidationError(path + ": the gap-fill distance must be >= 0 m, got " + formatNumber(options.fillMaxM));
    const std::string ext = fileExtension(path);
    ChmRead out;
    requireReadable(path);
    if (ext == ".asc")
        out.chm = readAscImpl(path, options.raster, true, out.nodataCells);
    else if (isGdalOnlyExtension(ext) || ((ext == ".tif" || ext == ".tiff") && hasGeotransform(path)))
        out.chm = readGeoHeights(path, options.raster, out.nodataCells);
    else
        out.chm = readTerrain(path, options.raster);
    Grid<float>& g = out.chm;
    const int w = g.width(), h = g.height();
    // A CHM with no data at all is the wrong file, band or nodata value, not a treeless
    // landscape: "filled" with 0 m it would give a canopy of no trees and exit 0.
    if (out.nodataCells > 0 && static_cast<double>(out.nodataCells) >= static_cast<double>(w) * h)
        throw IoError(path + ": every cell (" + std::to_string(out.nodataCells) +
                      ") is nodata: the canopy height model holds no height; check its nodata value and band "
                      "(gdalinfo -stats), or give a CHM with data");
    if (out.nodataCells > 0) {
        if (options.gaps == ChmGapRule::Fail)
            for (int iy = 0; iy < h; ++iy)
                for (int ix = 0; ix < w; ++ix)
                    if (std::isnan(g(ix, iy)))
                        throw IoError(path + ": " + std::to_string(out.nodataCells) + " nodata cell(s) in the canopy height model, the first at " +
                                      cellText(g, ix, iy) + "; fill them, or choose a gap rule (fill or zero)");
        // Fill: ring by ring from the data, each gap cell the mean of its 8 neighbours that
        // had a value before the ring (so the result does not depend on the scan order).
        const int rings = options.gaps == ChmGapRule::Fill ? static_cast<int>(std::ceil(options.fillMaxM / g.cellSizeM() - 1e-9)) : 0;
        for (int ring = 0; ring < rings; ++ring) {
            const Grid<float> before = g;
            bool any = false;
            for (int iy = 0; iy < h; ++iy)
                for (int ix = 0; ix < w; ++ix) {
                    if (!std::isnan(before(ix, iy))) continue;
                    double sum = 0;
                    int n = 0;
                    for (int dy = -1; dy <= 1; ++dy)
                        for (int dx = -1; dx <= 1; ++dx) {
                            const int x = ix + dx, y = iy + dy;
                            if ((dx == 0 && dy == 0) || x < 0 || y < 0 || x >= w || y >= h || std::isnan(before(x, y))) continue;
                            sum += before(x, y);
                            ++n;
                        }
                    if (n == 0) continue;
                    g(ix, iy) = static_cast<float>(sum / n);
                    ++out.filledCells;
                    any = true;
                }
            if (!any) break;
        }
        for (float& v : g.data())
            if (std::isnan(v)) {
                v = 0.0f;
                ++out.zeroedCells;
            }
    }
    for (float& v : g.data())
        if (v < 0) {
            out.mostNegativeM = std::min(out.mostNegativeM, static_cast<double>(v));
            v = 0.0f;
            ++out.negativeCells;
        }
    return out;
}

void writeTerrain(const std::string& path, const Grid<float>& terrain, const TerrainWriteOptions& options) {
    const std::string ext = fileExtension(path);
    if (ext == ".asc") return writeAsc(path, terrain);
    if (ext == ".h5" || ext == ".hdf5") return writeTerrainH5(path, terrain);
    if (isTerrainImageExtension(ext)) return writeTerrainImage(path, terrain, options);
    throw IoError(path + ": unknown terrain format '" + ext + "'; supported: " + supportedTerrainExtensions());
}

}  // namespace eco
