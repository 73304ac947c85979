// Charts: x-y line and bar plots with axes, ticks and labels, drawn on a Canvas. The one
// plotting helper of the toolkit (pair correlations, height histograms, ...).
#pragma once

#include <limits>
#include <string>
#include <vector>

#include "image_out.h"

namespace eco {

struct ChartSeries {
    std::string name;
    std::vector<double> x, y;
    Rgb colour{0.f, 0.f, 0.f};
    bool bars = false;  ///< draw as bars between consecutive x (x has y.size() + 1 edges)
};

/// Tick positions: 1, 2 or 5 times a power of ten, about `target` of them.
std::vector<double> niceTicks(double lo, double hi, int target = 6);

/// A 640 x 400 plot area with margins for tick labels, x in [xmin, xmax], y in [ymin, ymax]
/// (values outside drawn at the edge), grey grid at the ticks, lines 2 px wide, and a dashed
/// horizontal reference at referenceY (NaN = none). Returns the whole canvas, no legend.
Canvas chartCanvas(const std::vector<ChartSeries>& series, double xmin, double xmax, double ymin, double ymax,
                   const std::string& xlabel, const std::string& ylabel,
                   double referenceY = std::numeric_limits<double>::quiet_NaN());

/// Upper y limit for a set of series: the largest finite value, at least `floor`, with 8 %
/// headroom.
double chartTop(const std::vector<ChartSeries>& series, double floor);

}  // namespace eco
