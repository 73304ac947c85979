// Approximate instancing (synth/instancing.h, issue 29 item 2): prototypes found where the
// sizes cluster, exact when K covers every distinct size, errors that fall with K, species
// never mixed, the same bits for any thread count.
#include <catch2/catch.hpp>

#include <omp.h>

#include <cmath>
#include <set>

#include "instancing.h"
#include "rng.h"

using namespace eco;
using namespace eco::synth;

namespace {

Plant plant(int species, double h, double r, double x = 0) {
    Plant p;
    p.speciesId = species;
    p.xM = x;
    p.yM = 2 * x;
    p.heightM = h;
    p.crownRadiusM = r;
    return p;
}

}  // namespace

TEST_CASE("instancing: three size classes give three prototypes at their geometric means", "[instancing]") {
    std::vector<Plant> plants;
    // Classes around 0.1, 1 and 10 m, each plant within +-2 % of its class (log-symmetric).
    RandomStream rs(5, 0);
    for (int i = 0; i < 300; ++i) {
        const double h = std::pow(10.0, (i % 3) - 1) * std::exp(rs.uniform(-0.02, 0.02));
        plants.push_back(plant(0, h, 0.3 * h, i));
    }
    InstancingParams p;
    p.prototypesPerSpecies = 3;
    p.weightByCrownArea = false;
    const InstancingResult r = quantisePlants(plants, 1, p);
    REQUIRE(r.prototypes.size() == 3);
    CHECK(r.prototypes[0].heightM == Approx(0.1).epsilon(0.01));
    CHECK(r.prototypes[1].heightM == Approx(1.0).epsilon(0.01));
    CHECK(r.prototypes[2].heightM == Approx(10.0).epsilon(0.01));
    for (const Prototype& q : r.prototypes) CHECK(q.count == 100);
    CHECK(r.error.maxUnscaled < 0.05);
    // The scale brings every instance to its plant's height; the shape is exact (r = 0.3 h).
    for (std::size_t i = 0; i < plants.size(); ++i) {
        const Instance& in = r.instances[i];
        CHECK(r.prototypes[static_cast<std::size_t>(in.prototype)].heightM * in.scale == Approx(plants[i].heightM));
        CHECK(in.rotationDeg >= 0);
        CHECK(in.rotationDeg < 360);
        CHECK(in.xM == plants[i].xM);
    }
    CHECK(r.error.maxScaled < 1e-9);
}

TEST_CASE("instancing: exact when K covers the distinct sizes, errors fall with K, species apart", "[instancing]") {
    std::vector<Plant> plants;
    RandomStream rs(9, 1);
    for (int i = 0; i < 2000; ++i) {
        const int species = i % 2;
        const double h = std::exp(rs.uniform(std::log(0.05), std::log(20.0)));
        plants.push_back(plant(species, h, h * rs.uniform(0.2, 0.6), i));
    }
    // Five distinct sizes of species 2: K = 5 is exact.
    for (int i = 0; i < 50; ++i) plants.push_back(plant(2, 1.0 + i % 5, 0.5, 3000 + i));
    InstancingParams p;
    p.prototypesPerSpecies = 5;
    const InstancingResult exact = quantisePlants(plants, 3, p);
    CHECK(exact.errorBySpecies[2].maxUnscaled == Approx(0).margin(1e-12));
    std::set<int> speciesOfPrototype;
    for (std::size_t i = 0; i < plants.size(); ++i)
        CHECK(exact.prototypes[static_cast<std::size_t>(exact.instances[i].prototype)].speciesId == plants[i].speciesId);
    double previous = 1e300, first = 0;
    for (const int k : {1, 2, 4, 8, 16, 32}) {
        p.prototypesPerSpecies = k;
        p.weightByCrownArea = false;
        const InstancingResult r = quantisePlants(plants, 3, p);
        INFO("K = " << k);
        CHECK(r.error.meanUnscaled < previous);
        previous = r.error.meanUnscaled;
        if (k == 1) first = previous;
        CHECK(r.prototypes.size() <= static_cast<std::size_t>(2 * k + std::min(k, 5)));
    }
    // 32 prototypes over a 400-fold height range and a 3-fold crown shape: cells of about
    // 0.45 in log units, a mean error near 15 %, a tenth of one prototype's.
    CHECK(previous < 0.2);
    CHECK(previous < 0.1 * first);
}

TEST_CASE("instancing: the same bits with 1 and 2 threads, refusals", "[instancing]") {
    std::vector<Plant> plants;
    RandomStream rs(3, 2);
    for (int i = 0; i < 5000; ++i) {
        const double h = std::exp(rs.uniform(-3, 3));
        plants.push_back(plant(i % 4, h, h * rs.uniform(0.1, 1.0), i));
    }
    InstancingParams p;
    p.prototypesPerSpecies = 6;
    const int threads = omp_get_max_threads();
    omp_set_num_threads(1);
    const InstancingResult one = quantisePlants(plants, 4, p);
    omp_set_num_threads(2);
    const InstancingResult two = quantisePlants(plants, 4, p);
    omp_set_num_threads(threads);
    REQUIRE(one.prototypes.size() == two.prototypes.size());
    for (std::size_t i = 0; i < one.prototypes.size(); ++i) {
        CHECK(one.prototypes[i].heightM == two.prototypes[i].heightM);
        CHECK(one.prototypes[i].crownRadiusM == two.prototypes[i].crownRadiusM);
    }
    for (std::size_t i = 0; i < plants.size(); ++i) {
        CHECK(one.instances[i].prototype == two.instances[i].prototype);
        CHECK(one.instances[i].rotationDeg == two.instances[i].rotationDeg);
    }
    CHECK(one.error.meanUnscaled == two.error.meanUnscaled);

    std::vector<Plant> bad = plants;
    bad[7].heightM = 0;
    CHECK_THROWS_WITH(quantisePlants(bad, 4, p), Catch::Contains("plant 7") && Catch::Contains("no size"));
    p.prototypesPerSpecies = 0;
    CHECK_THROWS_AS(quantisePlants(plants, 4, p), ValidationError);
}
