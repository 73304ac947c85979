// Tests of the Deussen 1998 sampler (synth/deussen_sampler.cpp, SynthMethod::Deussen): error
// diffusion keeps a density image's mass where the image puts it, Lloyd relaxation evens the
// spacing (Clark-Evans R) without breaking minimum distances or moving plants out of their
// density class, canopy trunks are obstacles, and the result does not depend on the thread
// count. `eco synth --method deussen` is tested in synth_cli_test.cpp.
//
// The database is the synthesis tests' (synth_world_fixture.h); its region 0 (Western
// Swordfern 0.4, Redwood Sorrel 0.3, Tanoak 0.2, Toyon 0.1 of 1.2 plants per m^2) covers the
// whole plot through a hand-made cluster map, so every expected count is known exactly.
#include <omp.h>

#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <map>
#include <vector>


#include "biome_db.h"
#include "param_table_check.h"
#include "point_pattern.h"
#include "rng.h"
#include "synth_world_fixture.h"
#include "test_util.h"
#include "undergrowth.h"

using namespace eco;

namespace {

constexpr double kDensity = 1.2;  // region 0 of the fixture's database, plants per m^2

struct Plot {
    test::World world = test::makeWorld(0.0);  // no hard cores: the minimum distances are ours
    Grid<float> terrain;
    synth::ClusterMap map;
    std::vector<Plant> canopy;
};

/// A flat plot of side x side cells of 1 m, all in region 0 (combination 1, Conifer).
Plot makePlot(int side) {
    Plot p;
    p.terrain = Grid<float>(side, side, 1.0, 0.0, 0.0, 10.0f);
    p.map.combination = Grid<std::int32_t>::like(p.terrain, 1);
    p.map.region = Grid<std::int32_t>::like(p.terrain, 0);
    p.map.seedWeight = Grid<float>::like(p.terrain, 1.0f);
    return p;
}

synth::UndergrowthSample run(const Plot& p, const synth::SynthParams& params, const Grid<float>* image = nullptr) {
    return synth::sampleUndergrowth(p.world.db, p.world.biome, p.canopy, p.map, p.terrain, params, image);
}

synth::SynthParams deussen(int iterations, double minDistanceFactor = 0.5, std::uint64_t seed = 7) {
    synth::SynthParams params;
    params.method = synth::SynthMethod::Deussen;
    params.seed = seed;
    params.deussen.lloydIterations = iterations;
    params.deussen.minDistanceFactor = minDistanceFactor;
    return params;
}

/// Clark-Evans R of the points inside [margin, side - margin]^2 (nearest neighbours among all
/// points, so no edge correction is needed): mean nearest-neighbour distance over the
/// 0.5 / sqrt(density) of a Poisson pattern of the same density.
double clarkEvansInside(const std::vector<double>& x, const std::vector<double>& y, double side, double margin) {
    const PointGrid grid(x, y, 2.0);
    const std::vector<std::uint32_t>& order = grid.order();
    double sum = 0;
    std::size_t n = 0;
    for (std::size_t i = 0; i < x.size(); ++i) {
        if (x[i] < margin || x[i] > side - margin || y[i] < margin || y[i] > side - margin) continue;
        double best = 1e300;
        grid.forEachWithin(x[i], y[i], 10.0, [&](std::size_t s, double, double, double d2) {
            if (order[s] != i) best = std::min(best, d2);
        });
        sum += std::sqrt(best);
        ++n;
    }
    const double inner = (side - 2 * margin) * (side - 2 * margin);
    return (sum / static_cast<double>(n)) / (0.5 / std::sqrt(static_cast<double>(n) / inner));
}

std::vector<std::size_t> speciesCounts(const std::vector<Plant>& plants, std::size_t ns) {
    std::vector<std::size_t> c(ns, 0);
    for (const Plant& q : plants) ++c[static_cast<std::size_t>(q.speciesId)];
    return c;
}

}  // namespace

TEST_CASE("deussen: error diffusion keeps a density image's totals and puts more plants where it is brighter",
          "[synth][deussen]") {
    const int side = 100;
    Plot p = makePlot(side);
    // Four stripes west to east, relative densities 0, 0.2, 0.4, 0.8 (black to light grey).
    const double value[4] = {0.0, 0.2, 0.4, 0.8};
    Grid<float> image = Grid<float>::like(p.terrain, 0.0f);
    for (int iy = 0; iy < side; ++iy)
        for (int ix = 0; ix < side; ++ix) image(ix, iy) = static_cast<float>(value[ix / 25]);
    const double total = kDensity * side * side;  // the database's plants on the plot
    const double valueSum = 0.0 + 0.2 + 0.4 + 0.8;
    const DbRegion& reg = p.world.db.regions[0];
    for (int iterations : {0, 8}) {
        INFO("Lloyd iterations " << iterations);
        const synth::UndergrowthSample out = run(p, deussen(iterations), &image);
        // Each species keeps the database's total within 1 % (half a plant per tile and
        // species is all error diffusion may lose).
        const std::vector<std::size_t> counts = speciesCounts(out.plants, p.world.biome.species.size());
        for (std::size_t s = 0; s < counts.size(); ++s) {
            const double expected = total * reg.speciesProportion[s];
            INFO(p.world.biome.species[s].name << ": " << counts[s] << " of " << expected);
            CHECK(std::abs(static_cast<double>(counts[s]) - expected) <= 0.01 * expected + 1);
        }
        // Per stripe: total x value / sum of values, within 2 % after the half-toning (the
        // error crosses a stripe's edge a little; measured: -1.1 %, -0.4 %, +0.7 %) and 4 %
        // after relaxation (a density step is smoothed over about a plant's spacing: measured
        // -2.5 %, -0.4 %, +0.8 %), so the plants stay in their density class.
        std::size_t stripe[4] = {0, 0, 0, 0};
        for (const Plant& q : out.plants) ++stripe[std::min(3, static_cast<int>(q.xM / 25.0))];
        const double tolerance = iterations == 0 ? 0.02 : 0.04;
        for (int k = 0; k < 4; ++k) {
            const double expected = total * value[k] / valueSum;
            INFO("stripe " << k << ": " << stripe[k] << " plants, expected " << expected);
            CHECK(std::abs(static_cast<double>(stripe[k]) - expected) <= tolerance * expected + 2);
        }
        CHECK(stripe[0] == 0);  // black: none
        CHECK(stripe[1] < stripe[2]);
        CHECK(stripe[2] < stripe[3]);
    }
}

TEST_CASE("deussen: Lloyd relaxation evens the spacing and keeps every minimum distance", "[synth][deussen]") {
    const int side = 100;
    const double margin = 10;
    Plot p = makePlot(side);
    const double factor = 2.0;
    const synth::UndergrowthSample halftoned = run(p, deussen(0, factor));
    const synth::UndergrowthSample relaxed = run(p, deussen(8, factor));
    const std::size_t ns = p.world.biome.species.size();
    const std::vector<DbHistogram>& radius = p.world.db.regions[0].crownRadius;
    int checked = 0;
    for (std::size_t s = 0; s < ns; ++s) {
        if (!(p.world.db.regions[0].speciesProportion[s] > 0)) continue;
        auto coordinates = [&](const std::vector<Plant>& plants, std::vector<double>& x, std::vector<double>& y) {
            for (const Plant& q : plants)
                if (static_cast<std::size_t>(q.speciesId) == s) {
                    x.push_back(q.xM);
                    y.push_back(q.yM);
                }
        };
        std::vector<double> hx, hy, rx, ry;
        coordinates(halftoned.plants, hx, hy);
        coordinates(relaxed.plants, rx, ry);
        // A Poisson pattern of as many points.
        std::vector<double> px, py;
        RandomStream rs(11, s, 0);
        for (std::size_t i = 0; i < rx.size(); ++i) {
            px.push_back(rs.uniform() * side);
            py.push_back(rs.uniform() * side);
        }
        const double rHalftone = clarkEvansInside(hx, hy, side, margin);
        const double rRelaxed = clarkEvansInside(rx, ry, side, margin);
        const double rPoisson = clarkEvansInside(px, py, side, margin);
        INFO(p.world.biome.species[s].name << ": Clark-Evans R Poisson " << rPoisson << ", half-toned " << rHalftone
                                           << ", relaxed " << rRelaxed << " (" << rx.size() << " plants)");
        // R = 1 for Poisson (its standard error here is about 0.26 / sqrt(n) < 0.01); a perfect
        // hexagonal lattice has 2.15. Error diffusion alone is already regular (measured
        // 1.39 .. 1.61 over the four species), relaxation more (1.86 .. 1.90): the bound 1.7
        // separates them with a margin of at least 0.09.
        CHECK(rPoisson < 1.2);
        CHECK(rHalftone < 1.7);
        CHECK(rRelaxed > 1.7);
        CHECK(rRelaxed > rHalftone + 0.15);

        // The species' minimum distance: factor x its mean crown radius in the database,
        // computed here from the histogram's bins; no pair of the relaxed plants is closer.
        const DbHistogram& h = radius[s];
        double n = 0, sum = 0;
        for (std::size_t k = 0; k < h.counts.size(); ++k) {
            n += h.counts[k];
            sum += h.counts[k] * 0.5 * (h.edges[k] + h.edges[k + 1]);
        }
        const double dMin = factor * sum / n;
        REQUIRE(dMin > 0.3);
        const PointGrid grid(rx, ry, 2.0);
        double nearest = 1e300;
        for (std::size_t i = 0; i < rx.size(); ++i)
            grid.forEachWithin(rx[i], ry[i], dMin * 2, [&](std::size_t q, double, double, double d2) {
                if (grid.order()[q] != i) nearest = std::min(nearest, std::sqrt(d2));
            });
        INFO("minimum distance " << dMin << " m, nearest pair " << nearest << " m");
        CHECK(nearest >= dMin);
        ++checked;
    }
    CHECK(checked == 4);
    // The minimum distances did bite: some dots were jittered away or moves refused.
    std::int64_t refused = 0;
    for (const auto& d : relaxed.deussen)
        for (std::int64_t r : d.refused) refused += r;
    CHECK(refused + relaxed.dartsInhibited > 0);
}

TEST_CASE("deussen: canopy trunks are obstacles and the canopy stays as given", "[synth][deussen]") {
    const int side = 60;
    Plot p = makePlot(side);
    const int redwood = p.world.biome.speciesIndex("Redwood");
    for (int j = 0; j < 2; ++j)
        for (int i = 0; i < 2; ++i) {
            Plant t;
            t.speciesId = redwood;
            t.xM = 15.0 + 30.0 * i + 1.3 * j;
            t.yM = 15.0 + 30.0 * j - 0.7 * i;
            t.groundZM = 10.0;
            t.heightM = 40.0;
            t.crownRadiusM = 6.0;
            p.canopy.push_back(t);
        }
    const std::vector<Plant> before = p.canopy;
    synth::SynthParams params = deussen(8);
    params.trunkExclusionFactor = 0.5;  // discs of 3 m
    const synth::UndergrowthSample out = run(p, params);
    REQUIRE(p.canopy.size() == before.size());
    CHECK(std::memcmp(p.canopy.data(), before.data(), before.size() * sizeof(Plant)) == 0);
    std::size_t nearDisc = 0, inside = 0, tallerThanCrown = 0;
    double closest = 1e300;
    for (const Plant& q : out.plants)
        for (const Plant& t : p.canopy) {
            const double d = std::hypot(q.xM - t.xM, q.yM - t.yM);
            closest = std::min(closest, d);
            inside += d < params.trunkExclusionFactor * t.crownRadiusM;
            nearDisc += d < params.trunkExclusionFactor * t.crownRadiusM + 1.0;
            // Heights never above a crown over the plant (the structured sampler's size draw).
            tallerThanCrown += d <= t.crownRadiusM && !(q.heightM < t.heightM);
        }
    INFO(out.plants.size() << " plants; the nearest " << closest << " m from a trunk; " << nearDisc
                           << " within 1 m of a disc's edge");
    CHECK(inside == 0);
    CHECK(tallerThanCrown == 0);
    // Plants stand up to the discs (within 1 m of their edge), not in a wide empty ring:
    // the four rings of 1 m hold about 4 x pi x (4^2 - 3^2) x 1.2 = 106 plants at the mean density.
    CHECK(nearDisc > 40);
}

TEST_CASE("deussen: the same plants with 1 and 2 threads", "[synth][deussen]") {
    Plot p = makePlot(80);
    Plant t;
    t.speciesId = p.world.biome.speciesIndex("Redwood");
    t.xM = 33.3;
    t.yM = 41.7;
    t.groundZM = 10.0;
    t.heightM = 30.0;
    t.crownRadiusM = 5.0;
    p.canopy.push_back(t);
    Grid<float> image = Grid<float>::like(p.terrain, 0.0f);
    for (int iy = 0; iy < 80; ++iy)
        for (int ix = 0; ix < 80; ++ix) image(ix, iy) = static_cast<float>(0.1 + 0.9 * std::sin(0.07 * ix) * std::sin(0.05 * iy) * std::sin(0.07 * ix) * std::sin(0.05 * iy));
    synth::SynthParams params = deussen(4);
    params.deussen.halftoneTileM = 25;  // several tiles
    const int threadsBefore = omp_get_max_threads();
    std::vector<std::vector<Plant>> results;
    for (int threads : {1, 2}) {
        omp_set_num_threads(threads);
        results.push_back(run(p, params, &image).plants);
    }
    omp_set_num_threads(threadsBefore);
    REQUIRE(results[0].size() == results[1].size());
    REQUIRE(!results[0].empty());
    bool same = true;
    for (std::size_t i = 0; i < results[0].size(); ++i) {
        const Plant &a = results[0][i], &b = results[1][i];
        same = same && a.speciesId == b.speciesId && std::memcmp(&a.xM, &b.xM, sizeof(double)) == 0 &&
               std::memcmp(&a.yM, &b.yM, sizeof(double)) == 0 && std::memcmp(&a.heightM, &b.heightM, sizeof(double)) == 0 &&
               std::memcmp(&a.crownRadiusM, &b.crownRadiusM, sizeof(double)) == 0 &&
               std::memcmp(&a.groundZM, &b.groundZM, sizeof(double)) == 0;
    }
    CHECK(same);
    // Another seed: another pattern.
    params.seed += 1;
    const std::vector<Plant> other = run(p, params, &image).plants;
    CHECK((other.size() != results[0].size() || std::memcmp(&other[0].xM, &results[0][0].xM, sizeof(double)) != 0));
}

TEST_CASE("deussen: parameters, the density image's checks and the method's name", "[synth][deussen]") {
    test::checkParamTable(
        synth::deussenParamFields(), "docs/synth.md", [](const synth::DeussenParams& d) { d.validate(); },
        [](const synth::DeussenParams& d) { return d.asParameters(); }, 10);
    CHECK(synth::parseSynthMethod("deussen") == synth::SynthMethod::Deussen);
    CHECK(std::string(synth::toString(synth::SynthMethod::Deussen)) == "deussen");
    CHECK_THROWS_WITH(synth::parseSynthMethod("halftone"), Catch::Contains("'halftone'") && Catch::Contains("deussen"));
    // Recorded only with the Deussen method, so the other methods' scene files stay as they were.
    synth::SynthParams params;
    auto hasKey = [](const synth::SynthParams& q) {
        for (const auto& [k, v] : q.asParameters())
            if (k == "deussen_lloyd_iterations") return true;
        return false;
    };
    CHECK_FALSE(hasKey(params));
    params.method = synth::SynthMethod::Deussen;
    CHECK(hasKey(params));
    // An image of another geometry, or with another method, is refused.
    Plot p = makePlot(20);
    const Grid<float> small(10, 20, 1.0, 0.0, 0.0, 1.0f);
    CHECK_THROWS_WITH(run(p, deussen(1), &small), Catch::Contains("density image") && Catch::Contains("geometry"));
    const Grid<float> fine = Grid<float>::like(p.terrain, 1.0f);
    synth::SynthParams structured;
    CHECK_THROWS_WITH(run(p, structured, &fine), Catch::Contains("density image") && Catch::Contains("'structured'"));

    // A float TIFF: values as stored (any scale); a negative one is refused with its pixel.
    test::TempDir dir("deussen_image");
    const std::string tif = dir.file("density.tif");
    auto writeTif = [&](float at23) {
        std::vector<float> px(static_cast<std::size_t>(20 * 20), 3.0f);
        px[static_cast<std::size_t>(2 * 20 + 1)] = at23;  // column 2, row 3 (row 1 = north)
        REQUIRE(test::writeImage(tif, 20, 20, 1, SampleType::Float, SampleType::Float, px.data()));
    };
    writeTif(7.0f);
    const Grid<float> read = synth::readDensityImage(tif, p.terrain);
    CHECK(read(1, 17) == 7.0f);  // row 3 from the north of 20
    CHECK(read(0, 0) == 3.0f);
    writeTif(-1.0f);
    CHECK_THROWS_WITH(synth::readDensityImage(tif, p.terrain),
                      Catch::Contains("density.tif") && Catch::Contains("column 2, row 3") && Catch::Contains("-1"));
}
