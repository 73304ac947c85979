// Procedural default data, so that every command works without input files: a terrain,
// a density sketch (empty / sparse / dense) and a canopy height model (CHM).
//
// All three are pure functions of their parameters: randomness comes from the Philox
// generator keyed by (seed, stream, counter) (rng.h), so the result is bit-identical for
// any number of OpenMP threads. No clocks, no std::rand.
//
// The CHM generator is a STAND-IN for the paper's learned CHM (§4: conditional GANs trained
// on lidar DEM / sketch / CHM triples from Sonoma County), for which no training data is
// available here. It places sphere-crowned trees from the sketch and allometry. Real CHMs
// (lidar products) load through readTerrain (terrain_io.h).
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "grid.h"

namespace eco {

// ------------------------------------------------------------------------- terrain

/// Parameters of the procedural terrain. Lengths in metres; elevations in metres above
/// sea level. Features are sized in metres, so the landscape keeps its real-world scale
/// when the cell size changes.
struct TerrainGenParams {
    int width = 512, height = 512;  ///< cells (x / east, y / north)
    double cellSizeM = 0.914;       ///< metres per cell (the paper's 3 ft lidar grid)
    double originX = 0, originY = 0;  ///< lower-left corner (metres)
    std::uint64_t seed = 1;
    double reliefM = 70;            ///< height range of the hills above the valley rim
    double valleyDepthM = 25;       ///< depth of the valley below the lowest hills
    double baseElevationM = 60;     ///< creek bed where it leaves the domain
    double creekDropM = 20;         ///< fall of the creek bed across the domain (drains downstream)
    double ridgeWavelengthM = 260;  ///< largest ridge spacing of the ridged fBm
    double hillWavelengthM = 420;   ///< wavelength of the broad hills (plain fBm)
    double ridgeWeight = 0.6;       ///< share of ridged fBm in the hills (rest: plain fBm)
    double valleyHalfWidthM = 85;   ///< distance from the creek at which the walls reach valleyDepthM
    double meanderAmplitudeM = 35;  ///< sideways swing of the valley axis (capped at 12 % of the extent)
    double meanderWavelengthM = 350;
    /// Half width of the creek channel at the bank top, and of its flat bed. The bed is
    /// widened to at least one cell and the banks to one cell more, so the grid resolves them.
    double creekHalfWidthM = 3.0;
    double creekBedHalfWidthM = 1.5;
    double creekDepthM = 1.5;       ///< depth of the channel below the valley floor
    double smallestFeatureCells = 10; ///< fBm octaves stop at this wavelength (in cells)
};

/// Geometric description of what generateTerrain built (ground truth for tests and tools).
struct TerrainFeatures {
    /// Creek centreline, upstream to downstream, world coordinates (metres), one point
    /// per metre or so; both ends lie outside the domain.
    std::vector<std::array<double, 2>> creekPath;
    /// Creek bed elevation (metres) at each path point; strictly decreasing.
    std::vector<double> creekBedM;
};

/// Ridged hills cut by a meandering valley with a creek that drains out of the domain.
/// Elevations in metres, >= 0. Throws ValidationError on invalid parameters.
Grid<float> generateTerrain(const TerrainGenParams& params);
/// Same terrain, plus the creek path.
Grid<float> generateTerrain(const TerrainGenParams& params, TerrainFeatures& features);

// ------------------------------------------------------------------------- density sketch

/// The paper's painted discrete density map P (§3): three brushes.
enum DensityLevel : std::int32_t { Empty = 0, Sparse = 1, Dense = 2 };

/// Parameters of the procedural density sketch.
struct SketchParams {
    std::uint64_t seed = 1;
    double featureSizeM = 80;    ///< typical size of a patch (noise wavelength), metres
    double emptyFraction = 0.2;  ///< share of cells painted Empty
    double denseFraction = 0.5;  ///< share painted Dense; the rest is Sparse
};

/// Smooth noise thresholded at its quantiles, so the level fractions are met to within a
/// cell. Origin (0, 0); the noise is evaluated in local metres, so results do not depend on
/// the origin.
Grid<std::int32_t> generateDensitySketch(int width, int height, double cellSizeM, const SketchParams& params);
/// Same, with the geometry (size, cell size, origin) of `like`.
Grid<std::int32_t> generateDensitySketch(const Grid<float>& like, const SketchParams& params);

/// A painted sketch from a grey image (mean of the colour channels, ignoring alpha, in
/// [0, 1]): < 1/3 Empty, < 2/3 Sparse, else Dense. Image row 0 is the north edge. The image
/// must have exactly the size of `like` (whose geometry the result takes); it is never
/// resampled silently. IoError / ValidationError naming the file otherwise.
Grid<std::int32_t> readDensitySketch(const std::string& imagePath, const Grid<float>& like);
/// Write a sketch as an 8-bit grey image readable by readDensitySketch (Empty 0, Sparse
/// 0.5, Dense 1). Atomic.
void writeDensitySketch(const std::string& imagePath, const Grid<std::int32_t>& sketch);

// ------------------------------------------------------------------------- CHM

/// Parameters of the stand-in CHM generator. Heights in metres above ground.
struct ChmGenParams {
    std::uint64_t seed = 1;
    double denseSpacingM = 7;    ///< typical distance between neighbouring trees in Dense areas
    double sparseSpacingM = 18;  ///< ... in Sparse areas (Empty areas get none)
    double minHeightM = 8;
    double maxHeightM = 50;
    /// Crown radius r = exp(a + b ln h) (paper Eq. 2; Table 3 allometry D, Douglas-Fir / Redwood).
    double crownA = -0.72, crownB = 0.65;
    double heightFieldWavelengthM = 150;  ///< spatial scale of the smooth stand-height field
    double treeHeightSpread = 0.18;       ///< per-tree log-normal spread of height around the field
    double sparseHeightFactor = 0.8;      ///< trees in Sparse areas are this much shorter on average
    double denseGapFraction = 0.06;       ///< share of Dense area left as small canopy gaps
    double gapSizeM = 14;                 ///< typical size of those gaps (noise wavelength)
};

/// One tree of the generated canopy (ground truth for the canopy placer).
struct GeneratedTree {
    double x = 0, y = 0;         ///< trunk position, world metres
    double heightM = 0;          ///< apex height above ground
    double crownRadiusM = 0;     ///< r = exp(a + b ln h)
};

/// Crown radius of the allometry of `params` for a tree of heightM metres.
double chmCrownRadiusM(const ChmGenParams& params, double heightM);

/// Canopy height model (metres above ground) with the geometry of `sketch`: trees placed by
/// dart throwing with a per-level spacing (none in Empty cells; crowns never reach an Empty
/// cell centre), heights from a smooth field with per-tree variation in [min, max], crowns
/// as spheres: the CHM is the maximum over trees of h - r + sqrt(r^2 - d^2) inside each
/// crown disc, 0 elsewhere.
Grid<float> generateChm(const Grid<std::int32_t>& sketch, const ChmGenParams& params);
/// Same CHM, also returning the trees that made it.
Grid<float> generateChm(const Grid<std::int32_t>& sketch, const ChmGenParams& params,
                        std::vector<GeneratedTree>& trees);

/// Raise chm to the sphere-cap surface of each tree (max over trees; order-independent,
/// parallel over rows).
void rasterizeCrowns(const std::vector<GeneratedTree>& trees, Grid<float>& chm);

}  // namespace eco
