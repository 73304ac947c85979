// core/html_report: the pieces of the self-contained HTML reports that need no browser
// (tests/report_browser_test.cpp loads whole pages in Chromium).
#include <catch2/catch.hpp>

#include <cstring>
#include <fstream>
#include <regex>

#include "html_report.h"
#include "test_util.h"

using namespace eco;

TEST_CASE("html: base64 of the RFC 4648 test vectors, and back", "[html]") {
    const std::vector<std::pair<std::string, std::string>> vectors = {
        {"", ""}, {"f", "Zg=="}, {"fo", "Zm8="}, {"foo", "Zm9v"}, {"foob", "Zm9vYg=="}, {"fooba", "Zm9vYmE="}, {"foobar", "Zm9vYmFy"}};
    for (const auto& [plain, encoded] : vectors) {
        CHECK(html::base64(plain.data(), plain.size()) == encoded);
        const auto back = html::base64Decode(encoded);
        CHECK(std::string(back.begin(), back.end()) == plain);
    }
    std::vector<std::uint8_t> bytes(256);
    for (int i = 0; i < 256; ++i) bytes[static_cast<std::size_t>(i)] = static_cast<std::uint8_t>(255 - i);
    CHECK(html::base64Decode(html::base64(bytes.data(), bytes.size())) == bytes);
}

TEST_CASE("html: text is escaped, and a JSON string cannot end its script element", "[html]") {
    CHECK(html::escape("a<b & \"c\" 'd'>") == "a&lt;b &amp; &quot;c&quot; &#39;d&#39;&gt;");
    const std::string j = html::jsonString("</script><b>\"x\"\n\\");
    CHECK(j.find("</script") == std::string::npos);
    CHECK(j == "\"\\u003c/script\\u003e\\u003cb\\u003e\\\"x\\\"\\n\\\\\"");
    html::Document doc("t</title>");
    doc.paragraph("<script>alert(1)</script>");
    const std::string page = doc.str();
    CHECK(page.find("<title>t&lt;/title&gt;</title>") != std::string::npos);
    CHECK(page.find("<p>&lt;script&gt;alert(1)&lt;/script&gt;</p>") != std::string::npos);
}

TEST_CASE("html: Markdown tables, headings, code and lists become HTML", "[html]") {
    html::Document doc("md");
    doc.markdown("# Title\n\nSome `code` and **bold** text\non two lines.\n\n"
                 "| a | b \\| c | n |\n|---|---|---:|\n| 1 | x | 2.5 |\n| 3 | y | 4 |\n\n"
                 "```\nraw <text>\n```\n- one\n- two\n");
    const std::string page = doc.str();
    CHECK(page.find("<h1>Title</h1>") != std::string::npos);
    CHECK(page.find("<p>Some <code>code</code> and <strong>bold</strong> text on two lines.</p>") != std::string::npos);
    CHECK(page.find("<th>a</th><th>b | c</th><th class=\"num\">n</th>") != std::string::npos);
    CHECK(page.find("<tr><td>1</td><td>x</td><td class=\"num\">2.5</td></tr>") != std::string::npos);
    CHECK(page.find("<pre>raw &lt;text&gt;\n</pre>") != std::string::npos);
    CHECK(page.find("<ul>\n<li>one</li>\n<li>two</li>\n</ul>") != std::string::npos);
}

TEST_CASE("html: a picture is embedded as a data URI, a missing one left out", "[html]") {
    test::TempDir dir("html_picture");
    const std::string png = dir.file("p.png");
    {
        std::ofstream f(png, std::ios::binary);
        f << "\x89PNG-not-really";
    }
    html::Document doc("pictures");
    doc.picture(png, "a picture");
    doc.picture(dir.file("missing.png"), "absent");
    const std::string page = doc.str();
    const std::string expected = "data:image/png;base64," + html::base64("\x89PNG-not-really", std::strlen("\x89PNG-not-really"));
    CHECK(page.find("<img src=\"" + expected + "\" alt=\"a picture\">") != std::string::npos);
    CHECK(page.find("absent") == std::string::npos);
}

TEST_CASE("html: a scene view stores every plant, positions to 16 bits of the rectangle", "[html]") {
    html::SceneView scene;
    scene.x0M = 100, scene.y0M = 200, scene.x1M = 300, scene.y1M = 250;
    scene.speciesNames = {"a", "b"};
    Plant under;
    under.speciesId = 1, under.xM = 150, under.yM = 225, under.crownRadiusM = 0.35, under.heightM = 1.25;
    Plant tree;  // standing west of the rectangle: the quantization rectangle grows to hold it
    tree.speciesId = 0, tree.xM = 90, tree.yM = 210, tree.crownRadiusM = 4, tree.heightM = 30;
    scene.undergrowth = {under};
    scene.canopy = {tree};
    html::Document doc("scene");
    doc.sceneView(scene);
    const std::string page = doc.str();
    const auto field = [&](const std::string& key) {
        std::smatch m;
        const std::regex re("\"" + key + "\":\"?([^\",}]*)");
        REQUIRE(std::regex_search(page, m, re));
        return m[1].str();
    };
    CHECK(field("n") == "2");
    CHECK(field("nCanopy") == "1");
    CHECK(std::stod(field("qx0")) == 90);
    CHECK(std::stod(field("qx1")) == 300);
    const auto u16 = [&](const std::string& key, std::size_t i) {
        const auto bytes = html::base64Decode(field(key));
        REQUIRE(bytes.size() == 4);  // two plants, little-endian 16-bit
        return bytes[2 * i] | (bytes[2 * i + 1] << 8);
    };
    // Undergrowth first: x 150 over [90, 300], y 225 over [200, 250]; the tree at x 90.
    CHECK(std::abs(90 + u16("x", 0) * 210.0 / 65535 - 150) < 0.005);
    CHECK(std::abs(200 + u16("y", 0) * 50.0 / 65535 - 225) < 0.005);
    CHECK(u16("x", 1) == 0);
    CHECK(u16("r", 0) == 35);   // cm
    CHECK(u16("h", 1) == 3000); // cm
    const auto species = html::base64Decode(field("s"));
    CHECK(species == std::vector<std::uint8_t>{1, 0});
}

TEST_CASE("html: a plot view keeps the canopy trees whose crown reaches the plot", "[html]") {
    const auto plant = [](int species, double x, double y, double r) {
        Plant p;
        p.speciesId = species, p.xM = x, p.yM = y, p.crownRadiusM = r, p.heightM = 20;
        return p;
    };
    // A plot [10, 30] x [10, 20]: a tree inside, one outside whose crown reaches in (west),
    // one whose crown stops 0.5 m short (north), one far away.
    const std::vector<Plant> canopy = {plant(0, 15, 15, 3), plant(1, 7, 12, 3.5), plant(2, 20, 24, 3.5), plant(3, 500, 500, 9)};
    const html::SceneView view = html::plotView("plot", 10, 10, 30, 20, {"a", "b", "c", "d"}, canopy, {plant(1, 12, 11, 0.3)});
    CHECK(view.title == "plot");
    CHECK(view.x0M == 10);
    CHECK(view.y1M == 20);
    REQUIRE(view.canopy.size() == 2);
    CHECK(view.canopy[0].speciesId == 0);
    CHECK(view.canopy[1].speciesId == 1);
    REQUIRE(view.undergrowth.size() == 1);
    CHECK(view.undergrowth[0].xM == 12);
    CHECK(view.speciesNames.size() == 4);
    // No rectangle (a simulation file without its area): the plants' bounding box, and then
    // every tree is kept.
    const html::SceneView box = html::plotView("box", 0, 0, 0, 0, {}, canopy, {plant(1, 12, 11, 0.3)});
    CHECK(box.x0M == 7);
    CHECK(box.y0M == 11);
    CHECK(box.x1M == 500);
    CHECK(box.y1M == 500);
    CHECK(box.canopy.size() == 4);
    const html::SceneView none = html::plotView("none", 0, 0, 0, 0, {}, {}, {});
    CHECK(none.x1M - none.x0M == 1);
    CHECK(none.y1M - none.y0M == 1);
}
