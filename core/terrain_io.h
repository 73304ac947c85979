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
//   .h5 / .hdf5    our own: dataset /terrain/elevation (Grid layout of h5io.h, units "m");
//                  a canopy height file (/chm/height) is read when there is no terrain.
//
// Images carry no georeferencing we trust, so reading one needs cellSizeM (> 0) and takes
// its lower-left corner from originX/originY. Every reader rejects NaN or infinite values
// and names the file and the first offending cell. Every writer is atomic (AtomicOutput).
#pragma once

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
