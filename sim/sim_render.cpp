#include "sim_render.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numeric>

#include "chart.h"
#include "image_out.h"

namespace eco::sim {

namespace {

// The top-down picture of renderPlantsPng, with an optional event mask painted on the ground
// under the plants (tinted cells) and its boundary drawn over them.
void renderPlot(const std::string& path, const std::vector<UndergrowthPlant>& plants, const std::vector<Plant>& canopy,
                const SimArea& area, const Biome& biome, const std::string& title, int maxSidePx,
                const DisturbanceRecord* event) {
    const double ex = area.x1 - area.x0, ey = area.y1 - area.y0;
    const double scale = maxSidePx / std::max(ex, ey);  // pixels per metre
    const int w = std::max(1, static_cast<int>(std::lround(ex * scale)));
    const int h = std::max(1, static_cast<int>(std::lround(ey * scale)));
    Canvas c(w, h, {0.96f, 0.95f, 0.90f});
    auto px = [&](double x) { return (x - area.x0) * scale; };
    auto py = [&](double y) { return (area.y1 - y) * scale; };  // north up
    // The event's mask: which pixels' centres fall in a struck cell.
    const bool fire = event && event->kind == "fire";
    const Rgb maskFill = fire ? Rgb{0.98f, 0.62f, 0.30f} : Rgb{0.55f, 0.70f, 0.95f};
    const Rgb maskEdge = fire ? Rgb{0.70f, 0.10f, 0.05f} : Rgb{0.10f, 0.20f, 0.65f};
    std::vector<std::uint8_t> struck;
    if (event && event->mask.present()) {
        const Grid<std::uint8_t> g = event->mask.grid();
        struck.assign(static_cast<std::size_t>(w) * static_cast<std::size_t>(h), 0);
        for (int y = 0; y < h; ++y)
            for (int x = 0; x < w; ++x) {
                const int cx = g.cellX(area.x0 + (x + 0.5) / scale), cy = g.cellY(area.y1 - (y + 0.5) / scale);
                if (g.inside(cx, cy) && g(cx, cy)) {
                    struck[static_cast<std::size_t>(y) * static_cast<std::size_t>(w) + static_cast<std::size_t>(x)] = 1;
                    c.set(x, y, maskFill);
                }
            }
    }
    // Canopy crowns: outline circles, in a grey no species has (categoryColour).
    const Rgb outline{0.55f, 0.55f, 0.55f};
    for (const Plant& t : canopy) {
        const double r = t.crownRadiusM * scale;
        const int steps = std::max(16, static_cast<int>(r * 2));
        for (int i = 0; i < steps; ++i) {
            const double a0 = 2 * M_PI * i / steps, a1 = 2 * M_PI * (i + 1) / steps;
            c.drawLine(px(t.xM) + r * std::cos(a0), py(t.yM) + r * std::sin(a0), px(t.xM) + r * std::cos(a1),
                       py(t.yM) + r * std::sin(a1), outline);
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
    // The mask's boundary over the plants: struck pixels with an unstruck 4-neighbour.
    if (!struck.empty()) {
        auto at = [&](int x, int y) {
            return x >= 0 && y >= 0 && x < w && y < h &&
                   struck[static_cast<std::size_t>(y) * static_cast<std::size_t>(w) + static_cast<std::size_t>(x)];
        };
        for (int y = 0; y < h; ++y)
            for (int x = 0; x < w; ++x)
                if (at(x, y) && (!at(x - 1, y) || !at(x + 1, y) || !at(x, y - 1) || !at(x, y + 1))) c.set(x, y, maskEdge);
    }
    std::vector<std::pair<std::string, Rgb>> entries;
    for (std::size_t s = 0; s < used.size(); ++s)
        if (used[s]) entries.emplace_back(biome.species[s].name, categoryColour(static_cast<int>(s)));
    if (!canopy.empty()) entries.emplace_back("canopy crown (outline)", outline);
    if (event) {
        char m[96];
        std::snprintf(m, sizeof m, "%s (%.0f m2, ground tint)", fire ? "burnt cells" : "cells with plants thrown",
                      event->areaM2);
        entries.emplace_back(m, maskFill);
        entries.emplace_back(fire ? "burn edge" : "damage edge", maskEdge);
    }
    char size[64];
    std::snprintf(size, sizeof size, "%.0f m x %.0f m", ex, ey);
    entries.emplace_back(size, Rgb{1.f, 1.f, 1.f});
    // The title above the picture (it was drawn inside the plot's top strip), world-metre
    // axes and a scale bar round it.
    const MapFrame map = mapFrame(c, MapExtent{area.x0, area.y1 - h / scale, area.x0 + w / scale, area.y1});
    withLegend(map.canvas, title, entries).writePng(path);
}

}  // namespace

void renderPlantsPng(const std::string& path, const std::vector<UndergrowthPlant>& plants, const std::vector<Plant>& canopy,
                     const SimArea& area, const Biome& biome, const std::string& title, int maxSidePx) {
    renderPlot(path, plants, canopy, area, biome, title, maxSidePx, nullptr);
}

void renderDisturbancePng(const std::string& path, const DisturbanceRecord& event,
                          const std::vector<UndergrowthPlant>& plants, const std::vector<Plant>& canopy,
                          const SimArea& area, const Biome& biome, const std::string& title, int maxSidePx) {
    renderPlot(path, plants, canopy, area, biome, title, maxSidePx, &event);
}

void plotSpeciesCountsPng(const std::string& path, const std::vector<YearRecord>& ts, const Biome& biome,
                          const std::string& title) {
    const std::size_t ns = biome.species.size();
    double maxCount = 1, lastYear = 1;
    std::vector<bool> used(ns, false);
    for (const auto& r : ts) {
        lastYear = std::max<double>(lastYear, r.year);
        for (std::size_t s = 0; s < ns; ++s) {
            maxCount = std::max<double>(maxCount, static_cast<double>(r.count[s]));
            if (r.count[s] > 0) used[s] = true;
        }
    }
    Chart ch;
    ch.left = 70;
    ch.top = 56;
    ch.width = 810;
    ch.height = 454;
    const auto xt = niceTicks(0, lastYear, 8);
    const auto yTicks = niceTicks(0, maxCount, 5);
    // The y axis ends on a round value at or above the largest count.
    const double yStep = yTicks.size() > 1 ? yTicks[1] - yTicks[0] : maxCount;
    const double ymax = std::ceil(maxCount / yStep - 1e-9) * yStep;
    const auto yt = niceTicks(0, ymax, 5);
    ch.x = {0, lastYear, xt, [&](double v) { return tickLabel(v, xt.size() > 1 ? xt[1] - xt[0] : 1); }};
    ch.y = {0, ymax, yt, [&](double v) { return tickLabel(v, yStep); }};
    ch.style.gridColour = {0.88f, 0.88f, 0.88f};
    ch.style.tickFontPx = 13;
    for (std::size_t s = 0; s < ns; ++s) {
        if (!used[s]) continue;
        ChartSeries line{biome.species[s].name, {}, {}, categoryColour(static_cast<int>(s))};
        for (const auto& r : ts) {
            line.x.push_back(r.year);
            line.y.push_back(static_cast<double>(r.count[s]));
        }
        line.strokeOffsetsPx = {-1, 0, 1};  // 3 px wide
        ch.series.push_back(std::move(line));
    }
    const Rgb black{0.f, 0.f, 0.f};
    ch.texts = {{ch.left, 24, title, 16, black},
                {4, ch.top - 12, "plants", 14, black},
                {ch.left + ch.width / 2 - 16, ch.top + ch.height + 44, "year", 14, black}};
    Canvas c(ch.left + ch.width + 20, ch.top + ch.height + 56);
    drawChart(c, ch);
    std::vector<std::pair<std::string, Rgb>> entries;
    for (std::size_t s = 0; s < ns; ++s)
        if (used[s]) entries.emplace_back(biome.species[s].name, categoryColour(static_cast<int>(s)));
    withLegend(c, "Species", entries).writePng(path);
}

}  // namespace eco::sim
