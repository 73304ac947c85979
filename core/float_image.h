// Grids as float images for 3D packages (Blender, Houdini, Nuke): 32-bit OpenEXR.
#pragma once

#include <string>

#include "grid.h"

namespace eco {

/// A grid as a 32-bit float OpenEXR image: one channel named `Y`, row 0 = the northern row
/// (north-up, as the PNGs), uncompressed (any reader, or a few lines of numpy, reads it),
/// values as they are (no colour transform). The geometry is in the header as string
/// attributes `eco:cell_size_m`, `eco:origin_x_m`, `eco:origin_y_m` (lower-left corner,
/// world metres), `eco:units` and `eco:description` (docs/export.md). Atomic; IoError naming
/// the path on failure.
void writeFloatExr(const std::string& path, const Grid<float>& g, const std::string& units,
                   const std::string& description);

}  // namespace eco
