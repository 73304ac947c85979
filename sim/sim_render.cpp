#include "sim_render.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numeric>

#include "image_out.h"

namespace eco::sim {

void renderPlantsPng(const std::string& path, const std::vector<UndergrowthPlant>& plants, const std::vector<Plant>& canopy,
                     const SimArea& area, const Biome& biome, const std::string& title, int maxSidePx) {
    const double ex = area.x1 - area.x0, ey = area.y1 - area.y0;
    const double scale = maxSidePx / std::max(ex, ey);  // pixels per metre
    const int titleH = 28;
    const int w = std::max(1, static_cast<int>(std::lround(ex * scale)));
    const int h = std::max(1, static_cast<int>(std::lround(ey * scale)));
    Canvas c(w, h + titleH, {1.f, 1.f, 1.f});
    c.fillRect(0, titleH, w - 1, h + titleH - 1, {0.96f, 0.95f, 0.90f});
    auto px = [&](double x) { return (x - area.x0) * scale; };
    auto py = [&](double y) { return titleH + (area.y1 - y) * scale; };  // north up
    // Canopy crowns: outline circles.
    for (const Plant& t : canopy) {
        const double r = t.crownRadiusM * scale;
        const int steps = std::max(16, static_cast<int>(r * 2));
        for (int i = 0; i < steps; ++i) {
            const double a0 = 2 * M_PI * i / steps, a1 = 2 * M_PI * (i + 1) / steps;
            c.drawLine(px(t.xM) + r * std::cos(a0), py(t.yM) + r * std::sin(a0), px(t.xM) + r * std::cos(a1),
                       py(t.yM) + r * std::sin(a1), {0.55f, 0.55f, 0.55f});
        }
    }
    // Undergrowth: largest first so that small plants stay visible on top.
    std::vector<std::size_t> order(plants.size());
    std::iota(order.begin(), order.end(), 0);
    std::stable_sort(order.begin(), order.end(),
                     [&](std::size_t a, std::size_t b) { return plants[a].crownRadiusM > plants[b].crownRadiusM; });
    std::vector<bool> used(biome.species.size(), false);
    for (std::size_t i : order) {
        const UndergrowthPlant& p = plants[i];
        used[static_cast<std::size_t>(p.speciesId)] = true;
        const double r = std::max(0.6, p.crownRadiusM * scale);
        c.fillDisc(px(p.xM), py(p.yM), r, categoryColour(p.speciesId), 0.85f);
    }
    c.text(6, 20, title, 16, {0.f, 0.f, 0.f});
    std::vector<std::pair<std::string, Rgb>> entries;
    for (std::size_t s = 0; s < used.size(); ++s)
        if (used[s]) entries.emplace_back(biome.species[s].name, categoryColour(static_cast<int>(s)));
    entries.emplace_back("canopy crown (outline)", Rgb{0.55f, 0.55f, 0.55f});
    char scaleText[64];
    std::snprintf(scaleText, sizeof scaleText, "Species (%.0f m x %.0f m)", ex, ey);
    withLegend(c, scaleText, entries).writePng(path);
}

void plotSpeciesCountsPng(const std::string& path, const std::vector<YearRecord>& ts, const Biome& biome,
                          const std::string& title) {
    const int W = 900, H = 560, left = 70, right = 20, top = 40, bottom = 50;
    Canvas c(W, H, {1.f, 1.f, 1.f});
    const std::size_t ns = biome.species.size();
    int maxCount = 1, lastYear = 1;
    std::vector<bool> used(ns, false);
    for (const auto& r : ts) {
        lastYear = std::max(lastYear, r.year);
        for (std::size_t s = 0; s < ns; ++s) {
            maxCount = std::max(maxCount, static_cast<int>(r.count[s]));
            if (r.count[s] > 0) used[s] = true;
        }
    }
    // A "nice" axis maximum: 1, 2 or 5 times a power of ten.
    auto niceCeil = [](double v) {
        const double p = std::pow(10.0, std::floor(std::log10(v)));
        for (double m : {1.0, 2.0, 5.0, 10.0})
            if (m * p >= v) return m * p;
        return 10 * p;
    };
    const double ymax = niceCeil(maxCount), xmax = lastYear;
    const int pw = W - left - right, ph = H - top - bottom;
    auto X = [&](double year) { return left + year / xmax * pw; };
    auto Y = [&](double count) { return top + ph - count / ymax * ph; };
    const Rgb axis{0.f, 0.f, 0.f}, grid{0.88f, 0.88f, 0.88f};
    for (int i = 0; i <= 5; ++i) {
        const double v = ymax * i / 5;
        c.drawLine(left, Y(v), left + pw, Y(v), grid);
        char buf[32];
        std::snprintf(buf, sizeof buf, "%.0f", v);
        c.text(5, static_cast<int>(Y(v)) + 5, buf, 13, axis);
    }
    const double xstep = niceCeil(xmax / 8.0);
    for (double yr = 0; yr <= xmax + 1e-9; yr += xstep) {
        c.drawLine(X(yr), top, X(yr), top + ph, grid);
        char buf[32];
        std::snprintf(buf, sizeof buf, "%.0f", yr);
        c.text(static_cast<int>(X(yr)) - 8, top + ph + 18, buf, 13, axis);
    }
    c.drawLine(left, top, left, top + ph, axis);
    c.drawLine(left, top + ph, left + pw, top + ph, axis);
    c.text(left + pw / 2 - 20, H - 10, "Year", 14, axis);
    c.text(left, 25, title + "  (#plants)", 16, axis);
    for (std::size_t s = 0; s < ns; ++s) {
        if (!used[s]) continue;
        const Rgb col = categoryColour(static_cast<int>(s));
        for (std::size_t i = 1; i < ts.size(); ++i) {
            // Thick line: three parallel strokes.
            for (int d = -1; d <= 1; ++d)
                c.drawLine(X(ts[i - 1].year), Y(ts[i - 1].count[s]) + d, X(ts[i].year), Y(ts[i].count[s]) + d, col);
        }
    }
    std::vector<std::pair<std::string, Rgb>> entries;
    for (std::size_t s = 0; s < ns; ++s)
        if (used[s]) entries.emplace_back(biome.species[s].name, categoryColour(static_cast<int>(s)));
    withLegend(c, "Species", entries).writePng(path);
}

}  // namespace eco::sim
