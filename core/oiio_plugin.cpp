// The OpenImageIO plugin (eco_oiio.so; image_plugin.h): every call eco makes to OpenImageIO.
// Built as a module that links OpenImageIO, loaded by image_codec.cpp on first use.
#include <OpenImageIO/imagebuf.h>
#include <OpenImageIO/imagebufalgo.h>
#include <OpenImageIO/imageio.h>

#include "image_plugin.h"

namespace {

using eco::ImageFileReader;
using eco::ImageWriteResult;
using eco::ImageWriteSpec;
using eco::SampleType;

OIIO::TypeDesc typeOf(SampleType t) {
    switch (t) {
    case SampleType::UInt8: return OIIO::TypeDesc::UINT8;
    case SampleType::UInt16: return OIIO::TypeDesc::UINT16;
    case SampleType::Float: return OIIO::TypeDesc::FLOAT;
    }
    return OIIO::TypeDesc::UNKNOWN;
}

class Reader final : public ImageFileReader {
public:
    explicit Reader(std::unique_ptr<OIIO::ImageInput> in) : in_(std::move(in)) {}
    ~Reader() override { in_->close(); }
    int width() const override { return in_->spec().width; }
    int height() const override { return in_->spec().height; }
    int channels() const override { return in_->spec().nchannels; }
    SampleType stored() const override {
        const OIIO::TypeDesc f = in_->spec().format;
        if (f == OIIO::TypeDesc::UINT8 || f == OIIO::TypeDesc::INT8) return SampleType::UInt8;
        if (f == OIIO::TypeDesc::UINT16 || f == OIIO::TypeDesc::INT16) return SampleType::UInt16;
        return SampleType::Float;
    }
    bool readFloat(int channels, float* out) override {
        // A truncated TIFF can come back "read" with the missing strips as zeros: an error
        // the reader recorded on the way counts too.
        return in_->read_image(0, 0, 0, channels, OIIO::TypeDesc::FLOAT, out) && !in_->has_error();
    }
    std::string error() override { return in_->geterror(); }

private:
    std::unique_ptr<OIIO::ImageInput> in_;
};

class Plugin final : public eco::plugin::ImagePlugin {
public:
    ImageWriteResult write(const std::string& path, const ImageWriteSpec& spec, SampleType given,
                           const void* pixels) override {
        using Step = ImageWriteResult::Step;
        std::unique_ptr<OIIO::ImageOutput> io = OIIO::ImageOutput::create(spec.format);
        if (!io) return {Step::Create, OIIO::geterror()};
        OIIO::ImageSpec s(spec.width, spec.height, spec.channels, typeOf(spec.stored));
        if (!spec.channelNames.empty()) s.channelnames = spec.channelNames;
        for (const auto& [name, value] : spec.attributes) s.attribute(name, value);
        if (!io->open(path, s)) return {Step::Open, io->geterror()};
        if (!io->write_image(typeOf(given), pixels)) return {Step::Write, io->geterror()};
        if (!io->close()) return {Step::Close, io->geterror()};
        return {};
    }

    std::unique_ptr<ImageFileReader> open(const std::string& path, std::string& error) override {
        OIIO::ImageSpec config;
        config.attribute("oiio:UnassociatedAlpha", 1);  // keep values as stored where alpha is 0
        auto in = OIIO::ImageInput::open(path, &config);
        if (!in) {
            error = OIIO::geterror();
            return nullptr;
        }
        return std::make_unique<Reader>(std::move(in));
    }

    bool renderText(float* rgb, int width, int height, int x, int y, const std::string& text, int sizePx,
                    const std::string& font, const float colour[3]) override {
        OIIO::ImageSpec spec(width, height, 3, OIIO::TypeDesc::FLOAT);
        OIIO::ImageBuf buf(spec, rgb);
        return OIIO::ImageBufAlgo::render_text(buf, x, y, text, sizePx, font, {colour, 3});
    }
};

}  // namespace

extern "C" __attribute__((visibility("default"))) eco::plugin::ImagePlugin* eco_image_plugin(int abi) {
    static Plugin plugin;
    return abi == eco::plugin::kImagePluginAbi ? &plugin : nullptr;
}
