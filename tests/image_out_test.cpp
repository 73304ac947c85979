// Pictures: north-up orientation, legends, atomic writes (core/image_out.h).
#include <catch2/catch.hpp>

#include <OpenImageIO/imageio.h>

#include <filesystem>

#include "error.h"
#include "image_out.h"
#include "test_util.h"

using namespace eco;

namespace {

std::vector<unsigned char> readRgb(const std::string& path, int& w, int& h) {
    auto in = OIIO::ImageInput::open(path);
    REQUIRE(in);
    const auto& spec = in->spec();
    w = spec.width;
    h = spec.height;
    std::vector<unsigned char> px(static_cast<std::size_t>(w) * h * spec.nchannels);
    REQUIRE(in->read_image(0, 0, 0, spec.nchannels, OIIO::TypeDesc::UINT8, px.data()));
    REQUIRE(spec.nchannels == 3);
    return px;
}

}  // namespace

TEST_CASE("maps are drawn north-up with the colour bar", "[image]") {
    test::TempDir dir("image");
    // Non-square grid: the northern row (iy = height-1) is high, everything else low.
    Grid<float> g(40, 20, 1.0);
    for (int ix = 0; ix < g.width(); ++ix) g(ix, g.height() - 1) = 10.f;
    const std::string path = dir.file("map.png");
    writeMapPng(path, g, "test map", "units", Colormap::Greys, 0.0, 10.0);
    int w = 0, h = 0;
    const auto px = readRgb(path, w, h);
    CHECK(w > g.width());
    CHECK(h > g.height());
    // The picture is pasted at (12, 46): its first row (north) is white, the next black.
    auto at = [&](int x, int y) { return px[(static_cast<std::size_t>(y) * w + x) * 3]; };
    CHECK(at(12 + 5, 46) == 255);
    CHECK(at(12 + 5, 47) == 0);
    CHECK(at(12 + 5, 46 + 19) == 0);
    // No temporary file is left beside the output.
    int files = 0;
    for (const auto& e : std::filesystem::directory_iterator(dir.path())) files += e.is_regular_file();
    CHECK(files == 1);
}

TEST_CASE("category maps carry a legend and text renders", "[image]") {
    test::TempDir dir("image");
    Grid<std::int32_t> g(30, 10, 1.0, 0, 0, -1);
    for (int iy = 0; iy < 10; ++iy)
        for (int ix = 0; ix < 10; ++ix) g(ix, iy) = 1;
    const std::string path = dir.file("cat.png");
    writeCategoryPng(path, g, "species", {"alpha", "beta"}, "none");
    int w = 0, h = 0;
    readRgb(path, w, h);
    CHECK(w > 30 + 40);  // legend column added
    Canvas c(100, 30);
    CHECK(c.text(2, 20, "Hello", 14, {0.f, 0.f, 0.f}));
    bool anyDark = false;
    for (float v : c.pixels()) anyDark = anyDark || v < 0.5f;
    CHECK(anyDark);
}

TEST_CASE("writing into a missing directory fails with the path", "[image]") {
    Canvas c(4, 4);
    CHECK_THROWS_AS(c.writePng("/nonexistent-dir/x.png"), IoError);
    CHECK_THROWS_WITH(c.writePng("/nonexistent-dir/x.png"), Catch::Contains("/nonexistent-dir/x.png"));
}
