#include "chart.h"

#include <algorithm>
#include <cmath>
#include <sstream>

namespace eco {

namespace {
std::string tickLabel(double v) {
    std::ostringstream os;
    os << v;
    return os.str();
}
}  // namespace

std::vector<double> niceTicks(double lo, double hi, int target) {
    std::vector<double> t;
    if (!(hi > lo)) return {lo};
    const double raw = (hi - lo) / target;
    const double mag = std::pow(10.0, std::floor(std::log10(raw)));
    double step = mag;
    for (double m : {1.0, 2.0, 5.0, 10.0})
        if (raw <= m * mag) {
            step = m * mag;
            break;
        }
    for (double v = std::ceil(lo / step - 1e-9) * step; v <= hi + 1e-9 * step; v += step) t.push_back(std::abs(v) < 1e-12 * step ? 0.0 : v);
    return t;
}

Canvas chartCanvas(const std::vector<ChartSeries>& series, double xmin, double xmax, double ymin, double ymax,
                   const std::string& xlabel, const std::string& ylabel, double referenceY) {
    const int w = 640, h = 400, left = 70, right = 20, top = 16, bottom = 56;
    Canvas c(left + w + right, top + h + bottom);
    const Rgb black{0.f, 0.f, 0.f}, grey{0.82f, 0.82f, 0.82f};
    auto px = [&](double x) { return left + (x - xmin) / (xmax - xmin) * w; };
    auto py = [&](double y) { return top + h - (y - ymin) / (ymax - ymin) * h; };
    for (double t : niceTicks(xmin, xmax)) {
        c.drawLine(px(t), top, px(t), top + h, grey);
        c.drawLine(px(t), top + h, px(t), top + h + 5, black);
        c.text(static_cast<int>(px(t)) - 4 * static_cast<int>(tickLabel(t).size()), top + h + 20, tickLabel(t), 13, black);
    }
    for (double t : niceTicks(ymin, ymax)) {
        c.drawLine(left, py(t), left + w, py(t), grey);
        c.drawLine(left - 5, py(t), left, py(t), black);
        c.text(left - 10 - 8 * static_cast<int>(tickLabel(t).size()), static_cast<int>(py(t)) + 5, tickLabel(t), 13, black);
    }
    if (std::isfinite(referenceY) && referenceY > ymin && referenceY < ymax)
        for (int x = left; x < left + w; x += 8) c.drawLine(x, py(referenceY), std::min(x + 4, left + w), py(referenceY), {0.4f, 0.4f, 0.4f});
    auto clampY = [&](double y) { return std::clamp(y, ymin, ymax); };
    for (const ChartSeries& s : series) {
        if (s.bars) {
            for (std::size_t i = 0; i + 1 < s.x.size() && i < s.y.size(); ++i) {
                if (!(s.y[i] > ymin)) continue;
                c.fillRect(static_cast<int>(px(s.x[i])) + 1, static_cast<int>(py(clampY(s.y[i]))), static_cast<int>(px(s.x[i + 1])) - 1,
                           static_cast<int>(py(ymin)), s.colour);
            }
            continue;
        }
        for (std::size_t i = 0; i + 1 < s.x.size(); ++i)
            for (int o = 0; o < 2; ++o)  // 2 px wide
                c.drawLine(px(s.x[i]), py(clampY(s.y[i])) + o, px(s.x[i + 1]), py(clampY(s.y[i + 1])) + o, s.colour);
    }
    c.drawLine(left, top + h, left + w, top + h, black);
    c.drawLine(left, top, left, top + h, black);
    c.text(left + w / 2 - 4 * static_cast<int>(xlabel.size()), top + h + 44, xlabel, 14, black);
    c.text(4, top + 12, ylabel, 14, black);
    return c;
}

double chartTop(const std::vector<ChartSeries>& series, double floor) {
    double m = floor;
    for (const ChartSeries& s : series)
        for (double v : s.y)
            if (std::isfinite(v)) m = std::max(m, v);
    return m * 1.08;
}

}  // namespace eco
