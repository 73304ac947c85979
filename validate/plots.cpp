#include "plots.h"

#include <algorithm>
#include <cstdio>
#include <cmath>
#include <limits>
#include <sstream>

#include "chart.h"

namespace eco::validate {

void writeXYPlotPng(const std::string& path, const std::string& title, const std::string& xLabel,
                    const std::string& yLabel, const std::vector<PlotSeries>& series) {
    double x0 = std::numeric_limits<double>::infinity(), x1 = -x0, y0 = x0, y1 = -x0;
    for (const PlotSeries& s : series)
        for (std::size_t i = 0; i < std::min(s.x.size(), s.y.size()); ++i) {
            if (!std::isfinite(s.x[i]) || !std::isfinite(s.y[i])) continue;
            x0 = std::min(x0, s.x[i]);
            x1 = std::max(x1, s.x[i]);
            y0 = std::min(y0, s.y[i]);
            y1 = std::max(y1, s.y[i]);
        }
    if (!std::isfinite(x0)) x0 = 0, x1 = 1, y0 = 0, y1 = 1;
    if (!(x1 > x0)) x0 -= 0.5, x1 += 0.5;
    if (!(y1 > y0)) y0 -= 0.5, y1 += 0.5;
    const double padX = 0.04 * (x1 - x0), padY = 0.06 * (y1 - y0);
    x0 -= padX, x1 += padX, y0 -= padY, y1 += padY;

    Chart ch;
    ch.left = 78;
    ch.top = 40;
    ch.width = 640;
    ch.height = 420;
    const auto label = [](double v) {
        std::ostringstream os;
        os.precision(4);
        os << v;
        return os.str();
    };
    ch.x = {x0, x1, niceTicks(x0, x1, 6), label};
    ch.y = {y0, y1, niceTicks(y0, y1, 6), label};
    ch.style.gridColour = {0.85f, 0.85f, 0.85f};
    ch.style.tickFontPx = 12;
    ch.style.xLabelCharPx = 0;
    ch.style.xLabelDx = -12;
    ch.style.yLabelX = 6;
    ch.style.yLabelDy = 4;
    ch.style.frameAllSides = true;
    for (const PlotSeries& s : series) {
        ChartSeries cs{s.name, s.x, s.y, s.colour};
        cs.strokeOffsetsPx = s.line ? std::vector<int>{0} : std::vector<int>{};
        cs.skipNonFinite = true;
        cs.pointRadiusPx = s.pointRadiusPx;
        ch.series.push_back(std::move(cs));
    }
    const Rgb black{0.f, 0.f, 0.f};
    ch.texts = {{ch.left, 17, title, 15, black},
                {ch.left + ch.width / 2 - 4 * static_cast<int>(xLabel.size()), ch.top + ch.height + 44, xLabel, 13, black},
                {6, ch.top - 5, yLabel, 13, black}};
    Canvas c(ch.left + ch.width + 20, ch.top + ch.height + 58);
    drawChart(c, ch);
    std::vector<std::pair<std::string, Rgb>> legend;
    for (const PlotSeries& s : series)
        if (!s.name.empty()) legend.emplace_back(s.name, s.colour);
    if (legend.empty()) c.writePng(path);
    else withLegend(c, "", legend).writePng(path);
}

html::LinePlot toLinePlot(const std::string& title, const std::string& xLabel, const std::string& yLabel,
                          const std::vector<PlotSeries>& series) {
    html::LinePlot plot;
    plot.title = title;
    plot.xLabel = xLabel;
    plot.yLabel = yLabel;
    html::SeriesGroup group{title, {}};
    for (std::size_t i = 0; i < series.size(); ++i) {
        const PlotSeries& s = series[i];
        char hex[8];
        std::snprintf(hex, sizeof hex, "#%02x%02x%02x", static_cast<int>(std::lround(s.colour[0] * 255)),
                      static_cast<int>(std::lround(s.colour[1] * 255)), static_cast<int>(std::lround(s.colour[2] * 255)));
        group.series.push_back({s.name.empty() ? "series " + std::to_string(i + 1) : s.name, s.x, s.y, hex, false});
    }
    plot.groups.push_back(group);
    return plot;
}

html::LinePlot populationLinePlot(const std::vector<YearRecord>& census, const Biome& biome, const std::string& title) {
    html::LinePlot plot;
    plot.title = title;
    plot.xLabel = "year";
    plot.yLabel = "plants";
    plot.logYToggle = true;
    html::SeriesGroup group{"plants per species", {}};
    for (std::size_t s = 0; s < biome.species.size(); ++s) {
        html::Series line{biome.species[s].name, {}, {}, html::categoryHex(static_cast<int>(s)), false};
        bool any = false;
        for (const YearRecord& r : census) {
            const double c = s < r.count.size() ? r.count[s] : 0;
            any = any || c > 0;
            line.x.push_back(r.year);
            line.y.push_back(c);
        }
        if (any) group.series.push_back(line);
    }
    plot.groups.push_back(group);
    return plot;
}

html::SceneView plotSceneView(const std::string& title, const sim::SimArea& area, const Biome& biome,
                              const std::vector<Plant>& canopy, const std::vector<UndergrowthPlant>& undergrowth) {
    std::vector<std::string> names;
    for (const Species& s : biome.species) names.push_back(s.name);
    std::vector<Plant> plants(undergrowth.size());
    for (std::size_t i = 0; i < undergrowth.size(); ++i) {
        plants[i].speciesId = undergrowth[i].speciesId;
        plants[i].xM = undergrowth[i].xM;
        plants[i].yM = undergrowth[i].yM;
        plants[i].groundZM = undergrowth[i].groundZM;
        plants[i].heightM = undergrowth[i].heightM;
        plants[i].crownRadiusM = undergrowth[i].crownRadiusM;
    }
    return html::plotView(title, area.x0, area.y0, area.x1, area.y1, std::move(names), canopy, std::move(plants));
}

}  // namespace eco::validate
