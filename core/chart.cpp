#include "chart.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
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

namespace {

/// 1, 2 or 5 times a power of ten, the smallest not below (hi - lo) / target.
double niceStep(double lo, double hi, int target) {
    const double raw = (hi - lo) / std::max(1, target);
    const double mag = std::pow(10.0, std::floor(std::log10(raw)));
    for (double m : {1.0, 2.0, 5.0})
        if (raw <= m * mag * (1 + 1e-9)) return m * mag;
    return 10 * mag;
}

}  // namespace

std::vector<double> niceTicks(double lo, double hi, int target) {
    std::vector<double> t;
    if (!(hi > lo) || !std::isfinite(hi - lo)) return {lo};
    const double step = niceStep(lo, hi, target);
    // Multiples of the step by index, so 0.1 * 3 is 0.3 and not a sum drifting off it.
    const double first = std::ceil(lo / step - 1e-9);
    for (double k = first; k * step <= hi + 1e-9 * step; k += 1) {
        const double v = k * step;
        t.push_back(std::abs(v) < 1e-12 * step ? 0.0 : v);
    }
    return t;
}

std::string tickLabel(double v, double step) {
    int decimals = 0;
    if (step > 0 && std::isfinite(step))
        while (decimals < 6 && std::abs(step * std::pow(10.0, decimals) - std::round(step * std::pow(10.0, decimals))) > 1e-6)
            ++decimals;
    if (std::abs(v) < 0.5 * std::pow(10.0, -decimals)) v = 0;  // no "-0"
    char buf[64];
    std::snprintf(buf, sizeof buf, "%.*f", decimals, v);
    return buf;
}

std::vector<std::string> wrapText(const std::string& text, std::size_t maxChars) {
    std::vector<std::string> lines;
    std::istringstream words(text);
    std::string word, line;
    while (words >> word) {
        if (!line.empty() && line.size() + 1 + word.size() > maxChars) {
            lines.push_back(line);
            line.clear();
        }
        line += (line.empty() ? "" : " ") + word;
    }
    if (!line.empty()) lines.push_back(line);
    return lines;
}

namespace {

/// Step of a tick list (0 when it has fewer than two ticks).
double stepOf(const std::vector<double>& ticks) { return ticks.size() > 1 ? ticks[1] - ticks[0] : 0.0; }

std::function<std::string(double)> labelsFor(const std::vector<double>& ticks) {
    const double step = stepOf(ticks);
    return [step](double v) { return tickLabel(v, step); };
}

/// Rough width of DejaVu Sans text (mixed case and digits average about 0.56 of the size).
int textWidthPx(const std::string& s, int sizePx) { return static_cast<int>(std::ceil(0.56 * sizePx * s.size())); }

std::string cutToWidth(const std::string& s, int sizePx, int widthPx) {
    if (textWidthPx(s, sizePx) <= widthPx) return s;
    const std::size_t keep = static_cast<std::size_t>(std::max(0, widthPx / std::max(1, textWidthPx("x", sizePx)) - 3));
    return s.substr(0, keep) + "...";
}

/// Draw a key entry's sample at (x, baseline y); returns the x after its text.
int drawKeyEntry(Canvas& c, int x, int y, const ChartKey& k) {
    const int mid = y - 5;
    if (k.box) {
        c.fillRect(x, mid - 6, x + 14, mid + 6, k.colour);
    } else {
        for (int o = 0; o < std::max(1, k.widthPx); ++o) {
            if (k.dashed)
                for (int d = 0; d < 28; d += 8) c.drawLine(x + d, mid + o, x + d + 4, mid + o, k.colour);
            else
                c.drawLine(x, mid + o, x + 28, mid + o, k.colour);
        }
    }
    const int tx = x + (k.box ? 20 : 34);
    c.text(tx, y, k.name, 13, {0.f, 0.f, 0.f});
    return tx + textWidthPx(k.name, 13) + 18;
}

}  // namespace

Canvas chartPanels(const std::vector<ChartPanel>& panels, const ChartPanelsLayout& layout) {
    const Rgb black{0.f, 0.f, 0.f}, grey{0.3f, 0.3f, 0.3f};
    const int cols = std::max(1, std::min<int>(layout.columns, static_cast<int>(std::max<std::size_t>(1, panels.size()))));
    const int rows = std::max(1, (static_cast<int>(panels.size()) + cols - 1) / cols);
    // Panel box: title lines, the y label, the plot with tick labels left and below, the x label.
    const int padLeft = 62, padRight = 22, padTop = 50, padBottom = 50;
    const int panelW = padLeft + layout.plotWidthPx + padRight, panelH = padTop + layout.plotHeightPx + padBottom;
    const int width = std::max(cols * panelW, 420);
    const std::size_t titleChars = static_cast<std::size_t>(std::max(20, (width - 20) / 10));  // 17 px font
    const std::size_t noteChars = static_cast<std::size_t>(std::max(20, (width - 20) / 7));    // 13 px font
    std::vector<std::pair<std::string, int>> head;  // lines with their font size
    for (const auto& l : wrapText(layout.title, titleChars)) head.emplace_back(l, 17);
    for (const auto& note : layout.notes)
        for (const auto& l : wrapText(note, noteChars)) head.emplace_back(l, 13);
    // Key entries flow into rows as wide as the picture.
    std::vector<std::vector<const ChartKey*>> keyRows;
    int rowX = 10;
    for (const ChartKey& k : layout.key) {
        const int w = (k.box ? 20 : 34) + textWidthPx(k.name, 13) + 18;
        if (keyRows.empty() || rowX + w > width - 10) {
            keyRows.emplace_back();
            rowX = 10;
        }
        keyRows.back().push_back(&k);
        rowX += w;
    }
    int headH = 8;
    for (const auto& [line, size] : head) headH += size + 7;
    headH += static_cast<int>(keyRows.size()) * 20 + 4;
    Canvas c(width, headH + rows * panelH + 8);
    int y = 8;
    for (const auto& [line, size] : head) {
        y += size + 5;
        c.text(10, y, line, size, size > 13 ? black : grey);
        y += 2;
    }
    for (const auto& row : keyRows) {
        y += 20;
        int x = 10;
        for (const ChartKey* k : row) x = drawKeyEntry(c, x, y, *k);
    }
    for (std::size_t i = 0; i < panels.size(); ++i) {
        const ChartPanel& p = panels[i];
        const int ox = static_cast<int>(i % static_cast<std::size_t>(cols)) * panelW;
        const int oy = headH + static_cast<int>(i / static_cast<std::size_t>(cols)) * panelH;
        Chart ch;
        ch.left = ox + padLeft;
        ch.top = oy + padTop;
        ch.width = layout.plotWidthPx;
        ch.height = layout.plotHeightPx;
        const double x1 = p.xmax > p.xmin ? p.xmax : p.xmin + 1, y1 = p.ymax > p.ymin ? p.ymax : p.ymin + 1;
        const auto xt = niceTicks(p.xmin, x1, layout.ticksPerAxis), yt = niceTicks(p.ymin, y1, layout.ticksPerAxis);
        ch.x = {p.xmin, x1, xt, labelsFor(xt)};
        ch.y = {p.ymin, y1, yt, labelsFor(yt)};
        ch.style.tickFontPx = 11;
        ch.style.xLabelCharPx = 3;
        ch.style.xLabelDy = 18;
        ch.style.yLabelDy = 4;
        ch.style.axesOnTop = true;
        ch.reference = p.reference;
        ch.series = p.series;
        for (ChartSeries& s : ch.series) {
            if (!s.bars && s.strokeOffsetsPx == std::vector<int>{0}) s.strokeOffsetsPx = {0, 1};
            s.clampToAxes = true;
        }
        const int textW = panelW - 14;
        ch.texts = {{ox + 10, oy + 17, cutToWidth(p.title, 14, textW), 14, black}};
        if (!p.subtitle.empty()) ch.texts.push_back({ox + 10, oy + 31, cutToWidth(p.subtitle, 11, textW), 11, grey});
        ch.texts.push_back({ox + 10, ch.top - 6, layout.ylabel, 11, black});
        ch.texts.push_back({ch.left + ch.width / 2 - textWidthPx(layout.xlabel, 11) / 2, ch.top + ch.height + 36,
                            layout.xlabel, 11, black});
        drawChart(c, ch);
    }
    return c;
}

int downsampleFactor(int w, int h, int maxSide) {
    return std::max(1, static_cast<int>(std::ceil(static_cast<double>(std::max(w, h)) / maxSide)));
}

MapFrame mapFrame(const Canvas& picture, const MapExtent& world) {
    const int W = picture.width(), H = picture.height();
    const double spanX = world.x1M - world.x0M, spanY = world.y1M - world.y0M;
    const double pxW = spanX / W, pxH = spanY / H;  // metres per pixel
    const int target = std::clamp(W / 70, 2, 10), targetY = std::clamp(H / 60, 2, 10);  // a tick per 60-70 px
    const auto xt = niceTicks(world.x0M, world.x1M, target), yt = niceTicks(world.y0M, world.y1M, targetY);
    const double yStep = stepOf(yt);
    std::size_t longestY = 1, longestX = 1;
    for (double v : yt) longestY = std::max(longestY, tickLabel(v, yStep).size());
    for (double v : xt) longestX = std::max(longestX, tickLabel(v, stepOf(xt)).size());
    const int plotLeft = 18 + 8 * static_cast<int>(longestY), plotTop = 8;
    const int bottom = 62, right = 4 + 4 * static_cast<int>(longestX);
    char note[160];
    std::snprintf(note, sizeof note, "x (east), y (north) in world metres, north up; 1 px = %.3g m", pxW);
    // A small picture gets room on the right for the note under it (it was cut at the edge).
    const int width = std::max(plotLeft + W + right, plotLeft + textWidthPx(note, 11) + 6);
    MapFrame f{Canvas(width, plotTop + H + bottom), plotLeft, plotTop};
    f.canvas.paste(picture, plotLeft, plotTop);
    // The frame lies just outside the picture: the chart's rectangle starts one pixel
    // before it (left, top), and its axes run from one pixel's width before the west / after
    // the north edge, so that world x lands on column plotLeft + (x - x0) / pxW exactly.
    Chart ch;
    ch.left = plotLeft - 1;
    ch.top = plotTop - 1;
    ch.width = W + 1;
    ch.height = H + 1;
    ch.x = {world.x0M - pxW, world.x1M, xt, labelsFor(xt)};
    ch.y = {world.y0M, world.y1M + pxH, yt, labelsFor(yt)};
    ch.style.grid = false;
    ch.style.tickFontPx = 12;
    ch.style.xLabelCharPx = 4;
    ch.style.xLabelDy = 19;
    ch.style.yLabelDy = 4;
    ch.style.frameAllSides = true;
    ch.style.axesOnTop = true;
    drawChart(f.canvas, ch);
    // Scale bar: a round length near a fifth of the width, black and white halves.
    const double barM = niceTicks(0, spanX, 5).size() > 1 ? stepOf(niceTicks(0, spanX, 5)) : spanX;
    const int barPx = std::max(2, static_cast<int>(std::lround(barM / pxW)));
    const int by = plotTop + H + 34, bx = plotLeft;
    const Rgb black{0.f, 0.f, 0.f};
    f.canvas.fillRect(bx, by, bx + barPx / 2, by + 6, black);
    f.canvas.fillRect(bx + barPx / 2, by, bx + barPx, by + 1, black);
    f.canvas.fillRect(bx + barPx / 2, by + 5, bx + barPx, by + 6, black);
    f.canvas.fillRect(bx + barPx - 1, by, bx + barPx, by + 6, black);
    f.canvas.fillRect(bx, by - 3, bx + 1, by + 9, black);
    f.canvas.fillRect(bx + barPx - 1, by - 3, bx + barPx, by + 9, black);
    f.canvas.text(bx + barPx + 8, by + 9, tickLabel(barM, barM) + " m", 13, black);
    f.canvas.text(bx, by + 24, note, 11, {0.3f, 0.3f, 0.3f});
    return f;
}

Canvas chartCanvas(std::vector<ChartSeries> series, double xmin, double xmax, double ymin, double ymax,
                   const std::string& xlabel, const std::string& ylabel, double referenceY) {
    Chart ch;
    ch.left = 70;
    ch.top = 36;  // room above the plot for the y label, clear of the top tick label
    ch.width = 640;
    ch.height = 400;
    const auto xt = niceTicks(xmin, xmax), yt = niceTicks(ymin, ymax);
    ch.x = {xmin, xmax, xt, labelsFor(xt)};
    ch.y = {ymin, ymax, yt, labelsFor(yt)};
    ch.style.axesOnTop = true;
    if (std::isfinite(referenceY)) ch.reference = ChartReference{referenceY, {0.4f, 0.4f, 0.4f}, true};
    for (ChartSeries& s : series) {
        s.strokeOffsetsPx = {0, 1};  // 2 px wide
        s.clampToAxes = true;
    }
    ch.series = std::move(series);
    const Rgb black{0.f, 0.f, 0.f};
    ch.texts = {{ch.left + ch.width / 2 - 4 * static_cast<int>(xlabel.size()), ch.top + ch.height + 44, xlabel, 14, black},
                {4, ch.top - 14, ylabel, 14, black}};
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
