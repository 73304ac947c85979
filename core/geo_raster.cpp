// Georeferenced rasters through GDAL (geo_raster.h).
#include "geo_raster.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <optional>
#include <type_traits>
#include <limits>
#include <utility>
#include <vector>

#include "atomic_file.h"
#include "error.h"
#include "gdal_plugin.h"
#include "h5io.h"
#include "memory.h"
#include "plugin.h"

namespace eco {

namespace {

/// The GDAL plugin, loaded on first use (GDAL links about a hundred shared libraries: loaded
/// at every start they took most of it).
plugin::GdalPlugin& gdal() {
    static plugin::GdalPlugin& instance =
        loadPlugin<plugin::GdalPlugin>("eco_gdal.so", "eco_gdal_plugin", plugin::kGdalPluginAbi);
    return instance;
}

/// GDAL's reason after ": ", or nothing when it gave none.
std::string reason(const std::string& gdalMessage) { return gdalMessage.empty() ? "" : ": " + gdalMessage; }

}  // namespace

bool hasGeotransform(const std::string& path) {
    plugin::RasterInfo info;
    std::string error;
    return gdal().inspect(path, info, error) && info.hasGeotransform;
}

namespace {

/// One GeoTIFF of same-geometry bands (deflate; the first band's geometry and CRS). Float
/// bands write NaN as the declared nodata -3.4e38; integer bands declare `intNodata` when set.
template <typename T>
void writeGeoTiffBands(const std::string& path, const std::vector<const Grid<T>*>& bands,
                       const std::vector<std::string>& descriptions, const std::string& units, std::optional<int> intNodata) {
    constexpr bool kFloat = std::is_floating_point_v<T>;
    if (bands.empty() || bands.front()->empty()) throw ValidationError(path + ": cannot write an empty grid");
    const Grid<T>& g = *bands.front();
    for (const Grid<T>* b : bands)
        if (!b->sameGeometry(g)) throw ValidationError(path + ": the bands differ in geometry");
    plugin::GdalPlugin& plug = gdal();
    if (!g.crsWkt().empty() && !plug.validCrs(g.crsWkt())) throw ValidationError(path + ": the grid's CRS is not valid WKT");
    AtomicOutput out(path);
    const int w = g.width(), h = g.height();
    plugin::GeoTiffSpec spec;
    spec.width = w;
    spec.height = h;
    spec.isFloat = kFloat;
    const double gt[6] = {g.originX(), g.cellSizeM(), 0.0, g.originY() + h * g.cellSizeM(), 0.0, -g.cellSizeM()};
    std::copy(gt, gt + 6, spec.geotransform);
    spec.crsWkt = g.crsWkt();
    spec.units = units;
    constexpr float kNodata = -3.4e38f;
    std::vector<plugin::GeoTiffBand> meta(bands.size());
    for (std::size_t b = 0; b < bands.size(); ++b) {
        if (b < descriptions.size()) meta[b].description = descriptions[b];
        meta[b].hasNodata = !kFloat && intNodata.has_value();
        meta[b].nodata = kFloat ? static_cast<double>(kNodata) : static_cast<double>(intNodata.value_or(0));
    }
    static_assert(sizeof(T) == 4, "GeoTIFF cells are Float32 or Int32");
    const plugin::GeoTiffFill fill = [&](std::size_t b, void* target) {
        T* rows = static_cast<T*>(target);
        bool anyNan = false;
        for (int row = 0; row < h; ++row)
            for (int ix = 0; ix < w; ++ix) {
                T v = (*bands[b])(ix, h - 1 - row);  // the file's first row is the northern edge
                if constexpr (kFloat) {
                    if (std::isnan(v)) {
                        anyNan = true;
                        v = kNodata;
                    }
                }
                rows[static_cast<std::size_t>(row) * static_cast<std::size_t>(w) + static_cast<std::size_t>(ix)] = v;
            }
        return anyNan;
    };
    std::string error;
    switch (plug.writeGeoTiff(out.tempPath(), spec, meta, fill, error)) {
    case plugin::GdalStep::Done: break;
    case plugin::GdalStep::NoDriver: throw IoError(path + ": GDAL has no GeoTIFF driver");
    case plugin::GdalStep::BadCrs: throw ValidationError(path + ": the grid's CRS is not valid WKT");
    case plugin::GdalStep::Create: throw IoError(path + ": cannot create the GeoTIFF" + reason(error));
    default: throw IoError(path + ": cannot write the GeoTIFF's cells" + reason(error));
    }
    out.commit();
}

std::string safeName(std::string s) {
    for (char& c : s)
        if (!std::isalnum(static_cast<unsigned char>(c)) && c != '-') c = '_';
    return s;
}

}  // namespace

void writeGeoTiff(const std::string& path, const Grid<float>& g, const std::string& units) {
    writeGeoTiffBands<float>(path, {&g}, {}, units, std::nullopt);
}

void writeGeoTiff(const std::string& path, const std::vector<Grid<float>>& bands,
                  const std::vector<std::string>& descriptions, const std::string& units) {
    std::vector<const Grid<float>*> ptrs;
    for (const auto& b : bands) ptrs.push_back(&b);
    writeGeoTiffBands<float>(path, ptrs, descriptions, units, std::nullopt);
}

void writeGeoTiff(const std::string& path, const Grid<std::int32_t>& g, const std::string& units, std::optional<int> nodata) {
    writeGeoTiffBands<std::int32_t>(path, {&g}, {}, units, nodata);
}

std::vector<std::string> exportGridsAsGeoTiff(const std::string& h5Path, const std::string& dir, const std::string& prefix) {
    const h5::File f = h5::File::openRead(h5Path);
    std::vector<std::string> grids;  // dataset paths, in the file's (alphabetical) order
    std::vector<std::string> groups{"/"};
    while (!groups.empty()) {
        const std::string g = groups.back();
        groups.pop_back();
        std::vector<std::string> children = f.list(g);
        for (auto it = children.rbegin(); it != children.rend(); ++it) {
            const std::string p = (g == "/" ? "" : g) + "/" + *it;
            if (f.isGroup(p)) groups.push_back(p);
            else if (f.hasAttr(p, "cell_size_m") && f.hasAttr(p, "row_order")) grids.push_back(p);
        }
    }
    std::sort(grids.begin(), grids.end());
    if (grids.empty()) throw ValidationError(h5Path + ": no grid datasets (with cell_size_m and row_order) to export");
    static const char* kMonths[] = {"January", "February", "March",     "April",   "May",      "June",
                                    "July",    "August",   "September", "October", "November", "December"};
    std::vector<std::string> written;
    for (const std::string& name : grids) {
        const std::string out = dir + "/" + prefix + safeName(name.substr(1)) + ".tif";
        const std::string units = f.hasAttr(name, "units") ? f.attrString(name, "units") : "";
        const std::size_t rank = f.shape(name).size();
        if (f.isIntegerDataset(name)) {
            if (rank != 2) throw ValidationError(h5Path + ": " + name + ": integer grids must be 2-D");
            // "-1 none" in the long_name (species and cluster maps; in the units of files
            // written before CF units): -1 is declared nodata.
            const std::string longName = f.hasAttr(name, "long_name") ? f.attrString(name, "long_name") : "";
            const bool minusOneIsNone = (units + " " + longName).find("-1 none") != std::string::npos;
            const std::optional<int> nodata = minusOneIsNone ? std::optional<int>(-1) : std::nullopt;
            writeGeoTiff(out, f.readGridI32(name), units, nodata);
        } else if (rank == 3) {
            const std::vector<Grid<float>> planes = f.readStack(name);
            std::vector<std::string> names;
            for (std::size_t i = 0; i < planes.size(); ++i)
                names.push_back(planes.size() == 12 ? kMonths[i] : "plane " + std::to_string(i));
            writeGeoTiff(out, planes, names, units);
        } else {
            writeGeoTiff(out, f.readGrid(name), units);
        }
        written.push_back(out);
    }
    return written;
}

void writePlantsGpkg(const std::string& path, const std::vector<PlantLayer>& layers, const Biome& biome,
                     const std::string& crsWkt) {
    plugin::GdalPlugin& plug = gdal();
    if (!crsWkt.empty() && !plug.validCrs(crsWkt)) throw ValidationError(path + ": the CRS to write is not valid WKT");
    AtomicOutput out(path);
    std::size_t layer = 0, index = 0;
    const plugin::GpkgNext next = [&](plugin::GpkgPlant& row) {
        while (layer < layers.size() && (layers[layer].plants == nullptr || index >= layers[layer].plants->size())) {
            ++layer;
            index = 0;
        }
        if (layer >= layers.size()) return false;
        const Plant& p = (*layers[layer].plants)[index++];
        row.layer = layers[layer].name.c_str();
        const bool known = p.speciesId >= 0 && static_cast<std::size_t>(p.speciesId) < biome.species.size();
        row.species = known ? biome.species[static_cast<std::size_t>(p.speciesId)].name.c_str() : "";
        row.speciesId = p.speciesId;
        row.height = p.heightM;
        row.crownRadius = p.crownRadiusM;
        row.groundZ = p.groundZM;
        row.x = p.xM;
        row.y = p.yM;
        return true;
    };
    std::string field, error;
    switch (plug.writeGpkg(out.tempPath(), crsWkt, next, field, error)) {
    case plugin::GdalStep::Done: break;
    case plugin::GdalStep::NoDriver: throw IoError(path + ": GDAL has no GeoPackage driver");
    case plugin::GdalStep::BadCrs: throw ValidationError(path + ": the CRS to write is not valid WKT");
    case plugin::GdalStep::Create: throw IoError(path + ": cannot create the GeoPackage" + reason(error));
    case plugin::GdalStep::Layer: throw IoError(path + ": cannot create its layer" + reason(error));
    case plugin::GdalStep::Field: throw IoError(path + ": cannot create field " + field + reason(error));
    case plugin::GdalStep::Start: throw IoError(path + ": cannot start writing" + reason(error));
    case plugin::GdalStep::Feature: throw IoError(path + ": cannot write a plant" + reason(error));
    default: throw IoError(path + ": cannot finish writing" + reason(error));
    }
    out.commit();
}

std::string rasterCrsWkt(const std::string& path) {
    plugin::RasterInfo info;
    std::string error;
    return gdal().inspect(path, info, error) ? info.crsWkt : std::string();
}

bool sameCrs(const std::string& wktA, const std::string& wktB) {
    if (wktA.empty() || wktB.empty()) return wktA.empty() && wktB.empty();
    const int same = gdal().sameCrs(wktA, wktB);
    return same < 0 ? wktA == wktB : same == 1;
}

bool gridCentreLatLon(const Grid<float>& g, double& latDeg, double& lonDeg) {
    if (g.crsWkt().empty()) return false;
    const double x = g.originX() + 0.5 * g.width() * g.cellSizeM(), y = g.originY() + 0.5 * g.height() * g.cellSizeM();
    return gdal().geographicOf(g.crsWkt(), x, y, latDeg, lonDeg);
}

std::string crsDisplayName(const std::string& wkt) {
    if (wkt.empty()) return "";
    const std::string n = gdal().crsName(wkt);
    return n.empty() ? std::string("unnamed CRS") : n;
}

std::string sharedCrs(const std::string& wktA, const std::string& whatA, const std::string& wktB, const std::string& whatB) {
    if (wktA.empty() || wktB.empty() || sameCrs(wktA, wktB)) return wktA.empty() ? wktB : wktA;
    auto name = [](const std::string& wkt) { return crsDisplayName(wkt); };
    throw ValidationError(whatA + " is in " + name(wktA) + " but " + whatB + " is in " + name(wktB) +
                          ": the two must share one CRS; reproject one onto the other's grid, e.g. gdalwarp -t_srs <CRS of " + whatA +
                          "> -tr <cell size> -te <extent> " + whatB + " OUT.tif");
}

void requireSameCrs(const std::string& pathA, const std::string& pathB) {
    sharedCrs(rasterCrsWkt(pathA), pathA, rasterCrsWkt(pathB), pathB);
}

GeoRaster readGeoRaster(const std::string& path) {
    plugin::GdalPlugin& plug = gdal();
    plugin::RasterInfo info;
    std::string error;
    if (!plug.inspect(path, info, error))
        throw IoError(path + ": cannot read as a raster (missing, unreadable or not a format GDAL reads)" + reason(error));
    GeoRaster out;
    out.driver = info.driver;
    const int w = info.width, h = info.height;
    if (w <= 0 || h <= 0 || info.bands < 1) throw IoError(path + ": the raster has no cells or no band");
    // Cells as double, the nodata mask and the grid: about 13 bytes a cell.
    requireMemory(13.0 * w * h, path + ": a raster of " + std::to_string(w) + " x " + std::to_string(h) + " cells",
                  "crop or resample it first, e.g. gdal_translate -srcwin / gdalwarp -tr");
    const double* gt = info.geotransform;
    if (!info.hasGeotransform)
        throw ValidationError(path + ": no georeferencing (geotransform) in the file; give the cell size with --cell-size "
                              "or georeference it (gdal_translate -a_ullr ... -a_srs ...)");
    if (gt[2] != 0.0 || gt[4] != 0.0)
        throw ValidationError(path + ": the raster is rotated (geotransform terms " + formatNumber(gt[2]) + ", " +
                              formatNumber(gt[4]) + "); make it north-up first: gdalwarp IN OUT");
    const double cw = gt[1], chAbs = std::abs(gt[5]);
    if (!(cw > 0) || !(chAbs > 0) || !std::isfinite(cw) || !std::isfinite(chAbs))
        throw ValidationError(path + ": invalid cell size in the geotransform (" + formatNumber(cw) + " x " + formatNumber(gt[5]) + ")");
    if (std::abs(cw - chAbs) > 1e-9 * cw)
        throw ValidationError(path + ": cells are not square (" + formatNumber(cw, 10) + " x " + formatNumber(chAbs, 10) +
                              "); resample them: gdalwarp -tr " + formatNumber(cw, 10) + " " + formatNumber(cw, 10) + " IN OUT");
    if (info.hasCrs) {
        out.crsWkt = info.crsWkt;
        out.crsName = info.crsName;
        if (info.geographic)
            throw ValidationError(path + ": the raster is in a geographic CRS (" + out.crsName +
                                  ", cells in degrees); reproject it to a projected CRS in metres, e.g. gdalwarp -t_srs "
                                  "EPSG:<UTM zone> IN OUT");
        if (info.projected) {
            const double toMetres = info.linearUnits;
            if (std::abs(toMetres - 1.0) > 1e-9)
                throw ValidationError(path + ": the CRS's unit is not the metre (1 unit = " + formatNumber(toMetres, 10) +
                                      " m); reproject it to a CRS in metres with gdalwarp -t_srs");
        }
    }
    // After the CRS (a geographic raster's cells in degrees get that message instead).
    if (!cellSizeInRange(cw))
        throw ValidationError(path + ": cell size " + formatNumber(cw) + " in the geotransform " + cellSizeRangeText());
    plugin::RasterCells cells;
    switch (plug.readBand1(path, cells, error)) {
    case plugin::GdalStep::Done: break;
    case plugin::GdalStep::Mask: throw IoError(path + ": cannot read the raster's nodata mask" + reason(error));
    default: throw IoError(path + ": cannot read the raster's cells (corrupt or truncated file?)" + reason(error));
    }
    const std::vector<double>& px = cells.values;
    const std::vector<std::uint8_t>& valid = cells.valid;
    const double scale = cells.scale, offset = cells.offset;
    const bool northUp = gt[5] < 0;
    const double originY = northUp ? gt[3] + gt[5] * h : gt[3];
    out.grid = Grid<float>(w, h, cw, gt[0], originY);
    out.grid.setCrsWkt(out.crsWkt);
    for (int row = 0; row < h; ++row) {
        const int iy = northUp ? h - 1 - row : row;
        for (int ix = 0; ix < w; ++ix) {
            const std::size_t i = static_cast<std::size_t>(row) * static_cast<std::size_t>(w) + static_cast<std::size_t>(ix);
            if (!valid.empty() && valid[i] == 0) {
                out.grid(ix, iy) = std::numeric_limits<float>::quiet_NaN();
                ++out.nodataCells;
                continue;
            }
            const double v = px[i] * scale + offset;
            if (!std::isfinite(v) || std::abs(v) > 1e30)
                throw IoError(path + ": " + (std::isnan(v) ? "NaN" : "non-finite or huge") + " value " + formatNumber(v) + " at " +
                              cellText(out.grid, ix, iy) + " that the file does not mark as nodata; set its nodata value "
                              "(gdal_edit.py -a_nodata VALUE)");
            out.grid(ix, iy) = static_cast<float>(v);
        }
    }
    return out;
}

}  // namespace eco
