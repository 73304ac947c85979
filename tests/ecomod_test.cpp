// The EcoMod model (sim/ecomod.h): the height polyline, the suitabilities, domination between
// two constructed trees and among hundreds (against a brute-force search), under-dispersion
// seeding statistics, determinism across thread counts and checkpoint / resume, the step's
// caches and set-aside against plain yearly runs, and the refusal of bad parameters.
#include <catch2/catch.hpp>
#include <omp.h>

#include <cmath>
#include <cstring>
#include <limits>

#include "abiotics_fixture.h"
#include "cpu.h"
#include "ecomod.h"
#include "error.h"
#include "sim_config.h"
#include "sim_run.h"
#include "sim_scene_fixture.h"
#include "simulator.h"
#include "test_util.h"

using namespace eco;
using namespace eco::sim;

namespace {

// A flat, uniform scene of `sizeM` metres in 1 m cells (the suitability is the same everywhere).
Abiotics flatAbiotics(int sizeM) {
    return test::uniformAbiotics(Grid<float>(sizeM, sizeM, 1.0, 0, 0, 0.f), 50,
                                 {{Factor::Sun, 8},
                                  {Factor::Moisture, 60},
                                  {Factor::Temperature, 15},
                                  {Factor::Slope, 0},
                                  {Factor::Wind, 3}});
}

// The Sonoma biome with every species made indifferent to the site (v = 1 everywhere), no
// seeds and no immigrants: only what a test sets happens.
Biome quietBiome() {
    Biome b = defaultBiome();
    for (Species& s : b.species) {
        EcoModSpecies& e = s.ecomod;
        e.elevationTol = e.moistureTol = e.sunTol = e.windTol = 1e9;
        e.slopeHarm = 0;
        e.seedsPerYear = 0;
        e.immigrantsPerHaYear = 0;
    }
    return b;
}

SimParams ecomodParams() {
    SimParams p;
    p.kind = ModelKind::EcoMod;
    return p;
}

SimInputs flatScene(const Biome& b, int sizeM) {
    SimInputs in;
    in.biome = b;
    in.abiotics = flatAbiotics(sizeM);
    return in;
}

UndergrowthPlant tree(int species, double x, double y, double h, double ageYears = 0) {
    UndergrowthPlant p;
    p.speciesId = species;
    p.xM = x;
    p.yM = y;
    p.heightM = h;
    p.ageYears = ageYears;
    return p;
}

bool samePlants(const std::vector<UndergrowthPlant>& a, const std::vector<UndergrowthPlant>& b) {
    if (a.size() != b.size()) return false;
    for (std::size_t i = 0; i < a.size(); ++i) {
        const auto& p = a[i];
        const auto& q = b[i];
        if (p.id != q.id || p.speciesId != q.speciesId || std::memcmp(&p.xM, &q.xM, sizeof(double)) != 0 ||
            std::memcmp(&p.yM, &q.yM, sizeof(double)) != 0 || std::memcmp(&p.heightM, &q.heightM, sizeof(double)) != 0 ||
            std::memcmp(&p.growthAgeYears, &q.growthAgeYears, sizeof(double)) != 0 || p.ageYears != q.ageYears)
            return false;
    }
    return true;
}

// The same trees (bits), census (counts, mean heights and vigours, bits) and counters.
bool sameRun(const Simulation& a, const Simulation& b) {
    const YearRecord ra = a.census(), rb = b.census();
    return samePlants(a.plants(), b.plants()) && ra.count == rb.count &&
           std::memcmp(ra.meanVigour.data(), rb.meanVigour.data(), ra.meanVigour.size() * sizeof(double)) == 0 &&
           std::memcmp(ra.meanHeightM.data(), rb.meanHeightM.data(), ra.meanHeightM.size() * sizeof(double)) == 0 &&
           a.counters().diedDominated == b.counters().diedDominated &&
           a.counters().diedBackgroundOrStress == b.counters().diedBackgroundOrStress &&
           a.counters().plantMonths == b.counters().plantMonths && a.counters().germinated == b.counters().germinated;
}

}  // namespace

TEST_CASE("ecomod: the height polyline passes through its control points", "[sim][ecomod]") {
    EcoModSpeciesParams p;
    p.maturityAgeYears = 10;
    p.fullGrownAgeYears = 40;
    p.maxAgeYears = 100;
    p.matureHeightM = 6;
    p.fullHeightM = 10;
    CHECK(ecomodPolylineHeightM(p, 0) == 0);
    CHECK(ecomodPolylineHeightM(p, 5) == Approx(3));
    CHECK(ecomodPolylineHeightM(p, 10) == Approx(6));
    CHECK(ecomodPolylineHeightM(p, 25) == Approx(8));
    CHECK(ecomodPolylineHeightM(p, 40) == Approx(10));
    CHECK(ecomodPolylineHeightM(p, 90) == Approx(10));
    // Young trees grow faster (0.6 m/year) than old ones (0.133 m/year).
    CHECK(ecomodPolylineHeightM(p, 2) - ecomodPolylineHeightM(p, 1) > ecomodPolylineHeightM(p, 21) - ecomodPolylineHeightM(p, 20));
    CHECK(ecomodPolylineAgeYears(p, 3) == Approx(5));
    CHECK(ecomodPolylineAgeYears(p, 8) == Approx(25));
    CHECK(ecomodPolylineAgeYears(p, 12) == Approx(40));
}

TEST_CASE("ecomod: suitabilities of Eqs. 3-7", "[sim][ecomod]") {
    CHECK(ecomodDeviationSuitability(52, 50, 3, 0.1) == 1.0);          // within the tolerance
    CHECK(ecomodDeviationSuitability(55, 50, 3, 0.1) == Approx(0.5));  // 1 - 5 x 0.1
    CHECK(ecomodDeviationSuitability(80, 50, 3, 0.1) == 0.0);          // clamped at 0
    CHECK(ecomodSlopeSuitability(0, 2) == 1.0);
    CHECK(ecomodSlopeSuitability(60, 1) == Approx(0.75));  // 1 - (1 - cos 60)^2
    CHECK(ecomodSlopeSuitability(90, 2) == 0.0);
}

TEST_CASE("ecomod: a lone tree follows its polyline and dies between full-grown and maximum age", "[sim][ecomod]") {
    Biome b = quietBiome();
    const int s = b.speciesIndex("Toyon");
    Species& sp = b.species[static_cast<std::size_t>(s)];
    sp.ecomod.maturityAgeYears = 10;
    sp.ecomod.fullGrownAgeYears = 20;
    sp.ecomod.maxAgeYears = 30;
    sp.ecomod.matureHeightM = 4;
    sp.ecomod.fullHeightM = 6;
    Simulation sim(flatScene(b, 20), ecomodParams(), 3, {tree(s, 10, 10, 0.4)});  // growth age 1 from its height
    for (int y = 1; y <= 15; ++y) {
        sim.stepYear();
        REQUIRE(sim.plantCount() == 1);
        const UndergrowthPlant p = sim.plants()[0];
        CHECK(p.growthAgeYears == Approx(1 + y));
        CHECK(p.heightM == Approx(y + 1 <= 10 ? 0.4 * (y + 1) : 4 + 0.2 * (y + 1 - 10)));
        CHECK(p.crownRadiusM == Approx(sp.allometry.crownRadiusM(p.heightM)));
    }
    int diedAt = -1;
    for (int y = 16; y <= 31 && diedAt < 0; ++y) {
        sim.stepYear();
        if (sim.plantCount() == 0) diedAt = y;
    }
    // The initial tree is aged by its growth age (1 year), so it dies at an age in [20, 30].
    CHECK(diedAt >= 19);
    CHECK(diedAt <= 30);
    CHECK(sim.counters().diedBackgroundOrStress == 1);
}

TEST_CASE("ecomod: of two overlapping trees the more able dominates the other", "[sim][ecomod]") {
    Biome b = quietBiome();
    const int tall = b.speciesIndex("Coast Live Oak"), small = b.speciesIndex("Toyon");
    for (int s : {tall, small}) {
        EcoModSpecies& e = b.species[static_cast<std::size_t>(s)].ecomod;
        e.persistence = 0.8;
        e.dominatedGrowth = 0;
    }
    SECTION("dominated trees do not grow; the dominant one does") {
        for (int s : {tall, small}) b.species[static_cast<std::size_t>(s)].ecomod.dominatedSurvival = 1;
        // 8 m and 3 m apart by 2 m: crowns (about 1.7 m and 1.3 m) overlap; a = h / h_max x 0.8 x 1.
        Simulation sim(flatScene(b, 20), ecomodParams(), 1, {tree(tall, 10, 10, 8), tree(small, 12, 10, 3)});
        for (int y = 0; y < 5; ++y) sim.stepYear();
        const auto plants = sim.plants();
        REQUIRE(plants.size() == 2);
        CHECK(plants[0].heightM > 8);           // undominated: grew
        CHECK(plants[1].heightM == Approx(3));  // dominated: growth obstructed
        CHECK(plants[1].growthAgeYears == Approx(ecomodPolylineAgeYears(sim.ecomod()->speciesParams()[small], 3)));
    }
    SECTION("a dominated tree without persistence dies in the first year; the victor lives") {
        b.species[static_cast<std::size_t>(small)].ecomod.dominatedSurvival = 0;
        Simulation sim(flatScene(b, 20), ecomodParams(), 1, {tree(tall, 10, 10, 8), tree(small, 12, 10, 3)});
        sim.stepYear();
        REQUIRE(sim.plantCount() == 1);
        CHECK(sim.plants()[0].speciesId == tall);
        CHECK(sim.counters().diedDominated == 1);
    }
    SECTION("persistence decides between trees of equal height") {
        b.species[static_cast<std::size_t>(small)].ecomod.fullHeightM = 25;  // Toyon may grow as tall here
        b.species[static_cast<std::size_t>(small)].ecomod.persistence = 0.9;  // a = h / h_max x 0.9 > 0.8
        b.species[static_cast<std::size_t>(tall)].ecomod.dominatedSurvival = 0;
        Simulation sim(flatScene(b, 20), ecomodParams(), 1, {tree(tall, 10, 10, 5), tree(small, 11, 10, 5)});
        sim.stepYear();
        REQUIRE(sim.plantCount() == 1);
        CHECK(sim.plants()[0].speciesId == small);
    }
    SECTION("a seedling held under a full-grown tree grows once that tree is gone") {
        // The seedling (height 0, no dominated growth) under a full-grown oak stays dominated
        // while the oak lives; once it is removed (here by the disturbance hook) nothing holds
        // it: a guard for any shortcut that keeps such seedlings aside while their dominator lives.
        b.species[static_cast<std::size_t>(tall)].ecomod.fullHeightM = 20;
        b.species[static_cast<std::size_t>(tall)].ecomod.maxAgeYears = 1000;  // it does not die of age here
        b.species[static_cast<std::size_t>(small)].ecomod.dominatedSurvival = 1;
        Simulation sim(flatScene(b, 20), ecomodParams(), 1, {tree(tall, 10, 10, 20), tree(small, 10.5, 10, 0)});
        for (int y = 0; y < 4; ++y) sim.stepYear();
        REQUIRE(sim.plantCount() == 2);
        CHECK(sim.plants()[1].heightM == 0);  // dominated every year
        CHECK(sim.plants()[1].ageYears == 4);
        REQUIRE(sim.ecomod() != nullptr);
        CHECK(sim.ecomod()->removeTrees({1, 0}) == 1);
        sim.stepYear();
        REQUIRE(sim.plantCount() == 1);
        CHECK(sim.plants()[0].heightM > 0);  // free: grew
    }
    SECTION("trees whose neighbourhoods do not intersect both grow") {
        for (int s : {tall, small}) b.species[static_cast<std::size_t>(s)].ecomod.dominatedSurvival = 0;
        Simulation sim(flatScene(b, 20), ecomodParams(), 1, {tree(tall, 5, 10, 8), tree(small, 15, 10, 3)});
        sim.stepYear();
        REQUIRE(sim.plantCount() == 2);
        CHECK(sim.plants()[1].heightM > 3);
    }
}

TEST_CASE("ecomod: dominated seedlings survive each year with probability dominated_survival", "[sim][ecomod]") {
    // 2025 seedlings of height 0 under one full-grown oak: dominated every year, they die at
    // the rate of dominated_survival = 0.8 a year (the first year in the store's pass, the
    // next ones set aside): after k years N 0.8^k of them are left, within 4 binomial SDs.
    Biome b = quietBiome();
    const int oak = b.speciesIndex("Coast Live Oak"), toyon = b.speciesIndex("Toyon");
    EcoModSpecies& o = b.species[static_cast<std::size_t>(oak)].ecomod;
    o.fullHeightM = 20;
    o.maxAgeYears = 1000;  // no death of age here
    EcoModSpecies& t = b.species[static_cast<std::size_t>(toyon)].ecomod;
    t.dominatedSurvival = 0.8;
    t.dominatedGrowth = 0;
    t.maturityAgeYears = 50;  // neither mature nor dead of age within the test
    t.fullGrownAgeYears = 60;
    t.maxAgeYears = 200;
    std::vector<UndergrowthPlant> initial{tree(oak, 20, 20, 20)};
    for (int i = 0; i < 45; ++i)
        for (int j = 0; j < 45; ++j) initial.push_back(tree(toyon, 19.56 + 0.02 * i, 19.56 + 0.02 * j, 0));
    const double n = 45 * 45;
    Simulation sim(flatScene(b, 40), ecomodParams(), 3, initial);
    for (int k = 1; k <= 8; ++k) {
        sim.stepYear();
        const double p = std::pow(0.8, k), left = static_cast<double>(sim.plantCount()) - 1;
        INFO("year " << k << ": " << left << " seedlings left, expected " << n * p);
        CHECK(std::abs(left - n * p) < 4 * std::sqrt(n * p * (1 - p)));
        CHECK(sim.counters().diedDominated == static_cast<std::int64_t>(n - left));
    }
    REQUIRE(sim.ecomod() != nullptr);
    CHECK(sim.ecomod()->setAsideCount() > 0);  // the set-aside path was taken
    CHECK(sim.plants()[0].speciesId == oak);
}

// Sets the kernels' form for a test's scope and restores the processor's default after.
struct Avx2Scope {
    explicit Avx2Scope(bool on) { setAvx2Kernels(on); }
    ~Avx2Scope() { setAvx2Kernels(true); }
};

TEST_CASE("ecomod: the domination test agrees with a brute-force search over every pair", "[sim][ecomod]") {
    // Hundreds of trees of several species, many of height 0 (seedlings, which cannot dominate),
    // crowds and gaps, and static canopy trees; nobody dies of domination, so that each year's
    // outcome shows in the growth ages: a dominated tree keeps its growth age, the others gain a year.
    // Both forms of the search: AVX2 (where the processor has it) and the baseline.
    const bool avx2 = GENERATE(true, false);
    const Avx2Scope form(avx2);
    INFO("AVX2 search " << (avx2Kernels() ? "on" : "off"));
    Biome b = quietBiome();
    for (Species& s : b.species) {
        s.ecomod.dominatedGrowth = 0;
        s.ecomod.dominatedSurvival = 1;
        s.ecomod.maxAgeYears = 1000;  // no natural deaths in these years
        s.ecomod.fullGrownAgeYears = 500;
    }
    const int nsp = static_cast<int>(b.species.size());
    std::vector<UndergrowthPlant> initial;
    std::uint64_t state = 12345;
    auto uniform = [&state] {
        state = state * 6364136223846793005ull + 1442695040888963407ull;
        return static_cast<double>(state >> 11) * 0x1.0p-53;
    };
    for (int i = 0; i < 500; ++i) {
        const int s = static_cast<int>(uniform() * nsp) % nsp;
        const double h = uniform() < 0.4 ? 0.0 : uniform() * 0.5 * b.species[static_cast<std::size_t>(s)].maxHeightM;
        initial.push_back(tree(s, 1 + 58 * uniform(), 1 + 58 * uniform(), h));
    }
    SimInputs in = flatScene(b, 60);
    for (int c = 0; c < 6; ++c) {
        Plant t;
        t.speciesId = c % nsp;
        t.xM = 5 + 10 * c;
        t.yM = 30;
        t.heightM = 4 + 3 * c;
        t.crownRadiusM = 1 + c;
        in.canopy.push_back(t);
    }
    Simulation sim(in, ecomodParams(), 3, initial);
    const auto& params = sim.ecomod()->speciesParams();
    double hRef = 0;
    for (const auto& p : params) hRef = std::max(hRef, p.fullHeightM);
    std::size_t dominatedSeen = 0, freeSeen = 0, seedlingsDominated = 0;
    for (int year = 0; year < 3; ++year) {
        const std::vector<UndergrowthPlant> before = sim.plants();
        std::vector<bool> dominated(before.size(), false);
        for (std::size_t i = 0; i < before.size(); ++i) {
            const UndergrowthPlant& p = before[i];
            auto beats = [&](double qx, double qy, double qr, double qa) {
                const double dx = p.xM - qx, dy = p.yM - qy, rr = p.crownRadiusM + qr;
                return p.pool < qa && dx * dx + dy * dy < rr * rr;
            };
            for (std::size_t j = 0; j < before.size() && !dominated[i]; ++j)
                dominated[i] = j != i && beats(before[j].xM, before[j].yM, before[j].crownRadiusM, before[j].pool);
            for (const Plant& t : sim.relevantCanopy()) {
                const double a = t.heightM / hRef * params[static_cast<std::size_t>(t.speciesId)].persistence * 1.0;
                if (!dominated[i]) dominated[i] = beats(t.xM, t.yM, t.crownRadiusM, a);
            }
        }
        sim.stepYear();
        const std::vector<UndergrowthPlant> after = sim.plants();
        REQUIRE(after.size() == before.size());  // nobody died, and seeding is off
        for (std::size_t i = 0; i < before.size(); ++i) {
            REQUIRE(after[i].id == before[i].id);
            INFO("year " << year << ", tree " << before[i].id << " at (" << before[i].xM << ", " << before[i].yM
                         << "), height " << before[i].heightM);
            CHECK(after[i].growthAgeYears == before[i].growthAgeYears + (dominated[i] ? 0.0 : 1.0));
            (dominated[i] ? dominatedSeen : freeSeen) += 1;
            if (dominated[i] && before[i].heightM == 0) ++seedlingsDominated;
        }
    }
    // The scene tests both outcomes, seedlings among the dominated.
    CHECK(dominatedSeen > 200);
    CHECK(freeSeen > 100);
    CHECK(seedlingsDominated > 50);
}

TEST_CASE("ecomod: under-dispersion puts the share p_s of new trees near their parent, uniformly in its disc",
          "[sim][ecomod]") {
    // One mature parent in the centre of 100 m x 100 m, 2000 seeds establishing everywhere
    // (v = 1), p_s = 0.7, dispersal radius 10 m. A far seed lands within 10 m of the parent
    // with probability pi 10^2 / 100^2, so the count within 10 m is binomial with
    // p = 0.7 + 0.3 x 0.0314; it must lie within 4 standard deviations (significance 6e-5).
    Biome b = quietBiome();
    const int s = b.speciesIndex("Toyon");
    EcoModSpecies& e = b.species[static_cast<std::size_t>(s)].ecomod;
    e.maturityAgeYears = 5;
    e.fullGrownAgeYears = 100;
    e.maxAgeYears = 200;
    e.seedsPerYear = 2000;
    e.germination = 1;
    e.nearProbability = 0.7;
    e.dispersalRadiusM = 10;
    e.dominatedSurvival = 1;  // the seedlings under the parent survive the year
    const double cx = 50, cy = 50;
    Simulation sim(flatScene(b, 100), ecomodParams(), 7, {tree(s, cx, cy, 5, 50)});
    sim.stepYear();
    const auto plants = sim.plants();
    REQUIRE(plants.size() == 2001);
    int near = 0;
    int rings[4] = {0, 0, 0, 0};  // equal-area rings of the 10 m disc
    int cells[4][4] = {};         // each ring cut into its four quadrants round the parent
    for (std::size_t i = 1; i < plants.size(); ++i) {
        const double dx = plants[i].xM - cx, dy = plants[i].yM - cy, d2 = dx * dx + dy * dy;
        if (d2 < 100) {
            ++near;
            const int ring = std::min(3, static_cast<int>(d2 / 25));
            ++rings[ring];
            ++cells[ring][(dx < 0 ? 1 : 0) + (dy < 0 ? 2 : 0)];
        }
    }
    const double p = 0.7 + 0.3 * 3.14159265358979 * 100 / 10000;
    const double mean = 2000 * p, sd = std::sqrt(2000 * p * (1 - p));
    CHECK(std::fabs(near - mean) < 4 * sd);
    // Uniform in the disc: chi-square over the four equal-area rings, 3 degrees of freedom,
    // critical value 16.27 at significance 0.001.
    double chi2 = 0;
    for (int r : rings) chi2 += (r - near / 4.0) * (r - near / 4.0) / (near / 4.0);
    CHECK(chi2 < 16.27);
    // And in angle: chi-square over the 16 equal-area cells (rings x quadrants), 15 degrees of
    // freedom, critical value 37.70 at significance 0.001.
    double chi2Cells = 0;
    for (const auto& ring : cells)
        for (int c : ring) chi2Cells += (c - near / 16.0) * (c - near / 16.0) / (near / 16.0);
    CHECK(chi2Cells < 37.70);
    // Without under-dispersion the same count falls to the far seeds' share.
    e.nearProbability = 0;
    Simulation uniform(flatScene(b, 100), ecomodParams(), 7, {tree(s, cx, cy, 5, 50)});
    uniform.stepYear();
    int nearUniform = 0;
    for (const auto& q : uniform.plants())
        if ((q.xM - cx) * (q.xM - cx) + (q.yM - cy) * (q.yM - cy) < 100) ++nearUniform;
    const double p0 = 3.14159265358979 * 100 / 10000;
    CHECK(std::fabs((nearUniform - 1) - 2000 * p0) < 4 * std::sqrt(2000 * p0 * (1 - p0)));
}

TEST_CASE("ecomod: seedlings establish only where the site suits them", "[sim][ecomod]") {
    // Immigrants over a scene whose left half is too dry for the species: none establish there.
    Biome b = quietBiome();
    const int s = b.speciesIndex("Toyon");
    EcoModSpecies& e = b.species[static_cast<std::size_t>(s)].ecomod;
    e.moistureOpt = 60;
    e.moistureTol = 5;
    e.moistureHarm = 0.1;
    e.immigrantsPerHaYear = 4000;
    SimInputs in = flatScene(b, 50);
    for (auto& g : in.abiotics.moistureMm.months)
        for (int iy = 0; iy < 50; ++iy)
            for (int ix = 0; ix < 25; ++ix) g(ix, iy) = 10.f;
    Simulation sim(std::move(in), ecomodParams(), 2);
    sim.stepYear();
    int left = 0, right = 0;
    for (const auto& p : sim.plants()) (p.xM < 25 ? left : right)++;
    CHECK(left == 0);
    CHECK(right > 300);  // 1000 arrivals, about half on the right
}

TEST_CASE("ecomod: the same bytes for any thread count and after a checkpoint and resume", "[sim][ecomod][checkpoint]") {
    test::TempDir dir("ecomodresume");
    SimInputs in = test::smallDemoScene();
    const SimParams params = ecomodParams();
    setParallelThresholds(0, 0);  // the parallel paths even on this small scene
    const int threadsBefore = omp_get_max_threads();
    omp_set_num_threads(1);
    Simulation one(in, params, 5);
    for (int y = 0; y < 25; ++y) one.stepYear();
    omp_set_num_threads(std::max(2, threadsBefore));
    Simulation two(in, params, 5);
    for (int y = 0; y < 25; ++y) two.stepYear();
    CHECK(one.plantCount() > 100);
    CHECK(samePlants(one.plants(), two.plants()));

    Simulation first(in, params, 5);
    for (int y = 0; y < 11; ++y) first.stepYear();
    {
        auto f = h5::File::create(dir.file("state.h5"));
        first.saveState(f, "/state");
    }
    Simulation resumed(in, params, 5);
    {
        auto f = h5::File::openRead(dir.file("state.h5"));
        resumed.loadState(f, "/state");
    }
    CHECK(resumed.yearsDone() == 11);
    for (int y = 11; y < 25; ++y) resumed.stepYear();
    CHECK(samePlants(two.plants(), resumed.plants()));
    CHECK(two.counters().germinated == resumed.counters().germinated);
    CHECK(two.counters().diedDominated == resumed.counters().diedDominated);
    setParallelThresholds(kDefaultParallelPlants, kDefaultParallelCells);
    omp_set_num_threads(threadsBefore);

    // Another seed is another run, and a monthly run refuses an ecomod checkpoint.
    Simulation other(in, params, 6);
    auto f = h5::File::openRead(dir.file("state.h5"));
    CHECK_THROWS_WITH(other.loadState(f, "/state"), Catch::Contains("another run"));
    SimInputs small = test::smallDemoScene();
    small.area = SimArea{10, 10, 20, 20};
    Simulation monthly(small, SimParams{}, 5);
    CHECK_THROWS_WITH(monthly.loadState(f, "/state"), Catch::Contains("ecomod"));
}

TEST_CASE("ecomod: setting the suppressed seedlings aside changes no tree, census or counter", "[sim][ecomod]") {
    // The same run twice: once as it is, once with every set-aside seedling brought back into
    // the store after each year (removeTrees of nothing), so that each is tested, drawn and
    // aged by the store's pass every year instead of from its draws made ahead.
    SimInputs in = test::smallDemoScene();
    const SimParams params = ecomodParams();
    Simulation asleep(in, params, 7), awake(in, params, 7);
    REQUIRE(asleep.ecomod() != nullptr);
    REQUIRE(awake.ecomod() != nullptr);
    std::size_t maxAside = 0;
    bool same = true;
    for (int y = 0; y < 40 && same; ++y) {
        asleep.stepYear();
        awake.stepYear();
        maxAside = std::max(maxAside, asleep.ecomod()->setAsideCount());
        awake.ecomod()->removeTrees(std::vector<std::uint8_t>(awake.plantCount(), 0));
        CHECK(awake.ecomod()->setAsideCount() == 0);
        same = sameRun(asleep, awake);
        INFO("year " << y + 1);
        CHECK(same);
    }
    CHECK(maxAside > 50);  // the set-aside was exercised
    CHECK(asleep.plantCount() > 100);
}

TEST_CASE("ecomod: dozing dominated trees change no tree, census or counter", "[sim][ecomod]") {
    // The same run twice: once as it is, once with dozing off (every dominated tree of height
    // > 0 in the store's passes each year). Over 80 years trees doze, their witnesses die,
    // they are tested again, wake and grow, die of their lives or age, and dozers are the
    // witnesses and parents of others.
    SimInputs in = test::smallDemoScene();
    const SimParams params = ecomodParams();
    Simulation dozing(in, params, 11), awake(in, params, 11);
    REQUIRE(dozing.ecomod() != nullptr);
    REQUIRE(awake.ecomod() != nullptr);
    awake.ecomod()->setDozing(false);
    std::size_t maxDozing = 0;
    bool same = true;
    for (int y = 0; y < 80 && same; ++y) {
        dozing.stepYear();
        awake.stepYear();
        maxDozing = std::max(maxDozing, dozing.ecomod()->dozingCount());
        CHECK(awake.ecomod()->dozingCount() == 0);
        same = sameRun(dozing, awake);
        INFO("year " << y + 1);
        CHECK(same);
    }
    CHECK(maxDozing > 50);  // dozing was exercised
    CHECK(dozing.plantCount() > 100);
}

TEST_CASE("ecomod: the step's caches change no tree, census or counter", "[sim][ecomod]") {
    // The same run twice: once as it is, once with every cache of the step dropped after each
    // year (forgetCaches: the witnesses, the set-aside seedlings, the trees' grid places and
    // base, the cover guesses), so that every tree is tested by the plain search each year.
    SimInputs in = test::smallDemoScene();
    const SimParams params = ecomodParams();
    Simulation cached(in, params, 9), plain(in, params, 9);
    REQUIRE(cached.ecomod() != nullptr);
    REQUIRE(plain.ecomod() != nullptr);
    bool same = true;
    for (int y = 0; y < 50 && same; ++y) {
        cached.stepYear();
        plain.stepYear();
        plain.ecomod()->forgetCaches();
        CHECK(plain.ecomod()->setAsideCount() == 0);
        same = sameRun(cached, plain);
        INFO("year " << y + 1);
        CHECK(same);
    }
    // Every cache was exercised in the cached run.
    const EcoModel::CacheCounts c = cached.ecomod()->cacheCounts();
    CHECK(c.coverHits > 20);
    CHECK(c.wokenInPass > 5);
    CHECK(c.keysKept > 1000);
    CHECK(cached.plantCount() > 100);
}

TEST_CASE("ecomod: the AVX2 search finds what the baseline search finds", "[sim][ecomod]") {
    // The same run twice, one with the kernels' AVX2 forms and one with their baseline forms,
    // a year of each in turn: the same trees, censuses and counters every year (a search that
    // found another dominator first would change a witness, and the set-aside's events with it).
    if (!setAvx2Kernels(true)) {
        WARN("no AVX2 on this processor: its form of the search is not checked");
        return;
    }
    SimInputs in = test::smallDemoScene();
    const SimParams params = ecomodParams();
    Simulation wide(in, params, 13), base(in, params, 13);
    REQUIRE(wide.ecomod() != nullptr);
    bool same = true;
    for (int y = 0; y < 60 && same; ++y) {
        {
            const Avx2Scope form(true);
            wide.stepYear();
        }
        {
            const Avx2Scope form(false);
            base.stepYear();
        }
        same = sameRun(wide, base) && wide.ecomod()->cacheCounts().coverHits == base.ecomod()->cacheCounts().coverHits &&
               wide.ecomod()->setAsideCount() == base.ecomod()->setAsideCount();
        INFO("year " << y + 1);
        CHECK(same);
    }
    CHECK(wide.plantCount() > 100);
}

TEST_CASE("ecomod: the set-aside events' calendar lists what a scan of the event years lists", "[sim][ecomod]") {
    // Each year the set-aside trees under a canopy tree whose event falls in it, as the
    // calendar gives them (an entry per year modulo its length, kept in index order), are
    // compared with a scan of every set-aside tree's event year (checkSleeperCalendar).
    // Every tree brought back in year 20 (removeTrees of nothing: the calendar cleared), and
    // set aside again after.
    SimInputs in = test::smallDemoScene();
    Simulation sim(in, ecomodParams(), 9);
    REQUIRE(sim.ecomod() != nullptr);
    EcoModel& eco = *sim.ecomod();
    eco.checkSleeperCalendar(true);
    for (int y = 0; y < 60; ++y) {
        sim.stepYear();
        if (y == 19) {
            eco.removeTrees(std::vector<std::uint8_t>(sim.plantCount(), 0));
            CHECK(eco.setAsideCount() == 0);
        }
    }
    const EcoModel::CacheCounts c = eco.cacheCounts();
    CHECK(c.calendarEvents > 20);
    CHECK(c.calendarMismatches == 0);
    CHECK(eco.setAsideCount() > 50);
}

TEST_CASE("ecomod: the disturbance hook removes exactly the flagged trees", "[sim][ecomod]") {
    Biome b = quietBiome();
    const int s = b.speciesIndex("Toyon");
    Simulation sim(flatScene(b, 30), ecomodParams(), 1,
                   {tree(s, 5, 5, 1), tree(s, 15, 5, 1), tree(s, 25, 5, 1), tree(s, 5, 25, 1)});
    const auto before = sim.plants();
    REQUIRE(sim.ecomod() != nullptr);
    EcoModel& eco = *sim.ecomod();
    CHECK(eco.removeTrees({0, 1, 0, 1}) == 2);
    const auto after = sim.plants();
    REQUIRE(after.size() == 2);
    CHECK(after[0].id == before[0].id);
    CHECK(after[1].id == before[2].id);
    CHECK_THROWS_AS(eco.removeTrees({1}), ValidationError);
}

TEST_CASE("ecomod: bad values are refused naming the file, the key and the value", "[sim][ecomod][config]") {
    CHECK_THROWS_WITH(parseRunConfig("[model]\nkind = \"ecomood\"\n", "run.toml"),
                      Catch::Contains("run.toml") && Catch::Contains("kind") && Catch::Contains("ecomood") &&
                          Catch::Contains("\"ecomod\""));
    CHECK(parseRunConfig("[model]\nkind = \"ecomod\"\n", "run.toml").params.kind == ModelKind::EcoMod);
    CHECK(parseRunConfig("", "run.toml").params.kind == ModelKind::Monthly);
    // The default kind writes nothing new into the records (monthly outputs keep their bytes).
    CHECK(SimParams{}.toToml().find("kind") == std::string::npos);
    CHECK(ecomodParams().toToml().find("kind = \"ecomod\"") != std::string::npos);

    Biome b = defaultBiome();
    b.sourcePath = "my-biome.toml";
    Species& toyon = b.species[static_cast<std::size_t>(b.speciesIndex("Toyon"))];
    toyon.ecomod.maturityAgeYears = 80;
    toyon.ecomod.fullGrownAgeYears = 60;
    SimInputs in = flatScene(b, 20);
    CHECK_THROWS_WITH(Simulation(in, ecomodParams(), 1),
                      Catch::Contains("my-biome.toml") && Catch::Contains("Toyon") &&
                          Catch::Contains("maturity_age_years 80") && Catch::Contains("full_grown_age_years 60"));
    toyon.ecomod.maturityAgeYears = 10;
    toyon.ecomod.matureHeightM = 12;  // above the default full height, Toyon's max_height_m of 9 m
    in = flatScene(b, 20);
    CHECK_THROWS_WITH(Simulation(in, ecomodParams(), 1),
                      Catch::Contains("my-biome.toml") && Catch::Contains("mature_height_m 12"));
    // The monthly model's inspectors say which model they belong to.
    Simulation eco(flatScene(quietBiome(), 20), ecomodParams(), 1);
    CHECK_THROWS_WITH(eco.stepMonth(), Catch::Contains("monthly model"));
}
