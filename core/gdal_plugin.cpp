// The GDAL plugin (eco_gdal.so; gdal_plugin.h): every call eco makes to GDAL and OGR. Built
// as a module that links GDAL, loaded by geo_raster.cpp on first use.
#include <cpl_error.h>
#include <gdal_priv.h>
#include <ogr_spatialref.h>
#include <ogrsf_frmts.h>

#include <cmath>
#include <memory>
#include <mutex>
#include <utility>
#include <vector>

#include "gdal_plugin.h"

namespace {

using eco::plugin::GdalStep;

void registerGdal() {
    static std::once_flag once;
    std::call_once(once, [] { GDALAllRegister(); });
}

/// GDAL's messages go to the caller's exceptions, not to stderr: quiet while a call runs.
struct QuietGdal {
    QuietGdal() {
        CPLPushErrorHandler(CPLQuietErrorHandler);
        CPLErrorReset();
    }
    ~QuietGdal() { CPLPopErrorHandler(); }
    QuietGdal(const QuietGdal&) = delete;
    QuietGdal& operator=(const QuietGdal&) = delete;
};

std::string lastError() {
    const char* m = CPLGetLastErrorMsg();
    return m != nullptr ? std::string(m) : std::string();
}

struct DatasetCloser {
    void operator()(GDALDataset* d) const { GDALClose(GDALDataset::ToHandle(d)); }
};
using Dataset = std::unique_ptr<GDALDataset, DatasetCloser>;

Dataset openRaster(const std::string& path) {
    registerGdal();
    return Dataset(GDALDataset::Open(path.c_str(), GDAL_OF_RASTER | GDAL_OF_READONLY));
}

class Plugin final : public eco::plugin::GdalPlugin {
public:
    bool inspect(const std::string& path, eco::plugin::RasterInfo& info, std::string& error) override {
        QuietGdal quiet;
        const Dataset ds = openRaster(path);
        if (!ds) {
            error = lastError();
            return false;
        }
        info.driver = ds->GetDriver() != nullptr ? ds->GetDriver()->GetDescription() : "";
        info.width = ds->GetRasterXSize();
        info.height = ds->GetRasterYSize();
        info.bands = ds->GetRasterCount();
        info.hasGeotransform = ds->GetGeoTransform(info.geotransform) == CE_None;
        if (const OGRSpatialReference* srs = ds->GetSpatialRef()) {
            info.hasCrs = true;
            char* wkt = nullptr;
            if (srs->exportToWkt(&wkt) == OGRERR_NONE && wkt != nullptr) info.crsWkt = wkt;
            CPLFree(wkt);
            if (const char* name = srs->GetName()) info.crsName = name;
            info.geographic = srs->IsGeographic() != 0;
            info.projected = srs->IsProjected() != 0;
            if (info.projected) info.linearUnits = srs->GetLinearUnits();
        }
        return true;
    }

    GdalStep readBand1(const std::string& path, eco::plugin::RasterCells& cells, std::string& error) override {
        QuietGdal quiet;
        const Dataset ds = openRaster(path);
        if (!ds || ds->GetRasterCount() < 1) {
            error = lastError();
            return GdalStep::Create;
        }
        const int w = ds->GetRasterXSize(), h = ds->GetRasterYSize();
        GDALRasterBand* band = ds->GetRasterBand(1);
        cells.values.assign(static_cast<std::size_t>(w) * static_cast<std::size_t>(h), 0.0);
        if (band->RasterIO(GF_Read, 0, 0, w, h, cells.values.data(), w, h, GDT_Float64, 0, 0) != CE_None) {
            error = lastError();
            return GdalStep::Cells;
        }
        // Nodata: the band's mask (nodata value, alpha or an explicit mask); 0 = nodata.
        cells.valid.clear();
        if ((band->GetMaskFlags() & GMF_ALL_VALID) == 0) {
            cells.valid.resize(cells.values.size());
            if (band->GetMaskBand()->RasterIO(GF_Read, 0, 0, w, h, cells.valid.data(), w, h, GDT_Byte, 0, 0) != CE_None) {
                error = lastError();
                return GdalStep::Mask;
            }
        }
        int hasScale = 0, hasOffset = 0;
        cells.scale = band->GetScale(&hasScale);
        cells.offset = band->GetOffset(&hasOffset);
        if (!hasScale) cells.scale = 1;
        if (!hasOffset) cells.offset = 0;
        return GdalStep::Done;
    }

    GdalStep writeGeoTiff(const std::string& path, const eco::plugin::GeoTiffSpec& spec,
                          const std::vector<eco::plugin::GeoTiffBand>& bands, const eco::plugin::GeoTiffFill& fill,
                          std::string& error) override {
        QuietGdal quiet;
        registerGdal();
        GDALDriver* drv = GetGDALDriverManager()->GetDriverByName("GTiff");
        if (drv == nullptr) return GdalStep::NoDriver;
        OGRSpatialReference srs;
        if (!spec.crsWkt.empty() && srs.importFromWkt(spec.crsWkt.c_str()) != OGRERR_NONE) return GdalStep::BadCrs;
        const int w = spec.width, h = spec.height;
        char compress[] = "COMPRESS=DEFLATE";
        char interleave[] = "INTERLEAVE=BAND";
        char* options[] = {compress, interleave, nullptr};
        const GDALDataType type = spec.isFloat ? GDT_Float32 : GDT_Int32;
        const Dataset ds(drv->Create(path.c_str(), w, h, static_cast<int>(bands.size()), type, options));
        if (!ds) {
            error = lastError();
            return GdalStep::Create;
        }
        double gt[6];
        for (int i = 0; i < 6; ++i) gt[i] = spec.geotransform[i];
        ds->SetGeoTransform(gt);
        if (!spec.crsWkt.empty()) ds->SetSpatialRef(&srs);
        // 4-byte cells either way (Float32 or Int32).
        std::vector<std::int32_t> rows(static_cast<std::size_t>(w) * static_cast<std::size_t>(h));
        for (std::size_t b = 0; b < bands.size(); ++b) {
            GDALRasterBand* band = ds->GetRasterBand(static_cast<int>(b) + 1);
            const bool holdsNodata = fill(b, rows.data());
            if (holdsNodata || bands[b].hasNodata) band->SetNoDataValue(bands[b].nodata);
            if (!bands[b].description.empty()) band->SetDescription(bands[b].description.c_str());
            if (!spec.units.empty()) band->SetUnitType(spec.units.c_str());
            if (band->RasterIO(GF_Write, 0, 0, w, h, rows.data(), w, h, type, 0, 0) != CE_None) {
                error = lastError();
                return GdalStep::Cells;
            }
        }
        return GdalStep::Done;  // closed (flushed) as `ds` goes
    }

    GdalStep writeGpkg(const std::string& path, const std::string& crsWkt, const eco::plugin::GpkgNext& next,
                       std::string& field, std::string& error) override {
        QuietGdal quiet;
        registerGdal();
        GDALDriver* drv = GetGDALDriverManager()->GetDriverByName("GPKG");
        if (drv == nullptr) return GdalStep::NoDriver;
        OGRSpatialReference srs;
        if (!crsWkt.empty() && srs.importFromWkt(crsWkt.c_str()) != OGRERR_NONE) return GdalStep::BadCrs;
        const Dataset ds(drv->Create(path.c_str(), 0, 0, 0, GDT_Unknown, nullptr));
        const auto fail = [&](GdalStep step) {
            error = lastError();
            return step;
        };
        if (!ds) return fail(GdalStep::Create);
        OGRLayer* layer = ds->CreateLayer("plants", crsWkt.empty() ? nullptr : &srs, wkbPoint, nullptr);
        if (layer == nullptr) return fail(GdalStep::Layer);
        const std::pair<const char*, OGRFieldType> fields[] = {{"layer", OFTString},      {"species", OFTString},
                                                               {"species_id", OFTInteger}, {"height_m", OFTReal},
                                                               {"crown_radius_m", OFTReal}, {"ground_z_m", OFTReal}};
        for (const auto& [name, type] : fields) {
            OGRFieldDefn def(name, type);
            if (layer->CreateField(&def) != OGRERR_NONE) {
                field = name;
                return fail(GdalStep::Field);
            }
        }
        if (ds->StartTransaction() != OGRERR_NONE) return fail(GdalStep::Start);
        for (eco::plugin::GpkgPlant p; next(p);) {
            OGRFeature* f = OGRFeature::CreateFeature(layer->GetLayerDefn());
            f->SetField(0, p.layer);
            f->SetField(1, p.species);
            f->SetField(2, p.speciesId);
            f->SetField(3, p.height);
            f->SetField(4, p.crownRadius);
            f->SetField(5, p.groundZ);
            OGRPoint pt(p.x, p.y);
            f->SetGeometry(&pt);
            const OGRErr e = layer->CreateFeature(f);
            OGRFeature::DestroyFeature(f);
            if (e != OGRERR_NONE) return fail(GdalStep::Feature);
        }
        if (ds->CommitTransaction() != OGRERR_NONE) return fail(GdalStep::Commit);
        return GdalStep::Done;
    }

    bool validCrs(const std::string& wkt) override {
        OGRSpatialReference s;
        return s.importFromWkt(wkt.c_str()) == OGRERR_NONE;
    }

    std::string crsName(const std::string& wkt) override {
        OGRSpatialReference s;
        if (s.importFromWkt(wkt.c_str()) == OGRERR_NONE && s.GetName() != nullptr) return s.GetName();
        return "";
    }

    int sameCrs(const std::string& wktA, const std::string& wktB) override {
        OGRSpatialReference a, b;
        if (a.importFromWkt(wktA.c_str()) != OGRERR_NONE || b.importFromWkt(wktB.c_str()) != OGRERR_NONE) return -1;
        return a.IsSame(&b) != 0 ? 1 : 0;
    }

    bool geographicOf(const std::string& wkt, double x, double y, double& latDeg, double& lonDeg) override {
        OGRSpatialReference src;
        if (src.importFromWkt(wkt.c_str()) != OGRERR_NONE) return false;
        src.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
        OGRSpatialReference* geo = src.CloneGeogCS();
        if (geo == nullptr) return false;
        geo->SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);  // x = longitude, y = latitude
        OGRCoordinateTransformation* t = OGRCreateCoordinateTransformation(&src, geo);
        bool ok = false;
        if (t != nullptr) {
            double px = x, py = y;
            ok = t->Transform(1, &px, &py) != 0 && std::isfinite(px) && std::isfinite(py);
            if (ok) {
                lonDeg = px;
                latDeg = py;
            }
            OGRCoordinateTransformation::DestroyCT(t);
        }
        OGRSpatialReference::DestroySpatialReference(geo);
        return ok;
    }
};

}  // namespace

extern "C" __attribute__((visibility("default"))) eco::plugin::GdalPlugin* eco_gdal_plugin(int abi) {
    static Plugin plugin;
    return abi == eco::plugin::kGdalPluginAbi ? &plugin : nullptr;
}
