// Grid<T>: the one raster type of the toolkit.
//
// Convention (used everywhere, tested in tests/grid_test.cpp on a non-square grid):
//   * width  = number of columns, along world x (east);
//   * height = number of rows,    along world y (north);
//   * cell (ix, iy) is stored at data[iy * width + ix] (row-major, rows are y);
//   * row iy = 0 is the SOUTHERN row: the centre of cell (ix, iy) lies at world
//       x = originX + (ix + 0.5) * cellSizeM,   y = originY + (iy + 0.5) * cellSizeM,
//     where (originX, originY) is the lower-left corner of the grid (an ESRI ASCII grid's
//     xllcorner / yllcorner).
// Files whose first row is the northern edge (ESRI ASCII grids, images) are flipped by
// their readers and writers, never by the science code.
//
// A grid read from a georeferenced raster also carries its coordinate reference system
// (crsWkt, WKT; empty when unknown). It travels with the geometry: like() copies it, our
// HDF5 grids store it (h5io.h) and the GeoTIFF / GeoPackage writers put it in their files,
// so that outputs derived from a georeferenced input open in place in GIS software.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdio>
#include <string>
#include <utility>
#include <vector>

#include "error.h"
#include "memory.h"

namespace eco {

/// Cell sizes accepted anywhere, from flags and from files: 1 mm .. 10 km (a cell size of
/// 1e-300 m in a file was read and gave nonsense; issue 26).
inline constexpr double kMinCellSizeM = 1e-3;
inline constexpr double kMaxCellSizeM = 1e4;
/// True when `cellM` is a finite number in [kMinCellSizeM, kMaxCellSizeM].
inline bool cellSizeInRange(double cellM) { return cellM >= kMinCellSizeM && cellM <= kMaxCellSizeM; }
/// " must lie in [0.001, 10000] m" as message text.
inline std::string cellSizeRangeText() { return "must lie in [0.001, 10000] m"; }

template <typename T>
class Grid {
public:
    Grid() = default;
    Grid(int width, int height, double cellSizeM = 1.0, double originX = 0.0,
         double originY = 0.0, T fill = T{})
        : width_(width), height_(height), cellSizeM_(cellSizeM), originX_(originX),
          originY_(originY) {
        if (width < 0 || height < 0)
            throw ValidationError("Grid: negative size " + std::to_string(width) + " x " +
                                  std::to_string(height));
        if (!(cellSizeM > 0.0) || !std::isfinite(cellSizeM))
            throw ValidationError("Grid: cell size must be positive and finite, got " +
                                  std::to_string(cellSizeM));
        const std::size_t n = static_cast<std::size_t>(width) * static_cast<std::size_t>(height);
        if (n * sizeof(T) >= kLargeBufferBytes) {  // its pages faulted in by every thread
            data_.reserve(n);
            prepareLargeBuffer(data_.data(), n * sizeof(T));
        }
        data_.assign(n, fill);
    }

    /// Same geometry (size, cell size, origin, CRS) as `other`, every cell set to `fill`.
    template <typename U>
    static Grid like(const Grid<U>& other, T fill = T{}) {
        Grid g(other.width(), other.height(), other.cellSizeM(), other.originX(), other.originY(), fill);
        g.crsWkt_ = other.crsWkt();
        return g;
    }

    int width() const { return width_; }
    int height() const { return height_; }
    double cellSizeM() const { return cellSizeM_; }
    double originX() const { return originX_; }
    double originY() const { return originY_; }
    /// Coordinate reference system as WKT; empty when unknown (a generated terrain, an image).
    const std::string& crsWkt() const { return crsWkt_; }
    void setCrsWkt(std::string wkt) { crsWkt_ = std::move(wkt); }
    std::size_t size() const { return data_.size(); }
    bool empty() const { return data_.empty(); }

    /// Cell (ix, iy): ix is the column (east), iy the row counted from the south.
    T& operator()(int ix, int iy) { return data_[index(ix, iy)]; }
    const T& operator()(int ix, int iy) const { return data_[index(ix, iy)]; }
    std::size_t index(int ix, int iy) const {
        return static_cast<std::size_t>(iy) * static_cast<std::size_t>(width_) +
               static_cast<std::size_t>(ix);
    }
    bool inside(int ix, int iy) const {
        return ix >= 0 && iy >= 0 && ix < width_ && iy < height_;
    }
    /// Clamped access: cells outside the grid read as the nearest edge cell.
    const T& clamped(int ix, int iy) const {
        return (*this)(std::clamp(ix, 0, width_ - 1), std::clamp(iy, 0, height_ - 1));
    }

    /// World coordinates (metres) of the centre of cell (ix, iy).
    double cellCentreX(int ix) const { return originX_ + (ix + 0.5) * cellSizeM_; }
    double cellCentreY(int iy) const { return originY_ + (iy + 0.5) * cellSizeM_; }
    /// Cell containing world point (x, y); may be outside the grid (check with inside()).
    int cellX(double x) const { return static_cast<int>(std::floor((x - originX_) / cellSizeM_)); }
    int cellY(double y) const { return static_cast<int>(std::floor((y - originY_) / cellSizeM_)); }
    /// World extent.
    double extentX() const { return width_ * cellSizeM_; }
    double extentY() const { return height_ * cellSizeM_; }

    /// Bilinear sample at world (x, y) between cell centres, clamped at the edges.
    T sampleBilinear(double x, double y) const {
        const double fx = (x - originX_) / cellSizeM_ - 0.5;
        const double fy = (y - originY_) / cellSizeM_ - 0.5;
        const int x0 = static_cast<int>(std::floor(fx));
        const int y0 = static_cast<int>(std::floor(fy));
        const double tx = fx - x0, ty = fy - y0;
        const double a = clamped(x0, y0), b = clamped(x0 + 1, y0);
        const double c = clamped(x0, y0 + 1), d = clamped(x0 + 1, y0 + 1);
        return static_cast<T>((a * (1 - tx) + b * tx) * (1 - ty) + (c * (1 - tx) + d * tx) * ty);
    }

    /// True when both grids cover the same cells (size, cell size and origin).
    template <typename U>
    bool sameGeometry(const Grid<U>& o, double tolM = 1e-6) const {
        return width_ == o.width() && height_ == o.height() &&
               std::abs(cellSizeM_ - o.cellSizeM()) <= tolM &&
               std::abs(originX_ - o.originX()) <= tolM && std::abs(originY_ - o.originY()) <= tolM;
    }

    std::vector<T>& data() { return data_; }
    const std::vector<T>& data() const { return data_; }
    void fill(T v) { std::fill(data_.begin(), data_.end(), v); }

    /// "W x H cells of C m, origin (X, Y)": the geometry, for messages.
    std::string geometryText() const {
        char buf[160];
        std::snprintf(buf, sizeof buf, "%d x %d cells of %.10g m, origin (%.10g, %.10g)", width_, height_, cellSizeM_,
                      originX_, originY_);
        return buf;
    }

    T minValue() const { return data_.empty() ? T{} : *std::min_element(data_.begin(), data_.end()); }
    T maxValue() const { return data_.empty() ? T{} : *std::max_element(data_.begin(), data_.end()); }

private:
    int width_ = 0;
    int height_ = 0;
    double cellSizeM_ = 1.0;
    double originX_ = 0.0;
    double originY_ = 0.0;
    std::string crsWkt_;
    std::vector<T> data_;
};

/// `src` resampled onto the cells of `like` (bilinear between src's cell centres; the result
/// has like's geometry and src's CRS). ValidationError naming `what` when like's extent is not
/// inside src's (half a src cell of slack at each edge).
template <typename U>
Grid<float> resampledOnto(const Grid<float>& src, const Grid<U>& like, const std::string& what) {
    const double slack = 0.5 * src.cellSizeM();
    if (like.originX() < src.originX() - slack || like.originY() < src.originY() - slack ||
        like.originX() + like.extentX() > src.originX() + src.extentX() + slack ||
        like.originY() + like.extentY() > src.originY() + src.extentY() + slack)
        throw ValidationError(what + " (" + src.geometryText() + ") does not cover " + like.geometryText() +
                              "; it cannot be resampled onto those cells");
    Grid<float> out(like.width(), like.height(), like.cellSizeM(), like.originX(), like.originY());
    out.setCrsWkt(src.crsWkt());
    for (int iy = 0; iy < out.height(); ++iy)
        for (int ix = 0; ix < out.width(); ++ix) out(ix, iy) = src.sampleBilinear(out.cellCentreX(ix), out.cellCentreY(iy));
    return out;
}

/// A stack of same-geometry planes, e.g. 12 monthly maps (plane 0 = January).
template <typename T>
struct MonthlyGrids {
    std::vector<Grid<T>> months;
    const Grid<T>& operator[](int m) const { return months[static_cast<std::size_t>(m)]; }
    Grid<T>& operator[](int m) { return months[static_cast<std::size_t>(m)]; }
    /// Mean over the planes, cell by cell.
    Grid<T> annualMean() const {
        Grid<T> out = Grid<T>::like(months.at(0));
        for (const auto& g : months)
            for (std::size_t i = 0; i < out.size(); ++i) out.data()[i] += g.data()[i];
        for (auto& v : out.data()) v /= static_cast<T>(months.size());
        return out;
    }
};

using GridF = Grid<float>;

}  // namespace eco
