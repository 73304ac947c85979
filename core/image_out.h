// Pictures a person can read: false-colour maps with a titled legend, categorical maps with
// a named key, hillshades, and a small RGB canvas for plots and top-down renders.
// PNGs are written north-up (image row 0 = northern grid row), atomically.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "grid.h"

namespace eco {

using Rgb = std::array<float, 3>;  ///< linear 0..1 components written as 8-bit sRGB-ish values

/// Viridis, Blues, Browns and Greys are sequential (one hue or lightness that grows with the
/// value: densities, amounts); Heat diverges from blue through pale yellow to red; Terrain
/// is for elevation.
enum class Colormap { Viridis, Terrain, Blues, Heat, Greys, Browns };

/// Colour of t in [0, 1] on a colormap.
Rgb colormapColour(Colormap cmap, double t);
/// Distinct colour for category i (species, region); stable across runs.
Rgb categoryColour(int i);

/// An RGB raster with a few drawing primitives; (0, 0) is the top-left pixel.
class Canvas {
public:
    Canvas(int width, int height, Rgb background = {1.f, 1.f, 1.f});
    int width() const { return width_; }
    int height() const { return height_; }
    void set(int x, int y, Rgb c);
    Rgb get(int x, int y) const;
    void blend(int x, int y, Rgb c, float opacity);
    void fillRect(int x0, int y0, int x1, int y1, Rgb c);
    void drawLine(double x0, double y0, double x1, double y1, Rgb c);
    void fillDisc(double cx, double cy, double radius, Rgb c, float opacity = 1.f);
    /// Text with its baseline at (x, y), DejaVu Sans at `sizePx`; returns false if no font.
    bool text(int x, int y, const std::string& s, int sizePx, Rgb c);
    /// Paste another canvas with its top-left at (x, y).
    void paste(const Canvas& other, int x, int y);
    /// Write as 8-bit PNG (temporary file, then rename). IoError on failure.
    void writePng(const std::string& path) const;
    const std::vector<float>& pixels() const { return px_; }

private:
    int width_, height_;
    std::vector<float> px_;
};

/// Grid drawn north-up as a canvas, one pixel per cell, scaled down by an integer factor
/// so that the longer side is at most maxSide pixels.
Canvas gridToCanvas(const Grid<float>& g, Colormap cmap, double vmin, double vmax, int maxSide = 1024);

/// False-colour map with a title and a colour bar labelled in `units` from vmin to vmax.
/// When vmin >= vmax the range is taken from the data.
void writeMapPng(const std::string& path, const Grid<float>& g, const std::string& title,
                 const std::string& units, Colormap cmap, double vmin = 0, double vmax = 0);

/// Categorical map: value i >= 0 drawn in categoryColour(i) with names[i] in the key;
/// negative values drawn as `noneLabel` in light grey.
void writeCategoryPng(const std::string& path, const Grid<std::int32_t>& g, const std::string& title,
                      const std::vector<std::string>& names, const std::string& noneLabel = "none");

/// Hillshade in [0, 1] (sun from the north-west at 45 degrees).
Grid<float> hillshade(const Grid<float>& elevation);

/// Canvas with a legend column appended on the right: one coloured swatch per entry.
Canvas withLegend(const Canvas& picture, const std::string& title,
                  const std::vector<std::pair<std::string, Rgb>>& entries);

}  // namespace eco
