#include "abiotics.h"

#include <glm/geometric.hpp>
#include <glm/vec3.hpp>

#include <omp.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <queue>
#include <sstream>
#include <stdexcept>

#include "atomic_file.h"
#include "eco_version.h"
#include "provenance.h"
#include "geo_raster.h"
#include "error.h"
#include "h5io.h"
#include "memory.h"
#include "text_format.h"

namespace eco {

namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kDegToRad = kPi / 180.0;
constexpr int kMonths = 12;
constexpr std::array<const char*, 12> kMonthNames = {"January", "February", "March",     "April",
                                                     "May",     "June",     "July",      "August",
                                                     "September", "October", "November", "December"};

std::string num(double v) { return formatNumber(v, 6); }

void requireFinite(double v, const std::string& what) {
    if (!std::isfinite(v)) throw ValidationError(what + " must be finite, got " + num(v));
}

void validateClimate(const Climate& c) {
    requireFinite(c.latitudeDeg, "climate: latitude_deg");
    if (c.latitudeDeg < -90.0 || c.latitudeDeg > 90.0)
        throw ValidationError("climate: latitude_deg must be in [-90, 90], got " + num(c.latitudeDeg));
    requireFinite(c.lapseRateCPerKm, "climate: lapse_rate_c_per_km");
    for (int m = 0; m < kMonths; ++m) {
        const std::string month = kMonthNames[static_cast<std::size_t>(m)];
        requireFinite(c.temperatureC[static_cast<std::size_t>(m)], "climate: temperature_c (" + month + ")");
        const double rain = c.rainfallMm[static_cast<std::size_t>(m)];
        if (!std::isfinite(rain) || rain < 0)
            throw ValidationError("climate: rainfall_mm (" + month + ") must be >= 0, got " + num(rain));
        const double clarity = c.skyClarity[static_cast<std::size_t>(m)];
        if (!std::isfinite(clarity) || clarity < 0 || clarity > 1)
            throw ValidationError("climate: sky_clarity (" + month + ") must be in [0, 1], got " + num(clarity));
    }
}

void validateSoil(const Soil& s) {
    auto nonNegative = [](double v, const char* name) {
        if (!std::isfinite(v) || v < 0)
            throw ValidationError(std::string("soil: ") + name + " must be >= 0, got " + num(v));
    };
    nonNegative(s.runoffLimitMm, "runoff_limit_mm");
    nonNegative(s.slopeThresholdDeg, "slope_threshold_deg");
    nonNegative(s.saturationMm, "saturation_mm");
    if (!std::isfinite(s.slopeMaxDeg) || s.slopeMaxDeg < s.slopeThresholdDeg)
        throw ValidationError("soil: slope_max_deg must be >= slope_threshold_deg (" + num(s.slopeThresholdDeg) +
                              "), got " + num(s.slopeMaxDeg));
    if (!std::isfinite(s.evaporationFraction) || s.evaporationFraction < 0 || s.evaporationFraction > 1)
        throw ValidationError("soil: evaporation_fraction must be in [0, 1], got " + num(s.evaporationFraction));
}

void validateSunParams(const SunParams& p) { validateParams(p, sunParamFields(), "sun parameter"); }

// ---------------------------------------------------------------------------------------
// Gradient

/// dz/dx and dz/dy (metres per metre) by central differences, one-sided on the edges.
void gradient(const Grid<float>& z, std::vector<float>& gx, std::vector<float>& gy) {
    const int w = z.width(), h = z.height();
    const double cell = z.cellSizeM();
    gx.assign(z.size(), 0.f);
    gy.assign(z.size(), 0.f);
#pragma omp parallel for schedule(static)
    for (int iy = 0; iy < h; ++iy) {
        for (int ix = 0; ix < w; ++ix) {
            double dx = 0, dy = 0;
            if (w >= 2) {
                const int x0 = std::max(ix - 1, 0), x1 = std::min(ix + 1, w - 1);
                dx = (static_cast<double>(z(x1, iy)) - z(x0, iy)) / ((x1 - x0) * cell);
            }
            if (h >= 2) {
                const int y0 = std::max(iy - 1, 0), y1 = std::min(iy + 1, h - 1);
                dy = (static_cast<double>(z(ix, y1)) - z(ix, y0)) / ((y1 - y0) * cell);
            }
            gx[z.index(ix, iy)] = static_cast<float>(dx);
            gy[z.index(ix, iy)] = static_cast<float>(dy);
        }
    }
}

// ---------------------------------------------------------------------------------------
// Shadow sweeps
//
// A light direction s (unit vector towards the sun or a sky patch, x east, y north, z up)
// is swept over the grid line by line, starting from the line nearest the light. The
// "major axis" is the horizontal axis along which s has the larger component; lines run
// across it. For each cell, the point one line towards the light lies `offset` cells to the
// side (|offset| <= 1) and is linearly interpolated in the previous line; the shadow height
// there, max(terrain, shadow), decreases by the step length times tan(elevation) when it
// reaches this cell. A cell is shadowed when that height is above its terrain. Lines are
// stored contiguously: rows for a y-major sweep, columns (transposed copy) for x-major.

/// Elevation and gradient stored as lines: `lines` lines of `len` cells.
struct LineLayout {
    int len = 0;
    int lines = 0;
    std::vector<float> z, gx, gy;
};

LineLayout rowLayout(const Grid<float>& z, const std::vector<float>& gx, const std::vector<float>& gy) {
    return LineLayout{z.width(), z.height(), z.data(), gx, gy};
}

LineLayout columnLayout(const Grid<float>& z, const std::vector<float>& gx, const std::vector<float>& gy) {
    const int w = z.width(), h = z.height();
    LineLayout t{h, w, std::vector<float>(z.size()), std::vector<float>(z.size()), std::vector<float>(z.size())};
    for (int iy = 0; iy < h; ++iy)
        for (int ix = 0; ix < w; ++ix) {
            const std::size_t src = z.index(ix, iy);
            const std::size_t dst = static_cast<std::size_t>(ix) * static_cast<std::size_t>(h) +
                                    static_cast<std::size_t>(iy);
            t.z[dst] = z.data()[src];
            t.gx[dst] = gx[src];
            t.gy[dst] = gy[src];
        }
    return t;
}

/// Directions (x east, y north, z up) are glm vectors.
using Vec3 = glm::dvec3;

/// Geometry of one sweep direction.
struct SweepSetup {
    bool columns = false;  ///< x-major: lines are columns
    bool reverse = false;  ///< lines visited from the highest index down
    float offset = 0;      ///< lateral offset of the upstream point, cells, in [-1, 1]
    int k = 0;             ///< floor(offset)
    float f = 0;           ///< offset - k
    float drop = 0;        ///< shadow-height decrease per line step, metres
    float sx = 0, sy = 0, sz = 0;  ///< the direction, for the facing test
    int orientation() const { return (columns ? 2 : 0) + (reverse ? 1 : 0); }
};

SweepSetup setupSweep(const Vec3& s, double cellSizeM) {
    SweepSetup st;
    const double ax = std::abs(s.x), ay = std::abs(s.y);
    double major, lateral;
    if (ay >= ax) {
        st.columns = false;
        major = ay;
        lateral = s.x;
        st.reverse = s.y > 0;  // light from the north: start at the northern row
    } else {
        st.columns = true;
        major = ax;
        lateral = s.y;
        st.reverse = s.x > 0;  // light from the east: start at the eastern column
    }
    if (major < 1e-12) {
        // Light from the zenith: nothing casts a shadow.
        st.offset = 0;
        st.drop = std::numeric_limits<float>::infinity();
    } else {
        // Snap round-off (e.g. cos(pi/2) = 6e-17) so that axis-aligned directions stay
        // exactly axis-aligned and mirrored directions get mirrored offsets.
        double offset = std::clamp(lateral / major, -1.0, 1.0);
        if (std::abs(offset) < 1e-9) offset = 0.0;
        st.offset = static_cast<float>(offset);
        // One line step covers cellSizeM * |s_h| / major horizontally; times tan(elev) = s.z/|s_h|.
        st.drop = static_cast<float>(cellSizeM * s.z / major);
    }
    st.k = static_cast<int>(std::floor(st.offset));
    st.f = st.offset - static_cast<float>(st.k);
    st.sx = static_cast<float>(s.x);
    st.sy = static_cast<float>(s.y);
    st.sz = static_cast<float>(s.z);
    return st;
}

/// Shadow height at lateral position p (cells) of the previous line. Positions beyond the
/// first or last cell centre are outside the grid and cast no shadow (clamping them to the
/// edge cell instead would drag shadows along the edge lines).
inline float upstreamAt(const float* prev, int len, float p) {
    constexpr float kRoundOff = 1e-4f;
    if (p < -kRoundOff || p > static_cast<float>(len - 1) + kRoundOff) return -std::numeric_limits<float>::infinity();
    const float pc = std::clamp(p, 0.f, static_cast<float>(len - 1));
    const int i0 = static_cast<int>(pc);
    const int i1 = std::min(i0 + 1, len - 1);
    const float t = pc - static_cast<float>(i0);
    return prev[i0] * (1.f - t) + prev[i1] * t;
}

/// Per-thread scratch lines of a batch sweep.
struct SweepScratch {
    std::vector<std::vector<float>> prev, cur;
    std::vector<std::uint8_t> lit;
    void ensure(int batch, int len) {
        if (static_cast<int>(prev.size()) < batch) {
            prev.resize(static_cast<std::size_t>(batch));
            cur.resize(static_cast<std::size_t>(batch));
        }
        for (int b = 0; b < batch; ++b) {
            prev[static_cast<std::size_t>(b)].resize(static_cast<std::size_t>(len));
            cur[static_cast<std::size_t>(b)].resize(static_cast<std::size_t>(len));
        }
        lit.resize(static_cast<std::size_t>(len));
    }
};

/// Sweep a batch of directions that share one orientation (same line layout and order)
/// in a single pass over the lines, so that each line's data is read once per batch.
/// acc(b, line, lit) receives the 0/1 flags "lit by direction b" of one line.
template <class Acc>
void sweepBatch(const LineLayout& lay, const SweepSetup* setups, int batch, SweepScratch& sc, Acc&& acc) {
    const int len = lay.len, lines = lay.lines;
    sc.ensure(batch, len);
    const bool reverse = setups[0].reverse;
    std::uint8_t* lit = sc.lit.data();
    for (int step = 0; step < lines; ++step) {
        const int j = reverse ? lines - 1 - step : step;
        const std::size_t base = static_cast<std::size_t>(j) * static_cast<std::size_t>(len);
        const float* z = lay.z.data() + base;
        const float* gx = lay.gx.data() + base;
        const float* gy = lay.gy.data() + base;
        for (int b = 0; b < batch; ++b) {
            const SweepSetup& st = setups[b];
            float* prev = sc.prev[static_cast<std::size_t>(b)].data();
            float* cur = sc.cur[static_cast<std::size_t>(b)].data();
            const float sx = st.sx, sy = st.sy, sz = st.sz;
            if (step == 0) {
                // The line nearest the light: nothing upstream inside the grid.
                for (int i = 0; i < len; ++i) {
                    cur[i] = z[i];
                    lit[i] = static_cast<std::uint8_t>(sz - gx[i] * sx - gy[i] * sy > 0.f);
                }
            } else {
                const int k = st.k;
                const float f = st.f, g = 1.f - f, drop = st.drop;
                const int lo = std::max(0, -k);
                const int hi = std::min(len - 1, len - 2 - k);
                auto edge = [&](int i) {
                    const float up = upstreamAt(prev, len, static_cast<float>(i) + st.offset) - drop;
                    cur[i] = std::max(z[i], up);
                    lit[i] = static_cast<std::uint8_t>((up <= z[i]) & (sz - gx[i] * sx - gy[i] * sy > 0.f));
                };
                for (int i = 0; i < std::min(lo, len); ++i) edge(i);
                for (int i = lo; i <= hi; ++i) {
                    const float up = g * prev[i + k] + f * prev[i + k + 1] - drop;
                    cur[i] = std::max(z[i], up);
                    lit[i] = static_cast<std::uint8_t>((up <= z[i]) & (sz - gx[i] * sx - gy[i] * sy > 0.f));
                }
                for (int i = std::max(hi + 1, lo); i < len; ++i) edge(i);
            }
            acc(b, j, lit);
            std::swap(sc.prev[static_cast<std::size_t>(b)], sc.cur[static_cast<std::size_t>(b)]);
        }
    }
}

/// Split a sequence of setups into batches of at most maxBatch with one orientation each.
std::vector<std::pair<int, int>> makeBatches(const std::vector<SweepSetup>& setups, int maxBatch) {
    std::vector<std::pair<int, int>> batches;  // (first, count)
    int i = 0;
    const int n = static_cast<int>(setups.size());
    while (i < n) {
        int j = i + 1;
        while (j < n && j - i < maxBatch &&
               setups[static_cast<std::size_t>(j)].orientation() == setups[static_cast<std::size_t>(i)].orientation())
            ++j;
        batches.emplace_back(i, j - i);
        i = j;
    }
    return batches;
}

constexpr int kMaxBatch = 8;

/// Unit vector towards the sun (x east, y north, z up) at hour angle hourAngleRad
/// (negative in the morning), declination and latitude.
Vec3 sunDirection(double latitudeRad, double declinationRad, double hourAngleRad) {
    const double sinLat = std::sin(latitudeRad), cosLat = std::cos(latitudeRad);
    const double sinDec = std::sin(declinationRad), cosDec = std::cos(declinationRad);
    const double cosH = std::cos(hourAngleRad), sinH = std::sin(hourAngleRad);
    return Vec3{-cosDec * sinH, cosLat * sinDec - sinLat * cosDec * cosH, sinLat * sinDec + cosLat * cosDec * cosH};
}

/// Half day length as an hour angle in radians, [0, pi].
double sunsetHourAngle(double latitudeDeg, double declinationRad) {
    const double lat = latitudeDeg * kDegToRad;
    const double num = -std::sin(lat) * std::sin(declinationRad);
    const double den = std::cos(lat) * std::cos(declinationRad);
    if (den <= 1e-15) return num < 0 ? kPi : 0.0;  // at a pole: polar day or night
    const double c = num / den;
    if (c <= -1.0) return kPi;
    if (c >= 1.0) return 0.0;
    return std::acos(c);
}

/// Per-thread integer accumulators in both layouts; summing integers is exact, so the
/// result does not depend on which thread handled which direction.
template <typename T>
struct ThreadAccumulators {
    std::vector<std::vector<T>> rows, cols;
    explicit ThreadAccumulators(int threads, std::size_t cells)
        : rows(static_cast<std::size_t>(threads)), cols(static_cast<std::size_t>(threads)) {
        for (auto& r : rows) r.assign(cells, T{0});
        for (auto& c : cols) c.assign(cells, T{0});
    }
    void zero() {
        for (auto& r : rows) std::fill(r.begin(), r.end(), T{0});
        for (auto& c : cols) std::fill(c.begin(), c.end(), T{0});
    }
    /// Total of cell (ix, iy) of a w x h grid over the threads and both layouts.
    template <typename S>
    S total(int ix, int iy, int w, int h) const {
        const std::size_t r = static_cast<std::size_t>(iy) * static_cast<std::size_t>(w) + static_cast<std::size_t>(ix);
        const std::size_t c = static_cast<std::size_t>(ix) * static_cast<std::size_t>(h) + static_cast<std::size_t>(iy);
        S s = 0;
        for (std::size_t t = 0; t < rows.size(); ++t) s += static_cast<S>(rows[t][r]) + static_cast<S>(cols[t][c]);
        return s;
    }
};

/// Fixed-point scale of the sky-view weights.
constexpr double kSkyScale = 16777216.0;  // 2^24

}  // namespace

// ---------------------------------------------------------------------------------------
// Slope and temperature

Grid<float> slopeDegrees(const Grid<float>& elevationM) {
    std::vector<float> gx, gy;
    gradient(elevationM, gx, gy);
    Grid<float> out = Grid<float>::like(elevationM);
    for (std::size_t i = 0; i < out.size(); ++i) {
        const double g = std::hypot(static_cast<double>(gx[i]), static_cast<double>(gy[i]));
        out.data()[i] = static_cast<float>(std::atan(g) / kDegToRad);
    }
    return out;
}

MonthlyGrids<float> temperatureC(const Grid<float>& elevationM, const Climate& climate) {
    validateClimate(climate);
    MonthlyGrids<float> out;
    out.months.reserve(kMonths);
    for (int m = 0; m < kMonths; ++m) {
        Grid<float> g = Grid<float>::like(elevationM);
        const double t0 = climate.temperatureC[static_cast<std::size_t>(m)];
        const double lapsePerM = climate.lapseRateCPerKm / 1000.0;
        for (std::size_t i = 0; i < g.size(); ++i)
            g.data()[i] = static_cast<float>(t0 - lapsePerM * static_cast<double>(elevationM.data()[i]));
        out.months.push_back(std::move(g));
    }
    return out;
}

// ---------------------------------------------------------------------------------------
// Sun

// ---------------------------------------------------------------------------------------
// Wind

Grid<float> windOcclusionDeg(const Grid<float>& elevationM, const Wind& wind) {
    validateParams(wind, windFields(), "wind parameter");
    const int w = elevationM.width(), h = elevationM.height();
    const double cell = elevationM.cellSizeM();
    // Unit step towards where the wind comes from, in cells (x east, y north); components
    // below 1e-12 are rounded to 0 so that a wind along an axis samples exactly one row or
    // column (cos 270 deg is -1.8e-16, which would step off the southern row at once).
    const double dir = wind.directionDeg * kDegToRad;
    double ux = std::sin(dir), uy = std::cos(dir);
    if (std::abs(ux) < 1e-12) ux = 0;
    if (std::abs(uy) < 1e-12) uy = 0;
    const int samples = wind.samples;
    Grid<float> out = Grid<float>::like(elevationM, 0.f);
#pragma omp parallel for schedule(static)
    for (int iy = 0; iy < h; ++iy)
        for (int ix = 0; ix < w; ++ix) {
            const double z0 = elevationM(ix, iy);
            double best = 0;  // upwind ground lower than the cell does not occlude (EcoMod's phi := 0)
            for (int k = 1; k <= samples; ++k) {
                const double fx = ix + k * ux, fy = iy + k * uy;
                if (fx < -1e-9 || fy < -1e-9 || fx > (w - 1) + 1e-9 || fy > (h - 1) + 1e-9) break;
                const int x0 = std::clamp(static_cast<int>(std::floor(fx)), 0, w - 1);
                const int y0 = std::clamp(static_cast<int>(std::floor(fy)), 0, h - 1);
                const int x1 = std::min(x0 + 1, w - 1), y1 = std::min(y0 + 1, h - 1);
                const double tx = std::clamp(fx - x0, 0.0, 1.0), ty = std::clamp(fy - y0, 0.0, 1.0);
                const double zk = (elevationM(x0, y0) * (1 - tx) + elevationM(x1, y0) * tx) * (1 - ty) +
                                  (elevationM(x0, y1) * (1 - tx) + elevationM(x1, y1) * tx) * ty;
                best = std::max(best, std::atan2(zk - z0, k * cell));
            }
            out(ix, iy) = static_cast<float>(best / kDegToRad);
        }
    return out;
}

Grid<float> windSpeedMS(const Grid<float>& elevationM, const Wind& wind) {
    Grid<float> speed = windOcclusionDeg(elevationM, wind);
    for (float& v : speed.data()) {
        const double exposure = std::max(0.0, 1.0 - v / wind.thresholdDeg);
        v = static_cast<float>(wind.strengthMS * exposure);
    }
    return speed;
}

double solarDeclinationRad(int dayOfYear) {
    // Ecliptic longitude of the sun from the mean motion (0.98565 deg/day) with the
    // equation-of-centre term (1.914 deg, eccentricity 0.0167); perihelion ~ 3 January,
    // December solstice ~ 10 days before 1 January. Evaluated at local noon.
    const double n = dayOfYear - 1 + 0.5;
    const double meanMotion = 0.98565 * kDegToRad;
    const double longitudeFromSolstice =
        meanMotion * (n + 10.0) + 1.914 * kDegToRad * std::sin(meanMotion * (n - 2.0));
    const double sinObliquity = std::sin(23.44 * kDegToRad);
    return -std::asin(sinObliquity * std::cos(longitudeFromSolstice));
}

double dayLengthHours(double latitudeDeg, int dayOfYear) {
    return 24.0 * sunsetHourAngle(latitudeDeg, solarDeclinationRad(dayOfYear)) / kPi;
}

int dayOfYearFor(int month0, int dayOfMonth) {
    static constexpr std::array<int, 12> kStart = {0, 31, 59, 90, 120, 151, 181, 212, 243, 273, 304, 334};
    if (month0 < 0 || month0 > 11) throw ValidationError("month must be 0..11, got " + std::to_string(month0));
    return kStart[static_cast<std::size_t>(month0)] + dayOfMonth;
}

Grid<float> skyViewFactor(const Grid<float>& elevationM, const SunParams& params) {
    validateSunParams(params);
    const int w = elevationM.width(), h = elevationM.height();
    std::vector<float> gx, gy;
    gradient(elevationM, gx, gy);
    const LineLayout rowsLay = rowLayout(elevationM, gx, gy);
    const LineLayout colsLay = columnLayout(elevationM, gx, gy);

    // Directions: azimuth a_i = i * 360/A (clockwise from north), elevation band centres
    // e_j = (j + 0.5) * 90/E. Band j carries the cosine-weighted solid angle of the band,
    // (sin^2 e_top - sin^2 e_bottom) / A, the share of a uniform sky's light on flat ground.
    const int A = params.skyAzimuths, E = params.skyElevations;
    std::vector<SweepSetup> setups;
    std::vector<double> quanta;  // fixed-point weight of each direction
    std::vector<Vec3> dirs;
    std::int64_t flatTotal = 0;
    for (int i = 0; i < A; ++i) {
        const double az = 2.0 * kPi * i / A;
        for (int j = 0; j < E; ++j) {
            const double e0 = 0.5 * kPi * j / E, e1 = 0.5 * kPi * (j + 1) / E, ec = 0.5 * (e0 + e1);
            const double weight = (std::sin(e1) * std::sin(e1) - std::sin(e0) * std::sin(e0)) / A;
            const double q = std::nearbyint(weight * kSkyScale);
            const Vec3 d{std::sin(az) * std::cos(ec), std::cos(az) * std::cos(ec), std::sin(ec)};
            setups.push_back(setupSweep(d, elevationM.cellSizeM()));
            quanta.push_back(q);
            dirs.push_back(d);
            flatTotal += static_cast<std::int64_t>(q);
        }
    }
    const auto batches = makeBatches(setups, kMaxBatch);
    const int threads = std::max(1, omp_get_max_threads());
    ThreadAccumulators<std::uint32_t> acc(threads, elevationM.size());
    std::vector<SweepScratch> scratch(static_cast<std::size_t>(threads));

#pragma omp parallel for schedule(dynamic, 1) num_threads(threads)
    for (int bi = 0; bi < static_cast<int>(batches.size()); ++bi) {
        const int t = omp_get_thread_num();
        const int first = batches[static_cast<std::size_t>(bi)].first;
        const int count = batches[static_cast<std::size_t>(bi)].second;
        const SweepSetup& st0 = setups[static_cast<std::size_t>(first)];
        const LineLayout& lay = st0.columns ? colsLay : rowsLay;
        auto& out = st0.columns ? acc.cols[static_cast<std::size_t>(t)] : acc.rows[static_cast<std::size_t>(t)];
        sweepBatch(lay, &setups[static_cast<std::size_t>(first)], count, scratch[static_cast<std::size_t>(t)],
                   [&](int b, int line, const std::uint8_t* lit) {
                       const std::size_t di = static_cast<std::size_t>(first + b);
                       const Vec3 d = dirs[di];
                       const double q = quanta[di];
                       const std::size_t base = static_cast<std::size_t>(line) * static_cast<std::size_t>(lay.len);
                       for (int i = 0; i < lay.len; ++i) {
                           if (!lit[i]) continue;
                           // Cosine on the tilted surface relative to the cosine on flat
                           // ground (exactly 1 there), so flat open ground sums to flatTotal.
                           const double gxi = lay.gx[base + static_cast<std::size_t>(i)];
                           const double gyi = lay.gy[base + static_cast<std::size_t>(i)];
                           const double cosTilted = glm::dot(d, glm::normalize(Vec3(-gxi, -gyi, 1.0)));
                           out[base + static_cast<std::size_t>(i)] +=
                               static_cast<std::uint32_t>(std::nearbyint(q * cosTilted / d.z));
                       }
                   });
    }

    Grid<float> view = Grid<float>::like(elevationM);
#pragma omp parallel for schedule(static)
    for (int iy = 0; iy < h; ++iy)
        for (int ix = 0; ix < w; ++ix) {
            const auto s = acc.total<std::int64_t>(ix, iy, w, h);
            view(ix, iy) = static_cast<float>(std::min(1.0, static_cast<double>(s) / static_cast<double>(flatTotal)));
        }
    return view;
}

SunDetail sunDetail(const Grid<float>& elevationM, const Climate& climate, const SunParams& params,
                    const std::function<void(double fraction)>& progress) {
    validateElevation(elevationM);
    validateClimate(climate);
    validateSunParams(params);
    const int w = elevationM.width(), h = elevationM.height();
    const double latRad = climate.latitudeDeg * kDegToRad;

    // Sample plan: month m has N_m equal intervals between sunrise and sunset, sampled at
    // their midpoints.
    struct MonthPlan {
        double declinationRad = 0, halfDayRad = 0, dayLengthH = 0, intervalH = 0;
        int samples = 0;
    };
    std::array<MonthPlan, 12> plan{};
    long totalSamples = 0;
    for (int m = 0; m < kMonths; ++m) {
        MonthPlan& p = plan[static_cast<std::size_t>(m)];
        p.declinationRad = solarDeclinationRad(dayOfYearFor(m, params.dayOfMonth));
        p.halfDayRad = sunsetHourAngle(climate.latitudeDeg, p.declinationRad);
        p.dayLengthH = 24.0 * p.halfDayRad / kPi;
        p.samples = p.dayLengthH > 0 ? std::max(1, static_cast<int>(std::lround(p.dayLengthH * 60.0 / params.stepMinutes))) : 0;
        p.intervalH = p.samples > 0 ? p.dayLengthH / p.samples : 0.0;
        totalSamples += p.samples;
    }
    // Sky view counts as much work as its number of directions.
    const long skyWork = static_cast<long>(params.skyAzimuths) * params.skyElevations;
    const double totalWork = static_cast<double>(totalSamples + skyWork);
    long doneWork = 0;

    SunDetail out;
    out.skyView = skyViewFactor(elevationM, params);
    doneWork += skyWork;
    if (progress) progress(static_cast<double>(doneWork) / totalWork);

    std::vector<float> gx, gy;
    gradient(elevationM, gx, gy);
    const LineLayout rowsLay = rowLayout(elevationM, gx, gy);
    const LineLayout colsLay = columnLayout(elevationM, gx, gy);
    const int threads = std::max(1, omp_get_max_threads());
    ThreadAccumulators<std::uint16_t> counts(threads, elevationM.size());
    std::vector<SweepScratch> scratch(static_cast<std::size_t>(threads));

    out.directHours.months.reserve(kMonths);
    out.sunHours.months.reserve(kMonths);
    for (int m = 0; m < kMonths; ++m) {
        const MonthPlan& p = plan[static_cast<std::size_t>(m)];
        out.dayLengthHours[static_cast<std::size_t>(m)] = p.dayLengthH;
        std::vector<SweepSetup> setups;
        setups.reserve(static_cast<std::size_t>(p.samples));
        for (int s = 0; s < p.samples; ++s) {
            const double hourAngle = -p.halfDayRad + (s + 0.5) * (2.0 * p.halfDayRad / p.samples);
            setups.push_back(setupSweep(sunDirection(latRad, p.declinationRad, hourAngle), elevationM.cellSizeM()));
        }
        const auto batches = makeBatches(setups, kMaxBatch);
        counts.zero();
#pragma omp parallel for schedule(dynamic, 1) num_threads(threads)
        for (int bi = 0; bi < static_cast<int>(batches.size()); ++bi) {
            const int t = omp_get_thread_num();
            const int first = batches[static_cast<std::size_t>(bi)].first;
            const SweepSetup& st0 = setups[static_cast<std::size_t>(first)];
            const LineLayout& lay = st0.columns ? colsLay : rowsLay;
            auto& cnt = st0.columns ? counts.cols[static_cast<std::size_t>(t)] : counts.rows[static_cast<std::size_t>(t)];
            sweepBatch(lay, &setups[static_cast<std::size_t>(first)], batches[static_cast<std::size_t>(bi)].second,
                       scratch[static_cast<std::size_t>(t)], [&](int, int line, const std::uint8_t* lit) {
                           std::uint16_t* c = cnt.data() + static_cast<std::size_t>(line) * static_cast<std::size_t>(lay.len);
                           for (int i = 0; i < lay.len; ++i) c[i] = static_cast<std::uint16_t>(c[i] + lit[i]);
                       });
        }

        Grid<float> direct = Grid<float>::like(elevationM);
        Grid<float> total = Grid<float>::like(elevationM);
        const double clarity = climate.skyClarity[static_cast<std::size_t>(m)];
#pragma omp parallel for schedule(static)
        for (int iy = 0; iy < h; ++iy)
            for (int ix = 0; ix < w; ++ix) {
                const double directH = static_cast<double>(counts.total<long>(ix, iy, w, h)) * p.intervalH;
                direct(ix, iy) = static_cast<float>(directH);
                total(ix, iy) = static_cast<float>(clarity * directH +
                                                   (1.0 - clarity) * out.skyView(ix, iy) * p.dayLengthH);
            }
        out.directHours.months.push_back(std::move(direct));
        out.sunHours.months.push_back(std::move(total));
        doneWork += p.samples;
        if (progress) progress(static_cast<double>(doneWork) / totalWork);
    }
    return out;
}

MonthlyGrids<float> sunHours(const Grid<float>& elevationM, const Climate& climate, const SunParams& params,
                             const std::function<void(double fraction)>& progress) {
    return sunDetail(elevationM, climate, params, progress).sunHours;
}

MonthlyGrids<float> applyCanopyShade(const MonthlyGrids<float>& sun, const std::vector<ShadingTree>& trees) {
    if (sun.months.empty()) throw ValidationError("applyCanopyShade: no sun planes");
    const Grid<float>& g0 = sun.months.front();
    for (const auto& g : sun.months)
        if (!g.sameGeometry(g0)) throw ValidationError("applyCanopyShade: sun planes differ in geometry");
    // Transmission per cell, the product over covering trees in input order.
    Grid<double> transmission = Grid<double>::like(g0, 1.0);
    for (std::size_t t = 0; t < trees.size(); ++t) {
        const ShadingTree& tr = trees[t];
        if (!std::isfinite(tr.x) || !std::isfinite(tr.y))
            throw ValidationError("applyCanopyShade: tree " + std::to_string(t) + ": position must be finite");
        if (!std::isfinite(tr.crownRadiusM) || tr.crownRadiusM < 0)
            throw ValidationError("applyCanopyShade: tree " + std::to_string(t) + ": crownRadiusM must be >= 0, got " +
                                  num(tr.crownRadiusM));
        if (!std::isfinite(tr.alpha) || tr.alpha < 0 || tr.alpha > 1)
            throw ValidationError("applyCanopyShade: tree " + std::to_string(t) + ": alpha must be in [0, 1], got " +
                                  num(tr.alpha));
        // Cells whose centre may lie in the disc: the bounding box, clipped to the grid.
        const double cell = g0.cellSizeM();
        const int x0 = std::max(0, static_cast<int>(std::ceil((tr.x - tr.crownRadiusM - g0.originX()) / cell - 0.5)));
        const int x1 = std::min(g0.width() - 1,
                                static_cast<int>(std::floor((tr.x + tr.crownRadiusM - g0.originX()) / cell - 0.5)));
        const int y0 = std::max(0, static_cast<int>(std::ceil((tr.y - tr.crownRadiusM - g0.originY()) / cell - 0.5)));
        const int y1 = std::min(g0.height() - 1,
                                static_cast<int>(std::floor((tr.y + tr.crownRadiusM - g0.originY()) / cell - 0.5)));
        const double r2 = tr.crownRadiusM * tr.crownRadiusM;
        const double keep = 1.0 - tr.alpha;
        for (int iy = y0; iy <= y1; ++iy) {
            const double dy = g0.cellCentreY(iy) - tr.y;
            for (int ix = x0; ix <= x1; ++ix) {
                const double dx = g0.cellCentreX(ix) - tr.x;
                if (dx * dx + dy * dy <= r2) transmission(ix, iy) *= keep;
            }
        }
    }
    MonthlyGrids<float> out = sun;
    for (auto& g : out.months)
        for (std::size_t i = 0; i < g.size(); ++i)
            if (transmission.data()[i] != 1.0)
                g.data()[i] = static_cast<float>(static_cast<double>(g.data()[i]) * transmission.data()[i]);
    return out;
}

std::vector<ShadingTree> shadingTrees(const std::vector<Plant>& canopy, const Biome& biome) {
    std::vector<ShadingTree> trees;
    trees.reserve(canopy.size());
    for (std::size_t i = 0; i < canopy.size(); ++i) {
        const Plant& p = canopy[i];
        if (p.speciesId < 0 || static_cast<std::size_t>(p.speciesId) >= biome.species.size())
            throw ValidationError("canopy tree " + std::to_string(i) + ": species id " + std::to_string(p.speciesId) +
                                  " is not in biome '" + biome.name + "'");
        trees.push_back({p.xM, p.yM, p.crownRadiusM, biome.species[static_cast<std::size_t>(p.speciesId)].alpha});
    }
    return trees;
}

// ---------------------------------------------------------------------------------------
// Moisture

double MoistureBalance::sum(const std::array<double, 12>& a) {
    double s = 0;
    for (double v : a) s += v;
    return s;
}

double MoistureBalance::relativeError() const {
    const double rain = rainYearM3();
    if (rain <= 0) return 0.0;
    return std::abs(rain - (storageChangeYearM3() + evaporatedYearM3() + outflowYearM3())) / rain;
}

namespace {

/// Flow routing of a terrain: cells in processing order (every cell before the cells it
/// drains into) and, per cell, its receivers with the fraction of runoff each gets.
struct FlowRouting {
    std::vector<std::int32_t> order;          ///< cells, upstream first
    std::vector<std::int32_t> recvStart;      ///< CSR offsets into recv/recvFraction, size cells+1
    std::vector<std::int32_t> recv;
    std::vector<double> recvFraction;
};

FlowRouting routeFlow(const Grid<float>& z) {
    const int w = z.width(), h = z.height();
    const std::size_t n = z.size();
    // Priority-flood (min-heap on filled elevation, ties first-in first-out): seeded with
    // the edge cells, each popped cell raises its unvisited neighbours to at least its own
    // filled level. Pop order is non-decreasing in filled elevation, and the cell that
    // raised a neighbour (its parent) is a path to the edge even across filled pits and flats.
    struct Item {
        float level;
        std::uint64_t seq;
        std::int32_t cell;
        bool operator>(const Item& o) const { return level != o.level ? level > o.level : seq > o.seq; }
    };
    std::priority_queue<Item, std::vector<Item>, std::greater<Item>> heap;
    std::vector<float> filled(n, 0.f);
    std::vector<std::int32_t> parent(n, -1);
    std::vector<std::uint8_t> seen(n, 0);
    std::uint64_t seq = 0;
    auto seed = [&](int ix, int iy) {
        const std::size_t c = z.index(ix, iy);
        if (seen[c]) return;
        seen[c] = 1;
        filled[c] = z.data()[c];
        heap.push(Item{filled[c], seq++, static_cast<std::int32_t>(c)});
    };
    for (int ix = 0; ix < w; ++ix) {
        seed(ix, 0);
        seed(ix, h - 1);
    }
    for (int iy = 0; iy < h; ++iy) {
        seed(0, iy);
        seed(w - 1, iy);
    }
    static constexpr int kDx[8] = {1, 1, 0, -1, -1, -1, 0, 1};
    static constexpr int kDy[8] = {0, 1, 1, 1, 0, -1, -1, -1};
    FlowRouting r;
    r.order.reserve(n);
    while (!heap.empty()) {
        const Item it = heap.top();
        heap.pop();
        r.order.push_back(it.cell);
        const int ix = it.cell % w, iy = it.cell / w;
        for (int d = 0; d < 8; ++d) {
            const int nx = ix + kDx[d], ny = iy + kDy[d];
            if (!z.inside(nx, ny)) continue;
            const std::size_t c = z.index(nx, ny);
            if (seen[c]) continue;
            seen[c] = 1;
            filled[c] = std::max(z.data()[c], it.level);
            parent[c] = it.cell;
            heap.push(Item{filled[c], seq++, static_cast<std::int32_t>(c)});
        }
    }
    // Cells raised by the fill lie in depressions. Each drains through its outlet: the first
    // cell on its parent chain that was not raised (the pour point on the rim).
    const std::vector<std::int32_t> popOrder = std::move(r.order);
    std::vector<std::uint8_t> raised(n, 0);
    std::vector<std::int32_t> outlet(n, -1);
    for (const std::int32_t cell : popOrder) {
        const std::size_t c = static_cast<std::size_t>(cell);
        if (!(filled[c] > z.data()[c])) continue;
        raised[c] = 1;
        const std::size_t p = static_cast<std::size_t>(parent[c]);  // raised cells always have one
        outlet[c] = raised[p] ? outlet[p] : parent[c];
    }

    // Receivers, multiple flow directions weighted by drop / distance:
    //  * a cell on open ground shares its runoff among the neighbours whose filled level is
    //    lower; on a flat (none lower) it sends everything to its parent, towards the edge;
    //  * a cell in a depression flows down the real terrain to lower cells of the same
    //    depression, so the pit bottom collects its walls' runoff; a local minimum sends
    //    what it cannot absorb to the depression's outlet (the lake spills over the rim);
    //  * an edge cell with no receiver drains out of the domain.
    // Every step lowers (filled level; then pop order, with a depression ranked just after
    // its outlet; then elevation inside a depression), so the graph has no cycles.
    r.recvStart.assign(n + 1, 0);
    r.recv.reserve(n * 2);
    r.recvFraction.reserve(n * 2);
    for (std::size_t c = 0; c < n; ++c) {
        r.recvStart[c] = static_cast<std::int32_t>(r.recv.size());
        const int ix = static_cast<int>(c % static_cast<std::size_t>(w)), iy = static_cast<int>(c / static_cast<std::size_t>(w));
        const double zc = z.data()[c];
        double sum = 0;
        const std::size_t begin = r.recv.size();
        for (int d = 0; d < 8; ++d) {
            const int nx = ix + kDx[d], ny = iy + kDy[d];
            if (!z.inside(nx, ny)) continue;
            const std::size_t nc = z.index(nx, ny);
            double drop = 0;
            if (!raised[c]) {
                if (filled[nc] < filled[c]) drop = static_cast<double>(filled[c]) - filled[nc];
            } else if (raised[nc] && outlet[nc] == outlet[c] && z.data()[nc] < zc) {
                drop = zc - z.data()[nc];
            }
            if (drop > 0) {
                const double dist = (kDx[d] != 0 && kDy[d] != 0) ? std::sqrt(2.0) : 1.0;
                r.recv.push_back(static_cast<std::int32_t>(nc));
                r.recvFraction.push_back(drop / dist);
                sum += drop / dist;
            }
        }
        if (r.recv.size() == begin) {
            const std::int32_t to = raised[c] ? outlet[c] : parent[c];
            if (to >= 0) {
                r.recv.push_back(to);
                r.recvFraction.push_back(1.0);
                sum = 1.0;
            }
        }
        for (std::size_t k = begin; k < r.recv.size(); ++k) r.recvFraction[k] /= sum;
    }
    r.recvStart[n] = static_cast<std::int32_t>(r.recv.size());

    // Processing order: a topological order of the flow graph (Kahn), every cell before
    // the cells it drains into; first-in first-out from the cells in index order, so it is
    // deterministic.
    std::vector<std::int32_t> indegree(n, 0);
    for (const std::int32_t t : r.recv) ++indegree[static_cast<std::size_t>(t)];
    r.order.clear();
    r.order.reserve(n);
    for (std::size_t c = 0; c < n; ++c)
        if (indegree[c] == 0) r.order.push_back(static_cast<std::int32_t>(c));
    for (std::size_t head = 0; head < r.order.size(); ++head) {
        const std::size_t c = static_cast<std::size_t>(r.order[head]);
        for (std::int32_t k = r.recvStart[c]; k < r.recvStart[c + 1]; ++k) {
            const std::size_t t = static_cast<std::size_t>(r.recv[static_cast<std::size_t>(k)]);
            if (--indegree[t] == 0) r.order.push_back(static_cast<std::int32_t>(t));
        }
    }
    if (r.order.size() != n) throw std::logic_error("moisture routing: flow graph has a cycle (internal error)");

    return r;
}

}  // namespace

MonthlyGrids<float> moistureMm(const Grid<float>& elevationM, const Climate& climate, const Soil& soil,
                               MoistureBalance* balance, int spinUpYears,
                               const std::function<void(double fraction)>& progress) {
    validateElevation(elevationM);
    validateClimate(climate);
    validateSoil(soil);
    if (spinUpYears < 0 || spinUpYears > 1000)
        throw ValidationError("moisture: spin_up_years must be in [0, 1000], got " + std::to_string(spinUpYears));
    const std::size_t n = elevationM.size();
    const Grid<float> slope = slopeDegrees(elevationM);
    // Fraction of the inflow that may infiltrate: 1 up to the threshold slope, 0 from the
    // maximum slope, linear between.
    std::vector<double> infiltrable(n);
    for (std::size_t c = 0; c < n; ++c) {
        const double s = slope.data()[c];
        double f;
        if (s <= soil.slopeThresholdDeg) f = 1.0;
        else if (s >= soil.slopeMaxDeg) f = 0.0;
        else f = 1.0 - (s - soil.slopeThresholdDeg) / (soil.slopeMaxDeg - soil.slopeThresholdDeg);
        infiltrable[c] = f;
    }
    const FlowRouting route = routeFlow(elevationM);
    const double m3PerMm = elevationM.cellSizeM() * elevationM.cellSizeM() * 1e-3;

    // Cells renumbered in processing order, so that the monthly pass walks memory forwards.
    std::vector<std::int32_t> position(n);
    for (std::size_t k = 0; k < n; ++k) position[static_cast<std::size_t>(route.order[k])] = static_cast<std::int32_t>(k);
    std::vector<double> infiltrableAt(n);
    std::vector<std::int32_t> recvStart(n + 1), recv;
    std::vector<double> recvFraction;
    recv.reserve(route.recv.size());
    recvFraction.reserve(route.recv.size());
    for (std::size_t k = 0; k < n; ++k) {
        const std::size_t c = static_cast<std::size_t>(route.order[k]);
        infiltrableAt[k] = infiltrable[c];
        recvStart[k] = static_cast<std::int32_t>(recv.size());
        for (std::int32_t j = route.recvStart[c]; j < route.recvStart[c + 1]; ++j) {
            recv.push_back(position[static_cast<std::size_t>(route.recv[static_cast<std::size_t>(j)])]);
            recvFraction.push_back(route.recvFraction[static_cast<std::size_t>(j)]);
        }
    }
    recvStart[n] = static_cast<std::int32_t>(recv.size());

    std::vector<double> water(n, 0.0);  // soil store W, mm (by processing position)
    std::vector<double> runOn(n, 0.0);  // water arriving from upstream this month, mm
    MonthlyGrids<float> out;
    out.months.reserve(kMonths);
    MoistureBalance bal;
    auto storage = [&] {
        double s = 0;
        for (double v : water) s += v;
        return s;
    };
    for (int year = 0; year <= spinUpYears; ++year) {
        const bool record = year == spinUpYears;
        if (record) bal.initialStorageM3 = storage() * m3PerMm;
        for (int m = 0; m < kMonths; ++m) {
            const double rain = climate.rainfallMm[static_cast<std::size_t>(m)];
            const double before = record ? storage() : 0.0;
            std::fill(runOn.begin(), runOn.end(), 0.0);
            double absorbed = 0, outflow = 0, evaporated = 0;
            for (std::size_t k = 0; k < n; ++k) {
                const double inflow = rain + runOn[k];
                const double room = std::max(0.0, soil.saturationMm - water[k]);
                const double take = std::min({infiltrableAt[k] * inflow, soil.runoffLimitMm, room});
                water[k] += take;
                absorbed += take;
                double rest = inflow - take;
                if (rest <= 0) continue;
                const std::int32_t b = recvStart[k], e = recvStart[k + 1];
                if (b == e) {
                    outflow += rest;
                    continue;
                }
                // The last receiver gets the remainder so that no water is created or lost.
                const double runoff = rest;
                for (std::int32_t j = b; j < e - 1; ++j) {
                    const double part = runoff * recvFraction[static_cast<std::size_t>(j)];
                    runOn[static_cast<std::size_t>(recv[static_cast<std::size_t>(j)])] += part;
                    rest -= part;
                }
                runOn[static_cast<std::size_t>(recv[static_cast<std::size_t>(e - 1)])] += rest;
            }
            for (std::size_t k = 0; k < n; ++k) {
                const double e = soil.evaporationFraction * water[k];
                water[k] -= e;
                evaporated += e;
            }
            if (record) {
                const std::size_t mi = static_cast<std::size_t>(m);
                bal.rainM3[mi] = rain * static_cast<double>(n) * m3PerMm;
                bal.absorbedM3[mi] = absorbed * m3PerMm;
                bal.evaporatedM3[mi] = evaporated * m3PerMm;
                bal.outflowM3[mi] = outflow * m3PerMm;
                bal.storageChangeM3[mi] = (storage() - before) * m3PerMm;
                Grid<float> g = Grid<float>::like(elevationM);
                for (std::size_t k = 0; k < n; ++k)
                    g.data()[static_cast<std::size_t>(route.order[k])] = static_cast<float>(water[k]);
                out.months.push_back(std::move(g));
            }
            if (progress) progress(static_cast<double>(year * kMonths + m + 1) / (kMonths * (spinUpYears + 1)));
        }
    }
    bal.finalStorageM3 = storage() * m3PerMm;
    if (balance) *balance = bal;
    return out;
}

// ---------------------------------------------------------------------------------------
// All maps together

Grid<float> annualMap(const Abiotics& a, const AbioticMapInfo& m) {
    return m.isMonthly() ? (a.*(m.monthly)).annualMean() : a.*(m.single);
}

FactorGrids annualFactors(const Abiotics& a, const Grid<float>* sunHoursAnnual) {
    FactorGrids g;
    for (const AbioticMapInfo& m : kAbioticMaps)
        g[m.factor] = m.factor == Factor::Sun && sunHoursAnnual ? *sunHoursAnnual : annualMap(a, m);
    return g;
}

void validateElevation(const Grid<float>& elevationM, const std::string& what) {
    if (elevationM.width() < 3 || elevationM.height() < 3)
        throw ValidationError(what + ": grid must be at least 3 x 3 cells, got " + std::to_string(elevationM.width()) +
                              " x " + std::to_string(elevationM.height()));
    for (int iy = 0; iy < elevationM.height(); ++iy)
        for (int ix = 0; ix < elevationM.width(); ++ix)
            if (!std::isfinite(elevationM(ix, iy)))
                throw ValidationError(what + ": elevation at cell (" + std::to_string(ix) + ", " + std::to_string(iy) +
                                      ") is not finite");
}

const std::vector<ParamDesc<SunParams>>& sunParamFields() {
    using K = ParamDesc<SunParams>::Kind;
    using R = ParamRange;
    using P = SunParams;
    static const std::vector<ParamDesc<SunParams>> fields = {
        // Counts of samples per day are kept in 16 bits: at most 65535 samples (>= 0.022 min).
        {"sun_step_minutes", "sampling interval of the sun path (about)", "minutes", K::Real, &P::stepMinutes, nullptr,
         R::closed(0.1, 720)},
        {"sun_sky_azimuths", "azimuths of the sky-view sweeps", "", K::Integer, nullptr, &P::skyAzimuths,
         R::closed(1, 4096)},
        {"sun_sky_elevations", "elevation bands of the sky-view sweeps (0..90 degrees)", "", K::Integer, nullptr,
         &P::skyElevations, R::closed(1, 1024)},
        {"sun_day_of_month", "representative day of each month", "day", K::Integer, nullptr, &P::dayOfMonth,
         R::closed(1, 28)},
    };
    return fields;
}

const std::vector<ParamDesc<AbioticParams>>& abioticParamFields() {
    using K = ParamDesc<AbioticParams>::Kind;
    static const std::vector<ParamDesc<AbioticParams>> fields = {
        {"moisture_spin_up_years", "years of moisture routing run before the recorded year", "years", K::Integer, nullptr,
         &AbioticParams::moistureSpinUpYears, ParamRange::closed(0, 1000)},
    };
    return fields;
}

Abiotics computeAbiotics(const Grid<float>& elevationM, const Biome& biome, const AbioticParams& params,
                         const std::function<void(const std::string& stage, double fraction)>& progress) {
    validateElevation(elevationM);
    validateClimate(biome.climate);
    validateSoil(biome.soil);
    validateSunParams(params.sun);
    validateParams(params, abioticParamFields(), "abiotics parameter");
    validateParams(biome.wind, windFields(), "wind parameter");
    // The maps and the sun and moisture computations' buffers: a peak of about 280 bytes a
    // cell (measured: 1.2 GB for 2000 x 2000 cells, 94 MB for 400 x 300). Refused here, not
    // as an out-of-memory kill minutes later.
    const double cells = static_cast<double>(elevationM.width()) * static_cast<double>(elevationM.height());
    requireMemory(kAbioticsBytesPerCell * cells,
                  "the abiotic maps of a terrain of " + std::to_string(elevationM.width()) + " x " +
                      std::to_string(elevationM.height()) + " cells",
                  "about " + std::to_string(static_cast<int>(kAbioticsBytesPerCell)) +
                      " bytes a cell; crop or resample the terrain first, e.g. gdal_translate -srcwin / gdalwarp -tr");
    auto report = [&](const char* stage, double f) {
        if (progress) progress(stage, f);
    };
    Abiotics a;
    a.elevationM = elevationM;
    report("slope", 0.0);
    a.slopeDeg = slopeDegrees(elevationM);
    report("slope", 1.0);
    report("temperature", 0.0);
    a.temperatureC = temperatureC(elevationM, biome.climate);
    report("temperature", 1.0);
    report("sun", 0.0);
    a.sunHours = sunHours(elevationM, biome.climate, params.sun, [&](double f) { report("sun", f); });
    report("moisture", 0.0);
    a.moistureMm = moistureMm(elevationM, biome.climate, biome.soil, nullptr, params.moistureSpinUpYears,
                              [&](double f) { report("moisture", f); });
    report("wind", 0.0);
    a.windMS = windSpeedMS(elevationM, biome.wind);
    report("wind", 1.0);
    return a;
}

// ---------------------------------------------------------------------------------------
// File

namespace {

constexpr const char* kFormat = "eco-abiotics";
// 2: the wind map /wind and its wind_* attributes (version 1 files have no wind and are
// refused with a message saying so). A map added later (a new row of kAbioticMaps) does not
// change the version: the reader looks for each map of the table by its dataset and refuses
// a file without one, naming the map and saying the file was written before it existed;
// older code reads the maps it knows from a newer file (docs/factors.md).
constexpr std::int64_t kSchemaVersion = 2;

std::vector<double> toVector(const std::array<double, 12>& a) { return std::vector<double>(a.begin(), a.end()); }

// The fields of a table as attributes of `object`: reals as double, integers as int64.
template <typename S>
void writeParamAttrs(h5::File& f, const std::string& object, const S& p, const std::vector<ParamDesc<S>>& fields) {
    for (const auto& field : fields) {
        if (field.kind == ParamDesc<S>::Kind::Real) f.setAttr(object, field.key, p.*(field.real));
        else f.setAttr(object, field.key, static_cast<std::int64_t>(field.value(p)));
    }
}

}  // namespace

void writeAbiotics(const std::string& path, const Abiotics& maps, const Biome& biome, const AbioticParams& params) {
    const Grid<float>& e = maps.elevationM;
    // Monthly maps first, then the static ones (the order of the messages before the table).
    for (const bool monthly : {true, false})
        for (const AbioticMapInfo& m : kAbioticMaps) {
            if (m.isMonthly() != monthly) continue;
            if (monthly && (maps.*(m.monthly)).months.size() != static_cast<std::size_t>(kMonths))
                throw ValidationError(path + ": " + m.name + ": expected 12 monthly planes, got " +
                                      std::to_string((maps.*(m.monthly)).months.size()));
            forEachPlane(maps, m, [&](const Grid<float>& g) {
                if (!g.sameGeometry(e)) throw ValidationError(path + ": " + m.name + ": geometry differs from the elevation grid");
            });
        }

    AtomicOutput out(path);
    {
        h5::File f = h5::File::create(out.tempPath());
        f.writeGrid("/elevation", e, "m");
        for (const AbioticMapInfo& m : kAbioticMaps) {
            if (m.isMonthly()) f.writeStack(m.dataset, (maps.*(m.monthly)).months, m.unit);
            else f.writeGrid(m.dataset, maps.*(m.single), m.unit);
        }
        const std::string root = "/";
        f.setAttr(root, "format", std::string(kFormat));
        f.setAttr(root, "schema_version", kSchemaVersion);
        f.setAttr(root, "canopy_shade", maps.canopyShadeSource.empty() ? std::string("none") : maps.canopyShadeSource);
        f.setAttr(root, "code_version", std::string(ECO_VERSION_STRING));
        writeProvenance(f, {});  // what identifies the run: nothing measured
        f.setAttr(root, "biome_name", biome.name);
        f.setAttr(root, "months", std::string("plane 0 = January .. plane 11 = December"));
        f.setAttr(root, "latitude_deg", biome.climate.latitudeDeg);
        f.setAttr(root, "lapse_rate_c_per_km", biome.climate.lapseRateCPerKm);
        f.setAttr(root, "climate_temperature_c", toVector(biome.climate.temperatureC));
        f.setAttr(root, "climate_rainfall_mm", toVector(biome.climate.rainfallMm));
        f.setAttr(root, "climate_sky_clarity", toVector(biome.climate.skyClarity));
        f.setAttr(root, "soil_runoff_limit_mm", biome.soil.runoffLimitMm);
        f.setAttr(root, "soil_slope_threshold_deg", biome.soil.slopeThresholdDeg);
        f.setAttr(root, "soil_slope_max_deg", biome.soil.slopeMaxDeg);
        f.setAttr(root, "soil_evaporation_fraction", biome.soil.evaporationFraction);
        f.setAttr(root, "soil_saturation_mm", biome.soil.saturationMm);
        writeParamAttrs(f, root, params.sun, sunParamFields());
        std::vector<double> dayLengths;
        for (int m = 0; m < kMonths; ++m)
            dayLengths.push_back(dayLengthHours(biome.climate.latitudeDeg, dayOfYearFor(m, params.sun.dayOfMonth)));
        f.setAttr(root, "sun_day_length_hours", dayLengths);
        f.setAttr(root, "sun_model",
                  std::string("sky_clarity*direct_hours + (1-sky_clarity)*sky_view*day_length; direct: terrain "
                              "self-shadowing sweeps and facing test at interval midpoints, no refraction"));
        writeParamAttrs(f, root, params, abioticParamFields());
        f.setAttr(root, "moisture_model",
                  std::string("soil store W (mm) after each month: rain plus run-on infiltrates (fraction by slope, "
                              "capped by runoff limit and saturation), the rest runs off by multiple flow directions "
                              "(drop/distance) over the priority-flood filled surface; inside depressions down the "
                              "real terrain, overflow to the depression outlet; then evaporation"));
        for (const auto& field : windFields()) {
            const std::string key = std::string("wind_") + field.key;
            if (field.kind == ParamDesc<Wind>::Kind::Real) f.setAttr(root, key, biome.wind.*(field.real));
            else f.setAttr(root, key, static_cast<std::int64_t>(field.value(biome.wind)));
        }
        f.setAttr(root, "wind_model",
                  std::string("EcoMod wind shelter (Zamuda & Brest): occlusion = largest elevation angle of "
                              "wind_samples points upwind one cell apart (bilinear, 0 if none higher); "
                              "wind = strength * max(0, 1 - occlusion / threshold), m/s"));
    }
    out.commit();
}

Abiotics readAbiotics(const std::string& path) {
    const h5::File f = h5::File::openRead(path);
    if (!f.hasAttr("/", "format") || f.attrString("/", "format") != kFormat)
        throw IoError(path + ": not an eco-abiotics file (root attribute 'format' is missing or not '" +
                      std::string(kFormat) + "')");
    const std::int64_t version = f.attrInt("/", "schema_version");
    if (version == 1)
        throw IoError(path + ": eco-abiotics schema_version 1 has no wind map (/wind, schema 2); re-run eco abiotics "
                             "with this version");
    if (version != kSchemaVersion)
        throw IoError(path + ": unsupported eco-abiotics schema_version " + std::to_string(version) + " (expected " +
                      std::to_string(kSchemaVersion) + ")");
    auto require = [&](const std::string& name) {
        if (!f.exists(name)) throw IoError(path + ": dataset " + name + " is missing");
    };
    require("/elevation");
    for (const AbioticMapInfo& m : kAbioticMaps)
        if (!f.exists(m.dataset))
            throw IoError(path + ": dataset " + m.dataset + " is missing: no " + m.name +
                          " map (a file written before the " + m.name +
                          " map existed, or a damaged one); re-run eco abiotics with this version");

    Abiotics a;
    // Files written before the attribute existed hold the terrain's own sun.
    if (f.hasAttr("/", "canopy_shade") && f.attrString("/", "canopy_shade") != "none")
        a.canopyShadeSource = f.attrString("/", "canopy_shade");
    bool windRecorded = true;
    Wind w;
    for (const auto& field : windFields()) {
        const std::string key = std::string("wind_") + field.key;
        if (!f.hasAttr("/", key)) {
            windRecorded = false;
            break;
        }
        if (field.kind == ParamDesc<Wind>::Kind::Real) w.*(field.real) = f.attrDouble("/", key);
        else if (field.kind == ParamDesc<Wind>::Kind::Integer) w.*(field.integer) = static_cast<int>(f.attrInt("/", key));
    }
    if (windRecorded) a.mapWind = w;
    const auto eShape = f.shape("/elevation");
    if (eShape.size() != 2)
        throw IoError(path + ": dataset /elevation has rank " + std::to_string(eShape.size()) + ", expected [height][width]");
    a.elevationM = f.readGrid("/elevation");
    auto shapeText = [](const std::vector<hsize_t>& s) {
        std::string t = "[";
        for (std::size_t i = 0; i < s.size(); ++i) t += (i ? "][" : "") + std::to_string(s[i]);
        return t + "]";
    };
    const std::vector<hsize_t> planeShape = eShape;
    const std::vector<hsize_t> stackShape = {static_cast<hsize_t>(kMonths), eShape[0], eShape[1]};
    // The static maps first, then the monthly ones (the order of the messages before the table).
    for (const bool monthly : {false, true})
        for (const AbioticMapInfo& m : kAbioticMaps) {
            if (m.isMonthly() != monthly) continue;
            const auto s = f.shape(m.dataset);
            const std::vector<hsize_t>& expect = monthly ? stackShape : planeShape;
            if (s != expect)
                throw IoError(path + ": dataset " + m.dataset + " has shape " + shapeText(s) + ", expected " +
                              shapeText(expect));
            if (monthly) (a.*(m.monthly)).months = f.readStack(m.dataset);
            else a.*(m.single) = f.readGrid(m.dataset);
            forEachPlane(a, m, [&](const Grid<float>& g) {
                if (!g.sameGeometry(a.elevationM))
                    throw IoError(path + ": dataset " + m.dataset + " has a different cell size or origin than /elevation");
            });
        }
    // The values too (issue 26): a NaN sun or a negative moisture would flow into every
    // vigour, species map and database feature without a word.
    requireGridIn(a.elevationM, -1e5, 1e5, path, "/elevation");
    for (const bool monthly : {false, true})
        for (const AbioticMapInfo& m : kAbioticMaps) {
            if (m.isMonthly() != monthly) continue;
            int month = 0;
            forEachPlane(a, m, [&](const Grid<float>& g) {
                requireGridIn(g, m.lo, m.hi, path,
                              monthly ? std::string(m.dataset) + " (month " + std::to_string(month++) + ")" : m.dataset);
            });
        }
    return a;
}

}  // namespace eco
