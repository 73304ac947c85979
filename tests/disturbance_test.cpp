// Disturbance events (sim/disturbance.h, docs/disturbance.md): the fire spread rule on
// constructed grids, the kill rules, the yearly schedule, and the events inside the monthly
// simulator (stand clearing, thread count, checkpoints, configuration).
#include <catch2/catch.hpp>
#include <omp.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <map>
#include <set>
#include <sstream>
#include <cstring>
#include <filesystem>

#include "abiotics_fixture.h"
#include "disturbance.h"
#include "ecomod.h"
#include "error.h"
#include "h5io.h"
#include "sim_config.h"
#include "sim_render.h"
#include "sim_run.h"
#include "sim_scene_fixture.h"
#include "simulator.h"
#include "test_util.h"

using namespace eco;
using namespace eco::sim;

namespace {

// A square site of n x n cells of 1 m: elevation = slope x (x east), constant moisture and
// wind exposure; the area is the whole grid.
DisturbanceSite flatSite(int n, double slopeEast = 0, float moisture = 10, float wind = 0, double windFromDeg = 270) {
    DisturbanceSite s;
    s.elevationM = Grid<float>(n, n, 1.0, 0, 0, 0.f);
    for (int y = 0; y < n; ++y)
        for (int x = 0; x < n; ++x) s.elevationM(x, y) = static_cast<float>(slopeEast * (x + 0.5));
    s.moistureMm = Grid<float>(n, n, 1.0, 0, 0, moisture);
    s.windMS = Grid<float>(n, n, 1.0, 0, 0, wind);
    s.windFromDeg = windFromDeg;
    s.x1 = n;
    s.y1 = n;
    return s;
}

// Burnt cells east and west of column cx, summed over `events` fires ignited at (cx, cy).
std::pair<long, long> eastWest(const DisturbanceSite& s, const FireSettings& f, int cx, int cy, int events) {
    long east = 0, west = 0;
    const int n = s.elevationM.width();
    for (int e = 0; e < events; ++e) {
        const auto burnt = spreadFire(s, f, cx, cy, 7, static_cast<std::uint64_t>(e) + 1);
        for (int y = 0; y < n; ++y)
            for (int x = 0; x < n; ++x)
                if (burnt[s.elevationM.index(x, y)]) {
                    if (x > cx) ++east;
                    else if (x < cx) ++west;
                }
    }
    return {east, west};
}

FireSettings fireOn() {
    FireSettings f;
    f.enabled = true;
    return f;
}

}  // namespace

TEST_CASE("fire spread: the step probability follows slope, wind and moisture as documented", "[disturbance][fire]") {
    FireSettings f = fireOn();
    f.spreadProbability = 0.2;
    f.slopeFactor = 2.0;
    f.windFactor = 0.2;
    f.extinctionMoistureMm = 80;
    // Flat, calm, moisture 20 of 80: p0 x (1 - 20 / 80).
    CHECK(fireStepProbability(flatSite(5, 0, 20), f, 2, 2, 1, 0) == Approx(0.2 * 0.75));
    // Rise 0.3 m per 1 m step east: x exp(2 x 0.3) upslope, exp(-0.6) downslope.
    const DisturbanceSite sloped = flatSite(5, 0.3, 0);
    CHECK(fireStepProbability(sloped, f, 2, 2, 1, 0) == Approx(0.2 * std::exp(0.6)));
    CHECK(fireStepProbability(sloped, f, 2, 2, -1, 0) == Approx(0.2 * std::exp(-0.6)));
    CHECK(fireStepProbability(sloped, f, 2, 2, 0, 1) == Approx(0.2));
    // Diagonal step: rise 0.3 over sqrt(2) m.
    CHECK(fireStepProbability(sloped, f, 2, 2, 1, 1) == Approx(0.2 * std::exp(2 * 0.3 / std::sqrt(2.0))));
    // Westerly wind of 5 m/s blows east: x exp(0.2 x 5 x cos phi).
    const DisturbanceSite windy = flatSite(5, 0, 0, 5.f, 270);
    CHECK(fireStepProbability(windy, f, 2, 2, 1, 0) == Approx(0.2 * std::exp(1.0)));
    CHECK(fireStepProbability(windy, f, 2, 2, -1, 0) == Approx(0.2 * std::exp(-1.0)));
    CHECK(fireStepProbability(windy, f, 2, 2, 0, -1) == Approx(0.2).margin(1e-12));
    // A northerly wind (from 0 degrees) blows south.
    const DisturbanceSite northerly = flatSite(5, 0, 0, 5.f, 0);
    CHECK(fireStepProbability(northerly, f, 2, 2, 0, -1) == Approx(0.2 * std::exp(1.0)));
    // At or above the extinction moisture nothing passes; capped at 1.
    CHECK(fireStepProbability(flatSite(5, 0, 80), f, 2, 2, 1, 0) == 0.0);
    f.spreadProbability = 0.9;
    CHECK(fireStepProbability(flatSite(5, 3.0, 0), f, 2, 2, 1, 0) == 1.0);
}

TEST_CASE("fire spread: upslope and downwind burn further than downslope and upwind", "[disturbance][fire]") {
    FireSettings f = fireOn();
    f.spreadProbability = 0.3;  // near the percolation threshold: fires of tens of cells
    const int n = 41, c = 20, events = 60;
    SECTION("slope: elevation rises to the east") {
        const auto [east, west] = eastWest(flatSite(n, 0.25), f, c, c, events);
        INFO("east " << east << " west " << west);
        CHECK(east > 2 * west);
    }
    SECTION("wind: a westerly wind drives the fire east") {
        const auto [east, west] = eastWest(flatSite(n, 0, 0, 5.f, 270), f, c, c, events);
        INFO("east " << east << " west " << west);
        CHECK(east > 2 * west);
    }
    SECTION("flat and calm: no side is favoured (within 30 %)") {
        const auto [east, west] = eastWest(flatSite(n), f, c, c, events);
        INFO("east " << east << " west " << west);
        CHECK(std::abs(east - west) < 0.3 * (east + west) / 2);
    }
}

TEST_CASE("fire spread: wet cells stop the fire, a wet ignition burns nothing", "[disturbance][fire]") {
    FireSettings f = fireOn();
    f.spreadProbability = 1.0;  // every dry neighbour burns: the burnt set is the dry region reachable
    const int n = 30;
    DisturbanceSite s = flatSite(n, 0, 10);
    for (int y = 0; y < n; ++y) s.moistureMm(12, y) = 200.f;  // a wet creek along column 12
    const auto burnt = spreadFire(s, f, 5, 5, 3, 99);
    long left = 0, right = 0, wet = 0;
    for (int y = 0; y < n; ++y)
        for (int x = 0; x < n; ++x) {
            if (!burnt[s.elevationM.index(x, y)]) continue;
            if (x < 12) ++left;
            else if (x > 12) ++right;
            else ++wet;
        }
    CHECK(left == 12L * n);  // everything west of the creek
    CHECK(wet == 0);
    CHECK(right == 0);
    // Ignited in the creek: nothing burns.
    const auto none = spreadFire(s, f, 12, 7, 3, 99);
    CHECK(std::count(none.begin(), none.end(), std::uint8_t{1}) == 0);
}

TEST_CASE("fire spread: the same seed and event give the same cells, another seed other cells", "[disturbance][fire][determinism]") {
    FireSettings f = fireOn();
    f.spreadProbability = 0.3;
    const DisturbanceSite s = flatSite(41, 0.1, 5, 3.f, 200);
    const auto a = spreadFire(s, f, 20, 20, 42, 7);
    const auto b = spreadFire(s, f, 20, 20, 42, 7);
    CHECK(a == b);
    int differ = 0;
    for (std::uint64_t seed = 43; seed < 48; ++seed) differ += spreadFire(s, f, 20, 20, seed, 7) != a;
    CHECK(differ >= 4);
}

TEST_CASE("disturbance kills: fire by height and tolerance, storms by exposure and height", "[disturbance]") {
    FireSettings f = fireOn();
    f.severity = 0.8;
    f.scorchHeightM = 2.0;
    CHECK(fireKillProbability(f, 0.5, 0.0) == Approx(0.8));
    CHECK(fireKillProbability(f, 4.0, 0.0) == Approx(0.4));  // twice the scorch height: half
    CHECK(fireKillProbability(f, 0.5, 0.75) == Approx(0.2));
    CHECK(fireKillProbability(f, 0.5, 1.0) == 0.0);
    StormSettings s;
    s.severity = 0.6;
    s.referenceHeightM = 3.0;
    s.heightExponent = 2.0;
    CHECK(stormKillProbability(s, 3.0, 5.0, 5.0) == Approx(0.6));
    CHECK(stormKillProbability(s, 1.5, 5.0, 5.0) == Approx(0.6 * 0.25));
    CHECK(stormKillProbability(s, 6.0, 2.5, 5.0) == Approx(0.3));  // half exposed, capped height term
    CHECK(stormKillProbability(s, 6.0, 0.0, 5.0) == 0.0);           // sheltered

    // The draws: 2000 plants of 4 m (fire kill probability 0.4) in a fully burnt site.
    DisturbanceSettings ds;
    ds.fire = f;
    ds.fire.spreadProbability = 1.0;
    const DisturbanceSite site = flatSite(20);
    const std::size_t n = 2000;
    std::vector<std::uint64_t> id(n);
    std::vector<std::int32_t> sp(n, 0);
    std::vector<double> x(n), y(n), h(n, 4.0);
    for (std::size_t p = 0; p < n; ++p) {
        id[p] = p + 1;
        x[p] = 0.5 + static_cast<double>(p % 19);
        y[p] = 0.5 + static_cast<double>(p / 19 % 19);
    }
    PlannedEvent e{DisturbanceKind::Fire, 3, 7, 12345};
    const auto out = runDisturbance(e, ds, site, PlantArrays{n, id.data(), sp.data(), x.data(), y.data(), h.data()}, {0.0}, 2, 5);
    CHECK(out.record.areaM2 == Approx(400.0));
    const double killed = out.record.killed[0];
    // Binomial(2000, 0.4): sd 21.9; 4 sd.
    CHECK(std::abs(killed - 800.0) < 88.0);
    CHECK(out.record.killed[1] == 0);
    CHECK(out.record.kind == "fire");
}

TEST_CASE("disturbance schedule: forced years always, a yearly probability at its rate", "[disturbance]") {
    DisturbanceSettings s;
    s.fire.enabled = true;
    s.fire.timing.forcedYears = {3, 9};
    for (int y = 0; y < 12; ++y) CHECK(eventsOfYear(s, 1, y).size() == (y == 3 || y == 9 ? 1u : 0u));
    s.fire.timing.forcedYears.clear();
    s.fire.timing.probabilityPerYear = 0.05;  // a 20-year return interval
    s.storm.enabled = true;
    s.storm.timing.probabilityPerYear = 0.1;
    int fires = 0, storms = 0;
    const int years = 20000;
    for (int y = 0; y < years; ++y)
        for (const PlannedEvent& e : eventsOfYear(s, 8, y)) (e.kind == DisturbanceKind::Fire ? fires : storms)++;
    // Binomial: 1000 +- 31 and 2000 +- 42; 4 sd.
    CHECK(std::abs(fires - 1000) < 124);
    CHECK(std::abs(storms - 2000) < 170);
    // The same seed gives the same years.
    CHECK(eventsOfYear(s, 8, 17).size() == eventsOfYear(s, 8, 17).size());
}

// ------------------------------------------------------------------ inside the simulator

namespace {

DisturbanceSettings standClearingFire(int year) {
    DisturbanceSettings d;
    d.fire.enabled = true;
    d.fire.timing.forcedYears = {year};
    d.fire.timing.month = 6;  // July: before the August germination
    d.fire.spreadProbability = 1.0;
    d.fire.extinctionMoistureMm = 1e6;
    d.fire.severity = 1.0;
    d.fire.scorchHeightM = 100.0;
    return d;
}

bool sameState(const std::vector<UndergrowthPlant>& a, const std::vector<UndergrowthPlant>& b) {
    if (a.size() != b.size()) return false;
    for (std::size_t i = 0; i < a.size(); ++i)
        if (a[i].id != b[i].id || std::memcmp(&a[i].heightM, &b[i].heightM, sizeof(double)) != 0 ||
            std::memcmp(&a[i].pool, &b[i].pool, sizeof(double)) != 0)
            return false;
    return true;
}

}  // namespace

TEST_CASE("disturbance in the simulator: a stand-clearing fire kills every plant and is recorded", "[disturbance][sim]") {
    SimInputs in = test::smallDemoScene();
    in.area = SimArea{10, 10, 30, 30};
    Simulation sim(in, SimParams{}, 3);
    sim.setDisturbance(standClearingFire(2));
    for (int m = 0; m < 12 * 2 + 6; ++m) sim.stepMonth();  // up to June of year 2
    const std::size_t before = sim.plantCount();
    REQUIRE(before > 100);
    const SimCounters c0 = sim.counters();
    sim.stepMonth();  // July: the month's own mortality, then the fire
    const std::int64_t diedInJuly = sim.counters().diedBackgroundOrStress - c0.diedBackgroundOrStress +
                                    sim.counters().diedAtCanopy - c0.diedAtCanopy;
    CHECK(sim.plantCount() == 0);
    REQUIRE(sim.disturbances().size() == 1);
    const DisturbanceRecord& e = sim.disturbances()[0];
    CHECK(e.year == 2);
    CHECK(e.month == 6);
    CHECK(e.kind == "fire");
    CHECK(e.areaM2 == Approx(400.0));  // the whole 20 m x 20 m area
    std::int64_t killed = 0;
    for (auto k : e.killed) killed += k;
    CHECK(killed == static_cast<std::int64_t>(before) - diedInJuly);
    CHECK(sim.counters().diedDisturbance == killed);
    sim.stepMonth();  // August: germination on the cleared ground
    CHECK(sim.plantCount() > 0);
}

TEST_CASE("disturbance in the simulator: same plants and events with 1 and 2 threads, and after a resume",
          "[disturbance][sim][determinism][checkpoint]") {
    test::TempDir dir("disturbresume");
    SimInputs in = test::smallDemoScene();
    in.area = SimArea{8, 8, 32, 32};
    DisturbanceSettings d;
    d.fire.enabled = true;
    d.fire.timing.probabilityPerYear = 0.5;
    d.fire.spreadProbability = 0.4;
    d.storm.enabled = true;
    d.storm.timing.probabilityPerYear = 0.5;
    d.storm.severity = 1.0;
    d.storm.referenceHeightM = 0.3;
    const int threads = omp_get_max_threads();
    setParallelThresholds(0, 0);
    auto run = [&](int t, int months) {
        omp_set_num_threads(t);
        auto s = std::make_unique<Simulation>(in, SimParams{}, 9);
        s->setDisturbance(d);
        for (int m = 0; m < months; ++m) s->stepMonth();
        return s;
    };
    const auto one = run(1, 12 * 8);
    const auto two = run(2, 12 * 8);
    CHECK(one->disturbances().size() >= 4);
    CHECK(sameState(one->plants(), two->plants()));
    REQUIRE(one->disturbances().size() == two->disturbances().size());
    // Resume from a checkpoint taken mid-run (after some events).
    const auto first = run(2, 12 * 3 + 5);
    {
        auto f = h5::File::create(dir.file("state.h5"));
        first->saveState(f, "/state");
    }
    Simulation resumed(in, SimParams{}, 9);
    resumed.setDisturbance(d);
    {
        auto f = h5::File::openRead(dir.file("state.h5"));
        resumed.loadState(f, "/state");
    }
    for (int m = 0; m < 12 * 5 - 5; ++m) resumed.stepMonth();
    CHECK(sameState(one->plants(), resumed.plants()));
    REQUIRE(resumed.disturbances().size() == one->disturbances().size());
    for (std::size_t i = 0; i < resumed.disturbances().size(); ++i) {
        CHECK(resumed.disturbances()[i].year == one->disturbances()[i].year);
        CHECK(resumed.disturbances()[i].killed == one->disturbances()[i].killed);
        CHECK(resumed.disturbances()[i].areaM2 == one->disturbances()[i].areaM2);
        CHECK(resumed.disturbances()[i].mask.cells == one->disturbances()[i].mask.cells);  // masks kept by the checkpoint
        CHECK(one->disturbances()[i].mask.cells == two->disturbances()[i].mask.cells);
    }
    CHECK(resumed.counters().diedDisturbance == one->counters().diedDisturbance);
    // A run without disturbance refuses the checkpoint (another fingerprint).
    Simulation plain(in, SimParams{}, 9);
    auto f = h5::File::openRead(dir.file("state.h5"));
    CHECK_THROWS_WITH(plain.loadState(f, "/state"), Catch::Contains("another run") && Catch::Contains("disturbance settings"));
    setParallelThresholds(kDefaultParallelPlants, kDefaultParallelCells);
    omp_set_num_threads(threads);
}

TEST_CASE("disturbance config: [disturbance.fire] and [disturbance.storm] are read strictly", "[disturbance][config]") {
    const std::string base = "[inputs]\nabiotics = \"a.h5\"\ncanopy = \"c.h5\"\n";
    const RunConfig off = parseRunConfig(base, "t.toml");
    CHECK_FALSE(off.disturbance.enabled());
    const RunConfig c = parseRunConfig(base +
                                           "[disturbance.fire]\nreturn_interval_years = 50\nyears = [40]\nseverity = 1.0\n"
                                           "[disturbance.storm]\nprobability_per_year = 0.1\nmonth = 0\n",
                                       "t.toml");
    CHECK(c.disturbance.fire.enabled);
    CHECK(c.disturbance.fire.timing.probabilityPerYear == Approx(0.02));
    CHECK(c.disturbance.fire.timing.forcedYears == std::vector<int>{40});
    CHECK(c.disturbance.fire.timing.month == 7);
    CHECK(c.disturbance.fire.severity == 1.0);
    CHECK(c.disturbance.storm.enabled);
    CHECK(c.disturbance.storm.timing.month == 0);
    CHECK_THROWS_WITH(parseRunConfig(base + "[disturbance.fire]\nsevrity = 1.0\n", "t.toml"),
                      Catch::Contains("t.toml") && Catch::Contains("sevrity") && Catch::Contains("unknown key"));
    CHECK_THROWS_WITH(parseRunConfig(base + "[disturbance.fire]\nprobability_per_year = 0.1\nreturn_interval_years = 10\n", "t.toml"),
                      Catch::Contains("not both"));
    CHECK_THROWS_WITH(parseRunConfig(base + "[disturbance.storm]\nmonth = 12\n", "t.toml"), Catch::Contains("month"));
    CHECK_THROWS_WITH(parseRunConfig(base + "[disturbance.fire]\nseverity = 1.5\n", "t.toml"), Catch::Contains("severity"));
    // Forced years name the value and the range (an int, 0 = the first simulated year).
    CHECK_THROWS_WITH(parseRunConfig(base + "[disturbance.fire]\nyears = [3, -1]\n", "t.toml"),
                      Catch::Contains("t.toml") && Catch::Contains("'years'") && Catch::Contains("value -1: must lie in 0..2147483647"));
    CHECK_THROWS_WITH(parseRunConfig(base + "[disturbance.storm]\nyears = [2147483648]\n", "t.toml"),
                      Catch::Contains("value 2147483648: must lie in 0..2147483647"));
    // With the EcoMod model too (the events at the year's end).
    const RunConfig eco = parseRunConfig(base + "[model]\nkind = \"ecomod\"\n[disturbance.fire]\nyears = [10]\n", "t.toml");
    CHECK_NOTHROW(eco.validate());
    CHECK(eco.disturbance.fire.enabled);
}

namespace {

// A kind's settings in DisturbanceSettings and its numbers' ParamDesc table.
template <typename S>
struct KindOf;
template <>
struct KindOf<FireSettings> {
    static FireSettings& of(DisturbanceSettings& d) { return d.fire; }
    static const FireSettings& of(const DisturbanceSettings& d) { return d.fire; }
    static const std::vector<ParamDesc<FireSettings>>& params() { return fireParamFields(); }
};
template <>
struct KindOf<StormSettings> {
    static StormSettings& of(DisturbanceSettings& d) { return d.storm; }
    static const StormSettings& of(const DisturbanceSettings& d) { return d.storm; }
    static const std::vector<ParamDesc<StormSettings>>& params() { return stormParamFields(); }
};

// The number of a Timing or Setting field in s, and its descriptor's range.
template <typename S>
double numberOf(const DisturbanceField<S>& f, const S& s) {
    return f.timing ? f.timing->value(s.timing) : f.setting->value(s);
}
template <typename S>
const ParamRange& rangeOf(const DisturbanceField<S>& f) {
    return f.timing ? f.timing->range : f.setting->range;
}
template <typename S>
bool isInteger(const DisturbanceField<S>& f) {
    return f.timing && f.timing->kind == ParamDesc<EventTiming>::Kind::Integer;
}

// A valid value of field f other than its default (TOML text).
template <typename S>
std::string otherValidValue(const DisturbanceField<S>& f) {
    using K = typename DisturbanceField<S>::Kind;
    switch (f.kind) {
        case K::Enabled: return "false";
        case K::ReturnInterval: return "4.0";
        case K::ForcedYears: return "[5, 2]";
        case K::Timing:
        case K::Setting: break;
    }
    const double dflt = numberOf(f, S{});
    for (double v : {0.25, 0.5, 3.0, 5.0, 7.5, 1e3}) {
        if (isInteger(f)) v = std::floor(v);
        if (rangeOf(f).contains(v) && v != dflt) return isInteger(f) ? std::to_string(static_cast<int>(v)) : tomlReal(v);
    }
    FAIL("no other valid value for " << f.key());
    return {};
}

// Each key's value in s as text ("" for return_interval_years, which is stored as the probability).
template <typename S>
std::map<std::string, std::string> valuesOf(const S& s, const std::vector<DisturbanceField<S>>& fields) {
    using K = typename DisturbanceField<S>::Kind;
    std::map<std::string, std::string> out;
    for (const auto& f : fields)
        out[f.key()] = f.kind == K::Enabled ? (s.enabled ? "true" : "false") : f.tomlValue(s);
    return out;
}

// The descriptor table of a kind against its reader, its writer and its checks.
template <typename S>
void checkDisturbanceTable(const std::vector<DisturbanceField<S>>& fields, const std::string& table) {
    using K = typename DisturbanceField<S>::Kind;
    const std::string base = "[inputs]\nabiotics = \"a.h5\"\ncanopy = \"c.h5\"\n[disturbance." + table + "]\n";  // the key on line 5
    const std::string context = "[disturbance." + table + "]";
    S on{};
    on.enabled = true;
    const auto defaults = valuesOf(on, fields);
    std::set<std::string> keys;
    for (const auto& f : fields) {
        const std::string key = f.key();
        INFO(table << " key " << key);
        CHECK(keys.insert(key).second);  // each key once
        // Read: a valid value other than the default changes that key's value, and only it.
        const std::string value = otherValidValue(f);
        const RunConfig c = parseRunConfig(base + key + " = " + value + "\n", "t.toml");
        const auto got = valuesOf(KindOf<S>::of(c.disturbance), fields);
        const std::string changedKey = f.kind == K::ReturnInterval ? "probability_per_year" : key;
        for (const auto& [k, v] : got) {
            INFO("value of " << k);
            if (k == changedKey) CHECK(v != defaults.at(k));
            else CHECK(v == defaults.at(k));
        }
        if (f.kind != K::Enabled && f.kind != K::ReturnInterval) CHECK(got.at(key) == value);
        if (f.kind == K::ReturnInterval) CHECK(got.at("probability_per_year") == "0.25");
        // Refused: a value outside the range (or of the wrong type), naming the file, the
        // key's line, the table, the key and the value.
        std::string bad, expected;
        switch (f.kind) {
            case K::Enabled: bad = "1"; expected = "expected true or false"; break;
            case K::ReturnInterval: bad = "0.5"; expected = "value 0.5: must be at least 1 (years)"; break;
            case K::ForcedYears: bad = "[3, -1]"; expected = "value -1: must lie in 0..2147483647 (0 = the first simulated year)"; break;
            case K::Timing:
            case K::Setting: {
                const ParamRange& r = rangeOf(f);
                const double outside = r.highBound != ParamRange::Bound::None ? r.hi + 1 : r.lo - 1;
                bad = isInteger(f) ? std::to_string(static_cast<long long>(outside)) : tomlReal(outside);
                expected = "value " + bad + ": " + f.ruleText();
                // The wrong type, too.
                CHECK_THROWS_WITH(parseRunConfig(base + key + " = \"x\"\n", "t.toml"),
                                  Catch::Contains("t.toml:5: " + context + ": field '" + key + "': expected a"));
                // And validate() on settings made in code: the key, the value and the rule.
                DisturbanceSettings d;
                S& s = KindOf<S>::of(d);
                s.enabled = true;
                if (f.timing) setParam(s.timing, eventTimingParamFields(), key, outside, "timing");
                else setParam(s, KindOf<S>::params(), key, outside, "setting");
                CHECK_THROWS_WITH(d.validate("src"), Catch::Contains("src: " + context + " " + key + " = " + bad + ": " + f.ruleText()));
                break;
            }
        }
        CHECK_THROWS_WITH(parseRunConfig(base + key + " = " + bad + "\n", "t.toml"),
                          Catch::Contains("t.toml:5: " + context + ": field '" + key + "': " + expected));
    }
    // Written: toToml holds the written keys, in the table's order, and nothing else.
    DisturbanceSettings d;
    KindOf<S>::of(d) = on;
    std::istringstream lines(d.toToml());
    std::vector<std::string> written, describedWritten;
    for (std::string line; std::getline(lines, line);)
        if (line.rfind("[", 0) != 0) written.push_back(line.substr(0, line.find(" = ")));
    for (const auto& f : fields)
        if (f.written()) describedWritten.push_back(f.key());
    CHECK(written == describedWritten);
    // Every key at a value other than its default reads back from what toToml writes.
    std::string all = base;
    for (const auto& f : fields)
        if (f.kind != K::Enabled && f.kind != K::ReturnInterval) all += std::string(f.key()) + " = " + otherValidValue(f) + "\n";
    const RunConfig c = parseRunConfig(all, "t.toml");
    const RunConfig back = parseRunConfig(base.substr(0, base.find("[disturbance")) + c.disturbance.toToml(), "back.toml");
    CHECK(valuesOf(KindOf<S>::of(back.disturbance), fields) == valuesOf(KindOf<S>::of(c.disturbance), fields));
    for (const auto& f : fields)
        if (f.written()) CHECK(valuesOf(KindOf<S>::of(c.disturbance), fields).at(f.key()) != defaults.at(f.key()));
    // A key the table does not describe is refused.
    CHECK_THROWS_WITH(parseRunConfig(base + "not_a_key = 1\n", "t.toml"),
                      Catch::Contains("t.toml:5: " + context + ": field 'not_a_key': unknown key"));
}

}  // namespace

TEST_CASE("disturbance config: each described key is read, checked and written, and no other key is read", "[disturbance][config]") {
    // fireFields() / stormFields() drive the reader, the checks, toToml and eco config describe
    // (docs/disturbance.md): every key they describe is accepted and lands in its value (no
    // other), a bad value is refused with the file, line, table, key and value, toToml writes
    // exactly the written keys, and an undescribed key is refused.
    checkDisturbanceTable(fireFields(), "fire");
    checkDisturbanceTable(stormFields(), "storm");
    // Both spellings of the yearly chance at once are refused.
    CHECK_THROWS_WITH(parseRunConfig("[disturbance.storm]\nprobability_per_year = 0.1\nreturn_interval_years = 10\n", "t.toml"),
                      Catch::Contains("t.toml:3: [disturbance.storm]: field 'return_interval_years': give probability_per_year or "
                                      "return_interval_years, not both"));
    // toToml's text enters checkpoint fingerprints and the output's disturbance_toml: it is
    // the text the hand-written writer gave before the descriptors (checkpoints of runs with
    // disturbance keep resuming).
    DisturbanceSettings d;
    d.fire.enabled = d.storm.enabled = true;
    d.fire.timing.probabilityPerYear = 0.02;
    d.fire.timing.forcedYears = {40, 80};
    d.storm.timing.probabilityPerYear = 1.0 / 15;
    d.storm.referenceWindMS = 7;
    CHECK(d.toToml() ==
          "[disturbance.fire]\nprobability_per_year = 0.02\nyears = [40, 80]\nmonth = 7\nspread_probability = 0.35\n"
          "slope_factor = 2.0\nwind_factor = 0.2\nextinction_moisture_mm = 150.0\nseverity = 0.9\nscorch_height_m = 2.0\n"
          "default_tolerance = 0.0\n[disturbance.storm]\nprobability_per_year = 0.06666666666666667\nyears = []\nmonth = 11\n"
          "severity = 0.5\nreference_height_m = 3.0\nheight_exponent = 2.0\nreference_wind_ms = 7.0\n");
    // The storm's month default is its own (December), the fire's August.
    CHECK(paramField(eventTimingParamFields(), "month").key == std::string("month"));
    CHECK(fireFields()[4].defaultText() == "7");
    CHECK(stormFields()[4].defaultText() == "11");
}

namespace {

// Flat ground of w x h cells of 1 m, every species indifferent to the site (v = 1); in August
// only (the fire month) bone dry west of x = wetFromM and wetter than the extinction moisture
// east of it: a fire of spread probability 1 ignited in the west burns exactly the west part.
SimInputs ecomodFireScene(int w, int h, double wetFromM) {
    SimInputs in;
    in.biome = defaultBiome();
    for (Species& sp : in.biome.species) {
        EcoModSpecies& e = sp.ecomod;
        e.elevationTol = e.moistureTol = e.sunTol = e.windTol = 1e9;
        e.slopeHarm = 0;
        e.immigrantsPerHaYear = 10;  // a quick start from empty ground
    }
    const Grid<float> like(w, h, 1.0, 0, 0, 0.f);
    in.abiotics = test::uniformAbiotics(like, 50,
                                        {{Factor::Sun, 8},
                                         {Factor::Moisture, 60},
                                         {Factor::Temperature, 15},
                                         {Factor::Slope, 0},
                                         {Factor::Wind, 4}});  // exposure for storms (no species responds to it here)
    // August: bone dry (fire passes with the spread probability itself) or wet.
    Grid<float>& august = in.abiotics.moistureMm[7];
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) august(x, y) = x < wetFromM ? 0.f : 1000.f;
    return in;
}

}  // namespace

// The forced fire of the EcoMod test below: it burns the dry west part (x < kFireWetM) and
// scorches every tree there whole.
constexpr double kFireWetM = 50.0;
constexpr int kFireYear = 150, kFireAfter = 25;
DisturbanceSettings westFire() {
    DisturbanceSettings d;
    d.fire.enabled = true;
    d.fire.timing.forcedYears = {kFireYear};
    d.fire.spreadProbability = 1.0;
    d.fire.slopeFactor = 0;
    d.fire.windFactor = 0;
    d.fire.severity = 1.0;
    d.fire.scorchHeightM = 1000.0;  // scorches every tree whole
    return d;
}

// Trees, and pioneers (max age <= 100 years, as in the ecomod validation scenario), west of
// the wet edge.
struct WestCount {
    std::size_t all = 0, pioneers = 0;
};
WestCount westCount(const Simulation& sim) {
    WestCount c;
    for (const auto& p : sim.plants())
        if (p.xM < kFireWetM) {
            ++c.all;
            c.pioneers += sim.ecomod()->speciesParams()[static_cast<std::size_t>(p.speciesId)].maxAgeYears <= 100 ? 1 : 0;
        }
    return c;
}

// The fire scenario of another seed, for the recolonisation's share pooled over seeds: the
// west's counts kFireAfter years after the fire, with it and without it.
std::pair<WestCount, WestCount> westAfterFire(const SimInputs& in, std::uint64_t seed) {
    SimParams params;
    params.kind = ModelKind::EcoMod;
    Simulation burnt(in, params, seed), unburnt(in, params, seed);
    burnt.setDisturbance(westFire());
    for (int y = 0; y < kFireYear + 1 + kFireAfter; ++y) {  // as the test below: the fire at the end of year kFireYear
        burnt.stepYear();
        unburnt.stepYear();
    }
    REQUIRE(burnt.disturbances().size() == 1);
    REQUIRE(burnt.disturbances()[0].xM < kFireWetM);  // the ignition falls in the dry part
    return {westCount(burnt), westCount(unburnt)};
}

TEST_CASE("disturbance in EcoMod: a forced fire kills the trees of the burnt part, and pioneers recolonise it",
          "[disturbance][sim][ecomod]") {
    // 150 years of afforestation of empty ground, a fire at the end of year 150 that burns
    // the dry west part (x < 50 m of 80 m) and kills every tree there, then 25 more years;
    // compared with the same run without the fire.
    constexpr double kWet = kFireWetM;
    constexpr int kAfter = kFireAfter;
    const SimInputs in = ecomodFireScene(80, 40, kWet);
    const Biome& b = in.biome;
    SimParams params;
    params.kind = ModelKind::EcoMod;
    const DisturbanceSettings d = westFire();
    constexpr std::uint64_t kSeed = 4;  // its ignition falls in the dry part (checked below)
    Simulation burnt(in, params, kSeed), unburnt(in, params, kSeed);
    burnt.setDisturbance(d);
    for (int y = 0; y < kFireYear; ++y) {
        burnt.stepYear();
        unburnt.stepYear();
    }
    // Before the fire: the same trees as without disturbance (no event has struck yet).
    const auto before = burnt.plants();
    REQUIRE(before.size() == unburnt.plantCount());
    std::size_t westBefore = 0;
    for (const auto& p : before) westBefore += p.xM < kWet ? 1 : 0;
    REQUIRE(westBefore > 100);
    burnt.stepYear();  // year 150: growth, then the fire at its end
    unburnt.stepYear();
    REQUIRE(burnt.disturbances().size() == 1);
    const DisturbanceRecord& e = burnt.disturbances()[0];
    CHECK(e.kind == "fire");
    CHECK(e.year == kFireYear);
    REQUIRE(e.xM < kWet);
    CHECK(e.areaM2 == Approx(kWet * 40));
    // Every tree of the burnt part is dead, none of the rest (the unburnt run's trees east of
    // the edge are the burnt run's, one for one).
    std::size_t eastBurnt = 0, eastUnburnt = 0;
    for (const auto& p : burnt.plants()) {
        CHECK(p.xM >= kWet);
        ++eastBurnt;
    }
    std::size_t westKilled = 0;
    for (const auto& p : unburnt.plants()) (p.xM < kWet ? westKilled : eastUnburnt) += 1;
    CHECK(eastBurnt == eastUnburnt);
    std::int64_t killed = 0;
    for (auto k : e.killed) killed += k;
    CHECK(killed == static_cast<std::int64_t>(westKilled));
    CHECK(burnt.counters().diedDisturbance == killed);
    // Recolonisation: pioneers (max age <= 100 years, as in the ecomod validation scenario)
    // take the burnt ground first, far above their share of the mature stand. Their share
    // varies from seed to seed (1.35 - 3.5 x the unburnt share in single runs of seeds 2 -
    // 14), so it is pooled over this seed and two more whose ignition is in the dry part.
    for (int y = 0; y < kAfter; ++y) {
        burnt.stepYear();
        unburnt.stepYear();
    }
    WestCount after = westCount(burnt), control = westCount(unburnt);
    const std::size_t westAfter = after.all;
    for (std::uint64_t seed : {2, 3}) {
        const auto [withFire, without] = westAfterFire(in, seed);
        after.all += withFire.all;
        after.pioneers += withFire.pioneers;
        control.all += without.all;
        control.pioneers += without.pioneers;
    }
    const double pioneerShareBurnt = static_cast<double>(after.pioneers) / std::max<std::size_t>(after.all, 1);
    const double pioneerShareUnburnt = static_cast<double>(control.pioneers) / std::max<std::size_t>(control.all, 1);
    INFO("killed " << killed << "; west trees: " << westAfter << " after the fire; pioneer share over 3 seeds "
                        << pioneerShareBurnt << " against " << pioneerShareUnburnt << " without the fire");
    CHECK(westAfter > westKilled / 4);
    CHECK(pioneerShareBurnt > 1.5 * pioneerShareUnburnt);
    CHECK(pioneerShareBurnt > 0.2);
    (void)b;
}

TEST_CASE("disturbance in EcoMod: same trees and events with 1 and 2 threads, and after a resume",
          "[disturbance][sim][ecomod][determinism][checkpoint]") {
    test::TempDir dir("ecodisturbresume");
    const SimInputs in = ecomodFireScene(40, 40, 1000.0);
    SimParams params;
    params.kind = ModelKind::EcoMod;
    DisturbanceSettings d;
    d.fire.enabled = true;
    d.fire.timing.probabilityPerYear = 0.2;
    d.fire.spreadProbability = 0.3;
    d.fire.scorchHeightM = 5.0;
    d.storm.enabled = true;
    d.storm.timing.probabilityPerYear = 0.2;
    d.storm.severity = 0.2;
    const int threads = omp_get_max_threads();
    setParallelThresholds(0, 0);
    auto run = [&](int t, int years) {
        omp_set_num_threads(t);
        auto s = std::make_unique<Simulation>(in, params, 11);
        s->setDisturbance(d);
        for (int y = 0; y < years; ++y) s->stepYear();
        return s;
    };
    const auto one = run(1, 50);
    const auto two = run(2, 50);
    CHECK(one->disturbances().size() >= 10);
    CHECK(one->counters().diedDisturbance > 0);
    std::set<std::string> kinds;
    for (const auto& e : one->disturbances()) kinds.insert(e.kind);
    CHECK(kinds.size() == 2);  // fires and storms
    CHECK(sameState(one->plants(), two->plants()));
    const auto first = run(2, 23);  // mid-run, after some events
    {
        auto f = h5::File::create(dir.file("state.h5"));
        first->saveState(f, "/state");
    }
    Simulation resumed(in, params, 11);
    resumed.setDisturbance(d);
    {
        auto f = h5::File::openRead(dir.file("state.h5"));
        resumed.loadState(f, "/state");
    }
    for (int y = 23; y < 50; ++y) resumed.stepYear();
    CHECK(sameState(one->plants(), resumed.plants()));
    REQUIRE(resumed.disturbances().size() == one->disturbances().size());
    for (std::size_t i = 0; i < resumed.disturbances().size(); ++i) {
        CHECK(resumed.disturbances()[i].year == one->disturbances()[i].year);
        CHECK(resumed.disturbances()[i].killed == one->disturbances()[i].killed);
        CHECK(resumed.disturbances()[i].areaM2 == one->disturbances()[i].areaM2);
        CHECK(resumed.disturbances()[i].mask.cells == one->disturbances()[i].mask.cells);  // masks kept by the checkpoint
        CHECK(one->disturbances()[i].mask.cells == two->disturbances()[i].mask.cells);
    }
    CHECK(resumed.counters().diedDisturbance == one->counters().diedDisturbance);
    Simulation plain(in, params, 11);  // without disturbance: another fingerprint
    auto f = h5::File::openRead(dir.file("state.h5"));
    CHECK_THROWS_WITH(plain.loadState(f, "/state"), Catch::Contains("another run") && Catch::Contains("disturbance settings"));
    setParallelThresholds(kDefaultParallelPlants, kDefaultParallelCells);
    omp_set_num_threads(threads);
}

TEST_CASE("disturbance validation: after a stand-clearing fire the early species peak again and the late ones recover",
          "[disturbance][sim][succession]") {
    // A small plot of the demo scene: without fire the early species (Redwood Sorrel and
    // Western Swordfern, docs/simulator.md "Succession check") peak in the first years and
    // subside under the growing shrubs and saplings. A fire clearing every plant in year F
    // restarts the sequence from the seedbank. Compared with the same run without fire.
    SimInputs in = test::smallDemoScene();
    in.area = SimArea{4, 4, 40, 40};
    const Biome& b = in.biome;
    const std::size_t e0 = static_cast<std::size_t>(b.speciesIndex("Redwood Sorrel")),
                      e1 = static_cast<std::size_t>(b.speciesIndex("Western Swordfern"));
    auto earlyCount = [&](const YearRecord& r) { return r.count[e0] + r.count[e1]; };
    auto lateArea = [&](const YearRecord& r) {
        double a = 0;
        for (std::size_t s = 0; s < r.count.size(); ++s)
            if (s != e0 && s != e1) a += r.crownAreaM2[s];
        return a;
    };
    const int fireYear = 50, years = 90;
    auto run = [&](bool fire) {
        Simulation sim(in, SimParams{}, 4);
        if (fire) sim.setDisturbance(standClearingFire(fireYear));
        std::vector<YearRecord> ts{sim.census()};
        for (int y = 0; y < years; ++y) {
            sim.stepYear();
            ts.push_back(sim.census());
        }
        if (fire) CHECK(sim.disturbances().size() == 1);
        return ts;
    };
    const auto burnt = run(true), control = run(false);
    auto at = [](const std::vector<YearRecord>& ts, int y) { return ts[static_cast<std::size_t>(y)]; };
    int peakBefore = 0, peakAfter = 0, peakAfterYear = 0;
    for (int y = 0; y <= fireYear; ++y) peakBefore = std::max(peakBefore, earlyCount(at(burnt, y)));
    for (int y = fireYear + 1; y <= years; ++y)
        if (earlyCount(at(burnt, y)) > peakAfter) {
            peakAfter = earlyCount(at(burnt, y));
            peakAfterYear = y;
        }
    const int atFire = earlyCount(at(burnt, fireYear)), atEnd = earlyCount(at(burnt, years));
    const int controlAtPeak = earlyCount(at(control, peakAfterYear)), controlEnd = earlyCount(at(control, years));
    const double lateAtFire = lateArea(at(burnt, fireYear)), lateAfter = lateArea(at(burnt, fireYear + 1));
    const double lateEnd = lateArea(at(burnt, years)), lateControlEnd = lateArea(at(control, years));
    WARN("early: peak before " << peakBefore << ", at the fire " << atFire << ", peak after " << peakAfter << " in year "
                               << peakAfterYear << " (control " << controlAtPeak << "), end " << atEnd << " (control "
                               << controlEnd << "); late crown area: at the fire " << lateAtFire << ", after " << lateAfter
                               << ", end " << lateEnd << " (control " << lateControlEnd << ")");
    // The early species had subsided before the fire ...
    CHECK(atFire < 0.8 * peakBefore);
    // ... peak again within 10 years of it, well above the unburnt plot ...
    CHECK(peakAfterYear <= fireYear + 10);
    CHECK(peakAfter > 1.3 * controlAtPeak);
    // ... and subside again as the late species, cleared by the fire, recover.
    CHECK(atEnd < 0.85 * peakAfter);
    CHECK(lateAfter < 0.05 * lateAtFire);
    CHECK(lateEnd > 0.5 * lateControlEnd);
}

// ------------------------------------------------------------------ burn and damage masks

namespace {

// Plants of `control` (the same run without the event, stepped alike) missing from `struck`:
// the plants the event killed. REQUIREs that `struck` holds no plant `control` lacks.
std::vector<UndergrowthPlant> killedByEvent(const std::vector<UndergrowthPlant>& control,
                                            const std::vector<UndergrowthPlant>& struck) {
    std::set<std::uint64_t> alive;
    for (const auto& p : struck) alive.insert(p.id);
    std::set<std::uint64_t> inControl;
    for (const auto& p : control) inControl.insert(p.id);
    for (const auto& p : struck) REQUIRE(inControl.count(p.id) == 1);
    std::vector<UndergrowthPlant> out;
    for (const auto& p : control)
        if (!alive.count(p.id)) out.push_back(p);
    return out;
}

// The cells (mask grid order) holding at least one of `plants`.
std::set<std::int32_t> cellsOfPlants(const DisturbanceMask& m, const std::vector<UndergrowthPlant>& plants) {
    std::set<std::int32_t> cells;
    for (const auto& p : plants) {
        const int cx = static_cast<int>(std::floor((p.xM - m.originX) / m.cellSizeM));
        const int cy = static_cast<int>(std::floor((p.yM - m.originY) / m.cellSizeM));
        if (cx >= 0 && cy >= 0 && cx < m.width && cy < m.height) cells.insert(cy * m.width + cx);
    }
    return cells;
}

}  // namespace

TEST_CASE("disturbance masks: a fire's burn mask holds exactly the cells where the fire killed plants (monthly model)",
          "[disturbance][sim][mask]") {
    // A partial fire that kills every plant it reaches (severity 1, scorch height above every
    // plant, no tolerance), against the same run without it: the plants it killed are the
    // control's plants missing after the fire's month. The recorded mask must hold every
    // killed plant, and no cell of it may keep a plant.
    SimInputs in = test::smallDemoScene();
    in.area = SimArea{8, 8, 32, 32};
    DisturbanceSettings d;
    d.fire.enabled = true;
    d.fire.timing.forcedYears = {2};
    d.fire.timing.month = 6;  // July: no germination after it in its month (August's would differ)
    d.fire.spreadProbability = 0.45;
    d.fire.severity = 1.0;
    d.fire.scorchHeightM = 1000.0;
    constexpr std::uint64_t kSeed = 5;
    Simulation fire(in, SimParams{}, kSeed), control(in, SimParams{}, kSeed);
    fire.setDisturbance(d);
    for (int m = 0; m < 12 * 2 + 7; ++m) {  // to the end of July of year 2: the fire's month
        fire.stepMonth();
        control.stepMonth();
    }
    REQUIRE(fire.disturbances().size() == 1);
    const DisturbanceRecord& e = fire.disturbances()[0];
    const DisturbanceMask& m = e.mask;
    REQUIRE(m.present());
    const std::vector<UndergrowthPlant> before = control.plants();
    const std::vector<UndergrowthPlant> killed = killedByEvent(before, fire.plants());
    const std::size_t gridCells = static_cast<std::size_t>(m.width) * static_cast<std::size_t>(m.height);
    INFO("mask " << m.cells.size() << " of " << gridCells << " cells, " << killed.size() << " of " << before.size()
                 << " plants killed");
    // A partial burn, so that the mask has to separate burnt from unburnt ground.
    REQUIRE(m.cells.size() > gridCells / 10);
    REQUIRE(m.cells.size() < gridCells * 9 / 10);
    REQUIRE(killed.size() > 50);
    REQUIRE(killed.size() + 50 < before.size());
    std::int64_t recorded = 0;
    for (auto k : e.killed) recorded += k;
    CHECK(recorded == static_cast<std::int64_t>(killed.size()));
    // Every killed plant in the mask; every plant left alive outside it.
    std::size_t killedOutside = 0, aliveInside = 0;
    for (const auto& p : killed) killedOutside += m.contains(p.xM, p.yM) ? 0 : 1;
    for (const auto& p : fire.plants()) aliveInside += m.contains(p.xM, p.yM) ? 1 : 0;
    CHECK(killedOutside == 0);
    CHECK(aliveInside == 0);
    // The mask's cells that held a plant are the killed plants' cells, one for one.
    const std::set<std::int32_t> maskCells(m.cells.begin(), m.cells.end());
    std::set<std::int32_t> occupiedMask;
    for (std::int32_t c : cellsOfPlants(m, before))
        if (maskCells.count(c)) occupiedMask.insert(c);
    CHECK(cellsOfPlants(m, killed) == occupiedMask);
    // Its area is the recorded one (cells inside the simulated area, clipped).
    double area = 0;
    for (std::int32_t c : m.cells) {
        const double x0 = m.originX + (c % m.width) * m.cellSizeM, y0 = m.originY + (c / m.width) * m.cellSizeM;
        area += std::max(0.0, std::min(x0 + m.cellSizeM, 32.0) - std::max(x0, 8.0)) *
                std::max(0.0, std::min(y0 + m.cellSizeM, 32.0) - std::max(y0, 8.0));
    }
    CHECK(area == Approx(e.areaM2).epsilon(1e-9));
}

TEST_CASE("disturbance masks: EcoMod's fire and storm masks hold exactly the cells of the trees they killed",
          "[disturbance][sim][ecomod][mask]") {
    const SimInputs in = ecomodFireScene(40, 40, 1000.0);  // dry everywhere in August
    SimParams params;
    params.kind = ModelKind::EcoMod;
    constexpr int kYear = 40;
    DisturbanceSettings fireOnly;
    fireOnly.fire.enabled = true;
    fireOnly.fire.timing.forcedYears = {kYear};
    fireOnly.fire.spreadProbability = 0.25;  // a patchy burn, at the percolation threshold
    fireOnly.fire.slopeFactor = 0;
    fireOnly.fire.windFactor = 0;
    fireOnly.fire.severity = 1.0;
    fireOnly.fire.scorchHeightM = 1000.0;
    DisturbanceSettings stormOnly;
    stormOnly.storm.enabled = true;
    stormOnly.storm.timing.forcedYears = {kYear};
    stormOnly.storm.severity = 0.5;
    stormOnly.storm.referenceHeightM = 1.0;
    constexpr std::uint64_t kSeed = 3;
    Simulation burnt(in, params, kSeed), stormed(in, params, kSeed), control(in, params, kSeed);
    burnt.setDisturbance(fireOnly);
    stormed.setDisturbance(stormOnly);
    for (int y = 0; y <= kYear; ++y) {  // the events strike at the end of year kYear
        burnt.stepYear();
        stormed.stepYear();
        control.stepYear();
    }
    const std::vector<UndergrowthPlant> trees = control.plants();
    REQUIRE(trees.size() > 200);
    for (Simulation* sim : {&burnt, &stormed}) {
        REQUIRE(sim->disturbances().size() == 1);
        const DisturbanceRecord& e = sim->disturbances()[0];
        const DisturbanceMask& m = e.mask;
        REQUIRE(m.present());
        const std::vector<UndergrowthPlant> killed = killedByEvent(trees, sim->plants());
        const std::size_t gridCells = static_cast<std::size_t>(m.width) * static_cast<std::size_t>(m.height);
        INFO(e.kind << ": mask " << m.cells.size() << " of " << gridCells << " cells, " << killed.size() << " of "
                    << trees.size() << " trees killed");
        REQUIRE(killed.size() > 20);
        REQUIRE(killed.size() + 20 < trees.size());
        REQUIRE(m.cells.size() < gridCells * 9 / 10);
        std::size_t killedOutside = 0;
        for (const auto& p : killed) killedOutside += m.contains(p.xM, p.yM) ? 0 : 1;
        CHECK(killedOutside == 0);
        const std::set<std::int32_t> maskCells(m.cells.begin(), m.cells.end());
        if (e.kind == "fire") {
            // Burnt cells kill every tree (severity 1): none is left inside, and the burnt
            // cells that held a tree are the killed trees' cells.
            REQUIRE(m.cells.size() > gridCells / 10);
            std::size_t aliveInside = 0;
            for (const auto& p : sim->plants()) aliveInside += m.contains(p.xM, p.yM) ? 1 : 0;
            CHECK(aliveInside == 0);
            std::set<std::int32_t> occupiedMask;
            for (std::int32_t c : cellsOfPlants(m, trees))
                if (maskCells.count(c)) occupiedMask.insert(c);
            CHECK(cellsOfPlants(m, killed) == occupiedMask);
        } else {
            // A storm's mask is the cells in which a tree was thrown, exactly; survivors stand
            // in and out of it (severity 0.5).
            CHECK(cellsOfPlants(m, killed) == maskCells);
        }
    }
}

TEST_CASE("disturbance masks: the simulation file keeps each event's mask, and a table without masks still reads",
          "[disturbance][mask][io]") {
    test::TempDir dir("disturbmask");
    const Biome biome = defaultBiome();
    DisturbanceRecord fire;
    fire.year = 3;
    fire.month = 7;
    fire.kind = "fire";
    fire.areaM2 = 2.5;
    fire.killed.assign(biome.species.size(), 0);
    fire.killed[1] = 4;
    fire.mask.width = 5;
    fire.mask.height = 4;
    fire.mask.originX = 10;
    fire.mask.originY = 20;
    fire.mask.cellSizeM = 0.5;
    fire.mask.cells = {0, 6, 7, 19};
    DisturbanceRecord storm = fire;
    storm.kind = "storm";
    storm.mask.cells = {};  // a storm that threw nothing
    {
        auto f = h5::File::create(dir.file("t.h5"));
        writeDisturbanceTable(f, "/disturbance", {fire, storm}, biome);
    }
    auto f = h5::File::openRead(dir.file("t.h5"));
    const auto back = readDisturbanceTable(f, "/disturbance", biome.species.size());
    REQUIRE(back.size() == 2);
    CHECK(back[0].mask.cells == fire.mask.cells);
    CHECK(back[0].mask.width == 5);
    CHECK(back[0].mask.height == 4);
    CHECK(back[0].mask.originX == 10);
    CHECK(back[0].mask.cellSizeM == 0.5);
    CHECK(back[1].mask.present());
    CHECK(back[1].mask.cells.empty());
    // Cell 7 = (2, 1): world x in [11, 11.5), y in [20.5, 21); cell 19 = (4, 3).
    CHECK(back[0].mask.contains(11.2, 20.7));
    CHECK_FALSE(back[0].mask.contains(11.7, 20.7));
    CHECK(back[0].mask.contains(12.4, 21.9));
    CHECK_FALSE(back[0].mask.contains(12.6, 21.9));  // outside the grid
    const Grid<std::uint8_t> g = back[0].mask.grid();
    CHECK(g(2, 1) == 1);
    CHECK(g(3, 1) == 0);
    // A table as written before the masks: the same datasets without mask_*.
    {
        auto old = h5::File::create(dir.file("old.h5"));
        old.ensureGroup("/d");
        old.writeI32("/d/year", {3}, {1}, "years");
        old.writeI32("/d/month", {7}, {1}, "1");
        old.writeStrings("/d/kind", {"fire"});
        old.writeF64("/d/area", {2.5}, {1}, "m2");
        old.writeF64("/d/x", {1}, {1}, "m");
        old.writeF64("/d/y", {2}, {1}, "m");
        old.writeI32("/d/killed", fire.killed, {1, biome.species.size()}, "1");
    }
    auto o = h5::File::openRead(dir.file("old.h5"));
    const auto oldBack = readDisturbanceTable(o, "/d", biome.species.size());
    REQUIRE(oldBack.size() == 1);
    CHECK(oldBack[0].killed == fire.killed);
    CHECK_FALSE(oldBack[0].mask.present());
    // A malformed mask is refused with the dataset named.
    {
        auto bad = h5::File::create(dir.file("bad.h5"));
        DisturbanceRecord r = fire;
        r.mask.cells = {7, 6};  // not ascending
        writeDisturbanceTable(bad, "/disturbance", {r}, biome);
    }
    auto b = h5::File::openRead(dir.file("bad.h5"));
    CHECK_THROWS_WITH(readDisturbanceTable(b, "/disturbance", biome.species.size()), Catch::Contains("mask_cells"));
}

TEST_CASE("disturbance run: a biome whose wind differs from the abiotics' wind map is refused", "[disturbance][config]") {
    // The abiotics' exposure map was computed for wind from the east; the run's biome (the
    // embedded default) blows from the west. With fire on, the run stops before any output.
    test::TempDir dir("windmismatch");
    const SimInputs in = test::smallDemoScene();
    Biome easterly = in.biome;
    easterly.wind.directionDeg = 90;
    writeAbiotics(dir.file("east.h5"), in.abiotics, easterly, AbioticParams{});
    writeAbiotics(dir.file("west.h5"), in.abiotics, defaultBiome(), AbioticParams{});
    REQUIRE(defaultBiome().wind.directionDeg == 270);
    RunConfig c;
    c.canopyPath = "";  // EcoMod on empty ground
    c.params.kind = ModelKind::EcoMod;
    c.years = 1;
    c.disturbance.fire.enabled = true;
    c.disturbance.fire.timing.forcedYears = {0};
    c.abioticsPath = dir.file("east.h5");
    c.outputPath = dir.file("refused.h5");
    CHECK_THROWS_WITH(runSimulation(c, false),
                      Catch::Contains("east.h5: its wind map was computed for wind from 90 degrees at 5 m/s") &&
                          Catch::Contains("has wind from 270 degrees at 5 m/s"));
    CHECK_FALSE(std::filesystem::exists(c.outputPath));
    // The same biome as the map's: the run goes; without disturbance the wind is not used.
    c.abioticsPath = dir.file("west.h5");
    c.outputPath = dir.file("matching.h5");
    CHECK_NOTHROW(runSimulation(c, false));
    CHECK(std::filesystem::exists(c.outputPath));
    c.abioticsPath = dir.file("east.h5");
    c.outputPath = dir.file("quiet.h5");
    c.disturbance = DisturbanceSettings{};
    CHECK_NOTHROW(runSimulation(c, false));
}

TEST_CASE("disturbance pictures: each event is drawn over the plants at the end of its year, also after a resume",
          "[disturbance][sim][checkpoint]") {
    // A fire in year 1 of 5, with no snapshot until the last year: the picture must show the
    // stand of year 2's census (the plants just after the fire), not the last snapshot's.
    test::TempDir dir("eventpictures");
    const SimInputs in = test::smallDemoScene();
    writeAbiotics(dir.file("abiotics.h5"), in.abiotics, in.biome, AbioticParams{});
    RunConfig c;
    c.canopyPath = "";
    c.params.kind = ModelKind::EcoMod;
    c.years = 5;
    c.snapshotYears = {5};
    c.checkpointEveryYears = 1;
    c.disturbance.fire.enabled = true;
    c.disturbance.fire.timing.forcedYears = {1};
    c.disturbance.fire.spreadProbability = 0.6;
    c.disturbance.fire.severity = 1.0;
    c.disturbance.fire.scorchHeightM = 1000;
    c.abioticsPath = dir.file("abiotics.h5");
    c.outputPath = dir.file("full/sim.h5");
    c.pngDir = dir.file("full/png");
    std::vector<UndergrowthPlant> afterFire;
    std::vector<DisturbanceRecord> events;
    std::vector<Plant> canopy;
    SimArea area{};
    Biome biome;
    RunHooks hooks;
    hooks.onYear = [&](const Simulation& s, const RunRecord&) {
        if (s.yearsDone() == 2) {
            afterFire = s.plants();
            events = s.disturbances();
            canopy = s.relevantCanopy();
            area = s.area();
            biome = s.biome();
        }
    };
    runSimulation(c, false, hooks);
    REQUIRE(events.size() == 1);
    REQUIRE(events[0].killed.size() > 0);
    const std::string picture = dir.file("full/png/disturbance_000_year_0001_fire.png");
    REQUIRE(std::filesystem::exists(picture));
    renderDisturbancePng(dir.file("expected.png"), events[0], afterFire, canopy, area, biome,
                         describeDisturbance(events[0]) + "; plants at the end of its year (after 2 years)");
    CHECK(test::readAll(picture) == test::readAll(dir.file("expected.png")));
    // Stopped after year 3 (its checkpoint holds the picture) and resumed: the same bytes.
    c.outputPath = dir.file("part/sim.h5");
    c.pngDir = dir.file("part/png");
    RunHooks stop;
    stop.stopRequested = [] { return true; };
    int stops = 0;
    for (; stops < 10; ++stops) {
        const RunSummary r = runSimulation(c, stops > 0, stop);
        if (!r.stoppedEarly) break;
        CHECK_FALSE(std::filesystem::exists(dir.file("part/png/disturbance_000_year_0001_fire.png")));
    }
    CHECK(stops == 4);  // stopped after years 1, 2, 3 and 4; the fifth run finished
    CHECK(test::readAll(dir.file("part/png/disturbance_000_year_0001_fire.png")) == test::readAll(picture));
}
