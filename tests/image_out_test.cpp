// Pictures: north-up orientation, legends, atomic writes (core/image_out.h); the chart helper's
// round ticks, map axes and small multiples (core/chart.h).
#include <catch2/catch.hpp>

#include <filesystem>
#include <string>
#include <vector>

#include "chart.h"
#include "error.h"
#include "image_out.h"
#include "image_plugin.h"
#include "plugin.h"
#include "test_util.h"

using namespace eco;

namespace {

std::vector<unsigned char> readRgb(const std::string& path, int& w, int& h) {
    int channels = 0;
    std::vector<unsigned char> px = test::readImage8(path, w, h, channels);
    REQUIRE(!px.empty());
    REQUIRE(channels == 3);
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
    // The picture is pasted at (12, 46) plus the map axes' margin: its first row (north) is
    // white, the next black, and the frame round it black.
    const MapFrame frame = mapFrame(Canvas(40, 20), gridPictureExtent(g, 1, 40, 20));
    const int x0 = 12 + frame.plotLeft, y0 = 46 + frame.plotTop;
    auto at = [&](int x, int y) { return px[(static_cast<std::size_t>(y) * w + x) * 3]; };
    CHECK(at(x0 + 5, y0) == 255);
    CHECK(at(x0 + 5, y0 + 1) == 0);
    CHECK(at(x0 + 5, y0 + 19) == 0);
    CHECK(at(x0 + 5, y0 + 20) == 0);  // bottom of the frame
    CHECK(at(x0 + 5, y0 + 21) == 255);
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

TEST_CASE("niceTicks gives round steps that cover the range", "[image][chart]") {
    const std::vector<std::pair<double, double>> ranges = {{0, 468.0}, {0.3, 17.2}, {-5, 5},   {100, 220},
                                                           {0, 0.9},   {2.5e5, 2.5e5 + 1200}, {-0.07, 0.013}, {0, 19}};
    for (const auto& [lo, hi] : ranges) {
        INFO(lo << " .. " << hi);
        const std::vector<double> t = niceTicks(lo, hi, 5);
        REQUIRE(t.size() >= 3);
        CHECK(t.size() <= 11);
        const double step = t[1] - t[0];
        // 1, 2 or 5 times a power of ten.
        const double mantissa = step / std::pow(10.0, std::floor(std::log10(step) + 1e-9));
        CHECK((std::abs(mantissa - 1) < 1e-6 || std::abs(mantissa - 2) < 1e-6 || std::abs(mantissa - 5) < 1e-6));
        for (std::size_t i = 0; i < t.size(); ++i) {
            CHECK(t[i] >= lo - 1e-9 * step);
            CHECK(t[i] <= hi + 1e-9 * step);
            CHECK(std::abs(t[i] / step - std::round(t[i] / step)) < 1e-6);  // on the step's grid
            if (i) CHECK(std::abs(t[i] - t[i - 1] - step) < 1e-9 * std::max(1.0, std::abs(t[i])));
        }
        // Nothing more than a step left uncovered at either end.
        CHECK(t.front() - lo < step);
        CHECK(hi - t.back() < step);
    }
    CHECK(niceTicks(0, 0.9, 5) == std::vector<double>{0, 0.2, 0.4, 3 * 0.2, 0.8});  // k * step, not a drifting sum
    CHECK(tickLabel(0.6000000000000001, 0.2) == "0.6");
    CHECK(tickLabel(150, 50) == "150");
    CHECK(tickLabel(2.5, 2.5) == "2.5");
    CHECK(tickLabel(-1e-17, 0.25) == "0.00");
    CHECK(tickLabel(-0.0, 1) == "0");
}

TEST_CASE("a map frame of a small picture has room for its note", "[image][chart]") {
    // 40 x 20 pixels: the note under the scale bar ("x (east), y (north) in world metres, ...")
    // is wider than the picture; the canvas grows so that it is not cut at the right edge.
    const MapFrame f = mapFrame(Canvas(40, 20, {0.5f, 0.5f, 0.5f}), MapExtent{0, 0, 40, 20});
    const Canvas& c = f.canvas;
    int rightmost = -1;
    for (int y = f.plotTop + 20 + 40; y < c.height(); ++y)
        for (int x = 0; x < c.width(); ++x) {
            const Rgb v = c.get(x, y);
            if (v[0] + v[1] + v[2] < 2.7f) rightmost = std::max(rightmost, x);
        }
    INFO("canvas width " << c.width() << ", rightmost text column " << rightmost);
    CHECK(rightmost > f.plotLeft + 200);  // the note runs well past the picture
    CHECK(rightmost < c.width() - 3);     // and ends inside the canvas
}

TEST_CASE("a map frame puts its ticks on the columns and rows of known world coordinates", "[image][chart]") {
    // 400 x 200 pixels over x 1000..1100 m, y 2000..2100 m: 4 px per metre east, 2 per metre north.
    const Rgb fill{0.2f, 0.6f, 0.3f};
    const Canvas picture(400, 200, fill);
    const MapFrame f = mapFrame(picture, MapExtent{1000, 2000, 1100, 2100});
    const Canvas& c = f.canvas;
    auto dark = [&](int x, int y) {
        const Rgb v = c.get(x, y);
        return v[0] + v[1] + v[2] < 0.3f;
    };
    // The picture is intact, the frame one pixel outside it.
    CHECK(c.get(f.plotLeft, f.plotTop) == fill);
    CHECK(c.get(f.plotLeft + 399, f.plotTop + 199) == fill);
    CHECK(dark(f.plotLeft - 1, f.plotTop + 50));
    CHECK(dark(f.plotLeft + 400, f.plotTop + 50));
    CHECK(dark(f.plotLeft + 50, f.plotTop + 200));
    // About one x tick per 70 px: every 20 m (1000, 1020, ...). World x = 1040 m is column
    // plotLeft + 160, marked below the frame; 1050 m is no tick, and the columns beside a tick
    // are blank there.
    const int below = f.plotTop + 200 + 3;
    for (double xM : {1020.0, 1040.0, 1080.0}) {
        const int col = f.plotLeft + static_cast<int>((xM - 1000) * 4);
        INFO("x = " << xM << " m, column " << col);
        CHECK(dark(col, below));
        CHECK_FALSE(dark(col - 3, below));
        CHECK_FALSE(dark(col + 3, below));
    }
    CHECK_FALSE(dark(f.plotLeft + 200, below));
    // About one y tick per 60 px: every 50 m. World y = 2050 m is row plotTop + 100 (north
    // up), marked left of the frame; 2025 m is no tick.
    const int left = f.plotLeft - 1 - 3;
    CHECK(dark(left, f.plotTop + 100));
    CHECK_FALSE(dark(left, f.plotTop + 97));
    CHECK_FALSE(dark(left, f.plotTop + 103));
    CHECK_FALSE(dark(left, f.plotTop + 150));
    // Tick labels under the x ticks and a scale bar below them.
    bool label = false, bar = false;
    for (int x = f.plotLeft + 145; x < f.plotLeft + 175; ++x)
        for (int y = below + 5; y < below + 20; ++y) label = label || dark(x, y);
    CHECK(label);
    for (int y = f.plotTop + 200 + 25; y < c.height(); ++y) bar = bar || (dark(f.plotLeft + 2, y) && dark(f.plotLeft + 20, y));
    CHECK(bar);
}

TEST_CASE("chartCanvas keeps the y label clear of the top tick label", "[image][chart]") {
    ChartSeries s{"a", {0, 1, 2}, {0, 1, 2}, {0.f, 0.f, 1.f}};
    const Canvas c = chartCanvas({s}, 0, 2, 0, 2, "x (m)", "g(r)");  // a tick label at the top, y = 2
    // Rows of the left margin that hold ink: the y label's band, then (after a blank row) the
    // top tick label's.
    auto inkRow = [&](int y) {
        for (int x = 0; x < 62; ++x) {
            const Rgb v = c.get(x, y);
            if (v[0] + v[1] + v[2] < 2.4f) return true;
        }
        return false;
    };
    int first = -1;
    for (int y = 0; y < c.height() && first < 0; ++y)
        if (inkRow(y)) first = y;
    REQUIRE(first >= 0);
    int y = first;
    while (inkRow(y)) ++y;  // end of the first band
    int gap = 0;
    while (!inkRow(y + gap)) ++gap;
    CHECK(gap >= 2);
    // The second band is the top tick label: it reaches the row of the top tick (plot top).
    int second = y + gap, end = second;
    while (inkRow(end)) ++end;
    CHECK(second < 36 + 5);
    CHECK(end >= 36);
}

TEST_CASE("chartPanels draws every panel, beyond twelve", "[image][chart]") {
    std::vector<ChartPanel> panels;
    for (int i = 0; i < 15; ++i) {
        ChartPanel p;
        p.title = "pair " + std::to_string(i);
        p.xmax = 10;
        p.ymax = 3;
        p.series.push_back(ChartSeries{p.title, {0, 5, 10}, {0.5, 2.0, 1.0}, categoryColour(i)});
        p.reference = ChartReference{1.0, {0.45f, 0.45f, 0.45f}, true};
        panels.push_back(std::move(p));
    }
    ChartPanelsLayout layout;
    layout.title = "fifteen panels";
    layout.columns = 4;
    layout.xlabel = "r (m)";
    layout.ylabel = "g(r)";
    const Canvas c = chartPanels(panels, layout);
    // Every panel's own colour is there (lines are drawn without blending).
    for (int i = 0; i < 15; ++i) {
        INFO("panel " << i);
        bool found = false;
        for (int y = 0; y < c.height() && !found; ++y)
            for (int x = 0; x < c.width() && !found; ++x) found = c.get(x, y) == categoryColour(i);
        CHECK(found);
    }
    CHECK(c.height() > 4 * 180);  // four rows
}

TEST_CASE("plugins: a missing one is an error naming the file, the folders searched and ECO_PLUGIN_DIR", "[image][plugin]") {
    // core/plugin.h: the folders, in order; the build tree's plugin folder is among them, and
    // the OpenImageIO plugin is there (the tests above drew through it).
    const std::vector<std::string> dirs = pluginDirs();
    REQUIRE(dirs.size() >= 3);
    bool found = false;
    for (const std::string& d : dirs) found = found || std::filesystem::is_regular_file(d + "/eco_oiio.so");
    CHECK(found);
    try {
        pluginEntry("eco_no_such_plugin.so", "eco_image_plugin");
        FAIL("a missing plugin was loaded");
    } catch (const IoError& e) {
        const std::string what = e.what();
        CHECK(what.find("eco_no_such_plugin.so") != std::string::npos);
        CHECK(what.find("ECO_PLUGIN_DIR") != std::string::npos);
        CHECK(what.find(dirs.back()) != std::string::npos);
    }
    // A plugin that is there but lacks the entry point: named, with the symbol.
    try {
        pluginEntry("eco_oiio.so", "eco_no_such_entry");
        FAIL("a missing entry point was found");
    } catch (const IoError& e) {
        CHECK(std::string(e.what()).find("eco_no_such_entry") != std::string::npos);
    }
    // A plugin built for another interface version refuses, and core says so.
    CHECK_THROWS_WITH((loadPlugin<plugin::ImagePlugin>("eco_oiio.so", "eco_image_plugin", plugin::kImagePluginAbi + 1)),
                      Catch::Contains("eco_oiio.so") && Catch::Contains("another version of eco"));
}
