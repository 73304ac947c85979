// eco calibrate (issue 28 item 4): chi2, the linearised uncertainty on Jacobians whose answer
// is known, and the specification's checks.
#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <functional>
#include <map>
#include <memory>
#include <sstream>
#include <thread>
#include <tuple>

#include "biome.h"
#include "calibrate.h"
#include "error.h"
#include "rng.h"
#include "sim_file.h"
#include "sim_file_fixture.h"
#include "test_util.h"

using namespace eco;
using namespace eco::pipeline;

TEST_CASE("calibrate: chi2 of simulated values against targets with their sd", "[calibrate]") {
    std::vector<CalibrationTarget> targets(2);
    targets[0].value = 1.0;
    targets[0].sd = 0.5;
    targets[1].value = -2.0;
    targets[1].sd = 2.0;
    CHECK(chiSquare(targets, {1.0, -2.0}) == 0);
    CHECK(chiSquare(targets, {2.0, 0.0}) == Approx(4.0 + 1.0));
}

TEST_CASE("calibrate: a one-sided target has no residual on its good side", "[calibrate]") {
    std::vector<CalibrationTarget> targets(3);
    targets[0].value = 0.8;  // at least 0.8
    targets[0].sd = 0.1;
    targets[0].side = CalibrationTarget::Side::AtLeast;
    targets[1].value = 2.0;  // at most 2
    targets[1].sd = 0.5;
    targets[1].side = CalibrationTarget::Side::AtMost;
    targets[2].value = 1.0;  // two-sided
    targets[2].sd = 1.0;
    CHECK(targets[0].residual(0.9) == 0);
    CHECK(targets[0].residual(0.6) == Approx(-2.0));
    CHECK(targets[1].residual(1.0) == 0);
    CHECK(targets[1].residual(3.0) == Approx(2.0));
    CHECK(targets[2].residual(0.0) == Approx(-1.0));
    CHECK(chiSquare(targets, {0.9, 1.0, 1.0}) == 0);
    CHECK(chiSquare(targets, {0.6, 3.0, 3.0}) == Approx(4.0 + 4.0 + 4.0));
    CHECK(chiSquare(targets, {0.8, 2.0, 1.0}) == 0);
}

TEST_CASE("calibrate: a [calibrate.scene] specification, and its bad keys refused with the file, key and value", "[calibrate]") {
    test::TempDir dir("calibrate_scene_spec");
    const std::string scene = dir.file("scene.toml");
    std::ofstream(scene) << "[scene]\n";  // loadCalibrationSpec checks only that it exists (eco calibrate parses it)
    const auto write = [&](const std::string& calibrate, const std::string& sceneKeys, const std::string& rest) {
        const std::string path = dir.file("c.toml");
        std::ofstream(path) << "[calibrate]\nout_dir = \"" << dir.file("out") << "\"\n" << calibrate << "\n[calibrate.scene]\n" << sceneKeys << "\n" << rest;
        return path;
    };
    const std::string keys = "file = \"scene.toml\"\nplot_size_m = 20\nyears = 5\nseeds = [101, 202, 303]\nmodel = { roulette_age_exponent = 1.1225 }\n";
    const std::string params = "[calibrate.parameters]\n\"biome.species.Toyon.alpha\" = [0.2, 0.7]\n\"model.seeding_probability\" = [0.001, 0.006]\n";
    const std::string target = "[[target]]\noutput = \"ratio:Toyon@5/2\"\nmin = 0.8\nsd = 0.1\n[[target]]\noutput = \"share:Toyon@3-5\"\nmax = 0.4\nsd = 0.1\n";
    const auto spec = loadCalibrationSpec(write("", keys, params + target));
    CHECK(spec.scene.file == scene);
    CHECK(spec.scene.plotSizeM == 20);
    CHECK(spec.scene.years == 5);
    CHECK(spec.scene.seeds == std::vector<std::uint64_t>{101, 202, 303});
    CHECK(spec.replicates == 3);  // one per scene seed
    CHECK(spec.scene.model == std::vector<std::string>{"roulette_age_exponent = 1.1225"});
    CHECK(spec.targets[0].side == CalibrationTarget::Side::AtLeast);
    CHECK(spec.targets[0].value == 0.8);
    CHECK(spec.targets[1].side == CalibrationTarget::Side::AtMost);
    // The parameters in key order, or as written in the file.
    const std::string reversed = "[calibrate.parameters]\n\"model.seeding_probability\" = [0.001, 0.006]\n\"biome.species.Toyon.alpha\" = [0.2, 0.7]\n";
    CHECK(loadCalibrationSpec(write("", keys, reversed + target)).parameters[0].key == "biome.species.Toyon.alpha");
    const auto written = loadCalibrationSpec(write("parameters_as_written = true", keys, reversed + target));
    REQUIRE(written.parameters.size() == 2);
    CHECK(written.parameters[0].key == "model.seeding_probability");
    CHECK(written.parameters[1].key == "biome.species.Toyon.alpha");
    CHECK(written.start[0] == Approx(0.0035));
    CHECK(written.start[1] == Approx(0.45));
    const std::vector<std::tuple<std::string, std::string, std::string, std::string>> bad = {
        {"", "file = \"nowhere.toml\"\nplot_size_m = 20\nyears = 5\nseeds = [1]", params + target, "nowhere.toml"},
        {"", "plot_size_m = 20\nyears = 5\nseeds = [1]", params + target, "file"},
        {"", "file = \"scene.toml\"\nplot_size_m = 2\nyears = 5\nseeds = [1]", params + target, "plot_size_m"},
        {"", "file = \"scene.toml\"\nplot_size_m = 20\nyears = 0\nseeds = [1]", params + target, "years"},
        {"", "file = \"scene.toml\"\nplot_size_m = 20\nyears = 5\nseeds = []", params + target, "seeds"},
        {"", "file = \"scene.toml\"\nplot_size_m = 20\nyears = 5\nseeds = [-3]", params + target, "-3"},
        {"", "file = \"scene.toml\"\nplot_size_m = 20\nyears = 5\nseeds = [1]\nbiome = \"nobiome.toml\"", params + target, "nobiome.toml"},
        {"", "file = \"scene.toml\"\nplot_size_m = 20\nyears = 5\nseeds = [1]\nplot = 3", params + target, "plot"},
        {"replicates = 2", keys, params + target, "replicates"},
        {"", keys, "[calibrate.base.run]\nout_dir = \"x\"\n" + params + target, "base"},
        {"", keys, "[calibrate.parameters]\n\"terrain.seed\" = [1, 9]\n" + target, "terrain.seed"},
        {"", keys, params + "[[target]]\noutput = \"density@3\"\nvalue = 1\nmin = 0.5\nsd = 0.1\n", "min"},
    };
    for (const auto& [calibrate, sceneKeys, rest, expect] : bad) {
        INFO(calibrate << "\n" << sceneKeys << "\n" << rest);
        CHECK_THROWS_WITH(loadCalibrationSpec(write(calibrate, sceneKeys, rest)), Catch::Contains("c.toml") && Catch::Contains(expect));
    }
}

TEST_CASE("calibrate: the linearised sd of the parameters from the Jacobian of the residuals", "[calibrate]") {
    // Two targets, each moved by one parameter: residual = 2 p0 and 4 p1 (in units of the
    // targets' sd), so p0 can move 0.5 and p1 0.25 for one sd of its target.
    const auto sd = linearisedSd({{2.0, 0.0}, {0.0, 4.0}});
    CHECK(sd[0] == Approx(0.5));
    CHECK(sd[1] == Approx(0.25));
    // Correlated: both parameters move the first target; the second tells them apart.
    // J = [[1, 1], [1, -1]]: J^T J = 2 I, sd = 1 / sqrt(2) each.
    const auto corr = linearisedSd({{1.0, 1.0}, {1.0, -1.0}});
    CHECK(corr[0] == Approx(std::sqrt(0.5)));
    CHECK(corr[1] == Approx(std::sqrt(0.5)));
    // Parameters of very different units (a probability near 0.003 and an alpha near 0.5).
    const auto units = linearisedSd({{4000.0, 0.0}, {0.0, 8.0}});
    CHECK(units[0] == Approx(0.00025));
    CHECK(units[1] == Approx(0.125));
    // Not identifiable: the targets see only the sum of the two, or one parameter moves nothing.
    for (double v : linearisedSd({{1.0, 1.0}, {2.0, 2.0}})) CHECK(std::isnan(v));
    for (double v : linearisedSd({{1.0, 0.0}, {3.0, 0.0}})) CHECK(std::isnan(v));
}

TEST_CASE("calibrate: a bad specification is refused with its file and key", "[calibrate]") {
    test::TempDir dir("calibrate_spec");
    const auto write = [&](const std::string& calibrate, const std::string& rest) {
        const std::string path = dir.file("c.toml");
        std::ofstream(path) << "[calibrate]\nout_dir = \"" << dir.file("out") << "\"\n" << calibrate
                            << "\n[calibrate.base.run]\nout_dir = \"x\"\n" << rest;
        return path;
    };
    const std::string params = "[calibrate.parameters]\n\"model.seeding_probability\" = [0.001, 0.006]\n";
    const std::string target = "[[target]]\noutput = \"density@3\"\nvalue = 1.5\nsd = 0.1\n";
    CHECK_NOTHROW(loadCalibrationSpec(write("", params + target)));
    const auto spec = loadCalibrationSpec(write("", params + target));
    CHECK(spec.start == std::vector<double>{0.0035});
    CHECK(spec.targets[0].value == 1.5);
    const std::vector<std::pair<std::pair<std::string, std::string>, std::string>> bad = {
        {{"algorithm = \"lbfgs\"", params + target}, "algorithm"},
        {{"max_evaluations = 1", params + target}, "max_evaluations"},
        {{"", params}, "no [[target]]"},
        {{"", "[calibrate.parameters]\n\"model.seeding_probability\" = [0.006, 0.001]\n" + target}, "LOW < HIGH"},
        {{"", "[calibrate.parameters]\n\"model.seeding_probability\" = { low = 0.001, high = 0.006, start = 0.01 }\n" + target}, "outside"},
        {{"", params + "[[target]]\noutput = \"density@3\"\nsd = 0.1\n"}, "value"},
        {{"", params + "[[target]]\noutput = \"density@3\"\nvalue = 1\nsd = 0\n"}, "sd"},
        {{"", params + "[calibrate.truth]\n\"model.seeding_probability\" = 0.5\n" + target}, "outside its range"},
        {{"", params + "[calibrate.truth]\n" + target}, "seeding_probability"},
        {{"global = \"basinhopping\"", params + target}, "global"},
        {{"starts = 4", params + target}, "starts"},
        {{"global = \"multistart\"\nstarts = 1", params + target}, "starts"},
        {{"global = \"crs2\"\nmax_evaluations = 20\nglobal_evaluations = 20", params + target}, "global_evaluations"},
        {{"global = \"multistart\"\nglobal_evaluations = 10", params + target}, "global_evaluations"},
        {{"seed = 3", params + target}, "seed"},
        {{"global = \"crs\"\npopulation = 1", params + target}, "population"},
        {{"global = \"crs\"\nmax_evaluations = 100\npopulation = 8\nbatch = 9", params + target}, "batch"},
        {{"global = \"crs\"\nmax_evaluations = 30", params + target}, "global_evaluations"},  // 15 < the default population 20
        {{"global = \"crs2\"\nbatch = 2", params + target}, "batch"},
        {{"population = 10", params + target}, "population"},
    };
    for (const auto& [files, expect] : bad) {
        INFO(files.first << "\n" << files.second);
        CHECK_THROWS_WITH(loadCalibrationSpec(write(files.first, files.second)), Catch::Contains("c.toml") && Catch::Contains(expect));
    }
    // With a truth, the targets need no value (the truth's simulations give it).
    const auto truth = loadCalibrationSpec(write("", params + "[calibrate.truth]\n\"model.seeding_probability\" = 0.002\n" +
                                                         "[[target]]\noutput = \"density@3\"\nsd = 0.1\n"));
    CHECK(truth.truth == std::vector<double>{0.002});
    // The global searches' keys.
    const auto multi = loadCalibrationSpec(write("global = \"multistart\"\nstarts = 6\nseed = 9", params + target));
    CHECK(multi.global == "multistart");
    CHECK(multi.starts == 6);
    CHECK(multi.seed == 9);
    const auto crs = loadCalibrationSpec(write("global = \"crs2\"\nmax_evaluations = 30", params + target));
    CHECK(crs.globalEvaluations == 15);
    CHECK(searchSettingsOf(crs).global == "crs2");
    const auto rounds = loadCalibrationSpec(write("global = \"crs\"\nmax_evaluations = 60\nglobal_evaluations = 40\npopulation = 12\nbatch = 4\nseed = 3", params + target));
    CHECK(searchSettingsOf(rounds).global == "crs");
    CHECK(searchSettingsOf(rounds).population == 12);
    CHECK(searchSettingsOf(rounds).batchSize == 4);
    CHECK(searchSettingsOf(rounds).globalEvaluations == 40);
    // Defaults: 10 (k + 1) points, rounds of k + 1.
    const auto defaults = loadCalibrationSpec(write("global = \"crs\"\nmax_evaluations = 60", params + target));
    CHECK(crsPopulation(searchSettingsOf(defaults), 1) == 20);
    CHECK(crsBatchSize(searchSettingsOf(defaults), 1) == 2);
}

namespace {

/// A function of the unit square with four minima: each coordinate has a broad shallow well
/// at 0.6 (g = 0) and a narrow deep one near 0.1 (g = -0.156 at 0.11238): the global minimum
/// -0.312 at (0.11238, 0.11238), local ones at (0.11238, 0.6), (0.6, 0.11238) and (0.6, 0.6)
/// (-0.156 and 0). From the middle, (0.5, 0.5), a local search goes down into (0.6, 0.6).
constexpr double kDeepWell = 0.11238;
double twoWells(const std::vector<double>& u) {
    double f = 0;
    for (double x : u) f += (x - 0.6) * (x - 0.6) - 0.4 * std::exp(-std::pow((x - 0.1) / 0.1, 2));
    return f;
}

/// A batch objective of twoWells that records each batch (round) it is given, and evaluates
/// its points one after the other.
BatchObjective roundsOfTwoWells(std::vector<std::vector<std::vector<double>>>& rounds) {
    return [&rounds](const std::vector<std::vector<double>>& xs) {
        rounds.push_back(xs);
        std::vector<double> v;
        for (const auto& x : xs) v.push_back(twoWells(x));
        return v;
    };
}

/// A search whose third batch (round) throws stops, and that error comes through.
void checkFailingRoundStops(const std::function<double(const std::vector<double>&)>& f, const std::vector<double>& start, const SearchSettings& s) {
    int calls = 0;
    CHECK_THROWS_WITH(minimiseInUnitCube(f, start, s,
                                         [&](const std::vector<std::vector<double>>& xs) {
                                             if (++calls == 3) throw ValidationError("round 3 failed");
                                             return std::vector<double>(xs.size(), 1.0);
                                         }),
                      Catch::Contains("round 3 failed"));
    CHECK(calls == 3);
}

}  // namespace

TEST_CASE("calibrate search: on a function with several minima the local method is trapped, the global searches are not", "[calibrate]") {
    const std::vector<double> middle{0.5, 0.5};
    SearchSettings local;
    local.maxEvaluations = 300;
    local.tolerance = 1e-4;
    local.initialStep = 0.1;  // local searches from spread starts: a first step shorter than the default
    const SearchResult trapped = minimiseInUnitCube(twoWells, middle, local);
    REQUIRE(trapped.runs.size() == 1);
    CHECK(trapped.converged);  // stopped by the tolerance, in the wrong well
    CHECK(trapped.best[0] == Approx(0.6).margin(0.005));
    CHECK(trapped.best[1] == Approx(0.6).margin(0.005));
    CHECK(trapped.value > -0.01);
    CHECK(twoWells({kDeepWell, kDeepWell}) == Approx(-0.3122).margin(1e-4));
    for (const std::string global : {"multistart", "crs2", "isres"}) {
        INFO(global);
        SearchSettings s = local;
        s.global = global;
        s.starts = 16;
        s.maxEvaluations = global == "crs2" ? 600 : 3000;
        std::vector<std::vector<double>> points;
        const auto recorded = [&](const std::vector<double>& x) {
            points.push_back(x);
            return twoWells(x);
        };
        const SearchResult found = minimiseInUnitCube(recorded, middle, s);
        for (const SearchRun& r : found.runs) UNSCOPED_INFO(r.method << " from " << r.start[0] << ", " << r.start[1] << ": " << r.best[0] << ", " << r.best[1] << " f " << r.value << " in " << r.evaluations << " (" << r.stopReason << ")");
        CHECK(found.best[0] == Approx(kDeepWell).margin(0.005));
        CHECK(found.best[1] == Approx(kDeepWell).margin(0.005));
        CHECK(found.value < -0.3);
        CHECK(found.converged);  // the best's local search stopped by the tolerance
        CHECK(found.evaluations == static_cast<int>(points.size()));
        CHECK(found.evaluations <= s.maxEvaluations);
        for (const auto& x : points)
            for (double v : x) {
                CHECK(v >= 0);
                CHECK(v <= 1);
            }
        // Deterministic: the same settings evaluate the same points in the same order.
        std::vector<std::vector<double>> again;
        const SearchResult repeat = minimiseInUnitCube([&](const std::vector<double>& x) { again.push_back(x); return twoWells(x); }, middle, s);
        CHECK(again == points);
        CHECK(repeat.best == found.best);
        // Another seed: other points.
        s.seed = 2;
        std::vector<std::vector<double>> other;
        minimiseInUnitCube([&](const std::vector<double>& x) { other.push_back(x); return twoWells(x); }, middle, s);
        CHECK(other != points);
    }
}

TEST_CASE("calibrate search: multistart points begin with the start and spread over the unit cube", "[calibrate]") {
    const auto p = multistartPoints(3, 16, {0.2, 0.4, 0.6}, 1);
    REQUIRE(p.size() == 16);
    CHECK(p[0] == std::vector<double>{0.2, 0.4, 0.6});
    // Each coordinate of the 15 others: one point in each of 15 of the 16 sixteenths (the
    // shifted Sobol' points 1 .. 15 of 0 .. 15, which are stratified).
    for (std::size_t i = 0; i < 3; ++i) {
        std::vector<int> per(16, 0);
        for (std::size_t n = 1; n < p.size(); ++n) {
            REQUIRE(p[n][i] >= 0);
            REQUIRE(p[n][i] < 1);
            ++per[static_cast<std::size_t>(p[n][i] * 16)];
        }
        CHECK(*std::max_element(per.begin(), per.end()) == 1);
    }
    CHECK(multistartPoints(3, 16, {0.2, 0.4, 0.6}, 2) != p);
    CHECK(multistartPoints(3, 16, {0.2, 0.4, 0.6}, 1) == p);
    // A throwing objective stops the search and its exception comes through.
    SearchSettings s;
    CHECK_THROWS_WITH(minimiseInUnitCube([](const std::vector<double>&) -> double { throw ValidationError("boom"); }, {0.5}, s),
                      Catch::Contains("boom"));
}

TEST_CASE("calibrate search: parallel starts run in rounds, each start as it would run alone", "[calibrate]") {
    const std::vector<double> middle{0.5, 0.5};
    SearchSettings s;
    s.global = "multistart";
    s.parallelStarts = true;
    s.starts = 6;
    s.maxEvaluations = 600;  // 100 per start
    s.tolerance = 1e-4;
    s.initialStep = 0.1;
    std::vector<std::vector<std::vector<double>>> rounds;
    const BatchObjective batch = roundsOfTwoWells(rounds);
    const auto unused = [](const std::vector<double>&) -> double { throw ValidationError("the batch objective is used"); };
    const SearchResult found = minimiseInUnitCube(unused, middle, s, batch);
    REQUIRE(found.runs.size() == 6);
    CHECK(found.best[0] == Approx(kDeepWell).margin(0.005));
    CHECK(found.best[1] == Approx(kDeepWell).margin(0.005));
    // Round n holds the n-th point of every start still searching, in the order of the starts:
    // start i's points are the i-th of the rounds it takes part in, and they are the points of
    // the same local search run alone from that start with the same share of the budget.
    const auto starts = multistartPoints(2, 6, middle, s.seed);
    REQUIRE(rounds.size() > 1);
    CHECK(rounds.front().size() == 6);
    int total = 0;
    for (std::size_t i = 0; i < 6; ++i) {
        INFO("start " << i);
        SearchSettings alone = s;
        alone.global = "none";
        alone.parallelStarts = false;
        alone.maxEvaluations = 100;
        std::vector<std::vector<double>> own;
        const SearchResult single = minimiseInUnitCube([&](const std::vector<double>& x) { own.push_back(x); return twoWells(x); }, starts[i], alone);
        CHECK(found.runs[i].start == starts[i]);
        CHECK(found.runs[i].best == single.best);
        CHECK(found.runs[i].evaluations == static_cast<int>(own.size()));
        CHECK(found.runs[i].evaluations <= 100);
        total += found.runs[i].evaluations;
        // The rounds have shrinking sizes (a search that stops leaves them); start i's n-th
        // point sits in round n at its rank among the starts still running.
        for (std::size_t n = 0; n < own.size(); ++n) {
            REQUIRE(n < rounds.size());
            std::size_t before = 0;  // starts before i that still search in round n
            for (std::size_t j = 0; j < i; ++j)
                if (static_cast<int>(n) < found.runs[j].evaluations) ++before;
            REQUIRE(before < rounds[n].size());
            CHECK(rounds[n][before] == own[n]);
        }
    }
    std::size_t inRounds = 0;
    for (const auto& r : rounds) inRounds += r.size();
    CHECK(static_cast<int>(inRounds) == total);
    CHECK(found.evaluations == total);
    // The same settings, the same rounds.
    const auto first = rounds;
    rounds.clear();
    minimiseInUnitCube(unused, middle, s, batch);
    CHECK(rounds == first);
    // Without a batch objective the rounds go one point after the other through f: the same result.
    const SearchResult serial = minimiseInUnitCube(twoWells, middle, s);
    CHECK(serial.best == found.best);
    CHECK(serial.evaluations == found.evaluations);
    // A round that fails stops every search, and its error comes through.
    checkFailingRoundStops(unused, middle, s);
    // Fewer than 2 evaluations per start: refused.
    s.maxEvaluations = 11;
    CHECK_THROWS_WITH(minimiseInUnitCube(twoWells, middle, s), Catch::Contains("2 x starts"));
}

TEST_CASE("calibrate: a stem map's pair correlation as a target, measured against a snapshot's plants", "[calibrate]") {
    test::TempDir dir("calibrate_pcf");
    const Biome biome = defaultBiome();
    const int toyon = biome.speciesIndex("Toyon"), fern = biome.speciesIndex("Western Swordfern");
    // The stem map: Toyons on a 2 m grid in a 20 m x 20 m window (no two closer than 2 m: g = 0
    // below 2 m), and ferns at random (another species: left out by the target's species).
    std::vector<UndergrowthPlant> grid, ferns;
    std::ostringstream csv;
    csv << "x,y,species\n";
    for (int i = 0; i < 10; ++i)
        for (int j = 0; j < 10; ++j) {
            UndergrowthPlant p;
            p.id = static_cast<std::uint64_t>(grid.size() + 1);
            p.speciesId = toyon;
            p.xM = 1 + 2 * i;
            p.yM = 1 + 2 * j;
            p.heightM = 3;
            p.crownRadiusM = 0.5;
            grid.push_back(p);
            csv << p.xM << "," << p.yM << ",Toyon\n";
        }
    RandomStream rs(3, 0);
    for (int i = 0; i < 60; ++i) {
        UndergrowthPlant p;
        p.id = 1000 + static_cast<std::uint64_t>(i);
        p.speciesId = fern;
        p.xM = rs.uniform(0, 20);
        p.yM = rs.uniform(0, 20);
        p.heightM = 0.5;
        p.crownRadiusM = 0.2;
        ferns.push_back(p);
        csv << p.xM << "," << p.yM << ",Western Swordfern\n";
    }
    std::ofstream(dir.file("stems.csv")) << csv.str();
    const RectWindow window{0, 0, 20, 20};
    const PairCorrelationReference ref = pairCorrelationReference(dir.file("stems.csv"), window, "Toyon", 4.0, 8, 0.0, 1.0);
    CHECK(ref.points == 100);
    for (int k = 0; k < 4; ++k) CHECK(ref.observed[static_cast<std::size_t>(k)] == 0);  // r < 2 m
    CHECK(ref.observed[4] > 1);  // the grid's 2 m neighbours
    CHECK_THROWS_WITH(pairCorrelationReference(dir.file("stems.csv"), window, "Tanoak", 4.0, 8, 0.0, 0.0), Catch::Contains("no species 'Tanoak'"));
    CHECK_THROWS_WITH(pairCorrelationReference(dir.file("stems.csv"), window, "Toyon", 12.0, 8, 0.0, 0.0), Catch::Contains("half"));

    // Simulations over the same window: snapshot of year 5.
    SimulationOutput out = parseSimulationOutput("pcf:Toyon@5", "t");
    out.pcf = std::make_shared<const PairCorrelationReference>(ref);
    const auto simulate = [&](const std::string& name, std::vector<UndergrowthPlant> plants) {
        const std::string path = dir.file(name);
        test::writeSnapshotSimulation(path, biome, 5, {{5, plants}});
        return measureOutput(path, out);
    };
    // The same Toyons with the ferns and with Toyon seedlings below min_height (1 m): no difference.
    std::vector<UndergrowthPlant> same = grid;
    same.insert(same.end(), ferns.begin(), ferns.end());
    for (int i = 0; i < 30; ++i) {
        UndergrowthPlant p = grid[static_cast<std::size_t>(i)];
        p.id = 5000 + static_cast<std::uint64_t>(i);
        p.xM += 0.3;
        p.heightM = 0.2;
        same.push_back(p);
    }
    CHECK(simulate("same.h5", same) == 0);
    // The seedlings above min_height: pairs at 0.3 m, g of the first bin far above 0.
    std::vector<UndergrowthPlant> close = same;
    for (auto& p : close) p.heightM = std::max(p.heightM, 1.5);
    std::vector<double> x, y;
    for (const auto& p : close)
        if (p.speciesId == toyon) {
            x.push_back(p.xM);
            y.push_back(p.yM);
        }
    const std::vector<double> g = pairCorrelation(x, y, window, ref.bins);
    CHECK(g[0] > 1);
    double sq = 0;
    for (int k = 0; k < 8; ++k) sq += std::pow(g[static_cast<std::size_t>(k)] - ref.observed[static_cast<std::size_t>(k)], 2);
    const double rms = simulate("close.h5", close);
    CHECK(rms == Approx(std::sqrt(sq / 8)));
    CHECK(rms > 0.3);
    // r_min leaves the first bins out.
    PairCorrelationReference far = ref;
    far.rMinM = 1.0;
    double sqFar = 0;
    for (int k = 2; k < 8; ++k) sqFar += std::pow(g[static_cast<std::size_t>(k)] - ref.observed[static_cast<std::size_t>(k)], 2);
    CHECK(pairCorrelationDistance(far, g) == Approx(std::sqrt(sqFar / 6)));
    // No stem map: refused.
    CHECK_THROWS_WITH(measureOutput(dir.file("same.h5"), parseSimulationOutput("pcf@5", "t")), Catch::Contains("stem map"));

    // In a specification: a [[target]] with stem_map, window, r_max; no value.
    const std::string head = "[calibrate]\nout_dir = \"" + dir.file("out") + "\"\n[calibrate.parameters]\n\"model.seeding_probability\" = { low = 0.0001, high = 0.01, scale = \"log\" }\n"
                             "\"biome.species.Toyon.max_age_years\" = { low = 50, high = 200, integer = true, start = 150 }\n[calibrate.base.run]\nout_dir = \"x\"\n";
    const auto write = [&](const std::string& target) {
        const std::string path = dir.file("c.toml");
        std::ofstream(path) << head << "[[target]]\noutput = \"density@5\"\nvalue = 1\nsd = 0.1\n[[target]]\n" << target;
        return path;
    };
    const CalibrationSpec spec = loadCalibrationSpec(write("output = \"pcf:Toyon@5\"\nstem_map = \"stems.csv\"\nwindow = [0, 0, 20, 20]\nr_max = 4.0\nbins = 8\nmin_height = 1.0\nsd = 0.2\n"));
    REQUIRE(spec.targets.size() == 2);
    REQUIRE(spec.targets[1].output.pcf);
    CHECK(spec.targets[1].value == 0);
    CHECK(spec.targets[1].output.pcf->observed == ref.observed);
    // The log-scaled parameter starts in the middle of its log range; the integer at its start.
    std::map<std::string, double> start;
    for (std::size_t i = 0; i < spec.parameters.size(); ++i) start[spec.parameters[i].key] = spec.start[i];
    CHECK(start["model.seeding_probability"] == Approx(0.001));
    CHECK(start["biome.species.Toyon.max_age_years"] == 150);
    for (const auto& [target, expect] : std::vector<std::pair<std::string, std::string>>{
             {"output = \"pcf@5\"\nstem_map = \"stems.csv\"\nwindow = [0, 0, 20, 20]\nr_max = 4.0\nvalue = 0\nsd = 0.2\n", "value"},
             {"output = \"pcf@5\"\nstem_map = \"stems.csv\"\nwindow = [0, 0, 20]\nr_max = 4.0\nsd = 0.2\n", "window"},
             {"output = \"pcf@5\"\nstem_map = \"stems.csv\"\nwindow = [0, 0, 20, 20]\nr_max = 11.0\nsd = 0.2\n", "half"},
             {"output = \"pcf@5\"\nstem_map = \"none.csv\"\nwindow = [0, 0, 20, 20]\nr_max = 4.0\nsd = 0.2\n", "none.csv"},
             {"output = \"density@5\"\nvalue = 1\nr_max = 4.0\nsd = 0.2\n", "pcf targets"},
         }) {
        INFO(target);
        CHECK_THROWS_WITH(loadCalibrationSpec(write(target)), Catch::Contains("c.toml") && Catch::Contains(expect));
    }
}

TEST_CASE("calibrate search: crs evaluates rounds of trial points, finds the global minimum, and its rounds do not depend on how they run", "[calibrate]") {
    const std::vector<double> middle{0.5, 0.5};
    SearchSettings s;
    s.global = "crs";
    s.maxEvaluations = 700;
    s.globalEvaluations = 600;
    s.tolerance = 1e-3;
    s.initialStep = 0.02;  // the polish starts next to the minimum
    s.population = 20;
    s.batchSize = 4;
    std::vector<std::vector<std::vector<double>>> rounds;
    const BatchObjective serial = roundsOfTwoWells(rounds);  // one point after the other in this thread
    // The global phase goes through the batch objective, the local polish through f.
    int polished = 0;
    const auto polish = [&](const std::vector<double>& x) {
        ++polished;
        return twoWells(x);
    };
    const SearchResult found = minimiseInUnitCube(polish, middle, s, serial);
    REQUIRE(found.runs.size() == 2);
    const SearchRun& crs = found.runs[0];
    for (const SearchRun& r : found.runs) UNSCOPED_INFO(r.method << ": " << r.best[0] << ", " << r.best[1] << " f " << r.value << " in " << r.evaluations << " (" << r.stopReason << ")");
    CHECK(crs.method == "crs");
    // The global phase itself converges: its population contracts within the tolerance
    // around the deep well (the global minimum), before its budget.
    CHECK(crs.converged);
    CHECK(crs.stopReason == "the population contracted within the tolerance");
    CHECK(crs.evaluations < s.globalEvaluations);
    CHECK(crs.best[0] == Approx(kDeepWell).margin(0.002));
    CHECK(crs.best[1] == Approx(kDeepWell).margin(0.002));
    CHECK(found.value < -0.312);
    CHECK(found.converged);
    CHECK(polished == found.runs[1].evaluations);
    // The first round is the population (the start, then the multistart points); every later
    // round has the batch size's trial points (the last one at most), inside the cube.
    REQUIRE(rounds.size() > 2);
    CHECK(rounds[0] == multistartPoints(2, 20, middle, s.seed));
    std::size_t total = 0;
    for (std::size_t n = 1; n < rounds.size(); ++n) {
        CHECK(rounds[n].size() == 4);
        for (std::size_t i = 0; i < rounds[n].size(); ++i)
            for (std::size_t j = 0; j < i; ++j) CHECK(rounds[n][i] != rounds[n][j]);  // a repeated trial is drawn again
        for (const auto& x : rounds[n])
            for (double v : x) {
                CHECK(v >= 0);
                CHECK(v <= 1);
            }
        total += rounds[n].size();
    }
    CHECK(static_cast<int>(rounds[0].size() + total) == crs.evaluations);
    // The rounds' points are independent of each other: two workers evaluating a round's
    // halves side by side (as members_at_once children or MPI ranks do) give the same rounds.
    const auto first = rounds;
    rounds.clear();
    const BatchObjective twoAtOnce = [&](const std::vector<std::vector<double>>& xs) {
        rounds.push_back(xs);
        std::vector<double> v(xs.size());
        const std::size_t half = xs.size() / 2;
        std::thread other([&] {
            for (std::size_t i = half; i < xs.size(); ++i) v[i] = twoWells(xs[i]);
        });
        for (std::size_t i = 0; i < half; ++i) v[i] = twoWells(xs[i]);
        other.join();
        return v;
    };
    const SearchResult parallel = minimiseInUnitCube(polish, middle, s, twoAtOnce);
    CHECK(rounds == first);
    CHECK(parallel.best == found.best);
    CHECK(parallel.evaluations == found.evaluations);
    // Without a batch objective the rounds go through f one point after the other: the same.
    std::vector<std::vector<double>> points;
    const SearchResult oneByOne = minimiseInUnitCube([&](const std::vector<double>& x) { points.push_back(x); return twoWells(x); }, middle, s);
    CHECK(oneByOne.best == found.best);
    std::vector<std::vector<double>> flat;
    for (const auto& r : first)
        for (const auto& x : r) flat.push_back(x);
    REQUIRE(points.size() > flat.size());  // the polish follows
    CHECK(std::vector<std::vector<double>>(points.begin(), points.begin() + static_cast<std::ptrdiff_t>(flat.size())) == flat);
    // Another seed: other rounds.
    rounds.clear();
    s.seed = 2;
    minimiseInUnitCube(polish, middle, s, serial);
    CHECK(rounds != first);
    // A budget too small for the population is refused; a failing round stops the search.
    s.globalEvaluations = 19;
    CHECK_THROWS_WITH(minimiseInUnitCube(twoWells, middle, s), Catch::Contains("population"));
    s.globalEvaluations = 600;
    checkFailingRoundStops(polish, middle, s);
}
