// Reading and writing terrains (digital elevation models) and other single-band height
// rasters such as canopy height models.
//
// Formats, chosen by the file extension (case-insensitive):
//   .asc           ESRI ASCII grid. Geometry (cell size, lower-left corner) from the header;
//                  the first data row is the NORTHERN edge and is flipped into our
//                  south-first rows (grid.h). Values are metres.
//   .png           16-bit (or 8-bit) grey; first channel. Stored value v in [0, 1] means
//                  z = v * verticalScale + verticalOffsetM. Image row 0 is the north edge.
//   .tif / .tiff   as PNG for integer pixels; float pixels are used as stored (v), then
//   .exr           z = v * verticalScale + verticalOffsetM.
//   .img / .vrt    through GDAL (geo_raster.h): geometry from the geotransform, in metres.
//   .tif / .tiff   with a geotransform (GeoTIFF): through GDAL as .img; without one, as above.
//   .h5 / .hdf5    our own: dataset /terrain/elevation (Grid layout of h5io.h, units "m");
//                  a canopy height file (/chm/height) is read when there is no terrain.
//
// Plain images carry no georeferencing we trust, so reading one needs cellSizeM (> 0) and
// takes its lower-left corner from originX/originY; a georeferenced raster takes both from
// its geotransform (a cellSizeM given must agree). A terrain must have no nodata cells. Every reader rejects NaN or infinite values
// and names the file and the first offending cell. Every writer is atomic (AtomicOutput).
#pragma once

#include <cstdint>
#include <string>

#include "grid.h"

namespace eco {

/// How to interpret a terrain file. Vertical scale and offset describe image encodings;
/// for .asc and .h5 (which store metres) they must be left at 1 and 0.
struct TerrainReadOptions {
    double cellSizeM = 0;        ///< metres per cell; required for images, checked against .asc/.h5 when > 0
    double verticalScale = 1;    ///< metres per stored unit (images)
    double verticalOffsetM = 0;  ///< metres added after scaling (images)
    double originX = 0, originY = 0;  ///< lower-left corner for images (metres)
};

/// Read a terrain (metres), dispatching on the extension. Throws IoError (unreadable,
/// corrupt, non-finite value, unknown extension) or ValidationError (bad options).
Grid<float> readTerrain(const std::string& path, const TerrainReadOptions& options = {});

/// What becomes of the nodata cells of a canopy height model (lidar CHMs have gaps: no
/// returns over water, at the survey's edge, in shadows).
enum class ChmGapRule {
    Fill,  ///< cells within fillMaxM of data take the mean of their data neighbours, grown ring by ring; the rest 0
    Zero,  ///< every nodata cell is 0 (non-forest)
    Fail,  ///< a nodata cell is an error
};
struct ChmReadOptions {
    TerrainReadOptions raster;       ///< as for a terrain
    ChmGapRule gaps = ChmGapRule::Fill;
    double fillMaxM = 2.0;           ///< Fill: how far from data a gap is filled (m); farther cells are 0
};
/// A canopy height model as read, with what was repaired.
struct ChmRead {
    Grid<float> chm;                 ///< metres above ground, >= 0, no gaps
    std::int64_t nodataCells = 0;    ///< cells the file marks as nodata
    std::int64_t filledCells = 0;    ///< of those: filled from their neighbours
    std::int64_t zeroedCells = 0;    ///< of those: set to 0 (non-forest)
    std::int64_t negativeCells = 0;  ///< cells below 0 m, clamped to 0
    double mostNegativeM = 0;        ///< the lowest of them
    /// One line per repair ("CHM.tif: 120 nodata cells: 100 filled ..., 20 set to 0"), empty if none.
    std::string summary(const std::string& path) const;
};
/// Read a canopy height model (any terrain format; nodata only from georeferenced rasters
/// and .asc NODATA_value cells), apply the gap rule and clamp negative heights to 0.
ChmRead readChm(const std::string& path, const ChmReadOptions& options = {});
/// Parses "fill", "zero" or "fail" (ValidationError naming `what` otherwise).
ChmGapRule parseChmGapRule(const std::string& text, const std::string& what);

/// How to encode heights into images: stored = (z - verticalOffsetM) / verticalScale.
/// PNG stores it as 16-bit clamped to [0, 1]; TIFF and EXR as float32.
struct TerrainWriteOptions {
    double verticalScale = 1;    ///< metres per stored unit (images); > 0
    double verticalOffsetM = 0;  ///< metres subtracted before scaling (images)
};

/// Write a terrain (metres), dispatching on the extension; atomic. Vertical options are
/// ignored by the .asc and .h5 writers, which store metres.
void writeTerrain(const std::string& path, const Grid<float>& terrain,
                  const TerrainWriteOptions& options = {});

/// ESRI ASCII grid (see above). options.cellSizeM, when > 0, must agree with the header.
Grid<float> readAsc(const std::string& path, const TerrainReadOptions& options = {});
/// ESRI ASCII grid with xllcorner/yllcorner and shortest round-trip float text (exact).
void writeAsc(const std::string& path, const Grid<float>& terrain);

/// PNG / TIFF / EXR through OpenImageIO; first channel; cellSizeM required.
Grid<float> readTerrainImage(const std::string& path, const TerrainReadOptions& options);
/// PNG as 16-bit grey, TIFF / EXR as float32 grey.
void writeTerrainImage(const std::string& path, const Grid<float>& terrain,
                       const TerrainWriteOptions& options = {});

/// HDF5: /terrain/elevation, or else /chm/height; options.cellSizeM, when > 0, must agree.
Grid<float> readTerrainH5(const std::string& path, const TerrainReadOptions& options = {});
/// HDF5 with /terrain/elevation (units "m").
void writeTerrainH5(const std::string& path, const Grid<float>& terrain);

/// Lower-case extension of a path including the dot (".asc"), or "" when there is none.
std::string fileExtension(const std::string& path);
/// True for the extensions readTerrainImage / writeTerrainImage handle.
bool isTerrainImageExtension(const std::string& extension);
/// "'.asc', '.png', ..." for error messages.
std::string supportedTerrainExtensions();

}  // namespace eco
