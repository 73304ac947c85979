#include "chart.h"

#include <algorithm>
#include <cmath>
#include <sstream>

namespace eco {

double Chart::px(double v) const {
    return style.multiplyFirst ? left + (v - x.min) * width / (x.max - x.min) : left + (v - x.min) / (x.max - x.min) * width;
}

double Chart::py(double v) const {
    return style.multiplyFirst ? top + height - (v - y.min) * height / (y.max - y.min)
                               : top + height - (v - y.min) / (y.max - y.min) * height;
}

namespace {

void drawAxes(Canvas& c, const Chart& ch) {
    const Rgb black{0.f, 0.f, 0.f};
    const int l = ch.left, t = ch.top, r = ch.left + ch.width, b = ch.top + ch.height;
    c.drawLine(l, b, r, b, black);
    c.drawLine(l, t, l, b, black);
    if (ch.style.frameAllSides) {
        c.drawLine(l, t, r, t, black);
        c.drawLine(r, t, r, b, black);
    }
}

}  // namespace

void drawChart(Canvas& c, const Chart& ch) {
    const ChartStyle& st = ch.style;
    const Rgb black{0.f, 0.f, 0.f};
    const int l = ch.left, t = ch.top, r = ch.left + ch.width, b = ch.top + ch.height;
    for (double v : ch.x.ticks) {
        const double p = ch.px(v);
        if (st.grid) c.drawLine(p, t, p, b, st.gridColour);
        if (st.tickMarkPx > 0) c.drawLine(p, b, p, b + st.tickMarkPx, black);
        if (ch.x.label) {
            const std::string s = ch.x.label(v);
            c.text(static_cast<int>(p) - st.xLabelCharPx * static_cast<int>(s.size()) + st.xLabelDx, b + st.xLabelDy, s,
                   st.tickFontPx, black);
        }
    }
    for (double v : ch.y.ticks) {
        const double p = ch.py(v);
        if (st.grid) c.drawLine(l, p, r, p, st.gridColour);
        if (st.tickMarkPx > 0) c.drawLine(l - st.tickMarkPx, p, l, p, black);
        if (ch.y.label) {
            const std::string s = ch.y.label(v);
            c.text(st.yLabelX >= 0 ? st.yLabelX : l - 10 - 8 * static_cast<int>(s.size()), static_cast<int>(p) + st.yLabelDy,
                   s, st.tickFontPx, black);
        }
    }
    if (!st.axesOnTop) drawAxes(c, ch);
    if (ch.reference && std::isfinite(ch.reference->y) && ch.reference->y > ch.y.min && ch.reference->y < ch.y.max) {
        const double p = ch.py(ch.reference->y);
        if (ch.reference->dashed)
            for (int x = l; x < r; x += 8) c.drawLine(x, p, std::min(x + 4, r), p, ch.reference->colour);
        else
            c.drawLine(l, p, r, p, ch.reference->colour);
    }
    for (const ChartSeries& s : ch.series) {
        const auto yOf = [&](double v) { return s.clampToAxes ? std::clamp(v, ch.y.min, ch.y.max) : v; };
        if (s.bars) {
            for (std::size_t i = 0; i + 1 < s.x.size() && i < s.y.size(); ++i) {
                if (!(s.y[i] > ch.y.min)) continue;
                c.fillRect(static_cast<int>(ch.px(s.x[i])) + 1, static_cast<int>(ch.py(yOf(s.y[i]))),
                           static_cast<int>(ch.px(s.x[i + 1])) - 1, static_cast<int>(ch.py(ch.y.min)), s.colour);
            }
            continue;
        }
        const std::size_t n = std::min(s.x.size(), s.y.size());
        for (std::size_t i = 1; i < n; ++i) {
            if (s.skipNonFinite && !std::isfinite(s.x[i - 1] + s.y[i - 1] + s.x[i] + s.y[i])) continue;
            for (int o : s.strokeOffsetsPx)
                c.drawLine(ch.px(s.x[i - 1]), ch.py(yOf(s.y[i - 1])) + o, ch.px(s.x[i]), ch.py(yOf(s.y[i])) + o, s.colour);
        }
        if (s.pointRadiusPx > 0)
            for (std::size_t i = 0; i < n; ++i)
                if (std::isfinite(s.x[i] + s.y[i])) c.fillDisc(ch.px(s.x[i]), ch.py(s.y[i]), s.pointRadiusPx, s.colour, 0.9f);
    }
    if (st.axesOnTop) drawAxes(c, ch);
    for (const ChartText& text : ch.texts) c.text(text.x, text.y, text.text, text.sizePx, text.colour);
}

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
    for (double v = std::ceil(lo / step - 1e-9) * step; v <= hi + 1e-9 * step; v += step) t.push_back(std::abs(v) < 1e-12 * step ? 0.0 : v);
    return t;
}

Canvas chartCanvas(std::vector<ChartSeries> series, double xmin, double xmax, double ymin, double ymax,
                   const std::string& xlabel, const std::string& ylabel, double referenceY) {
    Chart ch;
    ch.left = 70;
    ch.top = 16;
    ch.width = 640;
    ch.height = 400;
    const auto label = [](double v) {
        std::ostringstream os;
        os << v;
        return os.str();
    };
    ch.x = {xmin, xmax, niceTicks(xmin, xmax), label};
    ch.y = {ymin, ymax, niceTicks(ymin, ymax), label};
    ch.style.axesOnTop = true;
    if (std::isfinite(referenceY)) ch.reference = ChartReference{referenceY, {0.4f, 0.4f, 0.4f}, true};
    for (ChartSeries& s : series) {
        s.strokeOffsetsPx = {0, 1};  // 2 px wide
        s.clampToAxes = true;
    }
    ch.series = std::move(series);
    const Rgb black{0.f, 0.f, 0.f};
    ch.texts = {{ch.left + ch.width / 2 - 4 * static_cast<int>(xlabel.size()), ch.top + ch.height + 44, xlabel, 14, black},
                {4, ch.top + 12, ylabel, 14, black}};
    Canvas c(ch.left + ch.width + 20, ch.top + ch.height + 56);
    drawChart(c, ch);
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
