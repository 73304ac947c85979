#include "image_codec.h"

#include "image_plugin.h"
#include "plugin.h"

namespace eco {

namespace {

/// The OpenImageIO plugin, loaded on first use.
plugin::ImagePlugin& images() {
    static plugin::ImagePlugin& instance =
        loadPlugin<plugin::ImagePlugin>("eco_oiio.so", "eco_image_plugin", plugin::kImagePluginAbi);
    return instance;
}

}  // namespace

ImageWriteResult writeImageFile(const std::string& path, const ImageWriteSpec& spec, SampleType given, const void* pixels) {
    return images().write(path, spec, given, pixels);
}

std::unique_ptr<ImageFileReader> openImageFile(const std::string& path, std::string& error) {
    return images().open(path, error);
}

bool renderText(float* rgb, int width, int height, int x, int y, const std::string& text, int sizePx,
                const std::string& font, const float colour[3]) {
    return images().renderText(rgb, width, height, x, y, text, sizePx, font, colour);
}

}  // namespace eco
