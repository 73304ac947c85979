#include "generate.h"

#include "memory.h"


#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <numeric>
#include <sstream>

#include "atomic_file.h"
#include "image_codec.h"
#include "image_in.h"
#include "error.h"
#include "rng.h"
#include "text_format.h"

namespace eco {

namespace {

constexpr double kTwoPi = 6.283185307179586;

// Stream identifiers: every random quantity has its own (seed, stream, counter) key.
constexpr std::uint64_t kStreamTerrainLayout = 0x7465727261696e01ull;  // valley axis, meanders
constexpr std::uint64_t kStreamRidgeOctave = 0x7465727261696e02ull;
constexpr std::uint64_t kStreamHillOctave = 0x7465727261696e03ull;
constexpr std::uint64_t kStreamWallNoise = 0x7465727261696e04ull;
constexpr std::uint64_t kStreamSketchOctave = 0x736b657463680001ull;
constexpr std::uint64_t kStreamChmHeightField = 0x63686d0000000001ull;
constexpr std::uint64_t kStreamChmGapField = 0x63686d0000000002ull;
constexpr std::uint64_t kStreamChmCandidate = 0x63686d0000000010ull;  // + level

std::string genNum(double v) { return formatNumber(v, 6); }

void requirePositive(double v, const char* field) {
    if (!(v > 0) || !std::isfinite(v))
        throw ValidationError(std::string(field) + " must be positive, got " + genNum(v));
}

void requireNonNegative(double v, const char* field) {
    if (!(v >= 0) || !std::isfinite(v))
        throw ValidationError(std::string(field) + " must be >= 0, got " + genNum(v));
}

double smoothstep(double t) {
    t = std::clamp(t, 0.0, 1.0);
    return t * t * (3.0 - 2.0 * t);
}

/// Polynomial smooth minimum: equal to min(a, b) when |a - b| >= k.
double smoothMin(double a, double b, double k) {
    const double h = std::max(k - std::abs(a - b), 0.0) / k;
    return std::min(a, b) - h * h * k * 0.25;
}

/// Gradient (Perlin-style) noise on a finite lattice covering a domain of extentX x extentY
/// metres. Lattice gradients are pure functions of (seed, stream, lattice index), drawn once
/// at construction; evaluation is then read-only and thread-safe. Values roughly in [-1, 1].
class GradientNoise {
public:
    GradientNoise(std::uint64_t seed, std::uint64_t stream, double extentX, double extentY,
                  double wavelengthM)
        : invWavelength_(1.0 / wavelengthM) {
        // A random lattice offset keeps lattice lines (where noise is 0) off the grid axes.
        RandomStream layout(seed, stream, 0);
        offsetX_ = layout.uniform();
        offsetY_ = layout.uniform();
        nx_ = static_cast<int>(std::ceil(extentX * invWavelength_)) + 3;
        ny_ = static_cast<int>(std::ceil(extentY * invWavelength_)) + 3;
        grad_.resize(static_cast<std::size_t>(nx_) * ny_ * 2);
        for (int j = 0; j < ny_; ++j)
            for (int i = 0; i < nx_; ++i) {
                const std::size_t k = static_cast<std::size_t>(j) * nx_ + i;
                // Counter 1 + k: block 0 of this stream is the lattice offset above.
                const auto bits = randomBits(seed, stream, 1 + k);
                const double angle = kTwoPi * bitsToUnit(bits[0], bits[1]);
                grad_[2 * k] = static_cast<float>(std::cos(angle));
                grad_[2 * k + 1] = static_cast<float>(std::sin(angle));
            }
    }

    /// Noise at local coordinates (metres from the grid's lower-left corner).
    double operator()(double x, double y) const {
        const double u = x * invWavelength_ + offsetX_;
        const double v = y * invWavelength_ + offsetY_;
        int i = static_cast<int>(std::floor(u));
        int j = static_cast<int>(std::floor(v));
        i = std::clamp(i, 0, nx_ - 2);
        j = std::clamp(j, 0, ny_ - 2);
        const double fx = u - i, fy = v - j;
        auto dot = [&](int di, int dj) {
            const std::size_t k = static_cast<std::size_t>(j + dj) * nx_ + (i + di);
            return grad_[2 * k] * (fx - di) + grad_[2 * k + 1] * (fy - dj);
        };
        auto fade = [](double t) { return t * t * t * (t * (t * 6.0 - 15.0) + 10.0); };
        const double sx = fade(fx), sy = fade(fy);
        const double a = dot(0, 0) + sx * (dot(1, 0) - dot(0, 0));
        const double b = dot(0, 1) + sx * (dot(1, 1) - dot(0, 1));
        // sqrt(2) maps the theoretical range of 2-D gradient noise, +-sqrt(1/2), to +-1.
        return std::clamp(1.41421356237 * (a + sy * (b - a)), -1.0, 1.0);
    }

private:
    double invWavelength_;
    double offsetX_ = 0, offsetY_ = 0;
    int nx_ = 0, ny_ = 0;
    std::vector<float> grad_;
};

/// Octaves of gradient noise from `wavelengthM` halving down to `smallestM` (at least one).
std::vector<GradientNoise> makeOctaves(std::uint64_t seed, std::uint64_t stream, double extentX,
                                       double extentY, double wavelengthM, double smallestM,
                                       int maxOctaves) {
    std::vector<GradientNoise> octaves;
    double wl = wavelengthM;
    for (int o = 0; o < maxOctaves; ++o, wl *= 0.5) {
        if (o > 0 && wl < smallestM) break;
        octaves.emplace_back(seed, mixStream(stream, static_cast<std::uint64_t>(o)), extentX, extentY, wl);
    }
    return octaves;
}

/// Fractional Brownian motion, amplitudes halving per octave, normalised to about [-1, 1].
double fbm(const std::vector<GradientNoise>& octaves, double x, double y) {
    double sum = 0, norm = 0, amp = 1;
    for (const auto& n : octaves) {
        sum += amp * n(x, y);
        norm += amp;
        amp *= 0.5;
    }
    return sum / norm;
}

/// Ridged fBm: sharp crests where the noise crosses zero; in [0, 1].
double ridgedFbm(const std::vector<GradientNoise>& octaves, double x, double y) {
    double sum = 0, norm = 0, amp = 1, weight = 1;
    for (const auto& n : octaves) {
        double r = 1.0 - std::abs(n(x, y));
        r *= r;
        // Finer ridges are strongest on the crests of coarser ones (Musgrave's weighting).
        sum += amp * r * weight;
        norm += amp;
        weight = std::clamp(r * 1.5, 0.0, 1.0);
        amp *= 0.5;
    }
    return sum / norm;
}

/// Map values to [0, 1] by their min and max.
void normaliseInPlace(std::vector<double>& v) {
    if (v.empty()) return;
    const auto [lo, hi] = std::minmax_element(v.begin(), v.end());
    const double a = *lo, range = *hi - *lo;
    for (double& x : v) x = range > 0 ? (x - a) / range : 0.5;
}

/// Meandering valley axis: s runs along the downstream direction d, t across it (along n);
/// the axis is t = m(s).
struct ValleyAxis {
    double cx = 0, cy = 0;    // a point on the straight axis (local metres)
    double dx = 1, dy = 0;    // downstream direction
    double amplitude = 0, wavelength = 1, phase1 = 0, phase2 = 0;
    double sMin = 0, sMax = 1;  // range of s over the domain

    static constexpr double kSecondRatio = 0.57;  // second harmonic wavelength ratio
    double s(double x, double y) const { return (x - cx) * dx + (y - cy) * dy; }
    double t(double x, double y) const { return -(x - cx) * dy + (y - cy) * dx; }
    double m(double s) const {
        return amplitude * (0.75 * std::sin(kTwoPi * s / wavelength + phase1) +
                            0.25 * std::sin(kTwoPi * s / (kSecondRatio * wavelength) + phase2));
    }
    double mSlope(double s) const {
        return amplitude * (0.75 * kTwoPi / wavelength * std::cos(kTwoPi * s / wavelength + phase1) +
                            0.25 * kTwoPi / (kSecondRatio * wavelength) *
                                std::cos(kTwoPi * s / (kSecondRatio * wavelength) + phase2));
    }
    /// Distance from the axis, to first order in the curvature.
    double distance(double x, double y) const {
        const double ss = s(x, y);
        const double slope = mSlope(ss);
        return std::abs(t(x, y) - m(ss)) / std::sqrt(1.0 + slope * slope);
    }
};

void validate(const TerrainGenParams& p) {
    if (p.width < 2 || p.height < 2)
        throw ValidationError("terrain generator: width and height must be >= 2 cells, got " +
                              std::to_string(p.width) + " x " + std::to_string(p.height));
    requirePositive(p.cellSizeM, "terrain generator: cellSizeM");
    requireNonNegative(p.reliefM, "terrain generator: reliefM");
    requirePositive(p.valleyDepthM, "terrain generator: valleyDepthM");
    requireNonNegative(p.baseElevationM, "terrain generator: baseElevationM");
    requireNonNegative(p.creekDropM, "terrain generator: creekDropM");
    if (!(p.creekDropM > 0)) throw ValidationError("terrain generator: creekDropM must be > 0 so the creek drains");
    requirePositive(p.ridgeWavelengthM, "terrain generator: ridgeWavelengthM");
    requirePositive(p.hillWavelengthM, "terrain generator: hillWavelengthM");
    if (!(p.ridgeWeight >= 0 && p.ridgeWeight <= 1))
        throw ValidationError("terrain generator: ridgeWeight must be in [0, 1], got " + genNum(p.ridgeWeight));
    requirePositive(p.valleyHalfWidthM, "terrain generator: valleyHalfWidthM");
    requireNonNegative(p.meanderAmplitudeM, "terrain generator: meanderAmplitudeM");
    requirePositive(p.meanderWavelengthM, "terrain generator: meanderWavelengthM");
    requirePositive(p.creekHalfWidthM, "terrain generator: creekHalfWidthM");
    requireNonNegative(p.creekBedHalfWidthM, "terrain generator: creekBedHalfWidthM");
    if (!(p.creekBedHalfWidthM < p.creekHalfWidthM))
        throw ValidationError("terrain generator: creekBedHalfWidthM must be < creekHalfWidthM");
    requireNonNegative(p.creekDepthM, "terrain generator: creekDepthM");
    requirePositive(p.smallestFeatureCells, "terrain generator: smallestFeatureCells");
    if (!std::isfinite(p.originX) || !std::isfinite(p.originY))
        throw ValidationError("terrain generator: origin must be finite");
}

}  // namespace

// ============================================================================ terrain

Grid<float> generateTerrain(const TerrainGenParams& p) {
    TerrainFeatures unused;
    return generateTerrain(p, unused);
}

Grid<float> generateTerrain(const TerrainGenParams& p, TerrainFeatures& features) {
    validate(p);
    const int w = p.width, h = p.height;
    // The result, the creek distance field and the octave sums: about 16 bytes a cell.
    requireMemory(16.0 * w * h, "a terrain of " + std::to_string(w) + " x " + std::to_string(h) + " cells",
                  "a smaller --width / --height, or larger cells");
    const double cell = p.cellSizeM;
    const double extentX = w * cell, extentY = h * cell;
    const double smallestM = p.smallestFeatureCells * cell;
    // The grid must resolve the channel: bed at least one cell wide each side of the axis,
    // banks at least one more cell.
    const double bedHalfM = std::max(p.creekBedHalfWidthM, cell);
    const double bankHalfM = std::max(p.creekHalfWidthM, bedHalfM + cell);

    // Valley layout: direction, position and meanders, all from one stream.
    RandomStream layout(p.seed, kStreamTerrainLayout);
    ValleyAxis axis;
    const double angle = kTwoPi * layout.uniform();
    axis.dx = std::cos(angle);
    axis.dy = std::sin(angle);
    axis.cx = extentX * (0.5 + 0.3 * (layout.uniform() - 0.5));
    axis.cy = extentY * (0.5 + 0.3 * (layout.uniform() - 0.5));
    // Cap the swing so the creek stays well inside small domains.
    axis.amplitude = std::min(p.meanderAmplitudeM, 0.12 * std::min(extentX, extentY));
    axis.wavelength = p.meanderWavelengthM;
    axis.phase1 = kTwoPi * layout.uniform();
    axis.phase2 = kTwoPi * layout.uniform();
    {
        const double cs[4][2] = {{0, 0}, {extentX, 0}, {0, extentY}, {extentX, extentY}};
        axis.sMin = std::numeric_limits<double>::max();
        axis.sMax = std::numeric_limits<double>::lowest();
        for (const auto& c : cs) {
            axis.sMin = std::min(axis.sMin, axis.s(c[0], c[1]));
            axis.sMax = std::max(axis.sMax, axis.s(c[0], c[1]));
        }
    }
    // Creek bed falls linearly downstream: the valley floor, and the terrain with it, tilts.
    const double dropPerM = p.creekDropM / (axis.sMax - axis.sMin);
    auto floorAt = [&](double s) { return p.baseElevationM + dropPerM * (axis.sMax - s); };

    const auto ridges = makeOctaves(p.seed, kStreamRidgeOctave, extentX, extentY, p.ridgeWavelengthM, smallestM, 10);
    const auto hills = makeOctaves(p.seed, kStreamHillOctave, extentX, extentY, p.hillWavelengthM, smallestM, 10);
    const auto wallNoise = makeOctaves(p.seed, kStreamWallNoise, extentX, extentY, 60.0, smallestM, 5);

    // Hill height field, normalised so that reliefM is the exact range of the hills.
    std::vector<double> hill(static_cast<std::size_t>(w) * h);
#pragma omp parallel for schedule(static)
    for (int iy = 0; iy < h; ++iy) {
        const double y = (iy + 0.5) * cell;
        for (int ix = 0; ix < w; ++ix) {
            const double x = (ix + 0.5) * cell;
            const double ridged = ridgedFbm(ridges, x, y);
            const double broad = 0.5 + 0.5 * fbm(hills, x, y);
            hill[static_cast<std::size_t>(iy) * w + ix] = p.ridgeWeight * ridged + (1.0 - p.ridgeWeight) * broad;
        }
    }
    normaliseInPlace(hill);

    Grid<float> out(w, h, cell, p.originX, p.originY);
    const double blendM = 0.25 * p.valleyDepthM;  // smooth-min width where walls meet hills
#pragma omp parallel for schedule(static)
    for (int iy = 0; iy < h; ++iy) {
        const double y = (iy + 0.5) * cell;
        for (int ix = 0; ix < w; ++ix) {
            const double x = (ix + 0.5) * cell;
            const double s = axis.s(x, y);
            const double dist = axis.distance(x, y);
            // Channel: flat bed, banks rising smoothly to the valley floor.
            double channel = -p.creekDepthM;
            if (dist > bedHalfM)
                channel = -p.creekDepthM * (1.0 - smoothstep((dist - bedHalfM) / (bankHalfM - bedHalfM)));
            // Valley walls: parabolic rise from the banks, roughened away from the creek.
            const double off = std::max(dist - bankHalfM, 0.0) / p.valleyHalfWidthM;
            const double wall = p.valleyDepthM * off * off * (1.0 + 0.4 * fbm(wallNoise, x, y));
            const double hillsAbove = p.valleyDepthM + p.reliefM * hill[static_cast<std::size_t>(iy) * w + ix];
            const double z = floorAt(s) + smoothMin(channel + wall, hillsAbove, blendM);
            out(ix, iy) = static_cast<float>(std::max(z, 0.0));
        }
    }

    // Creek path from beyond the upstream edge to beyond the downstream edge.
    features.creekPath.clear();
    features.creekBedM.clear();
    const double stepM = std::min(1.0, 0.5 * cell);
    const double margin = 2.0 * cell;
    for (double s = axis.sMin - margin; s <= axis.sMax + margin; s += stepM) {
        const double t = axis.m(s);
        const double x = axis.cx + s * axis.dx - t * axis.dy;
        const double y = axis.cy + s * axis.dy + t * axis.dx;
        features.creekPath.push_back({p.originX + x, p.originY + y});
        features.creekBedM.push_back(floorAt(s) - p.creekDepthM);
    }
    return out;
}

// ============================================================================ density sketch

namespace {

void validate(const SketchParams& p) {
    requirePositive(p.featureSizeM, "density sketch: featureSizeM");
    if (!(p.emptyFraction >= 0 && p.emptyFraction <= 1))
        throw ValidationError("density sketch: emptyFraction must be in [0, 1], got " + genNum(p.emptyFraction));
    if (!(p.denseFraction >= 0 && p.denseFraction <= 1))
        throw ValidationError("density sketch: denseFraction must be in [0, 1], got " + genNum(p.denseFraction));
    if (p.emptyFraction + p.denseFraction > 1.0 + 1e-12)
        throw ValidationError("density sketch: emptyFraction + denseFraction must be <= 1, got " +
                              genNum(p.emptyFraction + p.denseFraction));
}

/// Value below which `fraction` of `values` lie (k-th smallest, k = round(fraction * n)).
double lowerQuantileThreshold(std::vector<double> values, double fraction) {
    const std::size_t n = values.size();
    const auto k = static_cast<std::size_t>(std::llround(fraction * static_cast<double>(n)));
    if (k == 0) return -std::numeric_limits<double>::infinity();
    if (k >= n) return std::numeric_limits<double>::infinity();
    std::nth_element(values.begin(), values.begin() + static_cast<std::ptrdiff_t>(k), values.end());
    return values[k];
}

}  // namespace

Grid<std::int32_t> generateDensitySketch(const Grid<float>& like, const SketchParams& p) {
    validate(p);
    const int w = like.width(), h = like.height();
    if (w < 1 || h < 1) throw ValidationError("density sketch: empty grid");
    const double cell = like.cellSizeM();
    const auto octaves = makeOctaves(p.seed, kStreamSketchOctave, w * cell, h * cell, p.featureSizeM,
                                     2.0 * cell, 4);
    std::vector<double> field(static_cast<std::size_t>(w) * h);
#pragma omp parallel for schedule(static)
    for (int iy = 0; iy < h; ++iy)
        for (int ix = 0; ix < w; ++ix)
            field[static_cast<std::size_t>(iy) * w + ix] = fbm(octaves, (ix + 0.5) * cell, (iy + 0.5) * cell);

    // Thresholds at quantiles: the lowest emptyFraction of the field is Empty, the highest
    // denseFraction Dense.
    const double emptyBelow = lowerQuantileThreshold(field, p.emptyFraction);
    const double denseFrom = lowerQuantileThreshold(field, 1.0 - p.denseFraction);
    Grid<std::int32_t> out = Grid<std::int32_t>::like(like, Sparse);
    for (std::size_t i = 0; i < field.size(); ++i) {
        const double v = field[i];
        out.data()[i] = v < emptyBelow ? Empty : (v >= denseFrom ? Dense : Sparse);
    }
    return out;
}

Grid<std::int32_t> generateDensitySketch(int width, int height, double cellSizeM, const SketchParams& p) {
    if (width < 1 || height < 1)
        throw ValidationError("density sketch: size must be positive, got " + std::to_string(width) + " x " +
                              std::to_string(height));
    requirePositive(cellSizeM, "density sketch: cellSizeM");
    return generateDensitySketch(Grid<float>(width, height, cellSizeM), p);
}

Grid<std::int32_t> readDensitySketch(const std::string& imagePath, const Grid<float>& like) {
    // Colours kept as painted even where alpha is 0; the size checked before the pixels.
    const ImagePixels image = readImagePixels(imagePath, "density sketch", 0, [&](int w, int h, int) {
        if (w != like.width() || h != like.height())
            throw ValidationError(imagePath + ": density sketch is " + std::to_string(w) + " x " + std::to_string(h) +
                                  " pixels but the terrain is " + std::to_string(like.width()) + " x " +
                                  std::to_string(like.height()) +
                                  " cells; resample the sketch to the terrain's size (it is not resampled "
                                  "automatically)");
    });
    const int w = image.width, h = image.height, nch = image.channels;
    const std::vector<float>& px = image.values;
    // Grey value: mean of the colour channels (alpha, the 2nd of 2 or the 4th, ignored).
    const int colour = nch >= 3 ? 3 : 1;
    Grid<std::int32_t> out = Grid<std::int32_t>::like(like, Sparse);
    for (int row = 0; row < h; ++row) {
        const int iy = h - 1 - row;  // image row 0 = north
        for (int ix = 0; ix < w; ++ix) {
            const std::size_t k = (static_cast<std::size_t>(row) * w + ix) * nch;
            double grey = 0;
            for (int c = 0; c < colour; ++c) grey += px[k + c];
            grey /= colour;
            if (!std::isfinite(grey))
                throw IoError(imagePath + ": non-finite pixel at column " + std::to_string(ix + 1) +
                              ", row " + std::to_string(row + 1));
            out(ix, iy) = grey < 1.0 / 3.0 ? Empty : (grey < 2.0 / 3.0 ? Sparse : Dense);
        }
    }
    return out;
}

void writeDensitySketch(const std::string& imagePath, const Grid<std::int32_t>& sketch) {
    if (sketch.empty()) throw ValidationError(imagePath + ": cannot write an empty density sketch");
    const auto dot = imagePath.find_last_of('.');
    std::string ext = dot == std::string::npos ? "" : imagePath.substr(dot + 1);
    std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
    std::string format;
    if (ext == "png") format = "png";
    else if (ext == "tif" || ext == "tiff") format = "tiff";
    else throw IoError(imagePath + ": density sketches are written as .png or .tif");
    const int w = sketch.width(), h = sketch.height();
    std::vector<std::uint8_t> px(sketch.size());
    for (int row = 0; row < h; ++row)
        for (int ix = 0; ix < w; ++ix) {
            const std::int32_t level = sketch(ix, h - 1 - row);
            if (level != Empty && level != Sparse && level != Dense)
                throw ValidationError(imagePath + ": density level " + std::to_string(level) +
                                      " at cell (" + std::to_string(ix) + ", " + std::to_string(h - 1 - row) +
                                      ") is not 0, 1 or 2");
            px[static_cast<std::size_t>(row) * w + ix] = level == Empty ? 0 : (level == Sparse ? 128 : 255);
        }
    ImageWriteSpec spec;
    spec.format = format;
    spec.width = w;
    spec.height = h;
    spec.channels = 1;
    spec.stored = SampleType::UInt8;
    spec.attributes.emplace_back("DateTime", "");  // no time stamp in a TIFF: same sketch, same bytes
    spec.attributes.emplace_back("ImageDescription",
                                 "eco density sketch: black = empty, grey = sparse, white = dense; row 0 = north");
    AtomicOutput out(imagePath);
    const ImageWriteResult r = writeImageFile(out.tempPath(), spec, SampleType::UInt8, px.data());
    if (r.step == ImageWriteResult::Step::Create) throw IoError(imagePath + ": cannot create image writer: " + r.reason);
    if (r.step == ImageWriteResult::Step::Open) throw IoError(imagePath + ": cannot create image: " + r.reason);
    if (!r.ok()) throw IoError(imagePath + ": cannot write image: " + r.reason);
    out.commit();
}

// ============================================================================ CHM

namespace {

void validate(const ChmGenParams& p) {
    requirePositive(p.denseSpacingM, "CHM generator: denseSpacingM");
    requirePositive(p.sparseSpacingM, "CHM generator: sparseSpacingM");
    requirePositive(p.minHeightM, "CHM generator: minHeightM");
    requirePositive(p.maxHeightM, "CHM generator: maxHeightM");
    if (!(p.minHeightM <= p.maxHeightM))
        throw ValidationError("CHM generator: minHeightM (" + genNum(p.minHeightM) + ") must be <= maxHeightM (" +
                              genNum(p.maxHeightM) + ")");
    if (!std::isfinite(p.crownA) || !(p.crownB > 0) || !std::isfinite(p.crownB))
        throw ValidationError("CHM generator: crown allometry needs finite a and b > 0, got a = " + genNum(p.crownA) +
                              ", b = " + genNum(p.crownB));
    requirePositive(p.heightFieldWavelengthM, "CHM generator: heightFieldWavelengthM");
    requireNonNegative(p.treeHeightSpread, "CHM generator: treeHeightSpread");
    requirePositive(p.sparseHeightFactor, "CHM generator: sparseHeightFactor");
    if (!(p.denseGapFraction >= 0 && p.denseGapFraction < 1))
        throw ValidationError("CHM generator: denseGapFraction must be in [0, 1), got " + genNum(p.denseGapFraction));
    requirePositive(p.gapSizeM, "CHM generator: gapSizeM");
}

/// Distance from (x, y) (local metres) to the centre of the nearest Empty cell within
/// `radiusM`; radiusM when there is none that close.
double distanceToEmpty(const Grid<std::int32_t>& sketch, double x, double y, double radiusM) {
    const double cell = sketch.cellSizeM();
    const int cx = static_cast<int>(std::floor(x / cell)), cy = static_cast<int>(std::floor(y / cell));
    const int reach = static_cast<int>(std::ceil(radiusM / cell)) + 1;
    double best2 = radiusM * radiusM;
    for (int iy = std::max(cy - reach, 0); iy <= std::min(cy + reach, sketch.height() - 1); ++iy)
        for (int ix = std::max(cx - reach, 0); ix <= std::min(cx + reach, sketch.width() - 1); ++ix) {
            if (sketch(ix, iy) != Empty) continue;
            const double ddx = (ix + 0.5) * cell - x, ddy = (iy + 0.5) * cell - y;
            best2 = std::min(best2, ddx * ddx + ddy * ddy);
        }
    return std::sqrt(best2);
}

struct Candidate {
    std::uint64_t order;  // random priority: dart-throwing order
    double x, y;          // local metres
    double heightM;
    std::int32_t level;
};

}  // namespace

double chmCrownRadiusM(const ChmGenParams& p, double heightM) {
    return std::exp(p.crownA + p.crownB * std::log(heightM));
}

Grid<float> generateChm(const Grid<std::int32_t>& sketch, const ChmGenParams& p) {
    std::vector<GeneratedTree> unused;
    return generateChm(sketch, p, unused);
}

Grid<float> generateChm(const Grid<std::int32_t>& sketch, const ChmGenParams& p, std::vector<GeneratedTree>& trees) {
    validate(p);
    if (sketch.empty()) throw ValidationError("CHM generator: empty density sketch");
    const int w = sketch.width(), h = sketch.height();
    const double cell = sketch.cellSizeM();
    const double extentX = w * cell, extentY = h * cell;
    for (std::size_t i = 0; i < sketch.size(); ++i) {
        const std::int32_t v = sketch.data()[i];
        if (v != Empty && v != Sparse && v != Dense)
            throw ValidationError("CHM generator: density sketch value " + std::to_string(v) + " at cell (" +
                                  std::to_string(i % static_cast<std::size_t>(w)) + ", " +
                                  std::to_string(i / static_cast<std::size_t>(w)) + ") is not 0, 1 or 2");
    }

    // Smooth stand-height field (in [0, 1]) and small gaps inside Dense stands.
    const auto heightField = makeOctaves(p.seed, kStreamChmHeightField, extentX, extentY,
                                         p.heightFieldWavelengthM, 0.25 * p.heightFieldWavelengthM, 3);
    const auto gapField = makeOctaves(p.seed, kStreamChmGapField, extentX, extentY, p.gapSizeM, 0.5 * p.gapSizeM, 2);
    double gapAbove = std::numeric_limits<double>::infinity();
    if (p.denseGapFraction > 0) {
        std::vector<double> denseValues;
        for (int iy = 0; iy < h; ++iy)
            for (int ix = 0; ix < w; ++ix)
                if (sketch(ix, iy) == Dense) denseValues.push_back(fbm(gapField, (ix + 0.5) * cell, (iy + 0.5) * cell));
        if (!denseValues.empty()) gapAbove = lowerQuantileThreshold(std::move(denseValues), 1.0 - p.denseGapFraction);
    }

    // Candidates: one per jittered-grid cell of half the level's spacing. Each candidate's
    // position, height and priority come from its own stream, so they do not depend on
    // which other candidates are accepted.
    const double maxRadius = chmCrownRadiusM(p, p.maxHeightM);
    {  // one candidate per jittered cell of half the spacing (an upper bound over the levels)
        const double spacing = std::min(p.denseSpacingM, p.sparseSpacingM);
        const double cells = std::ceil(extentX / (0.5 * spacing)) * std::ceil(extentY / (0.5 * spacing));
        requireMemory(cells * static_cast<double>(sizeof(Candidate)) * 2.0,
                      "the CHM generator's " + formatNumber(cells, 3) + " tree candidates (spacing " +
                          formatNumber(spacing, 6) + " m over " + formatNumber(extentX, 6) + " x " + formatNumber(extentY, 6) + " m)",
                      "a larger --dense-spacing / --sparse-spacing");
    }
    std::vector<Candidate> candidates;
    for (const std::int32_t level : {Dense, Sparse}) {
        const double spacing = level == Dense ? p.denseSpacingM : p.sparseSpacingM;
        const double q = 0.5 * spacing;
        const auto nqx = static_cast<std::uint64_t>(std::ceil(extentX / q));
        const auto nqy = static_cast<std::uint64_t>(std::ceil(extentY / q));
        for (std::uint64_t j = 0; j < nqy; ++j)
            for (std::uint64_t i = 0; i < nqx; ++i) {
                RandomStream rng(p.seed, mixStream(kStreamChmCandidate + static_cast<std::uint64_t>(level), j * nqx + i));
                const double x = (static_cast<double>(i) + rng.uniform()) * q;
                const double y = (static_cast<double>(j) + rng.uniform()) * q;
                const std::uint64_t order = (static_cast<std::uint64_t>(rng.nextU32()) << 32) | rng.nextU32();
                const double spread = rng.normal();
                if (x >= extentX || y >= extentY) continue;
                const int ix = std::min(static_cast<int>(x / cell), w - 1);
                const int iy = std::min(static_cast<int>(y / cell), h - 1);
                if (sketch(ix, iy) != level) continue;
                if (level == Dense && fbm(gapField, (ix + 0.5) * cell, (iy + 0.5) * cell) >= gapAbove) continue;
                const double field = std::clamp(0.5 + 0.5 * fbm(heightField, x, y), 0.0, 1.0);
                double mean = p.minHeightM + (p.maxHeightM - p.minHeightM) * (0.15 + 0.7 * field);
                if (level == Sparse) mean *= p.sparseHeightFactor;
                double heightM = std::clamp(mean * std::exp(p.treeHeightSpread * spread), p.minHeightM, p.maxHeightM);
                // Keep every crown off the Empty cells: shorten the tree until its crown fits,
                // drop it if it would have to be shorter than minHeightM.
                const double room = distanceToEmpty(sketch, x, y, maxRadius + cell);
                if (chmCrownRadiusM(p, heightM) >= room) {
                    heightM = std::exp((std::log(0.999 * room) - p.crownA) / p.crownB);
                    if (heightM < p.minHeightM) continue;
                }
                candidates.push_back({order, x, y, heightM, level});
            }
    }
    // Dart throwing: Dense candidates first, each level in random order; a candidate is
    // kept when no kept trunk lies within 0.8 x the smaller of the two trees' level
    // spacings (so Sparse trees may stand at a Dense stand's edge).
    std::stable_sort(candidates.begin(), candidates.end(), [](const Candidate& a, const Candidate& b) {
        if (a.level != b.level) return a.level > b.level;
        return a.order < b.order;
    });
    const double bucketM = 0.8 * std::max(p.denseSpacingM, p.sparseSpacingM);
    const int nbx = static_cast<int>(std::ceil(extentX / bucketM)) + 1;
    const int nby = static_cast<int>(std::ceil(extentY / bucketM)) + 1;
    std::vector<std::vector<std::size_t>> buckets(static_cast<std::size_t>(nbx) * nby);
    std::vector<double> keptSpacing;
    trees.clear();
    for (const Candidate& c : candidates) {
        const double spacing = c.level == Dense ? p.denseSpacingM : p.sparseSpacingM;
        const int bx = static_cast<int>(c.x / bucketM), by = static_cast<int>(c.y / bucketM);
        bool free = true;
        for (int yy = std::max(by - 1, 0); yy <= std::min(by + 1, nby - 1) && free; ++yy)
            for (int xx = std::max(bx - 1, 0); xx <= std::min(bx + 1, nbx - 1) && free; ++xx)
                for (const std::size_t t : buckets[static_cast<std::size_t>(yy) * nbx + xx]) {
                    const double ddx = trees[t].x - c.x, ddy = trees[t].y - c.y;
                    const double minDist = 0.8 * std::min(spacing, keptSpacing[t]);
                    if (ddx * ddx + ddy * ddy < minDist * minDist) {
                        free = false;
                        break;
                    }
                }
        if (!free) continue;
        buckets[static_cast<std::size_t>(by) * nbx + bx].push_back(trees.size());
        keptSpacing.push_back(spacing);
        trees.push_back({c.x, c.y, c.heightM, chmCrownRadiusM(p, c.heightM)});  // local for now
    }
    for (auto& t : trees) {
        t.x += sketch.originX();
        t.y += sketch.originY();
    }

    Grid<float> chm = Grid<float>::like(sketch, 0.f);
    rasterizeCrowns(trees, chm);
    return chm;
}

void rasterizeCrowns(const std::vector<GeneratedTree>& trees, Grid<float>& chm) {
    const int w = chm.width(), h = chm.height();
    if (w == 0 || h == 0) return;
    // Trees bucketed by bands of rows; each row is then written by one thread only, and the
    // max over trees does not depend on order, so the result is schedule-independent.
    constexpr int kBandRows = 16;
    const int nBands = (h + kBandRows - 1) / kBandRows;
    std::vector<std::vector<std::size_t>> bands(static_cast<std::size_t>(nBands));
    for (std::size_t t = 0; t < trees.size(); ++t) {
        const auto& tr = trees[t];
        if (!(tr.crownRadiusM > 0)) continue;
        const int y0 = std::max(chm.cellY(tr.y - tr.crownRadiusM), 0);
        const int y1 = std::min(chm.cellY(tr.y + tr.crownRadiusM), h - 1);
        if (y0 > y1) continue;
        for (int b = y0 / kBandRows; b <= y1 / kBandRows; ++b) bands[static_cast<std::size_t>(b)].push_back(t);
    }
#pragma omp parallel for schedule(dynamic, 4)
    for (int iy = 0; iy < h; ++iy) {
        const double cy = chm.cellCentreY(iy);
        for (const std::size_t t : bands[static_cast<std::size_t>(iy / kBandRows)]) {
            const auto& tr = trees[t];
            const double r = tr.crownRadiusM;
            const double dy = cy - tr.y;
            if (std::abs(dy) >= r) continue;
            const int x0 = std::max(chm.cellX(tr.x - r), 0);
            const int x1 = std::min(chm.cellX(tr.x + r), w - 1);
            for (int ix = x0; ix <= x1; ++ix) {
                const double dx = chm.cellCentreX(ix) - tr.x;
                const double d2 = dx * dx + dy * dy;
                if (d2 >= r * r) continue;
                const float z = static_cast<float>(tr.heightM - r + std::sqrt(r * r - d2));
                float& cellZ = chm(ix, iy);
                if (z > cellZ) cellZ = z;
            }
        }
    }
}

}  // namespace eco
