// The interface between core (image_codec.cpp) and the OpenImageIO plugin (oiio_plugin.cpp,
// built as eco_oiio.so): one object with virtual functions, made by the plugin's entry
// point. Both sides are compiled from this header in one build (plugin.h), so the C++
// types on it need no stable ABI; kImagePluginAbi changes whenever this header does.
#pragma once

#include <memory>
#include <string>

#include "image_codec.h"

namespace eco::plugin {

constexpr int kImagePluginAbi = 1;

class ImagePlugin {
public:
    virtual ~ImagePlugin() = default;
    virtual ImageWriteResult write(const std::string& path, const ImageWriteSpec& spec, SampleType given,
                                   const void* pixels) = 0;
    virtual std::unique_ptr<ImageFileReader> open(const std::string& path, std::string& error) = 0;
    virtual bool renderText(float* rgb, int width, int height, int x, int y, const std::string& text, int sizePx,
                            const std::string& font, const float colour[3]) = 0;
};

}  // namespace eco::plugin

/// The plugin's entry point: its one ImagePlugin (owned by the plugin, alive until the
/// process ends), or nullptr when `abi` is not the kImagePluginAbi it was built with.
extern "C" eco::plugin::ImagePlugin* eco_image_plugin(int abi);
