// The undergrowth simulator (sim/): each process on its own, then integration, determinism
// across thread counts, checkpoint / resume, and bad inputs.
#include <catch2/catch.hpp>
#include <omp.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <random>
#include <sstream>

#include "abiotics_fixture.h"
#include "atomic_file.h"
#include "canopy_file.h"
#include "demo_scene.h"
#include "batch_math.h"
#include "error.h"
#include "footprint.h"
#include "paint.h"
#include "processes.h"
#include "sim_config.h"
#include "sim_run.h"
#include "sim_scene_fixture.h"
#include "simulator.h"
#include "test_util.h"

using namespace eco;
using namespace eco::sim;

namespace {

// Abiotics that are the same everywhere and every month.
Abiotics uniformAbiotics(int cells, double cellM, double sun, double water, double temp, double slope) {
    return test::uniformAbiotics(Grid<float>(cells, cells, cellM, 0, 0, 0.f), 50,
                                 {{Factor::Sun, sun},
                                  {Factor::Moisture, water},
                                  {Factor::Temperature, temp},
                                  {Factor::Slope, slope},
                                  {Factor::Wind, 5}});  // no test species responds to wind
}

// A biome whose crowns are tiny (r = 1 mm per metre of height): every plant covers its own
// cell only, so per-cell processes can be checked by hand.
Biome pointCrownBiome() {
    Biome b = defaultBiome();
    for (auto& s : b.species) {
        s.allometry.linear = true;
        s.allometry.linearFactor = 0.001;
    }
    return b;
}

UndergrowthPlant plantAt(const Biome& b, const std::string& species, double x, double y, double h) {
    UndergrowthPlant p;
    p.speciesId = b.speciesIndex(species);
    p.xM = x;
    p.yM = y;
    p.heightM = h;
    return p;
}

const UndergrowthPlant& bySpecies(const std::vector<UndergrowthPlant>& v, int s) {
    for (const auto& p : v)
        if (p.speciesId == s) return p;
    FAIL("species not found");
    return v.front();
}

bool sameSimPlants(const std::vector<UndergrowthPlant>& a, const std::vector<UndergrowthPlant>& b) {
    if (a.size() != b.size()) return false;
    for (std::size_t i = 0; i < a.size(); ++i) {
        const auto& p = a[i];
        const auto& q = b[i];
        if (p.id != q.id || p.speciesId != q.speciesId || std::memcmp(&p.xM, &q.xM, sizeof(double)) != 0 ||
            std::memcmp(&p.yM, &q.yM, sizeof(double)) != 0 || std::memcmp(&p.heightM, &q.heightM, sizeof(double)) != 0 ||
            std::memcmp(&p.pool, &q.pool, sizeof(double)) != 0 || std::memcmp(&p.vigour, &q.vigour, sizeof(double)) != 0 ||
            std::memcmp(&p.growthAgeYears, &q.growthAgeYears, sizeof(double)) != 0 || p.ageYears != q.ageYears)
            return false;
    }
    return true;
}

// Upper critical value of chi-square with `df` degrees of freedom at one-sided normal
// quantile z (Wilson-Hilferty; z = 3.09 for significance 0.001).
double chiSquareCritical(int df, double z) {
    const double k = df;
    const double t = 1.0 - 2.0 / (9.0 * k) + z * std::sqrt(2.0 / (9.0 * k));
    return k * t * t * t;
}

using test::smallDemoScene;

}  // namespace

// --------------------------------------------------------------------------- processes

TEST_CASE("shade: occupants in descending height, each attenuated by every taller one", "[sim][shade]") {
    const Biome b = pointCrownBiome();
    SimInputs in;
    in.biome = b;
    in.abiotics = uniformAbiotics(10, 1.0, 10.0, 100.0, 15.0, 5.0);
    const double x = 5.1, y = 5.1;  // centre of sim cell (25, 25)
    // Given out of height order on purpose.
    const std::vector<UndergrowthPlant> init = {plantAt(b, "California Laurel", x, y, 0.5),
                                                plantAt(b, "Toyon", x, y, 2.0), plantAt(b, "Tanoak", x, y, 1.0)};
    Simulation sim(in, SimParams{}, 1, init);
    sim.stepMonth();
    const auto pl = sim.plants();
    REQUIRE(pl.size() == 3);
    const double aToyon = b.species[b.speciesIndex("Toyon")].alpha;
    const double aTanoak = b.species[b.speciesIndex("Tanoak")].alpha;
    const double aLaurel = b.species[b.speciesIndex("California Laurel")].alpha;
    CHECK(bySpecies(pl, b.speciesIndex("Toyon")).sunShare == Approx(10.0).epsilon(1e-6));
    CHECK(bySpecies(pl, b.speciesIndex("Tanoak")).sunShare == Approx(10.0 * (1 - aToyon)).epsilon(1e-6));
    CHECK(bySpecies(pl, b.speciesIndex("California Laurel")).sunShare ==
          Approx(10.0 * (1 - aToyon) * (1 - aTanoak)).epsilon(1e-6));
    // What reaches the floor is the germination leftover.
    double sun = 0, water = 0;
    REQUIRE(sim.leftoverMeans(25, 25, 0, sun, water));
    CHECK(sun == Approx(10.0 * (1 - aToyon) * (1 - aTanoak) * (1 - aLaurel)).epsilon(1e-6));
    // A neighbouring free cell keeps everything.
    REQUIRE(sim.leftoverMeans(20, 25, 0, sun, water));
    CHECK(sun == Approx(10.0));
    CHECK(water == Approx(100.0));
}

TEST_CASE("shade: a canopy tree attenuates the cells under its crown by (1 - alpha)", "[sim][shade]") {
    const Biome b = pointCrownBiome();
    SimInputs in;
    in.biome = b;
    in.abiotics = uniformAbiotics(10, 1.0, 10.0, 100.0, 15.0, 5.0);
    const int fir = b.speciesIndex("Douglas-Fir");
    in.canopy = {Plant{fir, 5.0, 5.0, 50, 40, 1.0}};
    Simulation sim(in, SimParams{}, 1, {plantAt(b, "Toyon", 5.1, 5.1, 1.0)});
    const double keep = 1 - b.species[fir].alpha;
    CHECK(sim.canopyTransmission()(25, 25) == Approx(keep));
    CHECK(sim.canopyTransmission()(25, 31) == Approx(1.0));  // 1.1 m from the trunk
    sim.stepMonth();
    const auto pl = sim.plants();
    CHECK(pl[0].sunShare == Approx(10.0 * keep).epsilon(1e-6));
    // The canopy tree took its demand first: 100 - 4 left, one occupant, one seeding share.
    CHECK(pl[0].waterShare == Approx(4.0 + (96.0 - 4.0) / 2.0));
}

TEST_CASE("water: minimum demand in height order, remainder shared with one share for seeding", "[sim][water]") {
    // Pure function.
    CHECK(waterShareMm(100, 0, 3, 4) == Approx(4 + 88.0 / 4));
    CHECK(waterShareMm(100, 2, 3, 4) == Approx(4 + 88.0 / 4));
    CHECK(waterLeftoverMm(100, 3, 4) == Approx(22.0));
    // Scarcity: the tallest drink first, nothing is left to share.
    CHECK(waterShareMm(6, 0, 3, 4) == Approx(4.0));
    CHECK(waterShareMm(6, 1, 3, 4) == Approx(2.0));
    CHECK(waterShareMm(6, 2, 3, 4) == Approx(0.0));
    CHECK(waterLeftoverMm(6, 3, 4) == Approx(0.0));
    // Canopy trees take their demand, never more.
    CHECK(waterAfterCanopyMm(10, 2, 4) == Approx(2.0));
    CHECK(waterAfterCanopyMm(10, 3, 4) == Approx(0.0));

    // In the engine: three occupants of one cell.
    const Biome b = pointCrownBiome();
    for (double water : {100.0, 6.0}) {
        SimInputs in;
        in.biome = b;
        in.abiotics = uniformAbiotics(10, 1.0, 10.0, water, 15.0, 5.0);
        const double x = 5.1, y = 5.1;
        Simulation sim(in, SimParams{}, 1,
                       {plantAt(b, "Toyon", x, y, 2.0), plantAt(b, "Tanoak", x, y, 1.0), plantAt(b, "California Laurel", x, y, 0.5)});
        sim.stepMonth();
        const auto pl = sim.plants();
        REQUIRE(pl.size() == 3);
        const int order[3] = {b.speciesIndex("Toyon"), b.speciesIndex("Tanoak"), b.speciesIndex("California Laurel")};
        for (int k = 0; k < 3; ++k)
            CHECK(bySpecies(pl, order[k]).waterShare == Approx(waterShareMm(water, k, 3, 4.0)));
        double sun = 0, left = 0;
        REQUIRE(sim.leftoverMeans(25, 25, 0, sun, left));
        CHECK(left == Approx(waterLeftoverMm(water, 3, 4.0)).margin(1e-6));
    }
}

TEST_CASE("paint: the vectorised kernel gives the portable kernel's bits and the per-cell shares", "[sim][water][shade]") {
    // One band row of 64 cells painted by a stack of plants over random spans: the SSE2 kernel
    // (where built) and the portable one must agree bit for bit on every sum and cell, and each
    // cell's water must be waterShareMm of its height rank.
    constexpr std::size_t kCells = 64;
    constexpr int kPlants = 40;
    constexpr double kDemand = 4.0;
    std::uint64_t state = 0x9E3779B97F4A7C15ull;
    auto next = [&state](std::uint64_t bound) {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        return state % bound;
    };
    std::vector<double> base(kCells), avail(kCells), rest(kCells);
    std::vector<int> occupants(kCells, 0);
    struct PlantSpan {
        std::size_t first, len;
        float keep;
    };
    std::vector<PlantSpan> spans;
    for (int p = 0; p < kPlants; ++p) {
        const std::size_t first = next(kCells), len = 1 + next(std::min<std::uint64_t>(9, kCells - first));
        spans.push_back({first, len, 1.f - static_cast<float>(next(90)) / 100.f});
        for (std::size_t c = first; c < first + len; ++c) ++occupants[c];
    }
    for (std::size_t c = 0; c < kCells; ++c) {
        base[c] = 50.0 + static_cast<double>(next(100000)) / 977.0;
        avail[c] = static_cast<double>(next(6000)) / 97.0;  // from scarce to plenty for up to 40 occupants
        rest[c] = waterLeftoverMm(avail[c], occupants[c], kDemand);
    }
    // The arrays as the sweep pads them (kPaintPad cells past the last; the SSE2 kernel reads
    // and stores them back unchanged); the padding holds values a kernel must not disturb.
    for (std::size_t c = 0; c < kPaintPad; ++c) {
        base.push_back(1e300);
        avail.push_back(-1e300);
        rest.push_back(1e300);
    }
    auto paint = [&](auto lanesType, std::vector<double>& sums, std::vector<float>& trans, std::vector<std::int32_t>& painted) {
        trans.assign(kCells + kPaintPad, 1.f);
        painted.assign(kCells + kPaintPad, 0);
        for (std::size_t c = kCells; c < kCells + kPaintPad; ++c) {
            trans[c] = 0.375f;
            painted[c] = 1000;
        }
        const BandCells bc{base.data(), avail.data(), rest.data(), trans.data(), painted.data()};
        for (const PlantSpan& s : spans) {
            decltype(lanesType) lanes;
            // Two spans per plant when it is long enough: the lanes restart with each span.
            const std::size_t split = s.len / 2;
            lanes.span(bc, s.first, split, s.keep, kDemand);
            lanes.span(bc, s.first + split, s.len - split, s.keep, kDemand);
            sums.push_back(lanes.sunTotal());
            sums.push_back(lanes.waterTotal());
        }
    };
    std::vector<double> sumsScalar, sumsFast;
    std::vector<float> transScalar, transFast;
    std::vector<std::int32_t> paintedScalar, paintedFast;
    paint(PaintLanesScalar{}, sumsScalar, transScalar, paintedScalar);
    paint(PaintLanes{}, sumsFast, transFast, paintedFast);
#ifdef ECO_HAVE_AVX2_KERNELS
    if (eco::setAvx2Kernels(true)) {  // the processor has AVX2: its kernel gives the same bits too
        std::vector<double> sumsAvx2;
        std::vector<float> transAvx2;
        std::vector<std::int32_t> paintedAvx2;
        paint(PaintLanesAvx2{}, sumsAvx2, transAvx2, paintedAvx2);
        REQUIRE(sumsAvx2.size() == sumsScalar.size());
        CHECK(std::memcmp(sumsScalar.data(), sumsAvx2.data(), sumsScalar.size() * sizeof(double)) == 0);
        CHECK(std::memcmp(transScalar.data(), transAvx2.data(), (kCells + kPaintPad) * sizeof(float)) == 0);
        CHECK(paintedAvx2 == paintedScalar);
    } else {
        WARN("no AVX2 on this processor: the AVX2 paint kernel is not checked here");
    }
#endif
    REQUIRE(sumsScalar.size() == sumsFast.size());
    CHECK(std::memcmp(sumsScalar.data(), sumsFast.data(), sumsScalar.size() * sizeof(double)) == 0);
    CHECK(std::memcmp(transScalar.data(), transFast.data(), (kCells + kPaintPad) * sizeof(float)) == 0);
    CHECK(paintedFast == paintedScalar);
    for (std::size_t c = 0; c < kCells; ++c) CHECK(paintedFast[c] == occupants[c]);
    for (std::size_t c = kCells; c < kCells + kPaintPad; ++c) {  // the padding as it was
        CHECK(transFast[c] == 0.375f);
        CHECK(paintedFast[c] == 1000);
    }
    // A one-cell plant alone under the stack gets exactly the cell's formulas.
    std::vector<float> trans(kCells + kPaintPad, 1.f);
    std::vector<std::int32_t> painted(kCells + kPaintPad, 0);
    const BandCells bc{base.data(), avail.data(), rest.data(), trans.data(), painted.data()};
    for (int k = 0; k < occupants[7]; ++k) {
        const double sunExpected = base[7] * static_cast<double>(trans[7]);
        PaintLanes lanes;
        lanes.span(bc, 7, 1, 0.5f, kDemand);
        CHECK(lanes.sunTotal() == sunExpected);
        CHECK(lanes.waterTotal() == Approx(waterShareMm(avail[7], k, occupants[7], kDemand)).epsilon(1e-12));
    }
}

TEST_CASE("vigour exp: batchExp is within 2 ulp of std::exp, and its vector and scalar forms agree bit for bit", "[sim][vigour]") {
    // The vigour exponent ln(q) x^p is <= 0; the whole clamped range is checked.
    std::vector<double> x;
    for (int i = 0; i <= 200000; ++i) x.push_back(-708.0 + 1417.0 * i / 200000.0);
    for (double v : {0.0, -0.0, -1e-300, 1e-17, -0.5 * std::log(2.0), 0.5 * std::log(2.0), -745.0, 800.0}) x.push_back(v);
    std::vector<double> y(x.size()), ySse2(x.size());
    batchExp(x.data(), y.data(), x.size());  // the default: the AVX2 form where the processor has it
    eco::setAvx2Kernels(false);
    batchExp(x.data(), ySse2.data(), x.size());
    const bool avx2 = eco::setAvx2Kernels(true);
    if (!avx2) WARN("no AVX2 on this processor: its form of batchExp is not checked");
    CHECK(std::memcmp(ySse2.data(), y.data(), x.size() * sizeof(double)) == 0);
    double worst = 0;
    for (std::size_t i = 0; i < x.size(); ++i) {
        const double scalar = batchExpOne(x[i]);
        CHECK(std::memcmp(&y[i], &scalar, sizeof(double)) == 0);
        const double clamped = std::min(std::max(x[i], -708.0), 709.0), ref = std::exp(clamped);
        worst = std::max(worst, std::abs(y[i] - ref) / ref);
    }
    CHECK(worst <= 2 * std::numeric_limits<double>::epsilon());
    CHECK(batchExpOne(0.0) == 1.0);
}

TEST_CASE("crown radius log: batchLog is within 2 ulp of std::log, and its vector and scalar forms agree bit for bit", "[sim][growth]") {
    std::vector<double> x;
    std::mt19937_64 rng(7);
    std::uniform_real_distribution<double> exponent(-700.0, 700.0);
    for (int i = 0; i < 200000; ++i) x.push_back(std::exp(exponent(rng)));
    for (int i = 0; i <= 100000; ++i) x.push_back(0.5 + 1.5 * i / 100000.0);  // heights around 1 m, and both ends of m
    for (int i = -500; i <= 500; ++i) x.push_back(1.0 + i * 1e-13);
    for (double v : {1.0, 2.0, 0.5, std::sqrt(0.5), std::sqrt(2.0), std::numeric_limits<double>::min(),
                     std::numeric_limits<double>::max(), 1e-310, 5e-324})
        x.push_back(v);
    std::vector<double> y(x.size());
    batchLog(x.data(), y.data(), x.size());
    double worst = 0;
    for (std::size_t i = 0; i < x.size(); ++i) {
        const double scalar = batchLogOne(x[i]);
        CHECK(std::memcmp(&y[i], &scalar, sizeof(double)) == 0);
        const double ref = std::log(x[i]);
        if (ref == 0) {
            CHECK(y[i] == 0);
            continue;
        }
        const double ulp = std::nextafter(std::abs(ref), HUGE_VAL) - std::abs(ref);
        worst = std::max(worst, std::abs(y[i] - ref) / ulp);
    }
    CHECK(worst <= 2.0);
    CHECK(batchLogOne(0.0) == -HUGE_VAL);
    CHECK(std::isnan(batchLogOne(-1.0)));
    CHECK(batchLogOne(HUGE_VAL) == HUGE_VAL);
}

TEST_CASE("footprints: ceilClamped and floorClamped equal std::ceil / std::floor then clamping", "[sim][footprint]") {
    // Integers, halves, values next to integers, both signs, beyond the bounds, huge values.
    std::vector<double> ts = {0.0, -0.0, 1e-300, -1e-300, 1e300, -1e300, HUGE_VAL, -HUGE_VAL};
    for (int k = -12; k <= 12; ++k) {
        const double v = k * 0.5;
        ts.insert(ts.end(), {v, std::nextafter(v, HUGE_VAL), std::nextafter(v, -HUGE_VAL), v + 0.25, v - 1e-9});
    }
    eco::RandomStream rs(11, 0);
    for (int k = 0; k < 2000; ++k) ts.push_back(rs.uniform(-8.0, 8.0));
    for (const double t : ts)
        for (const auto& [lo, hi] : {std::pair{-1, 3}, std::pair{-2, 5}, std::pair{0, 0}, std::pair{-4, -2}}) {
            CAPTURE(t, lo, hi);
            CHECK(ceilClamped(t, lo, hi) == static_cast<int>(std::clamp(std::ceil(t), double(lo), double(hi))));
            CHECK(floorClamped(t, lo, hi) == static_cast<int>(std::clamp(std::floor(t), double(lo), double(hi))));
        }
    CHECK(ceilClamped(std::nan(""), -1, 7) == 7);
    CHECK(floorClamped(std::nan(""), -2, 9) == 9);
}

TEST_CASE("footprints: the AVX2 row bounds equal the scalar ones", "[sim][footprint]") {
#ifdef ECO_HAVE_AVX2_KERNELS
    if (!eco::setAvx2Kernels(true)) {
        WARN("no AVX2 on this processor: its form of rowBounds is not checked");
        return;
    }
    CellGrid g;
    g.W = 70;
    g.H = 64;
    g.cell = 0.2;
    g.ox = 5000.3;  // large coordinates: the same rounding in both forms
    g.oy = -123.9;
    eco::RandomStream rs(5, 0);
    int inside = 0, outside = 0;
    for (int t = 0; t < 20000; ++t) {
        // Discs inside, across the edges and beyond them; radii from 0 to 40 cells; chunks of
        // 1 to kRowChunk rows anywhere, also outside the grid (the AVX2 form writes rows up to
        // a multiple of 4, so the arrays are full chunks).
        const double x = g.ox + rs.uniform(-0.3, 1.3) * g.W * g.cell, y = g.oy + rs.uniform(-0.3, 1.3) * g.H * g.cell;
        const double r = t % 50 == 0 ? 0.0 : g.cell * 40.0 * rs.uniform(0.0, 1.0) * rs.uniform(0.0, 1.0);
        const int n = 1 + static_cast<int>(rs.uniform(0.0, 1.0) * CellGrid::kRowChunk) % CellGrid::kRowChunk;
        const int r0 = static_cast<int>(rs.uniform(-10.0, g.H + 10.0));
        int aS[CellGrid::kRowChunk], bS[CellGrid::kRowChunk], aV[CellGrid::kRowChunk], bV[CellGrid::kRowChunk];
        g.rowBoundsScalar(x, y, r, r0, n, aS, bS);
        g.rowBoundsAvx2(x, y, r, r0, n, aV, bV);
        for (int k = 0; k < n; ++k) {
            CAPTURE(x, y, r, r0, n, k);
            REQUIRE(aV[k] == aS[k]);
            REQUIRE(bV[k] == bS[k]);
            (aS[k] <= bS[k] ? inside : outside)++;
        }
    }
    CHECK(inside > 10000);  // both kinds of rows were met
    CHECK(outside > 10000);
#else
    WARN("not an x86-64 GCC build: no AVX2 form of rowBounds");
#endif
}

TEST_CASE("footprints: every radius of footprintRange gives the same spans, and most ranges are more than one radius", "[sim][footprint]") {
    CellGrid g;
    g.W = 60;
    g.H = 50;
    g.cell = 0.2;
    g.ox = 1000.25;  // large coordinates: rounding must not matter
    g.oy = -37.5;
    std::mt19937_64 rng(11);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    int nonTrivial = 0, cases = 0;
    for (int t = 0; t < 4000; ++t) {
        // Plants anywhere, edges included; radii from half a cell to 15 cells.
        const double x = g.ox + u(rng) * g.W * g.cell, y = g.oy + u(rng) * g.H * g.cell;
        const int ix = std::min(g.W - 1, static_cast<int>((x - g.ox) / g.cell)), iy = std::min(g.H - 1, static_cast<int>((y - g.oy) / g.cell));
        const double r = g.cell * (0.5 + 14.5 * u(rng) * u(rng));
        int lo, hi;
        g.rowRange(y, r, iy, lo, hi);
        std::vector<Span> sp(static_cast<std::size_t>(hi - lo + 1));
        g.footprintSpans(x, y, r, ix, iy, lo, hi, sp.data());
        const RadiusRange range = g.footprintRange(x, y, r, ix, iy, lo, hi, sp.data());
        REQUIRE(range.lo == r);
        REQUIRE(range.hi >= r);
        ++cases;
        if (range.hi > r) ++nonTrivial;
        // Radii across the range (its ends included) give the same rows and spans.
        for (int k = 0; k <= 8; ++k) {
            const double rk = k == 8 ? range.hi : r + (range.hi - r) * u(rng);
            if (!(rk < HUGE_VAL)) continue;
            int lo2, hi2;
            g.rowRange(y, rk, iy, lo2, hi2);
            REQUIRE(lo2 == lo);
            REQUIRE(hi2 == hi);
            std::vector<Span> sp2(sp.size());
            g.footprintSpans(x, y, rk, ix, iy, lo, hi, sp2.data());
            for (std::size_t j = 0; j < sp.size(); ++j) {
                REQUIRE(sp2[j].start == sp[j].start);
                REQUIRE(sp2[j].len == sp[j].len);
            }
        }
        // Just past the range (the probe is 1e-9 below the exact boundary), the footprint
        // grows: the range is not needlessly short.
        if (range.hi > r && range.hi < HUGE_VAL) {
            const double past = range.hi * (1.0 + 1e-8);
            int lo3, hi3;
            g.rowRange(y, past, iy, lo3, hi3);
            std::size_t cells = 0, cells3 = 0;
            for (const Span& s : sp) cells += s.len;
            std::vector<Span> sp3(static_cast<std::size_t>(hi3 - lo3 + 1));
            g.footprintSpans(x, y, past, ix, iy, lo3, hi3, sp3.data());
            for (const Span& s : sp3) cells3 += s.len;
            CHECK((lo3 != lo || hi3 != hi || cells3 > cells));
        }
    }
    CHECK(nonTrivial > cases * 9 / 10);
}

TEST_CASE("vigour: the engine's vigour is Eq. 1 on the plant's mean shares", "[sim][vigour]") {
    const Biome b = pointCrownBiome();
    SimInputs in;
    in.biome = b;
    in.abiotics = uniformAbiotics(10, 1.0, 7.0, 60.0, 18.0, 12.0);
    Simulation sim(in, SimParams{}, 1, {plantAt(b, "Toyon", 5.1, 5.1, 1.0)});
    sim.stepMonth();
    const auto p = sim.plants().at(0);
    CHECK(p.vigour == Approx(b.vigourOf(p.speciesId, {p.sunShare, p.waterShare, 18.0, 12.0})).epsilon(1e-6));
}

TEST_CASE("carbon pool: overflow above capacity, underflow below zero", "[sim][pool]") {
    const double cap = poolCapacity(3, 0.6, 0.2);
    CHECK(cap == Approx(0.36));
    auto s = updatePool(0.3, 0.2, cap);
    CHECK(s.pool == Approx(cap));
    CHECK(s.overflow == Approx(0.14));
    s = updatePool(0.1, 0.2, cap);
    CHECK(s.pool == Approx(0.3));
    CHECK(s.overflow == 0);
    s = updatePool(-0.1, -0.2, cap);
    CHECK(s.pool == Approx(-0.3));
    CHECK(s.overflow == 0);
    // Three months of maximum stress (-alpha a each) empty a full pool exactly.
    double pool = cap;
    for (int m = 0; m < 3; ++m) pool = updatePool(pool, -0.6 * 0.2, cap).pool;
    CHECK(pool == Approx(0.0).margin(1e-12));
    // Stress mortality is the underflow.
    CHECK(mortalityProbability(0.001, -0.3) == Approx(0.301));
    CHECK(mortalityProbability(0.001, 0.2) == Approx(0.001));
    CHECK(mortalityProbability(0.5, -0.9) == 1.0);
}

TEST_CASE("growth: smoothstep height reaches max height at max age under ideal vigour", "[sim][growth]") {
    CHECK(smoothstep(0) == 0);
    CHECK(smoothstep(0.5) == Approx(0.5));
    CHECK(smoothstep(1) == 1);
    CHECK(smoothstep(2) == 1);
    for (const auto& [maxAge, maxH] : std::vector<std::pair<double, double>>{{6, 0.25}, {150, 9}, {800, 110}}) {
        // Ideal: one month of overflow every month, every month a growth month.
        double ga = 0;
        const int months = static_cast<int>(12 * maxAge);
        for (int m = 0; m < months; ++m) {
            ga = advanceGrowthAgeYears(ga, 1.0, true, 1.0);
            if (m == months / 2 - 1) CHECK(idealHeightM(ga, maxAge, maxH) == Approx(maxH / 2).epsilon(1e-9));
        }
        CHECK(ga == Approx(maxAge).epsilon(1e-9));
        CHECK(idealHeightM(ga, maxAge, maxH) == Approx(maxH).epsilon(1e-9));
    }
    // Outside the growth period the overflow does not grow the plant.
    CHECK(advanceGrowthAgeYears(1.0, 0.5, false, 1.0) == 1.0);
    // The inverse used for initial plants.
    CHECK(idealHeightM(growthAgeForHeight(3.0, 150, 9), 150, 9) == Approx(3.0).epsilon(1e-9));
}

TEST_CASE("mortality: background rate leaves a fraction P_s alive at max age (binomial test)", "[sim][mortality]") {
    const double ps = 0.01, maxAge = 5.0;  // Western Swordfern
    const double mu = backgroundMortalityPerMonth(ps, maxAge);
    CHECK(std::pow(1 - mu, 12 * maxAge) == Approx(ps).epsilon(1e-12));
    // 20000 plants, the engine's random stream per plant and month.
    const int n = 20000;
    int alive = 0;
    for (int id = 1; id <= n; ++id) {
        bool dead = false;
        for (int m = 0; m < 12 * maxAge && !dead; ++m)
            dead = mortalityUniform(1234, static_cast<std::uint64_t>(id), static_cast<std::uint64_t>(m)) <
                   mortalityProbability(mu, 0.0);
        alive += dead ? 0 : 1;
    }
    // Two-sided test at significance 0.001: |k - n p| <= 3.29 sigma.
    const double sigma = std::sqrt(n * ps * (1 - ps));
    INFO("survivors " << alive << " expected " << n * ps << " sigma " << sigma);
    CHECK(std::abs(alive - n * ps) <= 3.29 * sigma);
}

TEST_CASE("engine: ideal vigour fills the pool, then overflow grows the plant in its growth months", "[sim][growth]") {
    // Redwood Sorrel at its optimum: sun 3.5 h, water share 100 mm (4 + (196 - 4) / 2),
    // temperature 13.5 C, slope 30: vigour = alpha every month. Both growth rules: the
    // literal one (1 month per unit overflow, as before the ideal rule existed) and the
    // ideal one (12 / (alpha x 9 months of the L period) months per unit overflow).
    const Biome b = pointCrownBiome();
    const int s = b.speciesIndex("Redwood Sorrel");
    const Species& sp = b.species[s];
    SimInputs in;
    in.biome = b;
    in.abiotics = uniformAbiotics(10, 1.0, 3.5, 196.0, 13.5, 30.0);
    UndergrowthPlant p = plantAt(b, "Redwood Sorrel", 5.1, 5.1, 0.0);
    p.growthAgeYears = 0.5;
    REQUIRE(sp.growthMonths.size() == 9);
    for (const GrowthRule rule : {GrowthRule::Literal, GrowthRule::Ideal}) {
        SimParams params;
        params.growthRule = rule;
        const double perOverflow = rule == GrowthRule::Literal ? 1.0 : 12.0 / (sp.alpha * 9.0);
        CHECK(growthMonthsPerUnitOverflow(rule, 1.0, sp.alpha, 9) == Approx(perOverflow).epsilon(1e-15));
        Simulation sim(in, params, 1, {p});
        const double cap = poolCapacity(3, sp.alpha, b.vigour.a);
        double expectGrowthAge = 0.5, pool = 0;
        for (int m = 0; m < 12; ++m) {
            sim.stepMonth();
            if (sim.plantCount() == 0) break;  // background mortality can strike: then stop checking
            const auto q = sim.plants().at(0);
            CHECK(q.vigour == Approx(sp.alpha).epsilon(1e-6));  // stored as float
            const PoolStep ps = updatePool(pool, sp.alpha, cap);
            pool = ps.pool;
            const bool growing = std::find(sp.growthMonths.begin(), sp.growthMonths.end(), m) != sp.growthMonths.end();
            expectGrowthAge = advanceGrowthAgeYears(expectGrowthAge, ps.overflow, growing, perOverflow);
            CHECK(q.pool == Approx(pool).epsilon(1e-12));
            CHECK(q.growthAgeYears == Approx(expectGrowthAge).epsilon(1e-12));
            CHECK(q.heightM == Approx(idealHeightM(expectGrowthAge, sp.maxAgeYears, sp.maxHeightM)).epsilon(1e-12));
        }
    }
}

TEST_CASE("growth rule ideal: an unstressed plant follows h_s(t) of Eq. 3 over its whole life", "[sim][growth]") {
    // A plant alone at its species' optimum (sun, temperature, slope at c; water share at c,
    // i.e. available water 2c - demand), starting in January with a full pool, real crowns
    // (it covers many cells, all alike). Background mortality and the canopy limit are
    // switched off. Tolerance: at every year end the growth age equals the calendar age
    // (plus the start) to 1e-9 years and the height h_s(t) to 1e-9 relative; within a year
    // the growth age runs ahead in the growth period and waits outside it, by less than a year.
    const Biome b = defaultBiome();
    struct Case {
        const char* species;
        int years;
    };
    for (const Case cs : {Case{"Western Swordfern", 5}, Case{"Toyon", 150}, Case{"Redwood Sorrel", 6}}) {
        const int s = b.speciesIndex(cs.species);
        const Species& sp = b.species[s];
        SimParams params;
        params.survivalAtMaxAge = 1.0 - 1e-9;
        params.canopyThresholdM = 1000.0;
        SimInputs in;
        in.biome = b;
        in.abiotics = uniformAbiotics(12, 1.0, sp.response(Factor::Sun).c, 2 * sp.response(Factor::Moisture).c - params.minWaterDemandMm, sp.response(Factor::Temperature).c,
                                      sp.response(Factor::Slope).c);
        const double ga0 = 1.0 / 12;
        UndergrowthPlant p = plantAt(b, cs.species, 6.1, 6.1, idealHeightM(ga0, sp.maxAgeYears, sp.maxHeightM));
        p.growthAgeYears = ga0;
        p.pool = poolCapacity(params.poolCapacityStressMonths, sp.alpha, b.vigour.a);
        Simulation sim(in, params, 3, {p});
        for (int y = 1; y <= cs.years; ++y) {
            for (int m = 0; m < 12; ++m) {
                sim.stepMonth();
                REQUIRE(sim.plantCount() == 1);
                const double t = ga0 + (12.0 * (y - 1) + m + 1) / 12.0;
                CHECK(std::abs(sim.plants()[0].growthAgeYears - t) < 1.0);
            }
            const auto q = sim.plants().at(0);
            INFO(cs.species << " year " << y);
            CHECK(q.vigour == Approx(sp.alpha).epsilon(1e-6));
            REQUIRE(q.growthAgeYears == Approx(ga0 + y).epsilon(1e-9));
            CHECK(q.heightM == Approx(idealHeightM(ga0 + y, sp.maxAgeYears, sp.maxHeightM)).epsilon(1e-9));
        }
        // The idealised specimen reaches its maximum height at the end of its lifespan.
        CHECK(sim.plants().at(0).heightM == Approx(sp.maxHeightM).epsilon(1e-9));
    }
    // Literal rule: the same Swordfern gains only alpha x 9 / 12 of a year per year.
    const int s = b.speciesIndex("Western Swordfern");
    const Species& sp = b.species[s];
    SimParams params;
    params.growthRule = GrowthRule::Literal;
    params.survivalAtMaxAge = 1.0 - 1e-9;
    SimInputs in;
    in.biome = b;
    in.abiotics = uniformAbiotics(12, 1.0, sp.response(Factor::Sun).c, 2 * sp.response(Factor::Moisture).c - params.minWaterDemandMm, sp.response(Factor::Temperature).c,
                                  sp.response(Factor::Slope).c);
    UndergrowthPlant p = plantAt(b, "Western Swordfern", 6.1, 6.1, 0.0);
    p.growthAgeYears = 1.0 / 12;
    p.pool = poolCapacity(params.poolCapacityStressMonths, sp.alpha, b.vigour.a);
    Simulation sim(in, params, 3, {p});
    for (int y = 0; y < 3; ++y) sim.stepYear();
    REQUIRE(sim.plantCount() == 1);
    CHECK(sim.plants()[0].growthAgeYears == Approx(1.0 / 12 + 3 * sp.alpha * 9.0 / 12.0).epsilon(1e-9));
}

TEST_CASE("engine: background mortality alone leaves P_s of a cohort at max age (binomial test)", "[sim][mortality]") {
    // 2000 Redwood Sorrels (max age 6 years) at their optimum, one per cell, crowns of one
    // cell: the pool never goes negative, so only background mortality acts.
    const Biome b = pointCrownBiome();
    SimInputs in;
    in.biome = b;
    in.abiotics = uniformAbiotics(20, 1.0, 3.5, 196.0, 13.5, 30.0);
    std::vector<UndergrowthPlant> cohort;
    for (int i = 0; i < 2000; ++i) cohort.push_back(plantAt(b, "Redwood Sorrel", 0.1 + 0.4 * (i % 50), 0.1 + 0.4 * (i / 50), 0.01));
    SimParams params;
    Simulation sim(in, params, 77, cohort);
    REQUIRE(sim.plantCount() == 2000);
    for (int y = 0; y < 6; ++y) sim.stepYear();
    const double n = 2000, ps = params.survivalAtMaxAge;
    const double sigma = std::sqrt(n * ps * (1 - ps));
    INFO("survivors " << sim.plantCount() << " expected " << n * ps);
    CHECK(std::abs(static_cast<double>(sim.plantCount()) - n * ps) <= 3.29 * sigma);  // significance 0.001
    CHECK(sim.counters().diedAtCanopy == 0);
}

TEST_CASE("seedbank: gamma within 4 r, linear to 0 at 12 r, packages of the canopy's sub-biomes", "[sim][seeding]") {
    CHECK(seedKernel(4.0, 1.0, 4, 12) == 1.0);
    CHECK(seedKernel(8.0, 1.0, 4, 12) == Approx(0.5));
    CHECK(seedKernel(12.0, 1.0, 4, 12) == 0.0);
    const Biome b = defaultBiome();
    SimInputs in;
    in.biome = b;
    in.abiotics = uniformAbiotics(30, 1.0, 10.0, 100.0, 15.0, 5.0);
    const double x = 15.1, y = 15.1;  // centre of sim cell (75, 75)
    in.canopy = {Plant{b.speciesIndex("Douglas-Fir"), x, y, 50, 40, 1.0}};
    SimParams params;
    Simulation sim(in, params, 1);
    const Grid<float>& prob = sim.seedProbability();
    const float gamma = static_cast<float>(params.seedingProbability);
    CHECK(prob(75, 75) == Approx(gamma));
    CHECK(prob(75 + 20, 75) == Approx(gamma).epsilon(1e-5));      // 4 r
    CHECK(prob(75, 75 - 20) == Approx(gamma).epsilon(1e-5));      // 4 r, southwards
    CHECK(prob(75 + 40, 75) == Approx(gamma / 2).epsilon(1e-4));  // 8 r
    CHECK(prob(75 + 60, 75) == Approx(0.0).margin(1e-9));         // 12 r
    CHECK(prob(75 + 70, 75) == 0.0f);
    // Douglas-Fir is a canopy species of sub-biome 1 (Conifer) only: bit 0.
    const auto pkg = sim.seedPackages();
    CHECK(pkg(75 + 59, 75) == 1);
    CHECK(pkg(75 + 61, 75) == 0);
    // Two overlapping trees add up.
    in.canopy.push_back(Plant{b.speciesIndex("Coast Live Oak"), x, y, 50, 20, 1.0});
    Simulation two(in, params, 1);
    CHECK(two.seedProbability()(75, 75) == Approx(2 * gamma));
    CHECK(two.seedPackages()(75, 75) == 0b11);  // Conifer and California Oak
}

TEST_CASE("roulette: rouletteSelect draws in proportion to the weights (chi-square)", "[sim][roulette]") {
    const double w[5] = {1.0, 0.0, 2.0, 3.0, 4.0};
    int counts[5] = {};
    RandomStream rng(99, 7);
    const int n = 100000;
    for (int i = 0; i < n; ++i) ++counts[rouletteSelect(w, 5, rng.uniform())];
    CHECK(counts[1] == 0);
    double chi2 = 0;
    for (int i : {0, 2, 3, 4}) {
        const double e = n * w[i] / 10.0;
        chi2 += (counts[i] - e) * (counts[i] - e) / e;
    }
    CHECK(chi2 < chiSquareCritical(3, 3.09));
    const double zero[3] = {0, 0, 0};
    CHECK(rouletteSelect(zero, 3, 0.5) == -1);
    CHECK(rouletteWeight(-0.1, 10, 1.2) == 0.0);
    CHECK(rouletteWeight(0.5, 10, 1.2) == Approx(0.5 / std::pow(10.0, 1.2)));
}

TEST_CASE("germination: seedlings per species follow max(0, vbar / maxage^beta) (chi-square)", "[sim][roulette]") {
    Biome b = defaultBiome();
    const int fir = b.speciesIndex("Douglas-Fir");
    b.species[fir].alpha = 0.0;  // no shade from the seed tree: every cell has the same resources
    SimInputs in;
    in.biome = b;
    const double S = 6.0, W = 100.0, T = 15.0, slope = 5.0;
    in.abiotics = uniformAbiotics(30, 1.0, S, W, T, slope);
    in.canopy = {Plant{fir, 15.0, 15.0, 50, 40, 3.0}};
    SimParams params;
    params.seedingProbability = 1.0;
    params.minWaterDemandMm = 0.0;
    params.seedingMonth = 0;
    Simulation sim(in, params, 5);
    sim.stepMonth();  // January: sweep, then germination
    const auto pl = sim.plants();
    REQUIRE(pl.size() > 5000);
    std::vector<double> expected(b.species.size(), 0.0);
    double total = 0;
    for (const Species& s : b.species) {
        if (std::find(s.subBiomes.begin(), s.subBiomes.end(), 1) == s.subBiomes.end()) continue;
        expected[s.id] = rouletteWeight(b.vigourOf(s.id, {S, W, T, slope}), s.maxAgeYears, params.rouletteAgeExponent);
        total += expected[s.id];
    }
    std::vector<int> counts(b.species.size(), 0);
    for (const auto& p : pl) ++counts[p.speciesId];
    double chi2 = 0;
    int df = -1;
    for (std::size_t s = 0; s < expected.size(); ++s) {
        if (expected[s] <= 0) {
            CHECK(counts[s] == 0);
            continue;
        }
        const double e = pl.size() * expected[s] / total;
        chi2 += (counts[s] - e) * (counts[s] - e) / e;
        ++df;
    }
    REQUIRE(df >= 2);
    INFO("chi2 " << chi2 << " df " << df);
    CHECK(chi2 < chiSquareCritical(df, 3.09));
    // One seedling per germinating cell, in that cell, with finite sizes.
    for (const auto& p : pl) {
        CHECK(std::isfinite(p.heightM));
        CHECK(p.heightM > 0);
    }
}

TEST_CASE("germination: a seedling occupies its cell at once and gets resources the next month", "[sim][seeding]") {
    const Biome b = defaultBiome();
    SimInputs in;
    in.biome = b;
    in.abiotics = uniformAbiotics(10, 1.0, 6.0, 100.0, 15.0, 5.0);
    in.canopy = {Plant{b.speciesIndex("Redwood"), 5.0, 5.0, 50, 60, 1.0}};
    SimParams params;
    params.seedingProbability = 1.0;
    params.seedingMonth = 0;
    Simulation sim(in, params, 3);
    sim.stepMonth();
    const std::size_t n = sim.plantCount();
    REQUIRE(n > 100);
    // No two seedlings share a root cell.
    std::map<std::pair<int, int>, int> roots;
    for (const auto& p : sim.plants()) ++roots[{sim.gridGeometry().cellX(p.xM), sim.gridGeometry().cellY(p.yM)}];
    for (const auto& [cell, k] : roots) CHECK(k == 1);
    sim.stepMonth();
    for (const auto& p : sim.plants()) {
        CHECK(std::isfinite(p.sunShare));
        CHECK(p.sunShare > 0);
        CHECK(p.waterShare > 0);
    }
}

TEST_CASE("canopy limit: undergrowth reaching the CHM (or the threshold) dies", "[sim][mortality]") {
    const Biome b = pointCrownBiome();
    SimInputs in;
    in.biome = b;
    in.abiotics = uniformAbiotics(10, 1.0, 10.0, 100.0, 15.0, 5.0);
    in.chmM = Grid<float>(10, 10, 1.0, 0, 0, 0.f);
    in.chmM(2, 2) = 8.f;
    SimParams params;
    Simulation sim(in, params, 1,
                   {plantAt(b, "Tanoak", 2.5, 2.5, 7.9999), plantAt(b, "Tanoak", 7.5, 7.5, 2.9999), plantAt(b, "Tanoak", 7.5, 2.5, 1.0)});
    // Grow every month until the two tall ones pass their limits (8 m and the 3 m threshold).
    for (int m = 0; m < 24; ++m) sim.stepMonth();
    CHECK(sim.counters().diedAtCanopy == 2);
    for (const auto& p : sim.plants()) CHECK(p.heightM < 3.0);
}

TEST_CASE("canopy_limit = canopy_only: in a gap undergrowth grows past the threshold, under the canopy it dies at the CHM",
          "[sim][mortality][readings]") {
    const Biome b = pointCrownBiome();
    SimInputs in;
    in.biome = b;
    in.abiotics = uniformAbiotics(10, 1.0, 10.0, 100.0, 15.0, 5.0);
    in.chmM = Grid<float>(10, 10, 1.0, 0, 0, 0.f);
    in.chmM(2, 2) = 8.f;
    SimParams params;
    params.canopyLimit = CanopyLimit::CanopyOnly;
    Simulation sim(in, params, 1,
                   {plantAt(b, "Tanoak", 2.5, 2.5, 7.9999), plantAt(b, "Tanoak", 7.5, 7.5, 2.9999), plantAt(b, "Tanoak", 7.5, 2.5, 1.0)});
    for (int m = 0; m < 24; ++m) sim.stepMonth();
    CHECK(sim.counters().diedAtCanopy == 1);  // the one under the 8 m canopy
    double tallest = 0;
    for (const auto& p : sim.plants()) tallest = std::max(tallest, p.heightM);
    CHECK(tallest > 3.0);  // the gap's sapling passed the 3 m threshold
}

TEST_CASE("germination_cells = every: covered cells germinate too, uncovered ones as before", "[sim][seeding][readings]") {
    const Biome b = defaultBiome();
    SimInputs in;
    in.biome = b;
    in.abiotics = uniformAbiotics(10, 1.0, 6.0, 100.0, 15.0, 5.0);
    in.canopy = {Plant{b.speciesIndex("Redwood"), 5.0, 5.0, 50, 60, 1.0}};
    // A 2.5 m Toyon (crown radius about 1.3 m) covers the cells around (5, 5).
    const std::vector<UndergrowthPlant> shrub{plantAt(b, "Toyon", 5.05, 5.05, 2.5)};
    const auto run = [&](GerminationCells g) {
        SimParams params;
        params.seedingProbability = 1.0;
        params.seedingMonth = 0;
        params.germinationCells = g;
        Simulation sim(in, params, 3, shrub);
        sim.stepMonth();
        return sim.plants();
    };
    const auto uncovered = run(GerminationCells::Uncovered), every = run(GerminationCells::Every);
    const auto under = [](const std::vector<UndergrowthPlant>& pl) {
        int n = 0;
        for (const auto& p : pl)
            if (p.id != 1 && std::hypot(p.xM - 5.05, p.yM - 5.05) < 1.0) ++n;
        return n;
    };
    INFO("uncovered " << uncovered.size() << " every " << every.size());
    CHECK(under(uncovered) == 0);
    CHECK(under(every) > 50);  // about pi x 1^2 / 0.04 = 78 cells, all with probability 1
    CHECK(every.size() > uncovered.size());
}

TEST_CASE("germination_vigour = mean_vigour: the weight is the mean of Eq. 1 over the season's months", "[sim][roulette][readings]") {
    // Sun, moisture and temperature that change month by month on an empty plot: the leftovers
    // are the canopy-shaded abiotics, so the expected weights follow from Biome::vigourOf.
    const Biome b = defaultBiome();
    const int fir = b.speciesIndex("Douglas-Fir");
    SimInputs in;
    in.biome = b;
    in.abiotics = uniformAbiotics(20, 1.0, 6.0, 100.0, 15.0, 5.0);
    for (int m = 0; m < 12; ++m) {
        std::fill(in.abiotics.sunHours[m].data().begin(), in.abiotics.sunHours[m].data().end(), static_cast<float>(3.0 + m));
        std::fill(in.abiotics.moistureMm[m].data().begin(), in.abiotics.moistureMm[m].data().end(), static_cast<float>(20.0 + 15.0 * m));
        std::fill(in.abiotics.temperatureC[m].data().begin(), in.abiotics.temperatureC[m].data().end(), static_cast<float>(5.0 + 2.0 * m));
    }
    in.canopy = {Plant{fir, 10.0, 10.0, 50, 30, 1.0}};  // seeds the plot; its crown covers (10, 10) only
    SimParams params;
    params.seedingProbability = 1e-9;  // (0 would give no seed packages) germination at the end of December:
    params.seedingMonth = 11;          // after 11 months the window holds January..November
    params.germinationVigour = GerminationVigour::MeanVigour;
    params.minWaterDemandMm = 4.0;
    Simulation mean(in, params, 1);
    params.germinationVigour = GerminationVigour::MeanResources;
    Simulation resources(in, params, 1);
    for (int m = 0; m < 11; ++m) {
        mean.stepMonth();
        resources.stepMonth();
    }
    // A cell far from the tree's crown (its seedbank covers everything within 12 r).
    const int ix = 50, iy = 25;  // (10.1, 5.1): 4.9 m from the tree, outside its crown, inside its 12 m seedbank
    const auto wMean = mean.germinationWeights(ix, iy), wRes = resources.germinationWeights(ix, iy);
    const double slope = 5.0;
    int compared = 0, differ = 0;
    for (const Species& s : b.species) {
        const double got = wMean[static_cast<std::size_t>(s.id)];
        if (std::find(s.subBiomes.begin(), s.subBiomes.end(), 1) == s.subBiomes.end()) {
            CHECK(got == 0);
            continue;
        }
        double sum = 0, sunSum = 0, waterSum = 0, tempSum = 0;
        int n = 0;
        for (int m : s.growthMonths) {
            if (m > 10) continue;  // outside the window
            const double sun = 3.0 + m, water = 20.0 + 15.0 * m - 0.0, temp = 5.0 + 2.0 * m;
            sum += b.vigourOf(s.id, {sun, water, temp, slope});
            sunSum += sun;
            waterSum += water;
            tempSum += temp;
            ++n;
        }
        const double expected = rouletteWeight(sum / n, s.maxAgeYears, params.rouletteAgeExponent);
        const double ofMeans = rouletteWeight(b.vigourOf(s.id, {sunSum / n, waterSum / n, tempSum / n, slope}), s.maxAgeYears,
                                              params.rouletteAgeExponent);
        INFO(s.name << ": mean_vigour " << got << " expected " << expected << "; mean_resources " << wRes[s.id] << " expected "
                    << ofMeans);
        CHECK(got == Approx(expected).epsilon(1e-9).margin(1e-12));
        CHECK(wRes[static_cast<std::size_t>(s.id)] == Approx(ofMeans).epsilon(1e-9).margin(1e-12));
        ++compared;
        differ += std::abs(expected - ofMeans) > 0.05 * ofMeans ? 1 : 0;
    }
    CHECK(compared >= 3);
    CHECK(differ >= 2);  // the two readings give different weights here (Eq. 1 is not linear)
}

// --------------------------------------------------------------------------- Deussen competition

namespace {

// Pairs of Toyons (2 m and 0.5 m tall, crown radii about 1.06 m and 0.30 m) whose roots are
// `gapM` apart, on a grid of pairs 4 m apart, at the Toyon optimum (unshared resources).
struct PairScene {
    SimInputs in;
    std::vector<UndergrowthPlant> plants;
};
PairScene toyonPairs(int pairsPerSide, double gapM) {
    PairScene sc;
    const Biome b = defaultBiome();
    const Species& sp = b.species[b.speciesIndex("Toyon")];
    sc.in.biome = b;
    sc.in.abiotics = uniformAbiotics(4 * pairsPerSide, 1.0, sp.response(Factor::Sun).c, sp.response(Factor::Moisture).c, sp.response(Factor::Temperature).c, sp.response(Factor::Slope).c);
    for (int j = 0; j < pairsPerSide; ++j)
        for (int i = 0; i < pairsPerSide; ++i) {
            sc.plants.push_back(plantAt(b, "Toyon", 4.0 * i + 1.05, 4.0 * j + 1.05, 2.0));
            sc.plants.push_back(plantAt(b, "Toyon", 4.0 * i + 1.05 + gapM, 4.0 * j + 1.05, 0.5));
        }
    return sc;
}

SimParams deussenParams(double survival) {
    SimParams p;
    p.competition = CompetitionMode::Deussen;
    p.deussenDominatedSurvival = survival;
    p.survivalAtMaxAge = 1.0 - 1e-9;  // no background mortality
    p.seedingProbability = 0.0;       // no germination
    return p;
}

}  // namespace

TEST_CASE("seeding_probability = 0 disables germination (validation runs from initial plants)", "[sim][seeding]") {
    SimInputs in = smallDemoScene();
    in.area = SimArea{10, 10, 30, 30};
    const Biome b = in.biome;
    SimParams p;
    p.seedingProbability = 0.0;
    Simulation sim(in, p, 7, {plantAt(b, "Toyon", 20.1, 20.1, 0.5), plantAt(b, "Tanoak", 15.1, 15.1, 0.5)});
    CHECK(sim.seedProbability().data() == std::vector<float>(sim.seedProbability().size(), 0.f));
    for (int y = 0; y < 3; ++y) sim.stepYear();
    CHECK(sim.counters().germinated == 0);
    CHECK(sim.plantCount() <= 2);
}

TEST_CASE("limits: a grid over 65535 cells wide, a biome of over 2048 species or of over 32 growth periods is refused, naming the limit", "[sim][config]") {
    SimInputs wide;
    wide.biome = defaultBiome();
    wide.abiotics = uniformAbiotics(4, 4000.0, 8, 50, 15, 0);  // 16 km: 80 000 cells of 0.2 m
    try {
        Simulation sim(wide, SimParams{}, 1);
        FAIL("a grid of 80 000 cells across was accepted");
    } catch (const ValidationError& e) {
        CHECK_THAT(e.what(), Catch::Contains("80000 x 80000 cells") && Catch::Contains("65535 cells wide"));
    }
    wide.area = SimArea{0, 0, 13000, 0.4};  // 65 000 x 2 cells: inside the limit
    CHECK_NOTHROW(Simulation(wide, SimParams{}, 1));

    // A copy of the scene's first species appended under a new name (and, when `ownMonth`
    // >= 0, with that growth month as a period of its own).
    const Species first = smallDemoScene().biome.species.front();
    auto addSpecies = [&first](SimInputs& in, const std::string& name, int ownMonth) {
        Species s = first;
        s.id = static_cast<int>(in.biome.species.size());
        s.name = name;
        if (ownMonth >= 0) {
            s.growthPeriod = name;
            s.growthMonths = {ownMonth};
        }
        in.biome.species.push_back(s);
    };
    auto refused = [](const SimInputs& in, const std::string& count, const std::string& limit) {
        try {
            Simulation sim(in, SimParams{}, 1);
            FAIL("a biome of " + count + " was accepted");
        } catch (const ValidationError& e) {
            CHECK_THAT(e.what(), Catch::Contains(count) && Catch::Contains(limit));
        }
    };
    SimInputs many = smallDemoScene();
    while (many.biome.species.size() <= 2048) addSpecies(many, "copy " + std::to_string(many.biome.species.size()), -1);
    refused(many, "2049 species", "at most 2048");

    // Every species with growth months of its own adds a growth period; germination keeps
    // sets of periods in 32-bit masks.
    SimInputs periods = smallDemoScene();
    for (std::size_t own = 0; periods.biome.growthPeriods.size() + own <= 32; ++own)
        addSpecies(periods, "own months " + std::to_string(own), static_cast<int>(own % 12));
    refused(periods, "33 growth periods", "at most 32");
    periods.biome.species.pop_back();  // 32 periods
    CHECK_NOTHROW(Simulation(periods, SimParams{}, 1));
}

TEST_CASE("deussen: ability is vigour x relative height, crowns intersect strictly", "[sim][deussen]") {
    CHECK(competitiveAbility(0.5, 2.0, 8.0) == Approx(0.125));
    CHECK(competitiveAbility(-0.1, 2.0, 8.0) < 0);
    CHECK(crownsIntersect(0, 0, 1, 1.5, 0, 0.6));
    CHECK_FALSE(crownsIntersect(0, 0, 1, 2.0, 0, 1.0));  // touching
    CHECK(dominatedSurvivalPerMonth(0.5, 0) == 1.0);
    CHECK(std::pow(dominatedSurvivalPerMonth(0.5, 1), 12) == Approx(0.5).epsilon(1e-12));
    CHECK(dominatedSurvivalPerMonth(0.5, 2) == Approx(std::pow(0.5, 2.0 / 12)).epsilon(1e-12));
}

TEST_CASE("deussen: the weaker of two intersecting plants dies at the expected rate (binomial test)", "[sim][deussen]") {
    for (const double survival : {0.5, 0.2}) {
        PairScene sc = toyonPairs(20, 1.0);  // 400 intersecting pairs
        Simulation sim(sc.in, deussenParams(survival), 17, sc.plants);
        REQUIRE(sim.plantCount() == 800);
        sim.stepMonth();
        {
            // Unshared resources: the small Toyon under the big one's crown sees the full sun.
            const auto pl = sim.plants();
            const Species& sp = sim.biome().species[pl[1].speciesId];
            CHECK(pl[1].sunShare == Approx(sp.response(Factor::Sun).c).epsilon(1e-6));
            CHECK(pl[1].waterShare == Approx(sp.response(Factor::Moisture).c).epsilon(1e-6));
        }
        for (int m = 1; m < 12; ++m) sim.stepMonth();
        int tall = 0, small = 0;
        for (const auto& p : sim.plants()) (p.heightM > 1.5 ? tall : small)++;
        CHECK(tall == 400);  // the stronger is never dominated
        CHECK(sim.counters().diedDominated == 400 - small);
        CHECK(sim.counters().diedBackgroundOrStress == 0);
        // One year of domination by one plant is survived with probability `survival`.
        const double n = 400, sigma = std::sqrt(n * survival * (1 - survival));
        INFO("survival " << survival << ": " << small << " of 400 dominated plants survived, expected " << n * survival);
        CHECK(std::abs(small - n * survival) <= 3.29 * sigma);  // two-sided, significance 0.001
    }
}

TEST_CASE("deussen: plants whose crowns do not intersect never die of domination", "[sim][deussen]") {
    PairScene sc = toyonPairs(10, 1.8);  // 1.8 m apart: crowns 1.06 + 0.30 m do not reach
    Simulation sim(sc.in, deussenParams(0.0), 17, sc.plants);
    for (int y = 0; y < 2; ++y) sim.stepYear();
    CHECK(sim.plantCount() == 200);
    CHECK(sim.counters().diedDominated == 0);
}

TEST_CASE("deussen: default mode unchanged, and bit-identical results with 1 and 2 threads", "[sim][deussen][determinism]") {
    CHECK(SimParams{}.competition == CompetitionMode::Resources);
    CHECK(SimParams{}.growthRule == GrowthRule::Ideal);
    SimInputs in = smallDemoScene();
    in.area = SimArea{8, 8, 32, 32};
    // The Deussen survival does not touch the resources mode.
    {
        SimParams a, b;
        b.deussenDominatedSurvival = 0.9;
        Simulation sa(in, a, 21), sb(in, b, 21);
        for (int y = 0; y < 8; ++y) {
            sa.stepYear();
            sb.stepYear();
        }
        CHECK(sameSimPlants(sa.plants(), sb.plants()));
        CHECK(sa.counters().diedDominated == 0);
    }
    setParallelThresholds(0, 0);  // exercise every parallel loop on this small scene
    std::vector<std::vector<UndergrowthPlant>> results;
    std::vector<std::int64_t> dominated;
    const int before = omp_get_max_threads();
    SimParams p;
    p.competition = CompetitionMode::Deussen;
    for (int threads : {1, 2}) {
        omp_set_num_threads(threads);
        Simulation sim(in, p, 21);
        for (int y = 0; y < 15; ++y) sim.stepYear();
        results.push_back(sim.plants());
        dominated.push_back(sim.counters().diedDominated);
    }
    omp_set_num_threads(before);
    setParallelThresholds(kDefaultParallelPlants, kDefaultParallelCells);
    REQUIRE(results[0].size() > 100);
    CHECK(dominated[0] > 0);
    CHECK(dominated[0] == dominated[1]);
    CHECK(sameSimPlants(results[0], results[1]));
}

// --------------------------------------------------------------------------- integration

TEST_CASE("integration: 25 years on a small plot keep every invariant", "[sim][integration]") {
    SimInputs in = smallDemoScene();
    in.area = SimArea{10, 10, 30, 30};
    const Biome b = in.biome;
    Simulation sim(in, SimParams{}, 7);
    std::size_t maxPlants = 0;
    for (int y = 0; y < 25; ++y) {
        sim.stepYear();
        const auto pl = sim.plants();
        maxPlants = std::max(maxPlants, pl.size());
        const SimArea a = sim.area();
        for (const auto& p : pl) {
            const Species& s = b.species[static_cast<std::size_t>(p.speciesId)];
            const double cap = poolCapacity(3, s.alpha, b.vigour.a);
            REQUIRE(std::isfinite(p.xM));
            REQUIRE(std::isfinite(p.heightM));
            REQUIRE(std::isfinite(p.crownRadiusM));
            REQUIRE(std::isfinite(p.pool));
            REQUIRE(std::isfinite(p.vigour));
            REQUIRE(std::isfinite(p.sunShare));
            REQUIRE(std::isfinite(p.waterShare));
            REQUIRE(p.xM >= a.x0);
            REQUIRE(p.xM < a.x1);
            REQUIRE(p.yM >= a.y0);
            REQUIRE(p.yM < a.y1);
            REQUIRE(p.pool <= cap + 1e-12);
            REQUIRE(p.pool > -1.0);
            REQUIRE(p.heightM > 0);
            REQUIRE(p.heightM <= s.maxHeightM);
            REQUIRE(p.crownRadiusM == Approx(s.allometry.crownRadiusM(p.heightM)));
            // The ideal rule concentrates a year's growth in the growth period: the growth age
            // may run ahead of the age within a year, never by a year.
            REQUIRE(p.growthAgeYears <= p.ageYears + 1.0 / 12 + 1.0);
            REQUIRE(p.vigour <= s.alpha + 1e-12);
            REQUIRE(p.vigour >= -s.alpha * b.vigour.a - 1e-12);
        }
        const YearRecord r = sim.census();
        std::int64_t total = 0;
        for (auto c : r.count) total += c;
        REQUIRE(total == static_cast<std::int64_t>(pl.size()));
    }
    CHECK(maxPlants > 100);
    CHECK(sim.counters().germinated > 0);
    CHECK(sim.counters().diedBackgroundOrStress > 0);
}

TEST_CASE("determinism: the AVX2 and the SSE2 kernels give identical plants", "[sim][determinism]") {
    // 30 years of ideal growth: crowns of many cells, so that the kernels' full and masked
    // groups of four are all exercised.
    SimInputs in = smallDemoScene();
    in.area = SimArea{8, 8, 32, 32};
    std::vector<std::vector<UndergrowthPlant>> results;
    bool avx2 = false;
    for (bool on : {false, true}) {
        avx2 = eco::setAvx2Kernels(on);
        Simulation sim(in, SimParams{}, 5);
        for (int y = 0; y < 30; ++y) sim.stepYear();
        results.push_back(sim.plants());
    }
    eco::setAvx2Kernels(true);  // back to the default: AVX2 where the processor has it
    if (!avx2) WARN("no AVX2 on this processor: both runs used the SSE2 kernel");
    REQUIRE(results[0].size() > 100);
    CHECK(sameSimPlants(results[0], results[1]));
}

TEST_CASE("determinism: identical plants with 1, 2 and 4 threads", "[sim][determinism]") {
    setParallelThresholds(0, 0);  // exercise every parallel loop on this small scene
    SimInputs in = smallDemoScene();
    in.area = SimArea{8, 8, 32, 32};
    std::vector<std::vector<UndergrowthPlant>> results;
    const int before = omp_get_max_threads();
    for (int threads : {1, 2, 4}) {
        omp_set_num_threads(threads);
        Simulation sim(in, SimParams{}, 21);
        for (int y = 0; y < 12; ++y) sim.stepYear();
        results.push_back(sim.plants());
    }
    omp_set_num_threads(before);
    setParallelThresholds(kDefaultParallelPlants, kDefaultParallelCells);
    REQUIRE(results[0].size() > 100);
    CHECK(sameSimPlants(results[0], results[1]));
    CHECK(sameSimPlants(results[0], results[2]));
}

TEST_CASE("dead kept between compactions, layouts reused: observing the run every month changes nothing", "[sim][determinism]") {
    // Run a steps years only: the dead stay in the store until many, and the months after
    // a month without growth (June to August in the Sonoma biome) reuse the layout. Run b
    // reads its plants every month, which settles the dead at once and so rebuilds every
    // layout: the same plants and counters, whatever the thread count.
    setParallelThresholds(0, 0);
    SimInputs in = smallDemoScene();
    in.area = SimArea{8, 8, 32, 32};
    const int before = omp_get_max_threads();
    for (int threads : {1, 2}) {
        omp_set_num_threads(threads);
        Simulation a(in, SimParams{}, 17), b(in, SimParams{}, 17);
        for (int y = 0; y < 15; ++y) a.stepYear();
        std::size_t seenAlive = 0;
        for (int m = 0; m < 15 * 12; ++m) {
            b.stepMonth();
            const std::size_t counted = b.plantCount();
            const std::vector<UndergrowthPlant> now = b.plants();
            REQUIRE(now.size() == counted);
            std::int64_t censusTotal = 0;
            for (std::int32_t c : b.census().count) censusTotal += c;
            REQUIRE(censusTotal == static_cast<std::int64_t>(counted));
            seenAlive += counted;
        }
        CHECK(seenAlive > 0);
        const std::vector<UndergrowthPlant> pa = a.plants(), pb = b.plants();
        REQUIRE(pa.size() > 100);
        CHECK(sameSimPlants(pa, pb));
        const SimCounters &ca = a.counters(), &cb = b.counters();
        CHECK(ca.plantMonths == cb.plantMonths);
        CHECK(ca.plantCellMonths == cb.plantCellMonths);
        CHECK(ca.germinated == cb.germinated);
        CHECK(ca.diedBackgroundOrStress == cb.diedBackgroundOrStress);
        CHECK(ca.diedAtCanopy == cb.diedAtCanopy);
        CHECK(ca.diedBackgroundOrStress + ca.diedAtCanopy > 100);
    }
    omp_set_num_threads(before);
    setParallelThresholds(kDefaultParallelPlants, kDefaultParallelCells);
}

TEST_CASE("atomic output: a commit removes the temporaries of killed writers, not of running ones", "[sim][checkpoint]") {
    // A kill -9 during a checkpoint leaves ".<name>.tmp<pid>" beside it; the next commit of
    // that output removes it when process <pid> no longer runs.
    eco::test::TempDir dir("atomic_output");
    const std::string target = dir.file("run.h5.checkpoint.h5");
    const pid_t child = ::fork();
    REQUIRE(child >= 0);
    if (child == 0) ::_exit(0);
    int status = 0;
    REQUIRE(::waitpid(child, &status, 0) == child);  // reaped: no process of that id runs now
    auto touch = [](const std::string& path) { std::ofstream(path) << "partial"; };
    const std::string stale = dir.file(".run.h5.checkpoint.h5.tmp" + std::to_string(child));
    const std::string running = dir.file(".run.h5.checkpoint.h5.tmp" + std::to_string(::getppid()));
    const std::string other = dir.file(".other.h5.tmp" + std::to_string(child));
    const std::string odd = dir.file(".run.h5.checkpoint.h5.tmpXYZ");
    for (const std::string& f : {stale, running, other, odd}) touch(f);
    eco::writeTextFile(target, "complete");
    std::ifstream in(target);
    std::string text;
    in >> text;
    CHECK(text == "complete");
    CHECK_FALSE(std::filesystem::exists(stale));
    CHECK(std::filesystem::exists(running));  // its writer may still commit
    CHECK(std::filesystem::exists(other));    // another output's
    CHECK(std::filesystem::exists(odd));      // not a name AtomicOutput gives
}

TEST_CASE("checkpoint: a resumed run is identical to an uninterrupted one", "[sim][checkpoint]") {
    test::TempDir dir("simresume");
    SimInputs in = smallDemoScene();
    in.area = SimArea{10, 10, 30, 30};
    Simulation straight(in, SimParams{}, 5);
    for (int m = 0; m < 12 * 9 + 5; ++m) straight.stepMonth();  // ends mid-year, mid-season
    Simulation first(in, SimParams{}, 5);
    for (int m = 0; m < 12 * 4 + 2; ++m) first.stepMonth();
    {
        auto f = h5::File::create(dir.file("state.h5"));
        first.saveState(f, "/state");
    }
    Simulation resumed(in, SimParams{}, 5);
    {
        auto f = h5::File::openRead(dir.file("state.h5"));
        resumed.loadState(f, "/state");
    }
    CHECK(resumed.monthsDone() == first.monthsDone());
    for (int m = 0; m < 12 * 5 + 3; ++m) resumed.stepMonth();
    REQUIRE(resumed.monthsDone() == straight.monthsDone());
    CHECK(straight.plantCount() > 50);
    CHECK(sameSimPlants(straight.plants(), resumed.plants()));
    CHECK(straight.counters().germinated == resumed.counters().germinated);

    // Another seed is another run: its checkpoint is refused.
    Simulation other(in, SimParams{}, 6);
    auto f = h5::File::openRead(dir.file("state.h5"));
    CHECK_THROWS_WITH(other.loadState(f, "/state"), Catch::Contains("another run"));
}

TEST_CASE("checkpoint: the paper's readings (every cell, monthly mean vigour, canopy only) resume identically too",
          "[sim][checkpoint][readings]") {
    test::TempDir dir("simresume_readings");
    SimInputs in = smallDemoScene();
    in.area = SimArea{10, 10, 30, 30};
    SimParams p;
    p.germinationCells = GerminationCells::Every;
    p.germinationVigour = GerminationVigour::MeanVigour;
    p.canopyLimit = CanopyLimit::CanopyOnly;
    Simulation straight(in, p, 5);
    for (int m = 0; m < 12 * 6 + 5; ++m) straight.stepMonth();
    Simulation first(in, p, 5);
    for (int m = 0; m < 12 * 3 + 4; ++m) first.stepMonth();  // mid-window: the monthly leftovers are in the state
    {
        auto f = h5::File::create(dir.file("state.h5"));
        first.saveState(f, "/state");
    }
    Simulation resumed(in, p, 5);
    {
        auto f = h5::File::openRead(dir.file("state.h5"));
        resumed.loadState(f, "/state");
    }
    for (int m = 0; m < 12 * 3 + 1; ++m) resumed.stepMonth();
    REQUIRE(resumed.monthsDone() == straight.monthsDone());
    CHECK(straight.plantCount() > 50);
    CHECK(sameSimPlants(straight.plants(), resumed.plants()));
    CHECK(straight.counters().germinated == resumed.counters().germinated);
    // The same bits on one thread.
    const int threads = omp_get_max_threads();
    omp_set_num_threads(1);
    Simulation single(in, p, 5);
    for (int m = 0; m < 12 * 6 + 5; ++m) single.stepMonth();
    omp_set_num_threads(threads);
    CHECK(sameSimPlants(straight.plants(), single.plants()));
    // The default readings are another run.
    Simulation defaults(in, SimParams{}, 5);
    auto f = h5::File::openRead(dir.file("state.h5"));
    CHECK_THROWS_WITH(defaults.loadState(f, "/state"), Catch::Contains("another run"));
}

// --------------------------------------------------------------------------- configuration

TEST_CASE("run config: paths are relative to the configuration file's directory", "[sim][config]") {
    test::TempDir dir("sim_config_paths");
    std::filesystem::create_directories(dir.file("cfg"));
    std::ofstream(dir.file("cfg/run.toml")) << "[inputs]\nabiotics = \"../in/a.h5\"\ncanopy = \"c.h5\"\nterrain = \"/abs/t.h5\"\n"
                                            << "biome = \"\"\ninitial = \"i.h5:/group\"\n"
                                            << "[outputs]\nhdf5 = \"out/sim.h5\"\ncsv = \"\"\npng_dir = \"png\"\n";
    const RunConfig c = loadRunConfig(dir.file("cfg/run.toml"));
    CHECK(c.abioticsPath == dir.file("in/a.h5"));
    CHECK(c.canopyPath == dir.file("cfg/c.h5"));
    CHECK(c.terrainPath == "/abs/t.h5");  // absolute: as written
    CHECK(c.biomePath.empty());           // "": the embedded biome, still
    CHECK(c.initialPath == dir.file("cfg/i.h5:/group"));
    CHECK(c.outputPath == dir.file("cfg/out/sim.h5"));
    CHECK(c.csvPath.empty());
    CHECK(c.pngDir == dir.file("cfg/png"));
    // Text without a file (tests, --model) keeps its paths; a default is not the file's.
    CHECK(parseRunConfig("[inputs]\nabiotics = \"a.h5\"\n", "text").abioticsPath == "a.h5");
    std::ofstream(dir.file("cfg/bare.toml")) << "[inputs]\nabiotics = \"a.h5\"\n";
    CHECK(loadRunConfig(dir.file("cfg/bare.toml")).outputPath == RunConfig{}.outputPath);
}

TEST_CASE("run config: the built-in defaults hold every key and read back", "[sim][config]") {
    // configs/sim-default.toml as built in equals the file, and its [model] is the defaults.
    const RunConfig file = loadRunConfig(test::sourcePath("configs/sim-default.toml"));
    const RunConfig embedded = parseRunConfig(embeddedDefaultRunConfigToml(), "embedded", test::sourcePath("configs/sim-default.toml"));
    CHECK(embedded.abioticsPath == file.abioticsPath);
    CHECK(embedded.years == file.years);
    CHECK(embedded.snapshotYears == file.snapshotYears);
    CHECK(embedded.params.toToml() == file.params.toToml());
    CHECK(file.params.toToml() == SimParams{}.toToml());
    // eco config defaults simulate: every model key (from simParamFields and the choices) once.
    const std::string text = defaultRunConfigToml();
    const RunConfig back = parseRunConfig(text, "defaults");
    CHECK(back.params.toToml() == SimParams{}.toToml());
    CHECK(back.years == file.years);
    CHECK(back.checkpointEveryYears == file.checkpointEveryYears);
    for (const auto& f : simParamFields()) {
        INFO(f.key);
        CHECK(text.find(std::string("\n") + f.key + " = ") != std::string::npos);
    }
    for (const char* key : {"growth_rule", "competition", "germination_cells", "germination_vigour", "canopy_limit"}) {
        INFO(key);
        CHECK(text.find(std::string("\n") + key + " = ") != std::string::npos);
    }
    CHECK(text.find("[model]") == text.rfind("[model]"));
    // The [disturbance.*] tables are there commented out (as printed, disturbance is off);
    // uncommented they read back as the defaults with both kinds on.
    CHECK_FALSE(back.disturbance.enabled());
    const std::size_t templateAt = text.find("\n# [disturbance.fire]\n");
    REQUIRE(templateAt != std::string::npos);
    CHECK(text.find("\n# [disturbance.storm]\n", templateAt) != std::string::npos);
    std::string uncommented = text.substr(0, templateAt + 1);
    std::istringstream lines(text.substr(templateAt + 1));
    for (std::string line; std::getline(lines, line);)  // the template's tables and keys, not its prose
        uncommented += (line.rfind("# [", 0) == 0 || line.find(" = ") != std::string::npos ? line.substr(2) : line) + "\n";
    const RunConfig withDisturbance = parseRunConfig(uncommented, "defaults, disturbance uncommented");
    DisturbanceSettings expected;
    expected.fire.enabled = expected.storm.enabled = true;
    CHECK(withDisturbance.disturbance.fire.enabled);
    CHECK(withDisturbance.disturbance.storm.enabled);
    CHECK(withDisturbance.disturbance.toToml() == expected.toToml());
    // The template is made from the descriptors: each written key of either table once, at
    // its default, with its doc line.
    auto templateHas = [&](const std::string& table, const std::string& key, const std::string& value, const char* doc) {
        const std::size_t at = text.find("\n# [disturbance." + table + "]\n");
        const std::size_t end = text.find("\n# [", at + 1);
        const std::string block = text.substr(at, end == std::string::npos ? std::string::npos : end - at);
        return block.find("\n# " + key + " = " + value + "  # " + doc) != std::string::npos;
    };
    for (const auto& f : fireFields())
        if (f.written()) CHECK(templateHas("fire", f.key(), f.tomlValue(FireSettings{}), f.doc()));
    for (const auto& f : stormFields())
        if (f.written()) CHECK(templateHas("storm", f.key(), f.tomlValue(StormSettings{}), f.doc()));
    CHECK(withDisturbance.disturbance.fire.spreadProbability == FireSettings{}.spreadProbability);
    CHECK(withDisturbance.disturbance.fire.timing.month == 7);
    CHECK(withDisturbance.disturbance.storm.timing.month == 11);
    CHECK(withDisturbance.disturbance.storm.referenceHeightM == StormSettings{}.referenceHeightM);
}

TEST_CASE("run config: strict parsing with the file and key named", "[sim][config]") {
    const RunConfig def = loadRunConfig(test::sourcePath("configs/sim-default.toml"));
    CHECK(def.params.cellSizeM == 0.2);
    CHECK(def.crop.has_value());
    CHECK(def.years > 0);
    const RunConfig c = parseRunConfig(
        "[inputs]\nabiotics = \"a.h5\"\ncanopy = \"c.h5\"\n[run]\nyears = 3\nseed = 9\ncrop = [0, 0, 10, 10]\n"
        "[model]\nseeding_probability = 0.01\nseeding_month = 8\n",
        "ok.toml");
    CHECK(c.seed == 9);
    CHECK(c.params.seedingProbability == 0.01);
    CHECK(c.params.seedingMonth == 8);
    CHECK_THROWS_WITH(parseRunConfig("[model]\nseeding_probabilty = 0.01\n", "typo.toml"),
                      Catch::Contains("typo.toml") && Catch::Contains("seeding_probabilty"));
    CHECK_THROWS_WITH(parseRunConfig("[run]\nyears = \"ten\"\n", "type.toml"),
                      Catch::Contains("type.toml") && Catch::Contains("years"));
    CHECK_THROWS_WITH(parseRunConfig("[model]\nseeding_probability = 2.0\n", "range.toml"),
                      Catch::Contains("range.toml") && Catch::Contains("seeding_probability"));
    CHECK_THROWS_WITH(parseRunConfig("[model]\nseeding_month = 12\n", "m.toml"), Catch::Contains("seeding_month"));
    CHECK_THROWS_WITH(parseRunConfig("[extra]\nx = 1\n", "top.toml"), Catch::Contains("extra"));
    CHECK_THROWS_AS(parseRunConfig("[run\n", "broken.toml"), IoError);
    CHECK_THROWS_WITH(parseArea("1,2,3", "--crop"), Catch::Contains("--crop"));
    // Parameters round-trip through their TOML record.
    SimParams p;
    p.seedingMonth = 3;
    p.minWaterDemandMm = 5.5;
    p.growthRule = GrowthRule::Literal;
    p.competition = CompetitionMode::Deussen;
    p.deussenDominatedSurvival = 0.25;
    const RunConfig back = parseRunConfig(p.toToml(), "record");
    CHECK(back.params.seedingMonth == 3);
    CHECK(back.params.minWaterDemandMm == 5.5);
    CHECK(back.params.growthRule == GrowthRule::Literal);
    CHECK(back.params.competition == CompetitionMode::Deussen);
    CHECK(back.params.deussenDominatedSurvival == 0.25);
    // Enum keys: the accepted spellings only, with the file, line and key named.
    CHECK_THROWS_WITH(parseRunConfig("[model]\ncell_size_m = 0.2\ngrowth_rule = \"fast\"\n", "enum.toml"),
                      Catch::Contains("enum.toml:3") && Catch::Contains("growth_rule") && Catch::Contains("\"ideal\""));
    CHECK_THROWS_WITH(parseRunConfig("[model]\ncompetition = 1\n", "enum.toml"),
                      Catch::Contains("competition") && Catch::Contains("string"));
    CHECK_THROWS_WITH(parseRunConfig("[model]\n\ndeussen_dominated_survival = 1.5\n", "range.toml"),
                      Catch::Contains("range.toml:3") && Catch::Contains("deussen_dominated_survival"));
    CHECK_THROWS_WITH(parseRunConfig("[outputs]\nhdf5 = 3\n", "type.toml"), Catch::Contains("type.toml:2") && Catch::Contains("hdf5"));
    // Empty strings are valid for paths ("" = none).
    CHECK(parseRunConfig("[inputs]\nbiome = \"\"\n", "empty.toml").biomePath.empty());
}

TEST_CASE("model parameters: one description drives reading, the record, attributes, validation and the docs table",
          "[sim][config]") {
    std::ifstream in(std::string(ECO_SOURCE_DIR) + "/docs/simulator.md");
    REQUIRE(in);
    std::stringstream docs;
    docs << in.rdbuf();
    const SimParams defaults;
    const std::string record = defaults.toToml();
    const auto named = defaults.namedValues();
    // + growth_rule, competition, germination_cells, germination_vigour, canopy_limit
    REQUIRE(named.size() == simParamFields().size() + 5);
    for (std::size_t i = 0; i < simParamFields().size(); ++i) {
        const auto& f = simParamFields()[i];
        INFO(f.key);
        CHECK(docs.str().find(paramDocRow(f)) != std::string::npos);
        CHECK(named[i].first == f.key);
        CHECK(named[i].second == f.value(defaults));
        CHECK(record.find(std::string("\n") + f.key + " = ") != std::string::npos);
        // A value outside the range (or, for the outer radius, below the inner one) is refused
        // with the key named, from a config and from validate().
        const double outside = f.real == &SimParams::seedOuterRadiusFactor ? 1.0
                               : f.range.highBound != ParamRange::Bound::None ? f.range.hi + 1
                                                                              : f.range.lo - 1;
        std::ostringstream cfg;
        cfg << "[model]\n" << f.key << " = " << (f.kind == ParamDesc<SimParams>::Kind::Integer ? std::to_string(static_cast<int>(outside)) : formatNumber(outside, 17) + (outside == std::floor(outside) ? ".0" : "")) << "\n";
        CHECK_THROWS_WITH(parseRunConfig(cfg.str(), "bad.toml"), Catch::Contains("bad.toml:2") && Catch::Contains(f.key));
    }
}

// --------------------------------------------------------------------------- wind

TEST_CASE("wind: the simulator reads the wind map only through the species that respond to it", "[sim][wind]") {
    auto run = [](const Biome& b, float windMS, std::uint64_t* fingerprint) {
        SimInputs in;
        in.biome = b;
        in.abiotics = uniformAbiotics(10, 1.0, 10.0, 100.0, 15.0, 5.0);
        in.abiotics.windMS.fill(windMS);
        Simulation sim(in, SimParams{}, 1, {plantAt(b, "Toyon", 5.1, 5.1, 1.0)});
        *fingerprint = sim.fingerprint();
        sim.stepMonth();
        return sim.plants();
    };
    // No species responds (as in Sonoma): the wind changes neither the plants nor the
    // checkpoint fingerprint.
    Biome b = pointCrownBiome();
    std::uint64_t calmPrint = 0, windyPrint = 0;
    const auto calm = run(b, 0.f, &calmPrint), windy = run(b, 9.f, &windyPrint);
    REQUIRE(calm.size() == 1);
    REQUIRE(windy.size() == 1);
    CHECK(calm[0].vigour == windy[0].vigour);
    CHECK(calm[0].heightM == windy[0].heightM);
    CHECK(calmPrint == windyPrint);
    // Toyon needs shelter (optimum 0 m/s, range 3): at 9 m/s it is far outside its range.
    b.species[static_cast<std::size_t>(b.speciesIndex("Toyon"))].response(Factor::Wind) = Response{0.0, 3.0};
    std::uint64_t shelteredPrint = 0, exposedPrint = 0;
    const auto sheltered = run(b, 0.f, &shelteredPrint), exposed = run(b, 9.f, &exposedPrint);
    CHECK(sheltered[0].vigour == calm[0].vigour);  // at its optimum the wind takes nothing
    CHECK(exposed[0].vigour < 0);                  // beyond the range: g < 0
    CHECK(shelteredPrint != exposedPrint);         // a checkpoint does not resume into another wind
}
