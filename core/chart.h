// Charts: the one plotting helper of the toolkit. A chart is a plot rectangle on a Canvas
// with two axes (ticks, grid, tick labels), optional reference line, series (lines, bars,
// markers) and free text; every picture with axes is drawn by drawChart (pair correlations
// and height histograms of eco inspect and eco pcf, the simulator's species counts, the
// validation plots and the comparison panels of eco compare). The style fields keep each of
// those pictures as it was.
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

/// Tick positions: 1, 2 or 5 times a power of ten, about `target` of them.
std::vector<double> niceTicks(double lo, double hi, int target = 6);

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
