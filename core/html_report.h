// Self-contained HTML reports (issue 31 item 4): one file that opens offline in any browser,
// with the pictures embedded as data URIs, interactive line plots (population over time,
// pair correlation g(r)) and a pan-and-zoom top view of a scene's plants, all drawn by a
// small hand-written script (canvas 2D, no libraries, no network). `eco run` and
// `eco validate` write one beside their report.md (docs/report.md).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "plants.h"

namespace eco::html {

/// Text with &, <, >, " and ' escaped for HTML content and attribute values.
std::string escape(const std::string& text);
/// Standard base64 (RFC 4648, with '=' padding) of `size` bytes.
std::string base64(const void* data, std::size_t size);
/// The bytes of `base64` decoded; IoError-free: characters outside the alphabet are skipped.
std::vector<std::uint8_t> base64Decode(const std::string& base64);
/// "data:image/png;base64,..." of a picture file (type from its extension: png, jpg, svg);
/// "" when the file cannot be read.
std::string dataUriOfFile(const std::string& path);
/// A JSON string literal (quotes included) of UTF-8 text; safe inside a <script> element
/// ('<' is written as \u003c, so "</script>" cannot end it).
std::string jsonString(const std::string& text);
/// "#rrggbb" of categoryColour(i) (core/image_out.h): the PNGs' colour of category i.
std::string categoryHex(int i);

/// One line of a plot: points (x[k], y[k]) joined in order; NaN leaves a gap.
struct Series {
    std::string name;
    std::vector<double> x, y;
    std::string colour;  ///< CSS colour; "" = categoryHex(index in its group)
    bool dashed = false;
};

/// A set of series shown together; a plot with several groups gets a selector.
struct SeriesGroup {
    std::string name;
    std::vector<Series> series;
};

/// An interactive line plot: hover reads the values, the legend toggles series, dragging
/// selects an x range to zoom into, double-click resets; optional log y.
struct LinePlot {
    std::string title, xLabel, yLabel;
    std::vector<SeriesGroup> groups;
    bool logYToggle = false;    ///< offer a "log y" check box
    double referenceY = 0;      ///< a horizontal grey reference line (e.g. g = 1) ...
    bool hasReferenceY = false; ///< ... drawn when true
    std::string referenceLabel;
};

/// The plants of a scene for the top view: world rectangle, species names (colours by
/// species id: categoryHex) and the plants; canopy trees are drawn above the undergrowth,
/// half transparent, with an outline.
struct SceneView {
    std::string title;
    double x0M = 0, y0M = 0, x1M = 0, y1M = 0;  ///< world rectangle shown, metres
    std::vector<std::string> speciesNames;
    std::vector<Plant> canopy, undergrowth;
};

/// A top view of a plot [x0, x1] x [y0, y1] (world metres), as both reports show a simulated
/// plot: its undergrowth, and of `canopy` (a simulation keeps its whole scene's) the trees
/// whose crown reaches the plot. An empty or inverted rectangle is replaced by the plants'
/// bounding box (a unit square when there are none).
SceneView plotView(std::string title, double x0M, double y0M, double x1M, double y1M,
                   std::vector<std::string> speciesNames, const std::vector<Plant>& canopy,
                   std::vector<Plant> undergrowth);

/// An HTML document built section by section; str() gives the whole page with its style
/// sheet and script. Everything passed as text is escaped; raw() and markdown() are the
/// only ways to add markup.
class Document {
public:
    explicit Document(std::string title);

    void heading(int level, const std::string& text);
    void paragraph(const std::string& text);
    /// Markup as it is (the caller escapes).
    void raw(const std::string& html);
    /// A table; `numeric[c]` right-aligns column c (missing entries: left).
    void table(const std::vector<std::string>& header, const std::vector<std::vector<std::string>>& rows,
               const std::vector<bool>& numeric = {});
    /// A picture file embedded as a data URI, with its caption; nothing when it is missing.
    void picture(const std::string& path, const std::string& caption);
    /// Preformatted text (tables printed by the tools).
    void preformatted(const std::string& text);
    /// A small subset of Markdown as HTML: '#' headings, pipe tables, fenced code, '- ' lists,
    /// images (embedded from `baseDir`), paragraphs with `code`, **bold** and *italic*.
    void markdown(const std::string& text, const std::string& baseDir = "");
    void linePlot(const LinePlot& plot);
    void sceneView(const SceneView& scene);

    /// The whole page.
    std::string str() const;

private:
    std::string title_;
    std::string body_;
    int nextId_ = 0;
};

/// Write the page atomically (core/atomic_file.h). IoError naming the path.
void writeDocument(const std::string& path, const Document& doc);

}  // namespace eco::html
