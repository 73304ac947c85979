// Georeferenced rasters through GDAL (geo_raster.h).
#include "geo_raster.h"

#include <gdal_priv.h>
#include <ogrsf_frmts.h>
#include <ogr_spatialref.h>
#include <cpl_error.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <optional>
#include <type_traits>
#include <limits>
#include <memory>
#include <mutex>
#include <utility>
#include <vector>

#include "atomic_file.h"
#include "error.h"
#include "h5io.h"
#include "memory.h"

namespace eco {

namespace {

void registerGdal() {
    static std::once_flag once;
    std::call_once(once, [] { GDALAllRegister(); });
}

/// GDAL's messages go to our exceptions, not to stderr: quiet while a call runs.
struct QuietGdal {
    QuietGdal() {
        CPLPushErrorHandler(CPLQuietErrorHandler);
        CPLErrorReset();
    }
    ~QuietGdal() { CPLPopErrorHandler(); }
    QuietGdal(const QuietGdal&) = delete;
    QuietGdal& operator=(const QuietGdal&) = delete;
};

std::string lastGdalError() {
    const char* m = CPLGetLastErrorMsg();
    return m != nullptr && *m != '\0' ? std::string(": ") + m : std::string();
}

struct DatasetCloser {
    void operator()(GDALDataset* d) const { GDALClose(GDALDataset::ToHandle(d)); }
};
using Dataset = std::unique_ptr<GDALDataset, DatasetCloser>;

Dataset openRaster(const std::string& path) {
    registerGdal();
    return Dataset(GDALDataset::Open(path.c_str(), GDAL_OF_RASTER | GDAL_OF_READONLY));
}

}  // namespace

bool hasGeotransform(const std::string& path) {
    QuietGdal quiet;
    const Dataset ds = openRaster(path);
    if (!ds) return false;
    double gt[6];
    return ds->GetGeoTransform(gt) == CE_None;
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
    QuietGdal quiet;
    registerGdal();
    GDALDriver* drv = GetGDALDriverManager()->GetDriverByName("GTiff");
    if (drv == nullptr) throw IoError(path + ": GDAL has no GeoTIFF driver");
    OGRSpatialReference srs;
    if (!g.crsWkt().empty() && srs.importFromWkt(g.crsWkt().c_str()) != OGRERR_NONE)
        throw ValidationError(path + ": the grid's CRS is not valid WKT");
    AtomicOutput out(path);
    const int w = g.width(), h = g.height();
    char compress[] = "COMPRESS=DEFLATE";
    char interleave[] = "INTERLEAVE=BAND";
    char* options[] = {compress, interleave, nullptr};
    const GDALDataType type = kFloat ? GDT_Float32 : GDT_Int32;
    {
        const Dataset ds(drv->Create(out.tempPath().c_str(), w, h, static_cast<int>(bands.size()), type, options));
        if (!ds) throw IoError(path + ": cannot create the GeoTIFF" + lastGdalError());
        double gt[6] = {g.originX(), g.cellSizeM(), 0.0, g.originY() + h * g.cellSizeM(), 0.0, -g.cellSizeM()};
        ds->SetGeoTransform(gt);
        if (!g.crsWkt().empty()) ds->SetSpatialRef(&srs);
        constexpr float kNodata = -3.4e38f;
        std::vector<T> rows(static_cast<std::size_t>(w) * static_cast<std::size_t>(h));
        for (std::size_t b = 0; b < bands.size(); ++b) {
            GDALRasterBand* band = ds->GetRasterBand(static_cast<int>(b) + 1);
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
            if (anyNan) band->SetNoDataValue(kNodata);
            if (!kFloat && intNodata) band->SetNoDataValue(*intNodata);
            if (b < descriptions.size()) band->SetDescription(descriptions[b].c_str());
            if (!units.empty()) band->SetUnitType(units.c_str());
            if (band->RasterIO(GF_Write, 0, 0, w, h, rows.data(), w, h, type, 0, 0) != CE_None)
                throw IoError(path + ": cannot write the GeoTIFF's cells" + lastGdalError());
        }
    }  // closed (flushed) before the commit
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
    QuietGdal quiet;
    registerGdal();
    GDALDriver* drv = GetGDALDriverManager()->GetDriverByName("GPKG");
    if (drv == nullptr) throw IoError(path + ": GDAL has no GeoPackage driver");
    OGRSpatialReference srs;
    if (!crsWkt.empty() && srs.importFromWkt(crsWkt.c_str()) != OGRERR_NONE)
        throw ValidationError(path + ": the CRS to write is not valid WKT");
    AtomicOutput out(path);
    {
        const Dataset ds(drv->Create(out.tempPath().c_str(), 0, 0, 0, GDT_Unknown, nullptr));
        if (!ds) throw IoError(path + ": cannot create the GeoPackage" + lastGdalError());
        OGRLayer* layer = ds->CreateLayer("plants", crsWkt.empty() ? nullptr : &srs, wkbPoint, nullptr);
        if (layer == nullptr) throw IoError(path + ": cannot create its layer" + lastGdalError());
        const std::pair<const char*, OGRFieldType> fields[] = {{"layer", OFTString},      {"species", OFTString},
                                                               {"species_id", OFTInteger}, {"height_m", OFTReal},
                                                               {"crown_radius_m", OFTReal}, {"ground_z_m", OFTReal}};
        for (const auto& [name, type] : fields) {
            OGRFieldDefn def(name, type);
            if (layer->CreateField(&def) != OGRERR_NONE) throw IoError(path + ": cannot create field " + name + lastGdalError());
        }
        if (ds->StartTransaction() != OGRERR_NONE) throw IoError(path + ": cannot start writing" + lastGdalError());
        for (const PlantLayer& l : layers) {
            if (l.plants == nullptr) continue;
            for (const Plant& p : *l.plants) {
                OGRFeature* f = OGRFeature::CreateFeature(layer->GetLayerDefn());
                f->SetField(0, l.name.c_str());
                const bool known = p.speciesId >= 0 && static_cast<std::size_t>(p.speciesId) < biome.species.size();
                f->SetField(1, known ? biome.species[static_cast<std::size_t>(p.speciesId)].name.c_str() : "");
                f->SetField(2, p.speciesId);
                f->SetField(3, p.heightM);
                f->SetField(4, p.crownRadiusM);
                f->SetField(5, p.groundZM);
                OGRPoint pt(p.xM, p.yM);
                f->SetGeometry(&pt);
                const OGRErr e = layer->CreateFeature(f);
                OGRFeature::DestroyFeature(f);
                if (e != OGRERR_NONE) throw IoError(path + ": cannot write a plant" + lastGdalError());
            }
        }
        if (ds->CommitTransaction() != OGRERR_NONE) throw IoError(path + ": cannot finish writing" + lastGdalError());
    }
    out.commit();
}

std::string rasterCrsWkt(const std::string& path) {
    QuietGdal quiet;
    const Dataset ds = openRaster(path);
    if (!ds) return "";
    const OGRSpatialReference* srs = ds->GetSpatialRef();
    if (srs == nullptr) return "";
    char* wkt = nullptr;
    std::string out;
    if (srs->exportToWkt(&wkt) == OGRERR_NONE && wkt != nullptr) out = wkt;
    CPLFree(wkt);
    return out;
}

bool sameCrs(const std::string& wktA, const std::string& wktB) {
    if (wktA.empty() || wktB.empty()) return wktA.empty() && wktB.empty();
    OGRSpatialReference a, b;
    if (a.importFromWkt(wktA.c_str()) != OGRERR_NONE || b.importFromWkt(wktB.c_str()) != OGRERR_NONE) return wktA == wktB;
    return a.IsSame(&b) != 0;
}

std::string sharedCrs(const std::string& wktA, const std::string& whatA, const std::string& wktB, const std::string& whatB) {
    if (wktA.empty() || wktB.empty() || sameCrs(wktA, wktB)) return wktA.empty() ? wktB : wktA;
    auto name = [](const std::string& wkt) {
        OGRSpatialReference s;
        if (s.importFromWkt(wkt.c_str()) == OGRERR_NONE && s.GetName() != nullptr) return std::string(s.GetName());
        return std::string("unnamed CRS");
    };
    throw ValidationError(whatA + " is in " + name(wktA) + " but " + whatB + " is in " + name(wktB) +
                          ": the two must share one CRS; reproject one onto the other's grid, e.g. gdalwarp -t_srs <CRS of " + whatA +
                          "> -tr <cell size> -te <extent> " + whatB + " OUT.tif");
}

void requireSameCrs(const std::string& pathA, const std::string& pathB) {
    sharedCrs(rasterCrsWkt(pathA), pathA, rasterCrsWkt(pathB), pathB);
}

GeoRaster readGeoRaster(const std::string& path) {
    QuietGdal quiet;
    const Dataset ds = openRaster(path);
    if (!ds) throw IoError(path + ": cannot read as a raster (missing, unreadable or not a format GDAL reads)" + lastGdalError());
    GeoRaster out;
    out.driver = ds->GetDriver() != nullptr ? ds->GetDriver()->GetDescription() : "";
    const int w = ds->GetRasterXSize(), h = ds->GetRasterYSize();
    if (w <= 0 || h <= 0 || ds->GetRasterCount() < 1) throw IoError(path + ": the raster has no cells or no band");
    // Cells as double, the nodata mask and the grid: about 13 bytes a cell.
    requireMemory(13.0 * w * h, path + ": a raster of " + std::to_string(w) + " x " + std::to_string(h) + " cells",
                  "crop or resample it first, e.g. gdal_translate -srcwin / gdalwarp -tr");
    double gt[6];
    if (ds->GetGeoTransform(gt) != CE_None)
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
    if (const OGRSpatialReference* srs = ds->GetSpatialRef()) {
        char* wkt = nullptr;
        if (srs->exportToWkt(&wkt) == OGRERR_NONE && wkt != nullptr) out.crsWkt = wkt;
        CPLFree(wkt);
        if (const char* name = srs->GetName()) out.crsName = name;
        if (srs->IsGeographic())
            throw ValidationError(path + ": the raster is in a geographic CRS (" + out.crsName +
                                  ", cells in degrees); reproject it to a projected CRS in metres, e.g. gdalwarp -t_srs "
                                  "EPSG:<UTM zone> IN OUT");
        if (srs->IsProjected()) {
            const double toMetres = srs->GetLinearUnits();
            if (std::abs(toMetres - 1.0) > 1e-9)
                throw ValidationError(path + ": the CRS's unit is not the metre (1 unit = " + formatNumber(toMetres, 10) +
                                      " m); reproject it to a CRS in metres with gdalwarp -t_srs");
        }
    }
    // After the CRS (a geographic raster's cells in degrees get that message instead).
    if (!cellSizeInRange(cw))
        throw ValidationError(path + ": cell size " + formatNumber(cw) + " in the geotransform " + cellSizeRangeText());
    GDALRasterBand* band = ds->GetRasterBand(1);
    std::vector<double> px(static_cast<std::size_t>(w) * static_cast<std::size_t>(h));
    if (band->RasterIO(GF_Read, 0, 0, w, h, px.data(), w, h, GDT_Float64, 0, 0) != CE_None)
        throw IoError(path + ": cannot read the raster's cells (corrupt or truncated file?)" + lastGdalError());
    // Nodata: the band's mask (nodata value, alpha or an explicit mask); 0 = nodata.
    std::vector<std::uint8_t> valid;
    if ((band->GetMaskFlags() & GMF_ALL_VALID) == 0) {
        valid.resize(px.size());
        if (band->GetMaskBand()->RasterIO(GF_Read, 0, 0, w, h, valid.data(), w, h, GDT_Byte, 0, 0) != CE_None)
            throw IoError(path + ": cannot read the raster's nodata mask" + lastGdalError());
    }
    int hasScale = 0, hasOffset = 0;
    double scale = band->GetScale(&hasScale), offset = band->GetOffset(&hasOffset);
    if (!hasScale) scale = 1;
    if (!hasOffset) offset = 0;
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
