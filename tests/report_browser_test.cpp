// The HTML reports (core/html_report.h, docs/report.md) in a real browser: headless Chromium
// (Debian's `chromium`, installed by tools/setup.sh) loads the page, its DOM is dumped and
// a screenshot taken. The page's own hooks say what happened: <pre id="eco-js-errors"> holds
// any script error, console.error or failed load; the body gets data-eco-ready="1" when
// every plot and scene is drawn; each drawn canvas carries data-eco-rect (CSS pixels) and
// data-eco-drawn. The screenshot is then read back (core's image reader) inside those rectangles.
// Labelled `browser` (ctest -LE browser leaves them out, e.g. in the sanitizer stage).
// Chromium missing is a failure, not a skip: CI installs it.
#include <catch2/catch.hpp>

#include <cmath>
#include <cstdlib>
#include <fstream>
#include <map>
#include <regex>
#include <sstream>

#include "html_report.h"
#include "image_out.h"
#include "test_util.h"
#include "validate.h"

namespace {

using eco::test::TempDir;

std::string readAll(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    std::ostringstream s;
    s << in.rdbuf();
    return s.str();
}

/// The Chromium binary: $ECO_CHROMIUM, else `chromium` (Debian) or `chromium-browser` on PATH.
std::string chromium() {
    if (const char* c = std::getenv("ECO_CHROMIUM"); c != nullptr && *c != '\0') return c;
    for (const char* name : {"chromium", "chromium-browser"}) {
        const std::string cmd = std::string("command -v ") + name + " > /dev/null 2>&1";
        if (std::system(cmd.c_str()) == 0) return name;
    }
    return "";
}

constexpr int kWindowW = 1280, kWindowH = 3000;

/// Run headless Chromium on a local page with one of `--dump-dom` or `--screenshot=PATH`;
/// the DOM (stdout) is returned, stderr goes to `log`.
std::string runChromium(const std::string& page, const std::string& mode, const std::string& log) {
    const std::string browser = chromium();
    if (browser.empty())
        FAIL("no chromium on PATH: install Debian's chromium (tools/setup.sh does) or name a binary in ECO_CHROMIUM");
    const std::string out = log + ".out";
    // --no-sandbox: CI runs as root, where Chromium's sandbox refuses to start; the page is
    // our own file. A fixed window and scale factor give the dump and the screenshot one layout.
    const std::string cmd = "timeout 60 " + browser +
                            " --headless --disable-gpu --no-sandbox --hide-scrollbars --force-device-scale-factor=1"
                            " --no-first-run --disable-extensions --window-size=" +
                            std::to_string(kWindowW) + "," + std::to_string(kWindowH) + " " + mode + " 'file://" + page +
                            "' > '" + out + "' 2> '" + log + "'";
    const int status = std::system(cmd.c_str());
    INFO(cmd << "\n" << readAll(log));
    REQUIRE(status == 0);
    return readAll(out);
}

struct Drawn {
    int x = 0, y = 0, w = 0, h = 0;
    long drawn = 0;
};

/// Every canvas of the dumped DOM that the page drew, in document order.
std::vector<Drawn> drawnCanvases(const std::string& dom) {
    std::vector<Drawn> out;
    const std::regex canvas("<canvas[^>]*>");
    const std::regex rect("data-eco-rect=\"(-?\\d+),(-?\\d+),(\\d+),(\\d+)\"");
    const std::regex drawn("data-eco-drawn=\"(\\d+)\"");
    for (auto it = std::sregex_iterator(dom.begin(), dom.end(), canvas); it != std::sregex_iterator(); ++it) {
        const std::string tag = it->str();
        std::smatch m, d;
        if (!std::regex_search(tag, m, rect) || !std::regex_search(tag, d, drawn)) continue;
        out.push_back({std::stoi(m[1]), std::stoi(m[2]), std::stoi(m[3]), std::stoi(m[4]), std::stol(d[1])});
    }
    return out;
}

/// The page loaded without errors and drew everything: the DOM's canvases.
std::vector<Drawn> loadCleanly(const std::string& page, const std::string& dir) {
    const std::string dom = runChromium(page, "--dump-dom", dir + "/dom.log");
    INFO(dom.substr(0, 4000));
    // Any script error, console.error or failed picture is written into the page.
    const std::regex errors("<pre[^>]*id=\"eco-js-errors\"[^>]*>([^<]*)");
    std::smatch m;
    if (std::regex_search(dom, m, errors)) FAIL("errors in the page: " << m[1]);
    CHECK(dom.find("data-eco-ready=\"1\"") != std::string::npos);
    return drawnCanvases(dom);
}

struct Screenshot {
    int width = 0, height = 0;
    std::vector<unsigned char> rgb;
    std::array<int, 3> at(int x, int y) const {
        const std::size_t i = (static_cast<std::size_t>(y) * width + x) * 3;
        return {rgb[i], rgb[i + 1], rgb[i + 2]};
    }
};

Screenshot screenshot(const std::string& page, const std::string& dir) {
    const std::string png = dir + "/shot.png";
    runChromium(page, "--screenshot=" + png, dir + "/shot.log");
    Screenshot s;
    int nc = 0;
    const std::vector<unsigned char> all = eco::test::readImage8(png, s.width, s.height, nc);
    REQUIRE(!all.empty());
    REQUIRE(nc >= 3);
    s.rgb.resize(static_cast<std::size_t>(s.width) * s.height * 3);
    for (std::size_t p = 0; p < static_cast<std::size_t>(s.width) * s.height; ++p)
        for (int c = 0; c < 3; ++c) s.rgb[p * 3 + c] = all[p * nc + c];
    return s;
}

/// A saturated pixel: a series' or a species' colour, not white, grey or black (axes, grid, text).
bool coloured(const std::array<int, 3>& c) {
    return std::max({c[0], c[1], c[2]}) - std::min({c[0], c[1], c[2]}) > 60;
}

/// Coloured pixels inside a canvas rectangle (its 1-pixel border left out).
long colouredIn(const Screenshot& s, const Drawn& r) {
    long n = 0;
    for (int y = r.y + 1; y < std::min(r.y + r.h - 1, s.height); ++y)
        for (int x = r.x + 1; x < std::min(r.x + r.w - 1, s.width); ++x) n += coloured(s.at(x, y)) ? 1 : 0;
    return n;
}

std::array<int, 3> hexColour(const std::string& hex) {
    return {std::stoi(hex.substr(1, 2), nullptr, 16), std::stoi(hex.substr(3, 2), nullptr, 16), std::stoi(hex.substr(5, 2), nullptr, 16)};
}

bool near(const std::array<int, 3>& a, const std::array<int, 3>& b, int tolerance) {
    for (int c = 0; c < 3; ++c)
        if (std::abs(a[c] - b[c]) > tolerance) return false;
    return true;
}

/// Where world point (x, y) of a scene view over [x0, x1] x [y0, y1] lands in the screenshot:
/// the view is fitted (98 %) and centred in its canvas, north up.
std::array<int, 2> scenePixel(const Drawn& canvas, double x0, double y0, double x1, double y1, double x, double y) {
    const double s = std::min(canvas.w / (x1 - x0), canvas.h / (y1 - y0)) * 0.98;
    const double cx = canvas.x + canvas.w / 2.0, cy = canvas.y + canvas.h / 2.0;
    return {static_cast<int>(std::lround(cx + (x - (x0 + x1) / 2) * s)), static_cast<int>(std::lround(cy - (y - (y0 + y1) / 2) * s))};
}

}  // namespace

TEST_CASE("report.html: a constructed scene and plot are drawn where their data say, north up", "[browser][report]") {
    TempDir dir("html_browser");
    // A 100 m x 50 m scene: one undergrowth plant of species 2 with a 6 m crown in the north-west
    // (x 20, y 40), nothing in the south-east; a plot whose one line rises from left to right.
    eco::html::Document doc("constructed");
    doc.heading(1, "constructed");
    eco::html::LinePlot plot;
    plot.title = "rising";
    plot.xLabel = "x";
    plot.yLabel = "y";
    eco::html::Series line{"y = x", {}, {}, "#d62728", false};
    for (int i = 0; i <= 50; ++i) {
        line.x.push_back(i);
        line.y.push_back(i);
    }
    plot.groups.push_back({"one", {line}});
    doc.linePlot(plot);
    eco::html::SceneView scene;
    scene.title = "one plant";
    scene.x0M = 0, scene.y0M = 0, scene.x1M = 100, scene.y1M = 50;
    scene.speciesNames = {"a", "b", "c"};
    eco::Plant p;
    p.speciesId = 2;
    p.xM = 20, p.yM = 40, p.heightM = 1, p.crownRadiusM = 6;
    scene.undergrowth = {p};
    doc.sceneView(scene);
    const std::string page = dir.file("page.html");
    eco::html::writeDocument(page, doc);

    const std::vector<Drawn> canvases = loadCleanly(page, dir.path().string());
    REQUIRE(canvases.size() == 2);
    const Drawn& plotRect = canvases[0];
    const Drawn& sceneRect = canvases[1];
    CHECK(plotRect.drawn == 51);   // points of the line
    CHECK(sceneRect.drawn == 1);   // the one plant
    REQUIRE(sceneRect.y + sceneRect.h <= kWindowH);
    const Screenshot shot = screenshot(page, dir.path().string());
    REQUIRE(shot.width == kWindowW);

    // The plot: coloured pixels, those in the left half lower (larger image y) than in the right.
    double leftY = 0, rightY = 0;
    long left = 0, right = 0;
    for (int y = plotRect.y + 1; y < plotRect.y + plotRect.h - 1; ++y)
        for (int x = plotRect.x + 1; x < plotRect.x + plotRect.w - 1; ++x) {
            if (!coloured(shot.at(x, y))) continue;
            if (x < plotRect.x + plotRect.w / 2) leftY += y, ++left;
            else rightY += y, ++right;
        }
    REQUIRE(left > 50);
    REQUIRE(right > 50);
    CHECK(leftY / left > rightY / right + 50);

    // The scene is fitted (98 %) and centred in its canvas: world (x, y) lands at
    // (cx + (x - 50) s, cy - (y - 25) s). The plant's centre has species 2's colour; the point
    // mirrored through the centre (south-east) is the white of the scene's ground.
    const double s = std::min(sceneRect.w / 100.0, sceneRect.h / 50.0) * 0.98;
    const double cx = sceneRect.x + sceneRect.w / 2.0, cy = sceneRect.y + sceneRect.h / 2.0;
    const int px = static_cast<int>(std::lround(cx + (20 - 50) * s)), py = static_cast<int>(std::lround(cy - (40 - 25) * s));
    const int qx = static_cast<int>(std::lround(cx + (80 - 50) * s)), qy = static_cast<int>(std::lround(cy - (10 - 25) * s));
    INFO("plant at pixel " << px << "," << py << "; scale " << s << " px/m");
    const auto c = shot.at(px, py);
    INFO("colour " << c[0] << "," << c[1] << "," << c[2] << " expected " << eco::html::categoryHex(2));
    CHECK(near(c, hexColour(eco::html::categoryHex(2)), 40));
    CHECK(near(shot.at(qx, qy), {255, 255, 255}, 2));
    // Within the crown (5 m from the centre) still the species; beyond it (8 m) white.
    CHECK(near(shot.at(static_cast<int>(std::lround(px + 5 * s)), py), hexColour(eco::html::categoryHex(2)), 40));
    CHECK(near(shot.at(static_cast<int>(std::lround(px + 8 * s)), py), {255, 255, 255}, 2));
}

TEST_CASE("eco run: report.html loads in Chromium without errors and shows the plots and the scene", "[browser][report][cli]") {
    TempDir dir("run_html");
    const std::string cfg = dir.file("pipeline.toml");
    {
        std::ofstream f(cfg);
        f << "[run]\nout_dir = \"out\"\nseed = 4\n"
          << "[terrain]\nwidth = 64\nheight = 64\ncell_size_m = 0.914\n"
          << "[chm]\n[abiotics]\nsun_step_minutes = 60\n"
          << "[canopy]\n"
          << "[simulate]\nconfig = \"" << eco::test::sourcePath("configs/sim-default.toml") << "\"\nyears = 2\n"
          << "crop = [5.0, 5.0, 35.0, 35.0]\n"
          << "[analyse]\nkmax = 2\n"
          << "[synth]\ntarget_seed = 9\nwidth = 48\nheight = 48\n";
    }
    const auto r = eco::test::runEco("--threads 2 run " + cfg);
    INFO(r.output);
    REQUIRE(r.exitCode == 0);
    const std::string page = dir.file("out/report.html");
    REQUIRE(std::filesystem::exists(page));
    CHECK_THAT(r.output, Catch::Contains("report.html"));
    const std::string html = readAll(page);
    // Self-contained: pictures as data URIs, nothing fetched.
    CHECK(html.find("<img src=\"data:image/png;base64,") != std::string::npos);
    CHECK(html.find("src=\"http") == std::string::npos);
    CHECK(html.find("src=\"png/") == std::string::npos);
    // The stage table: each stage with its command line, as report.md has it.
    CHECK(html.find("<td>terrain</td><td class=\"num\">") != std::string::npos);
    CHECK(html.find("<td>eco terrain generate --out ") != std::string::npos);
    CHECK(html.find("eco eco") == std::string::npos);

    const std::vector<Drawn> canvases = loadCleanly(page, dir.path().string());
    // The population plot, the g(r) plot and the scene.
    REQUIRE(canvases.size() == 3);
    for (const Drawn& d : canvases) {
        CHECK(d.drawn > 0);
        REQUIRE(d.y + d.h <= kWindowH);  // inside the screenshot
    }
    const Screenshot shot = screenshot(page, dir.path().string());
    // Each plot shows a coloured line (the species' lines; g(r) of the scene in red).
    CHECK(colouredIn(shot, canvases[0]) > 200);
    CHECK(colouredIn(shot, canvases[1]) > 200);
    // The scene: every plant covers at least a pixel; allowing half of them to overlap, at
    // least drawn / 2 pixels are neither the ground's white nor the margin's #f3f1ea.
    const Drawn& scene = canvases[2];
    long plantPixels = 0;
    for (int y = scene.y + 1; y < scene.y + scene.h - 1; ++y)
        for (int x = scene.x + 1; x < scene.x + scene.w - 1; ++x) {
            const auto c = shot.at(x, y);
            plantPixels += !near(c, {255, 255, 255}, 12) && !near(c, {243, 241, 234}, 12) ? 1 : 0;
        }
    INFO("plants drawn " << scene.drawn << ", pixels of plants " << plantPixels);
    CHECK(plantPixels >= scene.drawn / 2);
    CHECK(colouredIn(shot, scene) > 0);
}

TEST_CASE("eco validate: report.html with a plot, pictures and views from above loads without errors, plants where the data say",
          "[browser][report][validate]") {
    using namespace eco::validate;
    TempDir dir("validate_html");
    // A suite result as the scenarios make it: a failing check, a figure with its interactive
    // plot (plants per species per year) and one picture only.
    SuiteResult res;
    res.mode = Mode::Quick;
    ScenarioResult s;
    s.name = "demo";
    s.title = "Demo";
    s.description = "A *demo* scenario with `code`.";
    CheckResult c;
    c.scenario = "demo";
    c.spec.id = "grows";
    c.spec.kind = CheckSpec::Kind::AtLeast;
    c.spec.target = 1;
    c.value = 0.5;
    c.pass = c.spec.passes(c.value);
    s.checks.push_back(c);
    eco::Canvas picture(40, 30, {0.2f, 0.6f, 0.3f});
    picture.writePng(dir.file("demo.png"));
    eco::html::LinePlot plot;
    plot.title = "plants per species";
    plot.xLabel = "year";
    plot.yLabel = "plants";
    plot.logYToggle = true;
    eco::html::Series a{"Toyon", {0, 1, 2, 3}, {10, 40, 35, 30}, "", false}, b{"Tanoak", {0, 1, 2, 3}, {0, 5, 9, 12}, "", false};
    plot.groups.push_back({"plants per species", {a, b}});
    s.figures.push_back({"demo.png", "with a plot", plot});
    s.figures.push_back({"demo.png", "a picture only"});
    // A simulated plot from above beside its picture (as the forest scenarios' last render):
    // 100 m x 40 m, one undergrowth plant of species 1 in the west, a canopy tree of species 0
    // over the plot's south-east, one far outside it (dropped); and a scene shown only in
    // report.html (as the fidelity scenario's synthesized scene): one plant of species 3.
    const auto plant = [](int species, double x, double y, double r, double h) {
        eco::Plant p;
        p.speciesId = species, p.xM = x, p.yM = y, p.crownRadiusM = r, p.heightM = h;
        return p;
    };
    const std::vector<std::string> species = {"Douglas-Fir", "Toyon", "Tanoak", "Redwood"};
    s.figures.push_back({"demo.png", "a plot at the end",
                         eco::html::plotView("plot from above", 0, 0, 100, 40, species,
                                             {plant(0, 85, 8, 6, 30), plant(0, 400, 300, 6, 30)}, {plant(1, 20, 30, 5, 1)})});
    s.figures.push_back({"", "a scene shown only here",
                         eco::html::plotView("scene from above", 0, 0, 100, 40, species, {}, {plant(3, 70, 15, 5, 1)})});
    res.scenarios.push_back(s);
    writeReport(res, dir.path().string());
    const std::string page = dir.file("report.html");
    const std::string html = readAll(page);
    CHECK(html.find("<td><strong>FAIL</strong></td>") != std::string::npos);
    CHECK(html.find("<p>A <em>demo</em> scenario with <code>code</code>.</p>") != std::string::npos);
    // The render's picture is folded away under its view; the view-only figure has no picture.
    CHECK(html.find("<details><summary>a plot at the end (picture)</summary>") != std::string::npos);
    CHECK(html.find("alt=\"a scene shown only here\"") == std::string::npos);
    const std::string md = readAll(dir.file("report.md"));
    CHECK(md.find("![a plot at the end](demo.png)") != std::string::npos);
    CHECK(md.find("*a scene shown only here* (an interactive view, in report.html only)") != std::string::npos);
    CHECK(md.find("]()") == std::string::npos);

    const std::vector<Drawn> canvases = loadCleanly(page, dir.path().string());
    REQUIRE(canvases.size() == 3);
    CHECK(canvases[0].drawn == 8);  // the two lines' points
    CHECK(canvases[1].drawn == 2);  // the plant and the tree over the plot
    CHECK(canvases[2].drawn == 1);
    for (const Drawn& d : canvases) REQUIRE(d.y + d.h <= kWindowH);
    const Screenshot shot = screenshot(page, dir.path().string());
    CHECK(colouredIn(shot, canvases[0]) > 100);
    const auto colourAt = [&](const Drawn& canvas, double x, double y) {
        const auto p = scenePixel(canvas, 0, 0, 100, 40, x, y);
        INFO("world " << x << "," << y << " at pixel " << p[0] << "," << p[1]);
        return shot.at(p[0], p[1]);
    };
    const std::array<int, 3> white{255, 255, 255};
    // The plot: the plant in its species' colour, white where nothing stands (mirrored through
    // the centre, and beyond the crown), the canopy tree's crown not white (half transparent).
    CHECK(near(colourAt(canvases[1], 20, 30), hexColour(eco::html::categoryHex(1)), 40));
    CHECK(near(colourAt(canvases[1], 23, 30), hexColour(eco::html::categoryHex(1)), 40));
    CHECK(near(colourAt(canvases[1], 80, 10), white, 2) == false);
    CHECK(near(colourAt(canvases[1], 20, 10), white, 2));
    CHECK(near(colourAt(canvases[1], 28, 30), white, 2));
    // The view-only scene: its plant where the data say, nothing at the other's place.
    CHECK(near(colourAt(canvases[2], 70, 15), hexColour(eco::html::categoryHex(3)), 40));
    CHECK(near(colourAt(canvases[2], 30, 25), white, 2));
    CHECK(near(colourAt(canvases[2], 20, 30), white, 2));
}
