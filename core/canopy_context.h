// Canopy context of a point of the forest floor: how deep under the canopy cover it lies,
// and which crown is above it. The analyser records undergrowth statistics per context
// (density of each species at each depth, heights under crowns and in the open) and the
// synthesizer draws plants from them, so both must compute the context the same way: this
// file is that one definition (docs/analysis.md "Canopy context").
//
// * Cover: a point is covered when it lies inside some canopy crown disc
//   (|p - trunk| < crown radius).
// * Depth (m, signed): on a cell grid, + the distance from a covered cell centre to the
//   nearest uncovered one, - the distance from an uncovered centre to the nearest covered
//   one, both less half a cell (so the cover edge lies at 0 between the two centres);
//   exact Euclidean distance transform, clamped to +-kCanopyDepthCapM. A cell's context is
//   the bin of its depth (CanopyContextBins): deep shade, the crown rim, the gap edge, the
//   open clearing.
#pragma once

#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include "grid.h"
#include "plants.h"

namespace eco {

/// Depths are clamped to +- this (m): beyond it every cell is "deep" or "open" alike.
constexpr double kCanopyDepthCapM = 32.0;

/// Bins of the signed depth: edges (m, ascending, interior) split the real line into
/// edges.size() + 1 bins; bin 0 is (-inf, edges[0]), the last [edges.back(), +inf).
struct CanopyContextBins {
    std::vector<double> edgesM{-8.0, -4.0, -2.0, -1.0, 0.0, 1.0, 2.0, 4.0};
    int count() const { return static_cast<int>(edgesM.size()) + 1; }
    int binOf(double depthM) const;
    /// True when bin k lies under the cover (its lower edge >= 0).
    bool coveredBin(int k) const { return k > 0 && edgesM[static_cast<std::size_t>(k - 1)] >= 0.0; }
    /// "[-2, -1) m" ...
    std::string label(int k) const;
    /// ValidationError unless the edges are finite and strictly ascending (at least one).
    void validate(const std::string& what) const;
};

/// Covered mask (1 where the cell centre is inside some crown disc) of `geometry`'s cells.
Grid<std::uint8_t> canopyCoverMask(const Grid<float>& geometry, const std::vector<Plant>& canopy);

/// Signed depth (m) of every cell of `geometry` under the canopy's cover (see the top of
/// the file). Parallel over rows and columns; exact, so identical for any thread count.
Grid<float> canopyDepthMap(const Grid<float>& geometry, const std::vector<Plant>& canopy);

/// Context bin of every cell of a depth map.
Grid<std::uint8_t> canopyContextMap(const Grid<float>& depthM, const CanopyContextBins& bins);

/// Exact point queries on the crown discs of a canopy: a grid of square cells, each listing
/// the crowns that may reach into it, so a query tests a few crowns whatever the largest
/// crown is.
class CanopyCover {
public:
    explicit CanopyCover(const std::vector<Plant>& canopy);
    /// True when (x, y) is inside some crown disc.
    bool covered(double xM, double yM) const { return lowestCrownAboveM(xM, yM) < kNone; }
    /// Height (m) of the lowest canopy tree whose crown disc holds (x, y): the height an
    /// undergrowth plant there must stay below. +infinity where nothing covers the point.
    double lowestCrownAboveM(double xM, double yM) const;
    static constexpr double kNone = std::numeric_limits<double>::infinity();

private:
    double originX_ = 0, originY_ = 0, invCellM_ = 1;
    int nx_ = 0, ny_ = 0;
    std::vector<std::uint32_t> start_;  ///< [ny][nx] + 1: first entry of each cell in crown_
    std::vector<std::uint32_t> crown_;  ///< per entry: a tree whose crown may reach the cell
    struct Disc {
        double x, y, radius2, height;  ///< trunk, squared crown radius, height
    };
    std::vector<Disc> disc_;  ///< per tree with a crown, in the order of its trunk's cell
};

}  // namespace eco
