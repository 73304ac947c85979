// Reading raster images (PNG, TIFF, EXR, ...) through OpenImageIO (image_codec.h), for terrains, CHMs,
// density sketches and masks: one place that turns the library's failures into one-line
// errors naming the file.
#pragma once

#include <functional>
#include <string>
#include <vector>

#include "image_codec.h"

namespace eco {

/// Pixels of an image as float, rows from the northern (top) edge, channels interleaved.
/// OpenImageIO maps unsigned integer pixels to [0, 1] and leaves floats as stored.
struct ImagePixels {
    int width = 0;
    int height = 0;
    int channels = 0;
    SampleType stored = SampleType::UInt8;  ///< the sample type in the file
    std::vector<float> values;
};

/// Reads the first `maxChannels` channels of the image at `path` (all of them when 0),
/// never premultiplied by an alpha channel. `checkHeader(width, height, channels)` runs
/// before the pixels are allocated (sizes, memory). IoError naming the file and `what`
/// ("image", "density sketch") for a missing, unrecognised, corrupt or truncated file, with
/// the library's reason on the same line; libpng's own lines on stderr ("libpng error:
/// ...") are held back while the file is read.
ImagePixels readImagePixels(const std::string& path, const std::string& what, int maxChannels,
                            const std::function<void(int, int, int)>& checkHeader = {});

}  // namespace eco
