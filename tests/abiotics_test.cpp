// Tests of the abiotic maps (core/abiotics): analytic slope and lapse rate, astronomy
// against an independent formula and almanac figures, terrain shadowing against brute-force
// ray casting, moisture mass balance and routing, canopy shade, thread independence and the
// HDF5 file (the `eco abiotics` command: abiotics_cli_test.cpp). Grids are non-square throughout so that a
// transposed x/y shows up.
#include <omp.h>

#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <string>
#include <vector>

#include "abiotics.h"
#include "abiotics_fixture.h"
#include "error.h"
#include "h5io.h"
#include "param_table_check.h"
#include "terrain_io.h"
#include "test_util.h"

using namespace eco;

namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kDeg = kPi / 180.0;

/// Sonoma climate of SPEC §11, with a clarity curve from 0.43 (winter) to 0.92 (summer).
Climate sonomaClimate() {
    Climate c;
    c.latitudeDeg = 38.58;
    c.temperatureC = {13.5, 16.4, 18.6, 20.9, 24.4, 28.4, 32.1, 30.4, 29.3, 25.2, 18.2, 13.4};
    c.rainfallMm = {201.3, 162.46, 145.44, 73.56, 20.24, 12.81, 8, 11, 19.35, 52.94, 145.2, 158.57};
    c.skyClarity = {0.43, 0.5, 0.6, 0.72, 0.85, 0.92, 0.92, 0.9, 0.85, 0.7, 0.55, 0.45};
    c.lapseRateCPerKm = 9.8;
    return c;
}

Biome testBiome() {
    Biome b;
    b.name = "Test biome";
    b.climate = sonomaClimate();
    return b;
}

using test::makeTerrain;
using test::roughTerrain;
using test::ThreadCountGuard;

/// Spencer (1971) Fourier series for the declination, radians, at local noon.
double spencerDeclinationRad(int dayOfYear) {
    const double g = 2 * kPi * (dayOfYear - 1) / 365.0;
    return 0.006918 - 0.399912 * std::cos(g) + 0.070257 * std::sin(g) - 0.006758 * std::cos(2 * g) +
           0.000907 * std::sin(2 * g) - 0.002697 * std::cos(3 * g) + 0.00148 * std::sin(3 * g);
}

/// Day length (hours) for the sun centre at altitude h0 (degrees) with the declination given.
double independentDayLength(double latDeg, double decl, double h0Deg = 0.0) {
    const double lat = latDeg * kDeg;
    const double c = (std::sin(h0Deg * kDeg) - std::sin(lat) * std::sin(decl)) / (std::cos(lat) * std::cos(decl));
    return 24.0 / kPi * std::acos(std::clamp(c, -1.0, 1.0));
}

bool bitIdentical(const Grid<float>& a, const Grid<float>& b) {
    return a.sameGeometry(b) && a.size() == b.size() &&
           std::memcmp(a.data().data(), b.data().data(), a.size() * sizeof(float)) == 0;
}

bool bitIdentical(const MonthlyGrids<float>& a, const MonthlyGrids<float>& b) {
    if (a.months.size() != b.months.size()) return false;
    for (std::size_t m = 0; m < a.months.size(); ++m)
        if (!bitIdentical(a.months[m], b.months[m])) return false;
    return true;
}

}  // namespace

TEST_CASE("abiotics: temperature follows the lapse rate exactly", "[abiotics]") {
    const Climate c = sonomaClimate();
    const Grid<float> z = makeTerrain(7, 5, 10.0, [](double x, double y) { return 3.5 * x + 11.0 * y - 20; });
    const auto t = temperatureC(z, c);
    REQUIRE(t.months.size() == 12);
    for (int m = 0; m < 12; ++m) {
        REQUIRE(t[m].sameGeometry(z));
        for (int iy = 0; iy < z.height(); ++iy)
            for (int ix = 0; ix < z.width(); ++ix) {
                const double expect = c.temperatureC[static_cast<std::size_t>(m)] - 9.8 * z(ix, iy) / 1000.0;
                REQUIRE(t[m](ix, iy) == Approx(expect).margin(1e-5));
            }
    }
    // A different lapse rate is used as given.
    Climate c2 = c;
    c2.lapseRateCPerKm = 6.5;
    REQUIRE(temperatureC(z, c2)[6](3, 4) == Approx(c.temperatureC[6] - 6.5 * z(3, 4) / 1000.0).margin(1e-5));
}

TEST_CASE("abiotics: slope of an analytic plane is exact, edges included", "[abiotics]") {
    // z = 0.3 x + 0.1 y: gradient (0.3, 0.1), slope atan(sqrt(0.1)) everywhere.
    const Grid<float> z = makeTerrain(9, 6, 2.5, [](double x, double y) { return 0.3 * x + 0.1 * y; }, 100.0, 200.0);
    const Grid<float> s = slopeDegrees(z);
    REQUIRE(s.sameGeometry(z));
    const double expect = std::atan(std::sqrt(0.1)) / kDeg;
    for (int iy = 0; iy < z.height(); ++iy)
        for (int ix = 0; ix < z.width(); ++ix) REQUIRE(s(ix, iy) == Approx(expect).margin(1e-3));
    // x and y are not swapped: a plane rising only northwards.
    const Grid<float> zn = makeTerrain(9, 6, 2.0, [](double, double y) { return 1.0 * y; });
    REQUIRE(slopeDegrees(zn)(4, 3) == Approx(45.0).margin(1e-3));
    const Grid<float> flat(5, 4, 1.0, 0, 0, 12.f);
    REQUIRE(slopeDegrees(flat).maxValue() == 0.f);
}

TEST_CASE("abiotics: day length matches an independent formula and almanac figures", "[abiotics]") {
    // Declinations agree with Spencer's series to a fraction of a degree all year.
    for (int d = 1; d <= 365; d += 7)
        REQUIRE(solarDeclinationRad(d) == Approx(spencerDeclinationRad(d)).margin(0.6 * kDeg));
    for (int m = 0; m < 12; ++m) {
        const int doy = dayOfYearFor(m, 15);
        const double ours = dayLengthHours(38.58, doy);
        REQUIRE(ours == Approx(independentDayLength(38.58, spencerDeclinationRad(doy))).epsilon(0.02));
    }
    REQUIRE(dayOfYearFor(0, 15) == 15);
    REQUIRE(dayOfYearFor(11, 15) == 349);
    // Almanac figures at 38.58 N (Sacramento): 14.8 h at the June solstice, 9.5 h at the
    // December one. Almanacs count from the upper limb with refraction (sun centre at
    // -0.833 deg), which adds about 0.2 h; our day is geometric (no refraction).
    const double june = dayLengthHours(38.58, 172), december = dayLengthHours(38.58, 355);
    REQUIRE(independentDayLength(38.58, solarDeclinationRad(172), -0.833) == Approx(14.8).epsilon(0.01));
    REQUIRE(independentDayLength(38.58, solarDeclinationRad(355), -0.833) == Approx(9.5).epsilon(0.01));
    REQUIRE(june == Approx(14.8).margin(0.3));
    REQUIRE(december == Approx(9.5).margin(0.3));
    REQUIRE(june < 14.8);
    REQUIRE(december < 9.5);
    // Southern hemisphere mirrors: day(-lat) = 24 - day(lat). Equator: 12 h.
    REQUIRE(dayLengthHours(-38.58, 172) == Approx(24.0 - june).margin(1e-9));
    REQUIRE(dayLengthHours(0.0, 100) == Approx(12.0).margin(1e-9));
    // Polar day and night.
    REQUIRE(dayLengthHours(80.0, 172) == 24.0);
    REQUIRE(dayLengthHours(80.0, 355) == 0.0);
}

TEST_CASE("abiotics: open flat ground gets exactly the astronomical day length", "[abiotics]") {
    const Climate c = sonomaClimate();
    const Grid<float> z(23, 17, 5.0, 1000.0, 2000.0, 350.f);
    SunParams p;
    const SunDetail sun = sunDetail(z, c, p);
    REQUIRE(sun.sunHours.months.size() == 12);
    REQUIRE(sun.skyView.minValue() == 1.f);
    for (int m = 0; m < 12; ++m) {
        const int doy = dayOfYearFor(m, p.dayOfMonth);
        const double independent = independentDayLength(c.latitudeDeg, spencerDeclinationRad(doy));
        REQUIRE(sun.dayLengthHours[static_cast<std::size_t>(m)] == Approx(dayLengthHours(c.latitudeDeg, doy)));
        for (const float v : sun.sunHours[m].data()) {
            REQUIRE(v == Approx(independent).epsilon(0.02));
            REQUIRE(v == Approx(dayLengthHours(c.latitudeDeg, doy)).epsilon(1e-6));
        }
        for (const float v : sun.directHours[m].data()) REQUIRE(v == Approx(dayLengthHours(c.latitudeDeg, doy)).epsilon(1e-6));
    }
    // Polar day and night at 80 N.
    Climate arctic = c;
    arctic.latitudeDeg = 80.0;
    const SunDetail polar = sunDetail(z, arctic, p);
    REQUIRE(polar.sunHours[5](3, 4) == Approx(24.0).epsilon(1e-6));
    REQUIRE(polar.sunHours[11](3, 4) == 0.f);
    // Same in the southern hemisphere, where June has the short day.
    Climate south = c;
    south.latitudeDeg = -38.58;
    const auto s = sunHours(z, south, p);
    REQUIRE(s[5](11, 8) == Approx(dayLengthHours(-38.58, dayOfYearFor(5, 15))).epsilon(1e-6));
    REQUIRE(s[5](11, 8) < 10.f);
}

TEST_CASE("abiotics: a slope facing the equator gets more winter sun, in both hemispheres", "[abiotics]") {
    // A plane rising northwards faces south; rising southwards faces north.
    const Grid<float> facingSouth = makeTerrain(40, 30, 1.0, [](double, double y) { return 0.3 * y; });
    const Grid<float> facingNorth = makeTerrain(40, 30, 1.0, [](double, double y) { return -0.3 * y; });
    const SunParams p;
    Climate north = sonomaClimate();
    const SunDetail ns = sunDetail(facingSouth, north, p), nn = sunDetail(facingNorth, north, p);
    for (int m : {10, 11, 0, 1}) {  // November .. February
        INFO("month " << m);
        REQUIRE(ns.directHours[m](20, 15) > nn.directHours[m](20, 15) + 0.5f);
        REQUIRE(ns.sunHours[m](20, 15) > nn.sunHours[m](20, 15));
    }
    Climate south = north;
    south.latitudeDeg = -38.58;
    const SunDetail ss = sunDetail(facingSouth, south, p), sn = sunDetail(facingNorth, south, p);
    for (int m : {4, 5, 6, 7}) {  // May .. August, southern winter
        INFO("month " << m);
        REQUIRE(sn.directHours[m](20, 15) > ss.directHours[m](20, 15) + 0.5f);
        REQUIRE(sn.sunHours[m](20, 15) > ss.sunHours[m](20, 15));
    }
    // East-facing ground gets the morning: at the equinox a plane rising westwards (facing
    // east) and one rising eastwards (facing west) get equal totals by symmetry.
    const Grid<float> facingEast = makeTerrain(40, 30, 1.0, [](double x, double) { return -0.4 * x; });
    const Grid<float> facingWest = makeTerrain(40, 30, 1.0, [](double x, double) { return 0.4 * x; });
    const auto e = sunDetail(facingEast, north, p), w = sunDetail(facingWest, north, p);
    REQUIRE(e.directHours[2](20, 15) == Approx(w.directHours[2](20, 15)).margin(0.2));
}

TEST_CASE("abiotics: a plane steeper than the noon sun, facing away, gets no direct sun", "[abiotics]") {
    // December noon sun at 38.58 N is ~28 degrees high; a 45-degree north-facing plane never
    // faces it. In June (noon sun ~75 degrees) it does.
    const Grid<float> z = makeTerrain(30, 20, 1.0, [](double, double y) { return -1.0 * y; });
    const SunDetail s = sunDetail(z, sonomaClimate(), SunParams{});
    REQUIRE(s.directHours[11](15, 10) == 0.f);
    REQUIRE(s.directHours[5](15, 10) > 5.f);
    // Diffuse light still reaches it, reduced by the tilt.
    REQUIRE(s.skyView(15, 10) < 1.f);
    REQUIRE(s.skyView(15, 10) > 0.5f);
    REQUIRE(s.sunHours[11](15, 10) > 0.f);
}

TEST_CASE("abiotics: the bottom of a deep narrow pit gets less sun than open ground", "[abiotics]") {
    const double cx = 30.5, cy = 20.5;
    const Grid<float> z = makeTerrain(61, 41, 1.0, [&](double x, double y) {
        return std::hypot(x - cx, y - cy) < 3.0 ? -40.0 : 0.0;
    });
    const SunDetail s = sunDetail(z, sonomaClimate(), SunParams{});
    const int bx = 30, by = 20, ox = 5, oy = 35;
    REQUIRE(z(bx, by) == -40.f);
    REQUIRE(s.skyView(bx, by) < 0.2f);
    REQUIRE(s.skyView(ox, oy) == 1.f);
    for (int m = 0; m < 12; ++m) {
        INFO("month " << m);
        REQUIRE(s.directHours[m](bx, by) < 0.25f * s.directHours[m](ox, oy));
        REQUIRE(s.sunHours[m](bx, by) < 0.5f * s.sunHours[m](ox, oy));
    }
}

TEST_CASE("abiotics: terrain shadows agree with brute-force ray casting", "[abiotics]") {
    // A smooth hill and a north-south ridge on 2 m cells; the reference marches a ray from
    // each cell centre towards the sun through the bilinear terrain.
    const int w = 48, h = 36;
    const double cell = 2.0;
    const Grid<float> z = makeTerrain(w, h, cell, [](double x, double y) {
        return 30 * std::exp(-((x - 40) * (x - 40) + (y - 36) * (y - 36)) / (2 * 12.0 * 12.0)) +
               14 * std::exp(-((x - 72) * (x - 72)) / (2 * 5.0 * 5.0));
    });
    const Climate c = sonomaClimate();
    SunParams p;
    p.stepMinutes = 30;
    const SunDetail s = sunDetail(z, c, p);
    // Independent gradient (central differences) for the facing test.
    auto grad = [&](int ix, int iy) {
        const int x0 = std::max(ix - 1, 0), x1 = std::min(ix + 1, w - 1);
        const int y0 = std::max(iy - 1, 0), y1 = std::min(iy + 1, h - 1);
        return std::array<double, 2>{(z(x1, iy) - z(x0, iy)) / ((x1 - x0) * cell),
                                     (z(ix, y1) - z(ix, y0)) / ((y1 - y0) * cell)};
    };
    const double lat = c.latitudeDeg * kDeg;
    for (int m : {0, 3, 5, 9}) {
        const double decl = solarDeclinationRad(dayOfYearFor(m, p.dayOfMonth));
        const double dayH = dayLengthHours(c.latitudeDeg, dayOfYearFor(m, p.dayOfMonth));
        const int n = static_cast<int>(std::lround(dayH * 60 / p.stepMinutes));
        const double h0 = dayH / 24.0 * kPi;
        // Interior cells: the reference treats the half cell beyond the edge centres as
        // terrain, the sweep as outside the grid (no shadow).
        double sumAbs = 0, sum = 0;
        int within = 0, cells = 0;
        for (int iy = 2; iy < h - 2; ++iy)
            for (int ix = 2; ix < w - 2; ++ix) {
                int lit = 0;
                for (int k = 0; k < n; ++k) {
                    const double H = -h0 + (k + 0.5) * 2 * h0 / n;
                    // Sun vector: east, north, up.
                    const double se = -std::cos(decl) * std::sin(H);
                    const double sn = std::cos(lat) * std::sin(decl) - std::sin(lat) * std::cos(decl) * std::cos(H);
                    const double su = std::sin(lat) * std::sin(decl) + std::cos(lat) * std::cos(decl) * std::cos(H);
                    const auto g = grad(ix, iy);
                    if (su - g[0] * se - g[1] * sn <= 0) continue;
                    const double horiz = std::hypot(se, sn);
                    const double tanElev = su / horiz;
                    const double x0 = z.cellCentreX(ix), y0 = z.cellCentreY(iy);
                    bool shadow = false;
                    for (double t = 0.25 * cell;; t += 0.25 * cell) {
                        const double x = x0 + t * se / horiz, y = y0 + t * sn / horiz;
                        if (x < 0 || y < 0 || x > z.extentX() || y > z.extentY()) break;
                        if (z.sampleBilinear(x, y) > z(ix, iy) + t * tanElev) {
                            shadow = true;
                            break;
                        }
                    }
                    if (!shadow) ++lit;
                }
                const double ref = lit * dayH / n;
                const double diff = s.directHours[m](ix, iy) - ref;
                sum += diff;
                sumAbs += std::abs(diff);
                if (std::abs(diff) <= 1.01 * dayH / n) ++within;
                ++cells;
            }
        const double interval = dayH / n;
        INFO("month " << m << ": mean difference " << sum / cells << " h, mean |difference| " << sumAbs / cells
                      << " h, within one sample (" << interval << " h) " << within << " of " << cells);
        REQUIRE(std::abs(sum / cells) < 0.05 * interval);
        REQUIRE(sumAbs / cells < 0.15 * interval);
        REQUIRE(within >= static_cast<int>(0.98 * cells));
    }
}

TEST_CASE("abiotics: canopy shade multiplies by (1 - alpha) under a crown only", "[abiotics]") {
    const int w = 30, h = 20;
    MonthlyGrids<float> sun;
    for (int m = 0; m < 12; ++m) {
        Grid<float> g(w, h, 2.0, 10.0, 20.0);
        for (std::size_t i = 0; i < g.size(); ++i) g.data()[i] = 5.f + 0.01f * static_cast<float>(i) + 0.5f * m;
        sun.months.push_back(g);
    }
    const Grid<float>& g0 = sun[0];
    // Tree A centred on cell (10, 8), tree B overlapping it, tree C half outside the grid.
    const std::vector<ShadingTree> trees = {{g0.cellCentreX(10), g0.cellCentreY(8), 5.0, 0.4},
                                            {g0.cellCentreX(12) + 0.3, g0.cellCentreY(8), 3.0, 0.5},
                                            {10.0, 20.0 + 39.0, 4.0, 1.0}};
    const auto shaded = applyCanopyShade(sun, trees);
    REQUIRE(shaded.months.size() == 12);
    int underA = 0, underBoth = 0, outside = 0;
    for (int m = 0; m < 12; ++m)
        for (int iy = 0; iy < h; ++iy)
            for (int ix = 0; ix < w; ++ix) {
                double factor = 1.0;
                bool covered = false;
                for (const auto& t : trees)
                    if (std::hypot(g0.cellCentreX(ix) - t.x, g0.cellCentreY(iy) - t.y) <= t.crownRadiusM) {
                        factor *= 1.0 - t.alpha;
                        covered = true;
                    }
                if (!covered) {
                    REQUIRE(shaded[m](ix, iy) == sun[m](ix, iy));  // untouched, bit for bit
                    if (m == 0) ++outside;
                } else {
                    REQUIRE(shaded[m](ix, iy) == Approx(sun[m](ix, iy) * factor).epsilon(1e-6));
                }
                if (m == 0 && factor == Approx(0.6)) ++underA;
                if (m == 0 && factor == Approx(0.3)) ++underBoth;
            }
    REQUIRE(underA > 10);
    REQUIRE(underBoth > 2);
    REQUIRE(outside > 400);
    // The centre cell of A is under A only: exactly 0.6 times.
    REQUIRE(shaded[3](10, 8) == Approx(0.6 * sun[3](10, 8)));
    // Bad trees are rejected with the tree named.
    REQUIRE_THROWS_AS(applyCanopyShade(sun, {{1, 1, 2, 1.5}}), ValidationError);
    REQUIRE_THROWS_WITH(applyCanopyShade(sun, {{1, 1, 2, 0.5}, {1, 1, -2, 0.5}}), Catch::Contains("tree 1"));
}

TEST_CASE("abiotics: moisture: mass balance closes", "[abiotics]") {
    const Grid<float> z = roughTerrain(64, 48, 2.0);
    const Climate c = sonomaClimate();
    const Soil soil;
    for (int spinUp : {0, 1, 3}) {
        MoistureBalance b;
        const auto mm = moistureMm(z, c, soil, &b, spinUp);
        INFO("spin-up years " << spinUp);
        REQUIRE(mm.months.size() == 12);
        REQUIRE(b.relativeError() < 1e-3);
        const double cellM2 = 4.0;
        REQUIRE(b.rainYearM3() == Approx(MoistureBalance::sum(c.rainfallMm) * 1e-3 * cellM2 * 64 * 48));
        REQUIRE(b.outflowYearM3() > 0);
        REQUIRE(b.evaporatedYearM3() > 0);
        for (int m = 0; m < 12; ++m) {
            const std::size_t i = static_cast<std::size_t>(m);
            REQUIRE(b.rainM3[i] == Approx(b.storageChangeM3[i] + b.evaporatedM3[i] + b.outflowM3[i]).epsilon(1e-6));
            REQUIRE(b.storageChangeM3[i] == Approx(b.absorbedM3[i] - b.evaporatedM3[i]).margin(1e-6 * b.rainM3[i] + 1e-9));
        }
        REQUIRE(b.finalStorageM3 - b.initialStorageM3 == Approx(b.storageChangeYearM3()).epsilon(1e-9));
        // The December map is the store at the end of the year.
        double sumMm = 0;
        for (float v : mm[11].data()) sumMm += v;
        REQUIRE(sumMm * 1e-3 * cellM2 == Approx(b.finalStorageM3).epsilon(1e-5));
        // Values within [0, saturation].
        for (const auto& g : mm.months) {
            REQUIRE(g.minValue() >= 0.f);
            REQUIRE(g.maxValue() <= static_cast<float>(soil.saturationMm));
        }
    }
    // Spin-up starts January from a wetter, more plausible state than a dry soil.
    MoistureBalance b0, b1;
    moistureMm(z, c, soil, &b0, 0);
    moistureMm(z, c, soil, &b1, 1);
    REQUIRE(b0.initialStorageM3 == 0.0);
    REQUIRE(b1.initialStorageM3 > 0.0);
}

TEST_CASE("abiotics: moisture: the valley floor is wetter than the ridge above it", "[abiotics]") {
    // A flat-floored valley along y (floor |ix - 30| <= 3, draining south) between 26.6-degree
    // flanks that rise to sharp ridge crests at ix = 10 and 50.
    const double cell = 5.0;
    auto profile = [&](double ix) {
        const double d = std::abs(ix - 30.0);
        if (d <= 3) return 0.0;
        if (d <= 20) return (d - 3) * cell * 0.5;
        return (17 - (d - 20)) * cell * 0.5;
    };
    const Grid<float> z = makeTerrain(60, 40, cell, [&](double x, double y) { return profile(x / cell - 0.5) + 0.01 * y; });
    MoistureBalance b;
    const auto mm = moistureMm(z, sonomaClimate(), Soil{}, &b);
    REQUIRE(b.relativeError() < 1e-3);
    const int y = 20, ridgeX = 10;
    REQUIRE(z(ridgeX, y) > z(30, y) + 40.f);
    auto floorMean = [&](const Grid<float>& g) {
        double s = 0;
        for (int ix = 27; ix <= 33; ++ix) s += g(ix, y);
        return s / 7;
    };
    const Grid<float> annual = mm.annualMean();
    INFO("valley floor " << floorMean(annual) << " mm, ridge crest " << annual(ridgeX, y) << " mm (annual means)");
    // On a uniform flank every cell ends up absorbing about its own rain (run-on makes up
    // for the slope's lower infiltration), so the gain is concentrated at the flank foot.
    REQUIRE(floorMean(annual) > annual(ridgeX, y) + 2.0);
    for (int m = 0; m < 12; ++m) REQUIRE(floorMean(mm[m]) >= mm[m](ridgeX, y) - 1e-3);
    // The foot of each flank, where the run-on arrives, is wetter than the crest every dry month.
    for (int m = 4; m <= 9; ++m) {
        INFO("month " << m);
        REQUIRE(mm[m](27, y) > mm[m](ridgeX, y) + 5.f);
        REQUIRE(mm[m](33, y) > mm[m](ridgeX, y) + 5.f);
    }
    // A closed pit drains through its filled spill point and gets run-on: wetter than open
    // flat ground in the dry season.
    const Grid<float> pit = makeTerrain(33, 25, 2.0, [](double x, double y) {
        return -8.0 * std::exp(-((x - 33) * (x - 33) + (y - 25) * (y - 25)) / 60.0);
    });
    MoistureBalance pb;
    const auto pm = moistureMm(pit, sonomaClimate(), Soil{}, &pb);
    REQUIRE(pb.relativeError() < 1e-3);
    REQUIRE(pm[7](16, 12) > pm[7](1, 1));
}

TEST_CASE("abiotics: mirror-symmetric terrain gives mirror-symmetric maps", "[abiotics]") {
    // Symmetric about the column ix = 25 (x = 25.5 m): routing, infiltration and the sun
    // path (symmetric about noon) must not prefer a side.
    const int w = 51, h = 34;
    const Grid<float> z = makeTerrain(w, h, 1.0, [](double x, double y) {
        const double d = std::abs(x - 25.5);
        return 12 * std::exp(-d * d / 80.0) + 6 * std::exp(-(d - 14) * (d - 14) / 10.0) + 0.3 * y +
               2 * std::sin(0.4 * y);
    });
    for (int iy = 0; iy < h; ++iy)
        for (int ix = 0; ix < w; ++ix) REQUIRE(z(ix, iy) == z(w - 1 - ix, iy));
    MoistureBalance b;
    const auto mm = moistureMm(z, sonomaClimate(), Soil{}, &b);
    REQUIRE(b.relativeError() < 1e-3);
    SunParams p;
    p.stepMinutes = 20;
    const SunDetail sun = sunDetail(z, sonomaClimate(), p);
    const double interval = 20.0 / 60.0;
    for (int m = 0; m < 12; ++m)
        for (int iy = 0; iy < h; ++iy)
            for (int ix = 0; ix < w / 2; ++ix) {
                INFO("month " << m << " cell (" << ix << ", " << iy << ")");
                REQUIRE(mm[m](ix, iy) == Approx(mm[m](w - 1 - ix, iy)).margin(1e-3));
                REQUIRE(std::abs(sun.directHours[m](ix, iy) - sun.directHours[m](w - 1 - ix, iy)) <= 1.01 * interval);
            }
    for (int iy = 0; iy < h; ++iy)
        for (int ix = 0; ix < w / 2; ++ix)
            REQUIRE(sun.skyView(ix, iy) == Approx(sun.skyView(w - 1 - ix, iy)).margin(1e-3));
}

TEST_CASE("abiotics are bit-identical with 1 and 2 threads", "[abiotics]") {
    ThreadCountGuard guard;
    const Grid<float> z = roughTerrain(57, 43, 1.5);
    const Biome biome = testBiome();
    AbioticParams params;
    params.sun.stepMinutes = 15;
    omp_set_num_threads(1);
    const Abiotics one = computeAbiotics(z, biome, params);
    omp_set_num_threads(2);
    const Abiotics two = computeAbiotics(z, biome, params);
    REQUIRE(bitIdentical(one.slopeDeg, two.slopeDeg));
    REQUIRE(bitIdentical(one.temperatureC, two.temperatureC));
    REQUIRE(bitIdentical(one.sunHours, two.sunHours));
    REQUIRE(bitIdentical(one.moistureMm, two.moistureMm));
    REQUIRE(bitIdentical(one.windMS, two.windMS));
    omp_set_num_threads(3);
    REQUIRE(bitIdentical(skyViewFactor(z, params.sun), [&] {
        omp_set_num_threads(1);
        return skyViewFactor(z, params.sun);
    }()));
}

TEST_CASE("abiotics: computeAbiotics reports every stage and validates its input", "[abiotics]") {
    const Grid<float> z = roughTerrain(20, 13, 3.0);
    AbioticParams params;
    params.sun.stepMinutes = 30;
    std::vector<std::string> stages;
    double lastFraction = -1;
    bool monotone = true;
    const Abiotics a = computeAbiotics(z, testBiome(), params, [&](const std::string& s, double f) {
        if (stages.empty() || stages.back() != s) {
            stages.push_back(s);
            lastFraction = -1;
        }
        if (f < lastFraction) monotone = false;
        lastFraction = f;
    });
    REQUIRE(stages == std::vector<std::string>{"slope", "temperature", "sun", "moisture", "wind"});
    REQUIRE(lastFraction == Approx(1.0));
    REQUIRE(monotone);
    REQUIRE(bitIdentical(a.elevationM, z));
    REQUIRE(a.sunHours.months.size() == 12);

    const Grid<float> tiny(2, 5, 1.0);
    REQUIRE_THROWS_AS(computeAbiotics(tiny, testBiome(), params), ValidationError);
    REQUIRE_THROWS_WITH(computeAbiotics(tiny, testBiome(), params), Catch::Contains("at least 3 x 3"));
    Grid<float> withNan(4, 4, 1.0);
    withNan(2, 1) = std::nanf("");
    REQUIRE_THROWS_WITH(computeAbiotics(withNan, testBiome(), params), Catch::Contains("(2, 1)"));
    AbioticParams bad = params;
    bad.sun.stepMinutes = 0;
    REQUIRE_THROWS_AS(computeAbiotics(z, testBiome(), bad), ValidationError);
    Biome badBiome = testBiome();
    badBiome.climate.skyClarity[3] = 1.5;
    REQUIRE_THROWS_WITH(computeAbiotics(z, badBiome, params), Catch::Contains("April"));
}

TEST_CASE("abiotics parameters: one description drives validation, the attributes and the docs", "[abiotics]") {
    const Grid<float> z(4, 4, 1.0);
    const Biome biome = testBiome();
    test::checkParamTable(
        sunParamFields(), "docs/abiotics.md",
        [&](const SunParams& sun) {
            AbioticParams p;
            p.sun = sun;
            computeAbiotics(z, biome, p);
        },
        [](const SunParams&) { return std::vector<std::pair<std::string, std::string>>{}; }, 0);
    test::checkParamTable(
        abioticParamFields(), "docs/abiotics.md", [&](const AbioticParams& p) { computeAbiotics(z, biome, p); },
        [](const AbioticParams&) { return std::vector<std::pair<std::string, std::string>>{}; }, 0);
}

TEST_CASE("abiotics HDF5 round trip", "[abiotics]") {
    test::TempDir dir("abiotics_h5");
    const Grid<float> z = roughTerrain(26, 19, 2.0);
    const Biome biome = testBiome();
    AbioticParams params;
    params.sun.stepMinutes = 20;
    params.moistureSpinUpYears = 2;
    const Abiotics a = computeAbiotics(z, biome, params);
    const std::string path = dir.file("abiotics.h5");
    writeAbiotics(path, a, biome, params);
    REQUIRE(std::filesystem::exists(path));
    // No temporary file is left behind.
    REQUIRE(std::distance(std::filesystem::directory_iterator(dir.path()), std::filesystem::directory_iterator()) == 1);

    const Abiotics r = readAbiotics(path);
    REQUIRE(bitIdentical(r.elevationM, a.elevationM));
    REQUIRE(bitIdentical(r.slopeDeg, a.slopeDeg));
    REQUIRE(bitIdentical(r.sunHours, a.sunHours));
    REQUIRE(bitIdentical(r.moistureMm, a.moistureMm));
    REQUIRE(bitIdentical(r.temperatureC, a.temperatureC));
    REQUIRE(bitIdentical(r.windMS, a.windMS));
    REQUIRE(a.windMS.maxValue() > a.windMS.minValue());  // the rough terrain shelters some cells

    const h5::File f = h5::File::openRead(path);
    REQUIRE(f.attrString("/", "format") == "eco-abiotics");
    REQUIRE(f.attrInt("/", "schema_version") == 2);
    for (const auto& field : windFields()) {
        INFO(field.key);
        const std::string key = std::string("wind_") + field.key;
        if (field.kind == ParamDesc<Wind>::Kind::Real) CHECK(f.attrDouble("/", key) == field.value(biome.wind));
        else CHECK(f.attrInt("/", key) == static_cast<std::int64_t>(field.value(biome.wind)));
    }
    REQUIRE(f.attrString("/wind", "units") == "m/s");
    REQUIRE(f.attrString("/", "biome_name") == "Test biome");
    REQUIRE(f.attrDouble("/", "latitude_deg") == 38.58);
    REQUIRE(f.attrDouble("/", "sun_step_minutes") == 20.0);
    REQUIRE(f.attrInt("/", "sun_sky_azimuths") == 16);
    REQUIRE(f.attrInt("/", "moisture_spin_up_years") == 2);
    REQUIRE(f.attrDouble("/", "soil_saturation_mm") == 180.0);
    for (const auto& field : sunParamFields()) {  // every parameter of the table, typed by its kind
        INFO(field.key);
        if (field.kind == ParamDesc<SunParams>::Kind::Real) CHECK(f.attrDouble("/", field.key) == field.value(params.sun));
        else CHECK(f.attrInt("/", field.key) == static_cast<std::int64_t>(field.value(params.sun)));
    }
    for (const auto& field : abioticParamFields())
        CHECK(f.attrInt("/", field.key) == static_cast<std::int64_t>(field.value(params)));
    REQUIRE(f.attrDouble("/", "lapse_rate_c_per_km") == 9.8);
    REQUIRE(f.attrDoubles("/", "climate_rainfall_mm").size() == 12);
    REQUIRE(f.attrDoubles("/", "climate_sky_clarity")[0] == 0.43);
    REQUIRE(!f.attrString("/", "code_version").empty());
    REQUIRE(f.shape("/sun") == std::vector<hsize_t>{12, 19, 26});
    REQUIRE(f.attrString("/sun", "units") == "hours/day");
    REQUIRE(f.attrString("/moisture", "units") == "mm/month");
    REQUIRE(f.attrString("/temperature", "units") == "degC");
    REQUIRE(f.attrString("/slope", "units") == "degrees");
    REQUIRE(f.attrString("/elevation", "units") == "m");
}

TEST_CASE("abiotics: reading a broken abiotics file names the file and the dataset", "[abiotics]") {
    test::TempDir dir("abiotics_bad");
    const Grid<float> z = roughTerrain(12, 9, 1.0);
    AbioticParams params;
    params.sun.stepMinutes = 60;
    const Abiotics a = computeAbiotics(z, testBiome(), params);
    auto writePartial = [&](const std::string& path, bool withMoisture, int sunPlanes, bool withFormat,
                            std::int64_t version = 2) {
        h5::File f = h5::File::create(path);
        if (version >= 2) f.writeGrid("/wind", a.windMS, "m/s");
        f.writeGrid("/elevation", a.elevationM, "m");
        f.writeGrid("/slope", a.slopeDeg, "degrees");
        std::vector<Grid<float>> sun(a.sunHours.months.begin(), a.sunHours.months.begin() + sunPlanes);
        f.writeStack("/sun", sun, "hours/day");
        if (withMoisture) f.writeStack("/moisture", a.moistureMm.months, "mm/month");
        f.writeStack("/temperature", a.temperatureC.months, "degC");
        if (withFormat) {
            f.setAttr("/", "format", std::string("eco-abiotics"));
            f.setAttr("/", "schema_version", version);
        }
    };
    // A schema 1 file (before the wind map) is refused with a message that says so.
    const std::string v1 = dir.file("v1.h5");
    writePartial(v1, true, 12, true, 1);
    REQUIRE_THROWS_WITH(readAbiotics(v1), Catch::Contains(v1) && Catch::Contains("schema_version 1") &&
                                              Catch::Contains("no wind map") && Catch::Contains("re-run eco abiotics"));
    const std::string missing = dir.file("missing.h5");
    writePartial(missing, false, 12, true);
    REQUIRE_THROWS_AS(readAbiotics(missing), IoError);
    REQUIRE_THROWS_WITH(readAbiotics(missing), Catch::Contains("/moisture") && Catch::Contains(missing));

    const std::string shape = dir.file("shape.h5");
    writePartial(shape, true, 11, true);
    REQUIRE_THROWS_AS(readAbiotics(shape), IoError);
    REQUIRE_THROWS_WITH(readAbiotics(shape), Catch::Contains("/sun") && Catch::Contains("shape") &&
                                                 Catch::Contains(shape));

    const std::string foreign = dir.file("foreign.h5");
    writePartial(foreign, true, 12, false);
    REQUIRE_THROWS_WITH(readAbiotics(foreign), Catch::Contains("not an eco-abiotics file"));
    REQUIRE_THROWS_AS(readAbiotics(dir.file("nonexistent.h5")), IoError);
}

TEST_CASE("abiotics: a file without a map of the table is refused naming it, an extra map is left alone",
          "[abiotics][factors]") {
    // A factor added later adds its row to kAbioticMaps without a new schema version: the
    // reader looks for every map by its dataset, so a file written before the map existed
    // is refused naming it, and a file written by a later version (a map this version does
    // not know) is read for the maps it knows (docs/factors.md).
    test::TempDir dir("abiotics_maps");
    const Grid<float> z = roughTerrain(10, 8, 1.0);
    AbioticParams params;
    params.sun.stepMinutes = 60;
    const Abiotics a = computeAbiotics(z, testBiome(), params);
    auto write = [&](const std::string& path, const AbioticMapInfo* left, bool extra) {
        h5::File f = h5::File::create(path);
        f.writeGrid("/elevation", a.elevationM, "m");
        for (const AbioticMapInfo& m : kAbioticMaps) {
            if (&m == left) continue;
            if (m.isMonthly()) f.writeStack(m.dataset, (a.*(m.monthly)).months, m.unit);
            else f.writeGrid(m.dataset, a.*(m.single), m.unit);
        }
        if (extra) f.writeGrid("/soil_depth", a.slopeDeg, "m");
        f.setAttr("/", "format", std::string("eco-abiotics"));
        f.setAttr("/", "schema_version", static_cast<std::int64_t>(2));
    };
    for (const AbioticMapInfo& m : kAbioticMaps) {
        INFO(m.name);
        const std::string path = dir.file(std::string("without_") + m.name + ".h5");
        write(path, &m, false);
        REQUIRE_THROWS_AS(readAbiotics(path), IoError);
        REQUIRE_THROWS_WITH(readAbiotics(path), Catch::Contains(path) && Catch::Contains(std::string("dataset ") + m.dataset) &&
                                                    Catch::Contains(std::string("written before the ") + m.name + " map") &&
                                                    Catch::Contains("re-run eco abiotics"));
    }
    const std::string newer = dir.file("newer.h5");
    write(newer, nullptr, true);
    const Abiotics b = readAbiotics(newer);
    for (const AbioticMapInfo& m : kAbioticMaps) {
        INFO(m.name);
        const Grid<float> want = annualMap(a, m), got = annualMap(b, m);
        REQUIRE(got.sameGeometry(want));
        CHECK(got.data() == want.data());
    }
}

// ---------------------------------------------------------------------------------------
// Wind (EcoMod's wind shelter)

namespace {

/// Flat ground of `w` x `h` cells of `cell` metres with a wall `wallM` high on column `wallX`.
Grid<float> wallTerrain(int w, int h, double cell, int wallX, float wallM) {
    Grid<float> z(w, h, cell, 0, 0, 0.f);
    for (int iy = 0; iy < h; ++iy) z(wallX, iy) = wallM;
    return z;
}

}  // namespace

TEST_CASE("abiotics: wind: flat ground is fully exposed", "[abiotics][wind]") {
    Wind wind;
    wind.strengthMS = 6.5;
    for (double dir : {0.0, 45.0, 90.0, 200.0, 270.0, 359.0}) {
        wind.directionDeg = dir;
        const Grid<float> speed = windSpeedMS(Grid<float>(17, 11, 2.0, 0, 0, 12.f), wind);
        CHECK(speed.minValue() == 6.5f);
        CHECK(speed.maxValue() == 6.5f);
    }
    // A tilted plane: upwind ground rising slower than the threshold shelters partly,
    // ground falling away upwind not at all.
    Grid<float> plane(30, 5, 1.0);
    for (int iy = 0; iy < 5; ++iy)
        for (int ix = 0; ix < 30; ++ix) plane(ix, iy) = static_cast<float>(0.5 * ix);  // rises to the east
    wind.directionDeg = 270;  // from the west: upwind is lower
    CHECK(windSpeedMS(plane, wind).minValue() == 6.5f);
    wind.directionDeg = 90;  // from the east: upwind rises at atan(0.5) = 26.57 degrees
    const Grid<float> occ = windOcclusionDeg(plane, wind);
    CHECK(occ(3, 2) == Approx(std::atan(0.5) / kDeg).margin(1e-4));
    CHECK(occ(29, 2) == 0.f);  // the eastern edge has nothing upwind
    CHECK(windSpeedMS(plane, wind)(3, 2) == Approx(6.5 * (1 - std::atan(0.5) / kDeg / 45.0)).margin(1e-5));
}

TEST_CASE("abiotics: wind: a wall shelters the cells behind it within the expected distance", "[abiotics][wind]") {
    // A 10 m wall on column 20 of 2 m cells, wind from the west (upwind = west): cells east
    // of the wall see it at atan(10 / (2 d)) for d cells. With the 45 degree threshold the
    // cells within 5 cells (10 m) are fully sheltered; beyond, the exposure is
    // 1 - atan(5 / d) / 45 deg, until the wall is more than N_w = 10 cells upwind.
    const double cell = 2.0;
    const Grid<float> z = wallTerrain(40, 6, cell, 20, 10.f);
    Wind wind;
    wind.directionDeg = 270;
    wind.strengthMS = 4;
    const Grid<float> speed = windSpeedMS(z, wind);
    const Grid<float> occ = windOcclusionDeg(z, wind);
    for (int iy = 0; iy < 6; ++iy) {
        for (int d = 1; d <= 10; ++d) {
            INFO("cell " << d << " east of the wall, row " << iy);
            const double angle = std::atan(10.0 / (cell * d)) / kDeg;
            CHECK(occ(20 + d, iy) == Approx(angle).margin(1e-4));
            CHECK(speed(20 + d, iy) == Approx(4.0 * std::max(0.0, 1.0 - angle / 45.0)).margin(1e-5));
            if (d < 5) CHECK(speed(20 + d, iy) == 0.f);  // d = 5: exactly 45 degrees, up to rounding
        }
        for (int d = 11; 20 + d < 40; ++d) CHECK(speed(20 + d, iy) == 4.f);  // beyond N_w samples
        for (int ix = 0; ix <= 20; ++ix) CHECK(speed(ix, iy) == 4.f);       // upwind of the wall and its top
    }
    // More samples reach farther: with N_w = 15 the cells 12 and 13 east are sheltered a little.
    wind.samples = 15;
    CHECK(windSpeedMS(z, wind)(32, 3) < 4.f);
    CHECK(windSpeedMS(z, wind)(33, 3) > 0.f);
    // A lower threshold angle shelters more cells fully: atan(10 / 26) = 21 deg > 20.
    wind.thresholdDeg = 20;
    CHECK(windSpeedMS(z, wind)(33, 3) == 0.f);
}

TEST_CASE("abiotics: wind: the direction matters", "[abiotics][wind]") {
    const Grid<float> z = wallTerrain(40, 40, 1.0, 20, 8.f);  // a north-south wall
    Wind wind;
    wind.strengthMS = 5;
    auto at = [&](double dir, int ix, int iy) {
        wind.directionDeg = dir;
        return windSpeedMS(z, wind)(ix, iy);
    };
    // From the west the lee is east of the wall; from the east, west of it.
    CHECK(at(270, 23, 20) == 0.f);
    CHECK(at(270, 17, 20) == 5.f);
    CHECK(at(90, 17, 20) == 0.f);
    CHECK(at(90, 23, 20) == 5.f);
    // Along the wall (from the north or the south) nothing is sheltered beside it.
    CHECK(at(0, 23, 20) == 5.f);
    CHECK(at(180, 17, 20) == 5.f);
    // Obliquely from the south-west: the lee is north-east of the wall, at a longer
    // upwind distance than straight across (the path crosses the wall sqrt 2 farther).
    wind.directionDeg = 225;
    const Grid<float> sw = windSpeedMS(z, wind);
    CHECK(sw(23, 23) < 5.f);
    CHECK(sw(17, 17) == 5.f);
    const double oblique = windOcclusionDeg(z, wind)(23, 20);
    wind.directionDeg = 270;
    const double across = windOcclusionDeg(z, wind)(23, 20);
    CHECK(across == Approx(std::atan(8.0 / 3.0) / kDeg).margin(1e-4));
    CHECK(oblique > 45.0);
    CHECK(oblique < across - 5.0);
    // Transposing the terrain and turning the wind by 90 degrees gives the transposed map
    // (no x/y mix-up): a west-east wall with the wind from the south.
    const Grid<float> zt = [&] {
        Grid<float> t(40, 40, 1.0, 0, 0, 0.f);
        for (int ix = 0; ix < 40; ++ix) t(ix, 20) = 8.f;
        return t;
    }();
    wind.directionDeg = 180;
    const Grid<float> south = windSpeedMS(zt, wind);
    wind.directionDeg = 270;
    const Grid<float> west = windSpeedMS(z, wind);
    for (int iy = 0; iy < 40; ++iy)
        for (int ix = 0; ix < 40; ++ix) REQUIRE(south(iy, ix) == west(ix, iy));
}

TEST_CASE("abiotics: wind: parameters outside their ranges are refused", "[abiotics][wind]") {
    const Grid<float> z(5, 5, 1.0, 0, 0, 0.f);
    Wind wind;
    wind.thresholdDeg = 0;
    CHECK_THROWS_WITH(windSpeedMS(z, wind), Catch::Contains("threshold_deg"));
    wind = Wind{};
    wind.samples = 0;
    CHECK_THROWS_WITH(windSpeedMS(z, wind), Catch::Contains("samples"));
}

TEST_CASE("abiotics: a terrain whose maps would not fit in memory is refused before any work", "[abiotics][errors]") {
    // A 1 m lidar DEM read fine (13 bytes a cell) but its abiotics (about 280) were an
    // out-of-memory kill after minutes of work. ECO_MEMORY_LIMIT_MB stands for a small machine.
    const eco::Grid<float> z(512, 512, 1.0, 0.0, 0.0, 100.0f);  // 262,144 cells: about 73 MB of maps
    ::setenv("ECO_MEMORY_LIMIT_MB", "20", 1);
    bool progressCalled = false;
    auto call = [&] {
        (void)eco::computeAbiotics(z, testBiome(), eco::AbioticParams{},
                                   [&](const std::string&, double) { progressCalled = true; });
    };
    CHECK_THROWS_AS(call(), eco::ValidationError);
    CHECK_THROWS_WITH(call(), Catch::Contains("abiotic maps of a terrain of 512 x 512 cells needs about") &&
                                  Catch::Contains("available") && Catch::Contains("gdalwarp"));
    ::unsetenv("ECO_MEMORY_LIMIT_MB");
    CHECK_FALSE(progressCalled);
}
