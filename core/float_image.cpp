#include "float_image.h"

#include <OpenImageIO/imageio.h>

#include <cstdio>
#include <filesystem>
#include <memory>
#include <vector>

#include "atomic_file.h"
#include "error.h"

namespace eco {

void writeFloatExr(const std::string& path, const Grid<float>& g, const std::string& units, const std::string& description) {
    AtomicOutput out(path);
    // OIIO picks the format from the extension, so the temporary name ends in .exr too.
    const std::string temp = out.tempPath() + ".exr";
    {
        std::unique_ptr<OIIO::ImageOutput> io = OIIO::ImageOutput::create("openexr");
        if (!io) throw IoError(path + ": OpenEXR writer unavailable: " + OIIO::geterror());
        OIIO::ImageSpec spec(g.width(), g.height(), 1, OIIO::TypeDesc::FLOAT);
        spec.channelnames = {"Y"};
        spec.attribute("compression", "none");
        // OIIO stamps the current time as capDate unless DateTime is given: an empty one
        // keeps the same inputs giving the same bytes.
        spec.attribute("DateTime", "");
        const auto text = [](double v) {
            char buf[40];
            std::snprintf(buf, sizeof buf, "%.17g", v);
            return std::string(buf);
        };
        spec.attribute("eco:cell_size_m", text(g.cellSizeM()));
        spec.attribute("eco:origin_x_m", text(g.originX()));
        spec.attribute("eco:origin_y_m", text(g.originY()));
        spec.attribute("eco:units", units);
        spec.attribute("eco:description", description);
        const auto w = static_cast<std::size_t>(g.width());
        std::vector<float> rows(w * static_cast<std::size_t>(g.height()));
        for (int iy = 0; iy < g.height(); ++iy)  // image row 0 = the northern grid row
            for (int ix = 0; ix < g.width(); ++ix)
                rows[static_cast<std::size_t>(g.height() - 1 - iy) * w + static_cast<std::size_t>(ix)] = g(ix, iy);
        if (!io->open(temp, spec) || !io->write_image(OIIO::TypeDesc::FLOAT, rows.data()) || !io->close()) {
            std::remove(temp.c_str());
            throw IoError(path + ": cannot write OpenEXR: " + io->geterror());
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
