// Georeferenced rasters through GDAL (GeoTIFF, ERDAS IMG, VRT and every other format GDAL
// reads): band 1 with its geotransform, coordinate reference system, nodata mask and
// scale/offset. terrain_io.h dispatches georeferenced files here; this header is for the
// callers that need the nodata cells or the CRS (a canopy height model with gaps).
//
// Geometry: the grid's lower-left corner and cell size come from the geotransform, which
// must be north-up (no rotation terms) with square cells in metres: a raster in a
// geographic CRS (degrees), in feet, rotated or with rectangular cells is refused with the
// gdalwarp command that fixes it. Rows are stored south-first (grid.h) whatever the file's
// order.
//
// Cell positions in messages follow one convention everywhere (cellText): column and row
// from the LOWER-LEFT corner, 0-based, and the world x, y of the cell centre.
#pragma once
#include <cmath>
#include <cstdint>
#include <optional>
#include <string>

#include <vector>

#include "biome.h"
#include "error.h"
#include "grid.h"
#include "plants.h"
#include "text_format.h"

namespace eco {

/// One band of a georeferenced raster.
struct GeoRaster {
    Grid<float> grid;               ///< values with the band's scale/offset applied; NaN where nodata
    std::int64_t nodataCells = 0;   ///< cells the band's mask marks as nodata (NaN in grid)
    std::string crsWkt;             ///< the CRS as WKT; empty when the file has none
    std::string crsName;            ///< e.g. "WGS 84 / UTM zone 10N"; empty when none
    std::string driver;             ///< GDAL's short name of the format, e.g. "GTiff"
};

/// True when GDAL opens the file and finds a geotransform in it (false for a plain image,
/// or a file GDAL cannot open).
bool hasGeotransform(const std::string& path);

/// Band 1 of a georeferenced raster. Throws IoError (unreadable, not a raster, corrupt)
/// or ValidationError (no geotransform, rotated, non-square cells, degrees or feet, ...),
/// each naming the file.
GeoRaster readGeoRaster(const std::string& path);

/// Writes a grid as a GeoTIFF (float32, deflate) with its geotransform and its CRS (the
/// grid's crsWkt; none when empty), so that GIS software opens it in place. Atomic
/// (AtomicOutput). NaN cells are written as nodata (-3.4e38, declared). `units` becomes the
/// band's unit type when given.
void writeGeoTiff(const std::string& path, const Grid<float>& grid, const std::string& units = "");
/// Same-geometry planes as the bands of one GeoTIFF (e.g. 12 months), each with a description.
void writeGeoTiff(const std::string& path, const std::vector<Grid<float>>& bands,
                  const std::vector<std::string>& descriptions, const std::string& units = "");
/// An integer grid (species or cluster map) as an Int32 GeoTIFF; `nodata` declared when set.
void writeGeoTiff(const std::string& path, const Grid<std::int32_t>& grid, const std::string& units,
                  std::optional<int> nodata);

/// Every grid dataset of one of our HDF5 files (those with the geometry attributes of
/// h5io.h) as a GeoTIFF in `dir` named prefix + the dataset path ("/chm/height" ->
/// prefix + "chm_height.tif"): monthly stacks as 12 bands named after the months, integer
/// maps as Int32 (-1 declared nodata when the units say "-1 none"), each with the grid's
/// geotransform and CRS. Returns the files written. ValidationError when the file has no grid.
std::vector<std::string> exportGridsAsGeoTiff(const std::string& h5Path, const std::string& dir, const std::string& prefix);

/// Writes plants as a GeoPackage point layer "plants" (GIS software opens it in place):
/// fields layer, species, species_id, height_m, crown_radius_m, ground_z_m; points at (x, y)
/// in the given CRS (WKT; none when empty). Atomic (AtomicOutput).
void writePlantsGpkg(const std::string& path, const std::vector<PlantLayer>& layers, const Biome& biome,
                     const std::string& crsWkt);

/// The CRS (WKT) of a raster file GDAL opens; "" when it has none or is not a GDAL raster
/// (our HDF5 files, plain images). Reads no cells.
std::string rasterCrsWkt(const std::string& path);

/// Latitude and longitude (degrees) of the centre of a grid that carries a CRS (a
/// georeferenced terrain); false when it has none or GDAL cannot transform the point.
bool gridCentreLatLon(const Grid<float>& g, double& latDeg, double& lonDeg);

/// The CRS's name for messages ("WGS 84 / UTM zone 10N"); "unnamed CRS" when it has none
/// that GDAL reads, "" for an empty WKT.
std::string crsDisplayName(const std::string& wkt);

/// True when two CRSs (WKT) are the same coordinate system (GDAL's IsSame, so the same
/// system written two ways matches). Two empty strings are the same; one empty is not.
bool sameCrs(const std::string& wktA, const std::string& wktB);

/// The CRS two inputs share (`whatA`, `whatB` name them in the message): ValidationError when
/// both carry a CRS and the CRSs differ; otherwise the one that has one ("" when neither).
std::string sharedCrs(const std::string& wktA, const std::string& whatA, const std::string& wktB, const std::string& whatB);

/// ValidationError when both rasters carry a CRS and the CRSs differ, naming both files and
/// both CRSs and the gdalwarp command that aligns them. Nothing when either has none.
void requireSameCrs(const std::string& pathA, const std::string& pathB);

/// "column 3, row 7 from the lower left (0-based; x = 512.5 m, y = 1030 m)".
template <typename T>
std::string cellText(const Grid<T>& g, int ix, int iy) {
    return "column " + std::to_string(ix) + ", row " + std::to_string(iy) + " from the lower left (0-based; x = " +
           formatNumber(g.cellCentreX(ix), 10) + " m, y = " + formatNumber(g.cellCentreY(iy), 10) + " m)";
}

/// IoError naming the file, the dataset, the first cell (as cellText) whose value is not
/// finite or lies outside [lo, hi], and that value: grids read back from our own files
/// (abiotics, canopy), which a damaged or edited file could fill with anything.
template <typename T>
void requireGridIn(const Grid<T>& g, double lo, double hi, const std::string& path, const std::string& dataset) {
    for (int iy = 0; iy < g.height(); ++iy)
        for (int ix = 0; ix < g.width(); ++ix) {
            const double v = static_cast<double>(g(ix, iy));
            if (std::isfinite(v) && v >= lo && v <= hi) continue;
            throw IoError(path + ": " + dataset + ": value " + formatNumber(v, 6) + " at " + cellText(g, ix, iy) +
                          " must lie in [" + formatNumber(lo, 6) + ", " + formatNumber(hi, 6) + "]");
        }
}

}  // namespace eco
