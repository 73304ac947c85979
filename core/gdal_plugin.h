// The interface between core (geo_raster.cpp) and the GDAL plugin (gdal_plugin.cpp, built as
// eco_gdal.so; plugin.h): GDAL and the hundred shared libraries it links are loaded only by
// the commands that read or write georeferenced files. Plain data only; every check and
// message stays in geo_raster.cpp. Both sides come from one build; kGdalPluginAbi changes
// whenever this header does.
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

namespace eco::plugin {

constexpr int kGdalPluginAbi = 2;  // 2: geographicOf

/// What a raster file says about itself (nothing read from its cells).
struct RasterInfo {
    std::string driver;            ///< GDAL's short name of the format, e.g. "GTiff"
    int width = 0, height = 0, bands = 0;
    bool hasGeotransform = false;
    double geotransform[6] = {0, 1, 0, 0, 0, 1};
    bool hasCrs = false;
    std::string crsWkt, crsName;   ///< "" when none
    bool geographic = false, projected = false;
    double linearUnits = 1;        ///< metres per unit of a projected CRS
};

/// Band 1's cells as double (rows as in the file), its nodata mask (0 = nodata; empty when
/// every cell is valid) and its scale and offset (1 and 0 when the file has none).
struct RasterCells {
    std::vector<double> values;
    std::vector<std::uint8_t> valid;
    double scale = 1, offset = 0;
};

/// One band of a GeoTIFF to write: its description and nodata value, declared when
/// `hasNodata` or when the band's cells hold some (the fill function says so).
struct GeoTiffBand {
    std::string description;       ///< "" for none
    bool hasNodata = false;
    double nodata = 0;
};
/// Fills band `b`'s rows, north first (float or int32 as the file's type, width x height
/// values); true when it wrote nodata cells.
using GeoTiffFill = std::function<bool(std::size_t b, void* rows)>;
struct GeoTiffSpec {
    int width = 0, height = 0;
    bool isFloat = true;           ///< Float32, else Int32
    double geotransform[6] = {0, 1, 0, 0, 0, -1};
    std::string crsWkt;            ///< "" for none
    std::string units;             ///< every band's unit type; "" for none
};

/// One plant of a GeoPackage point layer.
struct GpkgPlant {
    const char* layer = "";
    const char* species = "";      ///< "" when unknown
    std::int32_t speciesId = -1;
    double x = 0, y = 0, height = 0, crownRadius = 0, groundZ = 0;
};
/// The next plant into its argument; false after the last.
using GpkgNext = std::function<bool(GpkgPlant&)>;

/// Which step of a write failed (the GDAL message in the plugin's error string).
enum class GdalStep { Done, NoDriver, BadCrs, Create, Layer, Field, Start, Feature, Commit, Cells, Mask };

class GdalPlugin {
public:
    virtual ~GdalPlugin() = default;
    /// False when GDAL cannot open `path` as a raster (`error`: GDAL's last message, may be "").
    virtual bool inspect(const std::string& path, RasterInfo& info, std::string& error) = 0;
    /// Band 1 of `path`: Create (cannot open), Cells (the cells) or Mask (the nodata mask) on failure.
    virtual GdalStep readBand1(const std::string& path, RasterCells& cells, std::string& error) = 0;
    virtual GdalStep writeGeoTiff(const std::string& path, const GeoTiffSpec& spec, const std::vector<GeoTiffBand>& bands,
                                  const GeoTiffFill& fill, std::string& error) = 0;
    /// A point layer "plants" (fields layer, species, species_id, height_m, crown_radius_m,
    /// ground_z_m) in `crsWkt` ("" for none); `field` names the field that could not be made.
    virtual GdalStep writeGpkg(const std::string& path, const std::string& crsWkt, const GpkgNext& next, std::string& field,
                               std::string& error) = 0;
    /// True when the WKT parses.
    virtual bool validCrs(const std::string& wkt) = 0;
    /// The CRS's name; "" when it does not parse or has none.
    virtual std::string crsName(const std::string& wkt) = 0;
    /// 1 same, 0 different, -1 when either does not parse.
    virtual int sameCrs(const std::string& wktA, const std::string& wktB) = 0;
    /// Latitude and longitude (degrees, on the CRS's own datum) of the point (x, y) of a CRS;
    /// false when the WKT does not parse or the point does not transform.
    virtual bool geographicOf(const std::string& wkt, double x, double y, double& latDeg, double& lonDeg) = 0;
};

}  // namespace eco::plugin

/// The plugin's entry point: its one GdalPlugin, or nullptr when `abi` is not kGdalPluginAbi.
extern "C" eco::plugin::GdalPlugin* eco_gdal_plugin(int abi);
