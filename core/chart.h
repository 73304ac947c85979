// Charts: the one plotting helper of the toolkit. A chart is a plot rectangle on a Canvas
// with two axes (ticks, grid, tick labels), optional reference line, series (lines, bars,
// markers) and free text; every picture with axes is drawn by drawChart: single plots
// (chartCanvas: eco pcf's and eco inspect's, calibration, instancing, validation plots),
// small multiples (chartPanels: pair correlations per species pair, height histograms per
// species, eco compare's regions), and the world-metre axes and scale bar round every map
// (mapFrame: terrain, abiotics, CHM, species, cluster, canopy, scene, forest floor, the
// simulator's plant pictures).
#pragma once

#include <functional>
#include <limits>
#include <optional>
#include <string>
#include <vector>

#include "image_out.h"

namespace eco {

struct ChartSeries {
    std::string name;
    std::vector<double> x, y;
    Rgb colour{0.f, 0.f, 0.f};
    bool bars = false;  ///< draw as bars between consecutive x (x has y.size() + 1 edges)
    /// Lines: one stroke per offset (pixels, downwards), so {0, 1} is 2 px wide; {} = no line.
    std::vector<int> strokeOffsetsPx{0};
    double pointRadiusPx = 0;     ///< markers (opacity 0.9); 0 = none
    bool clampToAxes = false;     ///< lines and bars: y values outside the y range drawn at its edge
    bool skipNonFinite = false;   ///< lines: leave out segments with a non-finite end
};

struct ChartAxis {
    double min = 0, max = 1;
    std::vector<double> ticks;  ///< values with a grid line, tick mark and label
    std::function<std::string(double)> label;  ///< tick label text; unset = no labels
};

/// Tick label placement and look. x labels: baseline at plot bottom + xLabelDy, left end at
/// tick - xLabelCharPx * length + xLabelDx. y labels: baseline at tick + yLabelDy, left end at
/// yLabelX when >= 0, else right-aligned as plot left - 10 - 8 * length.
struct ChartStyle {
    bool grid = true;
    Rgb gridColour{0.82f, 0.82f, 0.82f};
    int tickMarkPx = 5;  ///< black tick marks outside the plot; 0 = none
    int tickFontPx = 13;
    int xLabelDx = 0, xLabelCharPx = 4, xLabelDy = 20;
    int yLabelX = -1, yLabelDy = 5;
    bool frameAllSides = false;  ///< a box round the plot instead of the left and bottom axes
    bool axesOnTop = false;      ///< axes drawn after the series (else before)
    /// Value to pixel: (v - min) / (max - min) * length, or, MultiplyFirst, (v - min) * length /
    /// (max - min) (the comparison panels' rounding, kept so their pixels do not change).
    bool multiplyFirst = false;
};

/// A horizontal line across the plot at y, drawn before the series when inside (min, max).
struct ChartReference {
    double y = 1;
    Rgb colour{0.4f, 0.4f, 0.4f};
    bool dashed = true;  ///< 4 px dashes every 8 px
};

struct ChartText {
    int x = 0, y = 0;  ///< baseline start, canvas pixels
    std::string text;
    int sizePx = 13;
    Rgb colour{0.f, 0.f, 0.f};
};

struct Chart {
    int left = 0, top = 0, width = 640, height = 400;  ///< plot rectangle on the canvas
    ChartAxis x, y;
    ChartStyle style;
    std::optional<ChartReference> reference;
    std::vector<ChartSeries> series;
    std::vector<ChartText> texts;  ///< titles and axis labels, drawn last
    /// Canvas pixel of a value.
    double px(double v) const;
    double py(double v) const;
};

/// Draw in this order: grid, tick marks and labels (x, then y); the axes unless axesOnTop;
/// the reference; the series in order (lines, then markers, of each); the axes if axesOnTop;
/// the texts.
void drawChart(Canvas& canvas, const Chart& chart);

/// Tick positions: 1, 2 or 5 times a power of ten, about `target` of them, all inside
/// [lo, hi] (ends included when they fall on a step).
std::vector<double> niceTicks(double lo, double hi, int target = 6);

/// A tick label with the decimals its step needs: 150 -> "150", 2.5 -> "2.5", 0.25 -> "0.25";
/// never "-0".
std::string tickLabel(double v, double step);

/// Line style of a key entry drawn as a short line sample (or a filled box for bars).
struct ChartKey {
    std::string name;
    Rgb colour{0.f, 0.f, 0.f};
    bool dashed = false;
    int widthPx = 2;
    bool box = false;  ///< a filled square (bars, areas) instead of a line sample
};

/// One small multiple: a plot with its own ranges, title and series.
struct ChartPanel {
    std::string title;     ///< above the plot, bold-ish (14 px); cut with "..." to the panel width
    std::string subtitle;  ///< second line, grey (11 px); "" = none
    double xmin = 0, xmax = 1, ymin = 0, ymax = 1;
    std::vector<ChartSeries> series;
    std::optional<ChartReference> reference;
};

/// Layout of chartPanels: a title (wrapped to the picture width), notes under it, a key of
/// line styles, then the panels row by row, each with ticks and labels on both axes.
struct ChartPanelsLayout {
    std::string title;
    std::vector<std::string> notes;  ///< one line each under the title (wrapped when long)
    std::vector<ChartKey> key;
    std::string xlabel, ylabel;      ///< on every panel, with units ("r (m)")
    int columns = 3;
    int plotWidthPx = 300, plotHeightPx = 180;
    int ticksPerAxis = 5;
};

/// Small multiples: every panel drawn by drawChart with round ticks on both axes, lines 2 px
/// wide, values outside the y range at its edge. Returns the whole picture.
Canvas chartPanels(const std::vector<ChartPanel>& panels, const ChartPanelsLayout& layout);

/// `text` broken at spaces into lines of at most `maxChars` characters (longer words alone).
std::vector<std::string> wrapText(const std::string& text, std::size_t maxChars);

/// World rectangle of a north-up map picture, metres: x0 west edge, x1 east, y0 south, y1 north.
struct MapExtent {
    double x0M = 0, y0M = 0, x1M = 1, y1M = 1;
};

/// A map picture framed with world-metre axes: a box round it, tick marks and labels at
/// round steps (niceTicks) along the bottom (x, east) and left (y, north) edges, and under
/// them a scale bar of a round length with "x, y in m (world), north up". Tick k sits on the
/// pixel column plotLeft + (x - x0) / (x1 - x0) * picture width (the left edge of the pixel
/// that starts at x), rows likewise from the north edge.
struct MapFrame {
    Canvas canvas;
    int plotLeft = 0, plotTop = 0;  ///< where the picture's top-left pixel is on the canvas
};
MapFrame mapFrame(const Canvas& picture, const MapExtent& world);

/// World rectangle of a w x h picture of a grid drawn `factor` cells per pixel from its
/// north-west corner (gridToCanvas, writeCategoryPng): the west and north edges are the
/// grid's, the others where the last whole pixel ends.
template <class T>
MapExtent gridPictureExtent(const Grid<T>& g, int factor, int w, int h) {
    const double north = g.originY() + g.extentY();
    return {g.originX(), north - static_cast<double>(h) * factor * g.cellSizeM(),
            g.originX() + static_cast<double>(w) * factor * g.cellSizeM(), north};
}

/// Cells per pixel so that the longer side of a w x h grid is at most maxSide pixels.
int downsampleFactor(int w, int h, int maxSide);

/// The plot of eco inspect and eco pcf: a 640 x 400 plot area with margins for tick labels,
/// x in [xmin, xmax], y in [ymin, ymax] (values outside drawn at the edge), grey grid at the
/// ticks, lines 2 px wide, and a dashed horizontal reference at referenceY (NaN = none).
/// Returns the whole canvas, no legend.
Canvas chartCanvas(std::vector<ChartSeries> series, double xmin, double xmax, double ymin, double ymax,
                   const std::string& xlabel, const std::string& ylabel,
                   double referenceY = std::numeric_limits<double>::quiet_NaN());

/// Upper y limit for a set of series: the largest finite value, at least `floor`, with 8 %
/// headroom.
double chartTop(const std::vector<ChartSeries>& series, double floor);

}  // namespace eco
