// Georeferenced rasters through GDAL (geo_raster.h).
#include "geo_raster.h"

#include <gdal_priv.h>
#include <ogrsf_frmts.h>
#include <ogr_spatialref.h>
#include <cpl_error.h>

#include <cmath>
#include <limits>
#include <memory>
#include <mutex>
#include <utility>
#include <vector>

#include "atomic_file.h"
#include "error.h"

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

void writeGeoTiff(const std::string& path, const Grid<float>& g, const std::string& crsWkt) {
    if (g.empty()) throw ValidationError(path + ": cannot write an empty grid");
    QuietGdal quiet;
    registerGdal();
    GDALDriver* drv = GetGDALDriverManager()->GetDriverByName("GTiff");
    if (drv == nullptr) throw IoError(path + ": GDAL has no GeoTIFF driver");
    AtomicOutput out(path);
    const int w = g.width(), h = g.height();
    char compress[] = "COMPRESS=DEFLATE";
    char* options[] = {compress, nullptr};
    {
        const Dataset ds(drv->Create(out.tempPath().c_str(), w, h, 1, GDT_Float32, options));
        if (!ds) throw IoError(path + ": cannot create the GeoTIFF" + lastGdalError());
        double gt[6] = {g.originX(), g.cellSizeM(), 0.0, g.originY() + h * g.cellSizeM(), 0.0, -g.cellSizeM()};
        ds->SetGeoTransform(gt);
        if (!crsWkt.empty()) {
            OGRSpatialReference srs;
            if (srs.importFromWkt(crsWkt.c_str()) != OGRERR_NONE) throw ValidationError(path + ": the CRS to write is not valid WKT");
            ds->SetSpatialRef(&srs);
        }
        constexpr float kNodata = -3.4e38f;
        GDALRasterBand* band = ds->GetRasterBand(1);
        std::vector<float> rows(static_cast<std::size_t>(w) * static_cast<std::size_t>(h));
        bool anyNan = false;
        for (int row = 0; row < h; ++row)
            for (int ix = 0; ix < w; ++ix) {
                const float v = g(ix, h - 1 - row);  // the file's first row is the northern edge
                anyNan = anyNan || std::isnan(v);
                rows[static_cast<std::size_t>(row) * static_cast<std::size_t>(w) + static_cast<std::size_t>(ix)] = std::isnan(v) ? kNodata : v;
            }
        if (anyNan) band->SetNoDataValue(kNodata);
        if (band->RasterIO(GF_Write, 0, 0, w, h, rows.data(), w, h, GDT_Float32, 0, 0) != CE_None)
            throw IoError(path + ": cannot write the GeoTIFF's cells" + lastGdalError());
    }  // closed (flushed) before the commit
    out.commit();
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

void requireSameCrs(const std::string& pathA, const std::string& pathB) {
    const std::string a = rasterCrsWkt(pathA), b = rasterCrsWkt(pathB);
    if (a.empty() || b.empty() || sameCrs(a, b)) return;
    auto name = [](const std::string& wkt) {
        OGRSpatialReference s;
        if (s.importFromWkt(wkt.c_str()) == OGRERR_NONE && s.GetName() != nullptr) return std::string(s.GetName());
        return std::string("unnamed CRS");
    };
    throw ValidationError(pathA + " is in " + name(a) + " but " + pathB + " is in " + name(b) +
                          ": the two must share one CRS; reproject one onto the other's grid, e.g. gdalwarp -t_srs <CRS of " + pathA +
                          "> -tr <cell size> -te <extent> " + pathB + " OUT.tif");
}

GeoRaster readGeoRaster(const std::string& path) {
    QuietGdal quiet;
    const Dataset ds = openRaster(path);
    if (!ds) throw IoError(path + ": cannot read as a raster (missing, unreadable or not a format GDAL reads)" + lastGdalError());
    GeoRaster out;
    out.driver = ds->GetDriver() != nullptr ? ds->GetDriver()->GetDescription() : "";
    const int w = ds->GetRasterXSize(), h = ds->GetRasterYSize();
    if (w <= 0 || h <= 0 || ds->GetRasterCount() < 1) throw IoError(path + ": the raster has no cells or no band");
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
