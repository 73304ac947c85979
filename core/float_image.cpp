#include "float_image.h"

#include <cstdio>
#include <filesystem>
#include <memory>
#include <vector>

#include "atomic_file.h"
#include "error.h"
#include "image_codec.h"

namespace eco {

void writeFloatExr(const std::string& path, const Grid<float>& g, const std::string& units, const std::string& description) {
    AtomicOutput out(path);
    // OIIO picks the format from the extension, so the temporary name ends in .exr too.
    const std::string temp = out.tempPath() + ".exr";
    {
        ImageWriteSpec spec;
        spec.format = "openexr";
        spec.width = g.width();
        spec.height = g.height();
        spec.channels = 1;
        spec.stored = SampleType::Float;
        spec.channelNames = {"Y"};
        spec.attributes.emplace_back("compression", "none");
        // OIIO stamps the current time as capDate unless DateTime is given: an empty one
        // keeps the same inputs giving the same bytes.
        spec.attributes.emplace_back("DateTime", "");
        const auto text = [](double v) {
            char buf[40];
            std::snprintf(buf, sizeof buf, "%.17g", v);
            return std::string(buf);
        };
        spec.attributes.emplace_back("eco:cell_size_m", text(g.cellSizeM()));
        spec.attributes.emplace_back("eco:origin_x_m", text(g.originX()));
        spec.attributes.emplace_back("eco:origin_y_m", text(g.originY()));
        spec.attributes.emplace_back("eco:units", units);
        spec.attributes.emplace_back("eco:description", description);
        const auto w = static_cast<std::size_t>(g.width());
        std::vector<float> rows(w * static_cast<std::size_t>(g.height()));
        for (int iy = 0; iy < g.height(); ++iy)  // image row 0 = the northern grid row
            for (int ix = 0; ix < g.width(); ++ix)
                rows[static_cast<std::size_t>(g.height() - 1 - iy) * w + static_cast<std::size_t>(ix)] = g(ix, iy);
        const ImageWriteResult r = writeImageFile(temp, spec, SampleType::Float, rows.data());
        if (r.step == ImageWriteResult::Step::Create) throw IoError(path + ": OpenEXR writer unavailable: " + r.reason);
        if (!r.ok()) {
            std::remove(temp.c_str());
            throw IoError(path + ": cannot write OpenEXR: " + r.reason);
        }
    }
    std::error_code ec;
    std::filesystem::rename(temp, out.tempPath(), ec);
    if (ec) {
        std::remove(temp.c_str());
        throw IoError(path + ": cannot write OpenEXR: " + ec.message());
    }
    out.commit();
}

}  // namespace eco
