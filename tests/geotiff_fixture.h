// Small GeoTIFFs made in the tests (through GDAL): a projected or geographic CRS, a
// geotransform, a nodata value, scale/offset; rows given north first, as in the file.
#pragma once
#include <gdal_priv.h>
#include <ogr_spatialref.h>

#include <stdexcept>
#include <string>
#include <vector>

namespace eco::test {

struct GeoTiffSpec {
    int width = 4, height = 3;
    std::vector<double> northFirst;       ///< width x height values, the northern row first
    double geotransform[6] = {500000.0, 0.5, 0.0, 4200001.5, 0.0, -0.5};  ///< UTM metres, north-up
    int epsg = 32610;                     ///< WGS 84 / UTM zone 10N; 0 = no CRS
    bool hasNodata = false;
    double nodata = -9999;
    double scale = 1, offset = 0;         ///< band scale/offset (1 / 0: none written)
    GDALDataType type = GDT_Float32;
};

inline void writeGeoTiff(const std::string& path, const GeoTiffSpec& s) {
    GDALAllRegister();
    GDALDriver* drv = GetGDALDriverManager()->GetDriverByName("GTiff");
    if (drv == nullptr) throw std::runtime_error("no GTiff driver");
    GDALDataset* ds = drv->Create(path.c_str(), s.width, s.height, 1, s.type, nullptr);
    if (ds == nullptr) throw std::runtime_error("cannot create " + path);
    double gt[6];
    for (int i = 0; i < 6; ++i) gt[i] = s.geotransform[i];
    ds->SetGeoTransform(gt);
    if (s.epsg != 0) {
        OGRSpatialReference srs;
        srs.importFromEPSG(s.epsg);
        ds->SetSpatialRef(&srs);
    }
    GDALRasterBand* b = ds->GetRasterBand(1);
    if (s.hasNodata) b->SetNoDataValue(s.nodata);
    if (s.scale != 1) b->SetScale(s.scale);
    if (s.offset != 0) b->SetOffset(s.offset);
    std::vector<double> v = s.northFirst;
    v.resize(static_cast<std::size_t>(s.width) * static_cast<std::size_t>(s.height), 0.0);
    if (b->RasterIO(GF_Write, 0, 0, s.width, s.height, v.data(), s.width, s.height, GDT_Float64, 0, 0) != CE_None)
        throw std::runtime_error("cannot write " + path);
    GDALClose(GDALDataset::ToHandle(ds));
}

}  // namespace eco::test
