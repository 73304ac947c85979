// Small x-y plots for the validation report (log-log self-thinning fits, time series), drawn
// by the one chart helper (core/chart.h).
#pragma once

#include <string>
#include <vector>

#include "html_report.h"
#include "image_out.h"
#include "plants.h"
#include "sim_config.h"
#include "sim_file.h"

namespace eco::validate {

struct PlotSeries {
    std::string name;          ///< legend entry ("" = not in the legend)
    std::vector<double> x, y;
    Rgb colour{0.f, 0.f, 0.f};
    bool line = false;         ///< connect the points with lines
    double pointRadiusPx = 0;  ///< 0 = no markers
};

/// Axes with ticks and labels, the series, and a legend; ranges from the data. Atomic PNG.
void writeXYPlotPng(const std::string& path, const std::string& title, const std::string& xLabel,
                    const std::string& yLabel, const std::vector<PlotSeries>& series);

/// The same series as an interactive plot for report.html (line or points as drawn here).
html::LinePlot toLinePlot(const std::string& title, const std::string& xLabel, const std::string& yLabel,
                          const std::vector<PlotSeries>& series);

/// Plants per species (those that ever had one) and year of a census, for report.html.
html::LinePlot populationLinePlot(const std::vector<YearRecord>& census, const Biome& biome, const std::string& title);

/// A simulated plot from above for report.html (html::plotView): its undergrowth and the
/// canopy trees whose crown reaches it, species named and coloured as in `biome`.
html::SceneView plotSceneView(const std::string& title, const sim::SimArea& area, const Biome& biome,
                              const std::vector<Plant>& canopy, const std::vector<UndergrowthPlant>& undergrowth);

}  // namespace eco::validate
