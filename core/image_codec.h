// Image files (PNG, TIFF, OpenEXR, ...) through OpenImageIO, which lives in a plugin loaded
// on first use (plugin.h): OpenImageIO pulls about 260 shared libraries (FFmpeg, OpenCV,
// DCMTK, ...) whose loading took 0.3 s of every eco process's start, images or not
// (docs/install.md). These are the only doors to it: readers of pictures (image_in.h) and
// writers of pictures and float images (image_out.h, float_image.h, terrain_io.h,
// generate.h) go through here, and so do the tests that look at pixels.
#pragma once

#include <memory>
#include <string>
#include <utility>
#include <vector>

namespace eco {

/// How a pixel value is stored in memory or in a file.
enum class SampleType { UInt8, UInt16, Float };

/// An image file to write: its format (OpenImageIO's name: "png", "tiff", "openexr"), size,
/// channels and the sample type stored in the file; optional channel names and string
/// attributes of its header (e.g. "ImageDescription", "compression").
struct ImageWriteSpec {
    std::string format;
    int width = 0;
    int height = 0;
    int channels = 1;
    SampleType stored = SampleType::UInt8;
    std::vector<std::string> channelNames;
    std::vector<std::pair<std::string, std::string>> attributes;
};

/// What went wrong when an image was written: the step and the library's reason.
struct ImageWriteResult {
    enum class Step { Done, Create, Open, Write, Close };
    Step step = Step::Done;
    std::string reason;
    bool ok() const { return step == Step::Done; }
};

/// Writes `pixels` (rows from the top, channels interleaved, of type `given`; converted to
/// the stored type) to `path`, whatever its extension, as spec.format. Not atomic: callers
/// write to AtomicOutput's temporary path. The result says which step failed and why; the
/// callers word the error. IoError only when the plugin cannot be loaded.
ImageWriteResult writeImageFile(const std::string& path, const ImageWriteSpec& spec, SampleType given, const void* pixels);

/// An image file opened for reading: its size and channels, then its pixels as float.
class ImageFileReader {
public:
    virtual ~ImageFileReader() = default;
    virtual int width() const = 0;
    virtual int height() const = 0;
    virtual int channels() const = 0;
    /// The sample type stored in the file (UInt8, UInt16 or Float; other integer and half
    /// types are reported as the nearest of these).
    virtual SampleType stored() const = 0;
    /// The first `channels` channels of every pixel as float (rows from the top; unsigned
    /// integers mapped to [0, 1]); false when the file is corrupt or truncated (error()).
    virtual bool readFloat(int channels, float* out) = 0;
    /// The library's reason for the last failure, on one line or several.
    virtual std::string error() = 0;
};

/// Opens an image file for reading, with alpha never premultiplied into the colours;
/// nullptr when the file is not an image the library reads (`error` says why).
std::unique_ptr<ImageFileReader> openImageFile(const std::string& path, std::string& error);

/// Draws `text` into an RGB float buffer (rows from the top) with the baseline's left end at
/// (x, y), in the font `font` (a name fontconfig knows, e.g. "DejaVuSans") at `sizePx`
/// pixels; false when the font is missing.
bool renderText(float* rgb, int width, int height, int x, int y, const std::string& text, int sizePx,
                const std::string& font, const float colour[3]);

}  // namespace eco
