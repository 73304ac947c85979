#include "plots.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>

namespace eco::validate {

namespace {

std::vector<double> niceTicks(double lo, double hi, int target) {
    std::vector<double> t;
    if (!(hi > lo)) return {lo};
    const double raw = (hi - lo) / target;
    const double mag = std::pow(10.0, std::floor(std::log10(raw)));
    double step = 10 * mag;
    for (double m : {1.0, 2.0, 5.0, 10.0})
        if (raw <= m * mag) {
            step = m * mag;
            break;
        }
    for (double v = std::ceil(lo / step - 1e-9) * step; v <= hi + 1e-9 * step; v += step)
        t.push_back(std::abs(v) < 1e-12 * step ? 0.0 : v);
    return t;
}

std::string label(double v) {
    std::ostringstream os;
    os.precision(4);
    os << v;
    return os.str();
}

}  // namespace

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

    const int w = 640, h = 420, left = 78, right = 20, top = 40, bottom = 58;
    Canvas c(left + w + right, top + h + bottom);
    const Rgb black{0.f, 0.f, 0.f}, grey{0.85f, 0.85f, 0.85f};
    auto px = [&](double x) { return left + (x - x0) / (x1 - x0) * w; };
    auto py = [&](double y) { return top + h - (y - y0) / (y1 - y0) * h; };
    for (double t : niceTicks(x0, x1, 6)) {
        c.drawLine(px(t), top, px(t), top + h, grey);
        c.drawLine(px(t), top + h, px(t), top + h + 5, black);
        c.text(static_cast<int>(px(t)) - 12, top + h + 20, label(t), 12, black);
    }
    for (double t : niceTicks(y0, y1, 6)) {
        c.drawLine(left, py(t), left + w, py(t), grey);
        c.drawLine(left - 5, py(t), left, py(t), black);
        c.text(6, static_cast<int>(py(t)) + 4, label(t), 12, black);
    }
    c.drawLine(left, top, left, top + h, black);
    c.drawLine(left, top + h, left + w, top + h, black);
    c.drawLine(left, top, left + w, top, black);
    c.drawLine(left + w, top, left + w, top + h, black);
    for (const PlotSeries& s : series) {
        const std::size_t n = std::min(s.x.size(), s.y.size());
        if (s.line)
            for (std::size_t i = 1; i < n; ++i)
                if (std::isfinite(s.x[i - 1] + s.y[i - 1] + s.x[i] + s.y[i]))
                    c.drawLine(px(s.x[i - 1]), py(s.y[i - 1]), px(s.x[i]), py(s.y[i]), s.colour);
        if (s.pointRadiusPx > 0)
            for (std::size_t i = 0; i < n; ++i)
                if (std::isfinite(s.x[i] + s.y[i])) c.fillDisc(px(s.x[i]), py(s.y[i]), s.pointRadiusPx, s.colour, 0.9f);
    }
    c.text(left, 17, title, 15, black);
    c.text(left + w / 2 - 4 * static_cast<int>(xLabel.size()), top + h + 44, xLabel, 13, black);
    c.text(6, top - 5, yLabel, 13, black);
    std::vector<std::pair<std::string, Rgb>> legend;
    for (const PlotSeries& s : series)
        if (!s.name.empty()) legend.emplace_back(s.name, s.colour);
    if (legend.empty()) c.writePng(path);
    else withLegend(c, "", legend).writePng(path);
}

}  // namespace eco::validate
