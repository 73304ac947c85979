#include "image_out.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <sstream>

#include "atomic_file.h"
#include "chart.h"
#include "error.h"
#include "image_codec.h"

namespace eco {

namespace {

Rgb lerp(const Rgb& a, const Rgb& b, double t) {
    return {static_cast<float>(a[0] + (b[0] - a[0]) * t), static_cast<float>(a[1] + (b[1] - a[1]) * t),
            static_cast<float>(a[2] + (b[2] - a[2]) * t)};
}

Rgb ramp(const std::vector<Rgb>& stops, double t) {
    t = std::clamp(t, 0.0, 1.0) * static_cast<double>(stops.size() - 1);
    const std::size_t i = std::min(static_cast<std::size_t>(t), stops.size() - 2);
    return lerp(stops[i], stops[i + 1], t - static_cast<double>(i));
}

const std::string kFont = "DejaVuSans";

std::string formatTick(double v) {
    std::ostringstream s;
    const double a = std::abs(v);
    s.precision(a >= 100 || a == 0 ? 0 : (a >= 10 ? 1 : 2));
    s << std::fixed << v;
    return s.str();
}

}  // namespace

Rgb colormapColour(Colormap cmap, double t) {
    // Stops are approximations of the usual perceptual maps, sampled by eye.
    static const std::vector<Rgb> viridis = {{0.267f, 0.005f, 0.329f}, {0.283f, 0.141f, 0.458f},
                                             {0.254f, 0.265f, 0.530f}, {0.207f, 0.372f, 0.553f},
                                             {0.164f, 0.471f, 0.558f}, {0.128f, 0.567f, 0.551f},
                                             {0.135f, 0.659f, 0.518f}, {0.267f, 0.749f, 0.441f},
                                             {0.478f, 0.821f, 0.318f}, {0.741f, 0.873f, 0.150f},
                                             {0.993f, 0.906f, 0.144f}};
    static const std::vector<Rgb> terrain = {{0.20f, 0.40f, 0.25f}, {0.45f, 0.62f, 0.35f}, {0.80f, 0.78f, 0.50f},
                                             {0.62f, 0.48f, 0.35f}, {0.95f, 0.95f, 0.95f}};
    static const std::vector<Rgb> blues = {{0.97f, 0.95f, 0.85f}, {0.70f, 0.85f, 0.80f}, {0.35f, 0.65f, 0.85f},
                                           {0.10f, 0.35f, 0.70f}, {0.03f, 0.12f, 0.40f}};
    static const std::vector<Rgb> heat = {{0.10f, 0.10f, 0.45f}, {0.30f, 0.55f, 0.85f}, {0.95f, 0.95f, 0.75f},
                                          {0.95f, 0.55f, 0.20f}, {0.65f, 0.05f, 0.10f}};
    static const std::vector<Rgb> greys = {{0.f, 0.f, 0.f}, {1.f, 1.f, 1.f}};
    // Pale cream to dark brown (ColorBrewer's YlOrBr, thinned): litter, bare soil.
    static const std::vector<Rgb> browns = {{1.00f, 0.97f, 0.85f}, {0.99f, 0.85f, 0.55f}, {0.93f, 0.55f, 0.20f},
                                            {0.70f, 0.33f, 0.07f}, {0.40f, 0.18f, 0.04f}};
    switch (cmap) {
        case Colormap::Viridis: return ramp(viridis, t);
        case Colormap::Terrain: return ramp(terrain, t);
        case Colormap::Blues: return ramp(blues, t);
        case Colormap::Heat: return ramp(heat, t);
        case Colormap::Greys: return ramp(greys, t);
        case Colormap::Browns: return ramp(browns, t);
    }
    return ramp(greys, t);
}

Rgb categoryColour(int i) {
    static const std::vector<Rgb> palette = {
        {0.12f, 0.47f, 0.71f}, {1.00f, 0.50f, 0.05f}, {0.17f, 0.63f, 0.17f}, {0.84f, 0.15f, 0.16f},
        {0.58f, 0.40f, 0.74f}, {0.55f, 0.34f, 0.29f}, {0.89f, 0.47f, 0.76f}, {0.00f, 0.45f, 0.45f},
        {0.74f, 0.74f, 0.13f}, {0.09f, 0.75f, 0.81f}, {0.00f, 0.30f, 0.15f}, {0.65f, 0.81f, 0.89f},
        {0.99f, 0.75f, 0.44f}, {0.70f, 0.87f, 0.54f}, {0.40f, 0.00f, 0.40f}, {0.98f, 0.60f, 0.60f},
        {0.20f, 0.20f, 0.60f}, {0.60f, 0.60f, 0.20f}};
    if (i < 0) return {0.85f, 0.85f, 0.85f};
    return palette[static_cast<std::size_t>(i) % palette.size()];
}

Canvas::Canvas(int width, int height, Rgb background)
    : width_(width), height_(height), px_(static_cast<std::size_t>(width) * height * 3) {
    if (width <= 0 || height <= 0) throw ValidationError("Canvas: size must be positive");
    for (std::size_t i = 0; i < px_.size(); i += 3) {
        px_[i] = background[0];
        px_[i + 1] = background[1];
        px_[i + 2] = background[2];
    }
}

void Canvas::set(int x, int y, Rgb c) {
    if (x < 0 || y < 0 || x >= width_ || y >= height_) return;
    const std::size_t i = (static_cast<std::size_t>(y) * width_ + x) * 3;
    px_[i] = c[0];
    px_[i + 1] = c[1];
    px_[i + 2] = c[2];
}

Rgb Canvas::get(int x, int y) const {
    const std::size_t i = (static_cast<std::size_t>(y) * width_ + x) * 3;
    return {px_[i], px_[i + 1], px_[i + 2]};
}

void Canvas::blend(int x, int y, Rgb c, float opacity) {
    if (x < 0 || y < 0 || x >= width_ || y >= height_) return;
    set(x, y, lerp(get(x, y), c, opacity));
}

void Canvas::fillRect(int x0, int y0, int x1, int y1, Rgb c) {
    for (int y = std::max(0, y0); y < std::min(height_, y1); ++y)
        for (int x = std::max(0, x0); x < std::min(width_, x1); ++x) set(x, y, c);
}

void Canvas::drawLine(double x0, double y0, double x1, double y1, Rgb c) {
    const int steps = static_cast<int>(std::ceil(std::max(std::abs(x1 - x0), std::abs(y1 - y0)))) + 1;
    for (int i = 0; i <= steps; ++i) {
        const double t = static_cast<double>(i) / steps;
        set(static_cast<int>(std::lround(x0 + (x1 - x0) * t)), static_cast<int>(std::lround(y0 + (y1 - y0) * t)), c);
    }
}

void Canvas::fillDisc(double cx, double cy, double radius, Rgb c, float opacity) {
    const int x0 = static_cast<int>(std::floor(cx - radius)), x1 = static_cast<int>(std::ceil(cx + radius));
    const int y0 = static_cast<int>(std::floor(cy - radius)), y1 = static_cast<int>(std::ceil(cy + radius));
    const double r2 = std::max(radius * radius, 0.25);
    for (int y = std::max(0, y0); y <= std::min(height_ - 1, y1); ++y)
        for (int x = std::max(0, x0); x <= std::min(width_ - 1, x1); ++x) {
            const double dx = x + 0.5 - cx, dy = y + 0.5 - cy;
            if (dx * dx + dy * dy <= r2) blend(x, y, c, opacity);
        }
}

bool Canvas::text(int x, int y, const std::string& s, int sizePx, Rgb c) {
    const float col[3] = {c[0], c[1], c[2]};
    return renderText(px_.data(), width_, height_, x, y, s, sizePx, kFont, col);
}

void Canvas::paste(const Canvas& other, int x, int y) {
    for (int j = 0; j < other.height(); ++j)
        for (int i = 0; i < other.width(); ++i) set(x + i, y + j, other.get(i, j));
}

void Canvas::writePng(const std::string& path) const {
    AtomicOutput out(path);
    // OIIO picks the format from the extension, so the temporary name ends in .png too.
    const std::string temp = out.tempPath() + ".png";
    {
        ImageWriteSpec spec;
        spec.format = "png";
        spec.width = width_;
        spec.height = height_;
        spec.channels = 3;
        spec.stored = SampleType::UInt8;
        std::vector<unsigned char> bytes(px_.size());
        for (std::size_t i = 0; i < px_.size(); ++i)
            bytes[i] = static_cast<unsigned char>(std::lround(std::clamp(px_[i], 0.f, 1.f) * 255.f));
        const ImageWriteResult r = writeImageFile(temp, spec, SampleType::UInt8, bytes.data());
        if (r.step == ImageWriteResult::Step::Create) throw IoError(path + ": PNG writer unavailable: " + r.reason);
        if (!r.ok()) {
            std::remove(temp.c_str());
            throw IoError(path + ": cannot write PNG: " + r.reason);
        }
    }
    std::error_code ec;
    std::filesystem::rename(temp, out.tempPath(), ec);
    if (ec) {
        std::remove(temp.c_str());
        throw IoError(path + ": cannot write PNG: " + ec.message());
    }
    out.commit();
}

Canvas gridToCanvas(const Grid<float>& g, Colormap cmap, double vmin, double vmax, int maxSide) {
    const int factor = downsampleFactor(g.width(), g.height(), maxSide);
    const int w = std::max(1, g.width() / factor), h = std::max(1, g.height() / factor);
    Canvas c(w, h);
    const double span = vmax > vmin ? vmax - vmin : 1.0;
    for (int py = 0; py < h; ++py)
        for (int px = 0; px < w; ++px) {
            // Average the block of cells; image row 0 is the northern edge.
            double sum = 0;
            int n = 0;
            for (int j = 0; j < factor; ++j)
                for (int i = 0; i < factor; ++i) {
                    const int ix = px * factor + i;
                    const int iy = g.height() - 1 - (py * factor + j);
                    if (g.inside(ix, iy) && std::isfinite(g(ix, iy))) {
                        sum += g(ix, iy);
                        ++n;
                    }
                }
            c.set(px, py, n ? colormapColour(cmap, (sum / n - vmin) / span) : Rgb{0.8f, 0.8f, 0.8f});
        }
    return c;
}

namespace {

constexpr int kMargin = 12;
constexpr int kTitleH = 34;
constexpr int kFontPx = 14;

Canvas framed(const Canvas& picture, const std::string& title, int extraRight) {
    Canvas out(picture.width() + 2 * kMargin + extraRight, picture.height() + kTitleH + 2 * kMargin);
    out.paste(picture, kMargin, kTitleH + kMargin);
    out.text(kMargin, kTitleH - 6, title, 18, {0.f, 0.f, 0.f});
    return out;
}

}  // namespace

void writeMapPng(const std::string& path, const Grid<float>& g, const std::string& title,
                 const std::string& units, Colormap cmap, double vmin, double vmax) {
    if (g.empty()) throw ValidationError(path + ": cannot draw an empty grid");
    if (!(vmin < vmax)) {
        vmin = std::numeric_limits<double>::max();
        vmax = std::numeric_limits<double>::lowest();
        for (float v : g.data())
            if (std::isfinite(v)) {
                vmin = std::min<double>(vmin, v);
                vmax = std::max<double>(vmax, v);
            }
        if (!(vmin < vmax)) vmax = vmin + 1.0;
    }
    const Canvas picture = gridToCanvas(g, cmap, vmin, vmax);
    const int factor = downsampleFactor(g.width(), g.height(), 1024);
    const MapFrame map = mapFrame(picture, gridPictureExtent(g, factor, picture.width(), picture.height()));
    const int barW = 22, labelW = 90;
    Canvas out = framed(map.canvas, title, barW + labelW + kMargin);
    // The colour bar beside the map, as tall as the picture itself.
    const int top = kTitleH + kMargin + map.plotTop, h = picture.height(), x0 = kMargin * 2 + map.canvas.width();
    for (int y = 0; y < h; ++y) {
        const Rgb c = colormapColour(cmap, 1.0 - static_cast<double>(y) / std::max(1, h - 1));
        out.fillRect(x0, top + y, x0 + barW, top + y + 1, c);
    }
    for (int k = 0; k <= 4; ++k) {
        const double v = vmax - (vmax - vmin) * k / 4.0;
        const int y = top + static_cast<int>(std::lround((h - 1) * k / 4.0));
        out.fillRect(x0 + barW, y, x0 + barW + 4, y + 1, {0.f, 0.f, 0.f});
        out.text(x0 + barW + 6, y + kFontPx / 2, formatTick(v), kFontPx, {0.f, 0.f, 0.f});
    }
    out.text(x0, top - 6, units, kFontPx, {0.f, 0.f, 0.f});
    out.writePng(path);
}

Canvas withLegend(const Canvas& picture, const std::string& title,
                  const std::vector<std::pair<std::string, Rgb>>& entries) {
    std::size_t longest = 0;
    for (const auto& e : entries) longest = std::max(longest, e.first.size());
    const int legendW = 30 + static_cast<int>(longest) * 8 + kMargin;
    const int rowH = 20;
    const int needH = static_cast<int>(entries.size()) * rowH + kTitleH + 2 * kMargin;
    Canvas out(picture.width() + 2 * kMargin + legendW, std::max(picture.height() + kTitleH + 2 * kMargin, needH));
    out.paste(picture, kMargin, kTitleH + kMargin);
    out.text(kMargin, kTitleH - 6, title, 18, {0.f, 0.f, 0.f});
    const int x0 = picture.width() + 2 * kMargin;
    for (std::size_t i = 0; i < entries.size(); ++i) {
        const int y = kTitleH + kMargin + static_cast<int>(i) * rowH;
        out.fillRect(x0, y, x0 + 16, y + 14, entries[i].second);
        out.text(x0 + 22, y + 12, entries[i].first, kFontPx, {0.f, 0.f, 0.f});
    }
    return out;
}

void writeCategoryPng(const std::string& path, const Grid<std::int32_t>& g, const std::string& title,
                      const std::vector<std::string>& names, const std::string& noneLabel) {
    if (g.empty()) throw ValidationError(path + ": cannot draw an empty grid");
    const int factor = downsampleFactor(g.width(), g.height(), 1024);
    const int w = std::max(1, g.width() / factor), h = std::max(1, g.height() / factor);
    Canvas picture(w, h);
    std::vector<bool> used(names.size(), false);
    bool anyNone = false;
    for (int py = 0; py < h; ++py)
        for (int px = 0; px < w; ++px) {
            const int v = g(px * factor, g.height() - 1 - py * factor);
            if (v >= 0 && static_cast<std::size_t>(v) < names.size()) used[static_cast<std::size_t>(v)] = true;
            else anyNone = true;
            picture.set(px, py, categoryColour(v >= 0 && static_cast<std::size_t>(v) < names.size() ? v : -1));
        }
    std::vector<std::pair<std::string, Rgb>> entries;
    for (std::size_t i = 0; i < names.size(); ++i)
        if (used[i]) entries.emplace_back(names[i], categoryColour(static_cast<int>(i)));
    if (anyNone) entries.emplace_back(noneLabel, categoryColour(-1));
    withLegend(mapFrame(picture, gridPictureExtent(g, factor, w, h)).canvas, title, entries).writePng(path);
}

Grid<float> hillshade(const Grid<float>& elevation) {
    Grid<float> out = Grid<float>::like(elevation);
    const double az = 315.0 * M_PI / 180.0, alt = 45.0 * M_PI / 180.0;
    // Light direction: x east, y north; azimuth clockwise from north.
    const double lx = std::sin(az) * std::cos(alt), ly = std::cos(az) * std::cos(alt), lz = std::sin(alt);
    const double c2 = 2.0 * elevation.cellSizeM();
#pragma omp parallel for schedule(static)
    for (int iy = 0; iy < elevation.height(); ++iy)
        for (int ix = 0; ix < elevation.width(); ++ix) {
            const double dzdx = (elevation.clamped(ix + 1, iy) - elevation.clamped(ix - 1, iy)) / c2;
            const double dzdy = (elevation.clamped(ix, iy + 1) - elevation.clamped(ix, iy - 1)) / c2;
            const double n = std::sqrt(dzdx * dzdx + dzdy * dzdy + 1.0);
            out(ix, iy) = static_cast<float>(std::max(0.0, (-dzdx * lx - dzdy * ly + lz) / n));
        }
    return out;
}

}  // namespace eco
