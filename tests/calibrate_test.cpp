// eco calibrate (issue 28 item 4): chi2, the linearised uncertainty on Jacobians whose answer
// is known, and the specification's checks.
#include <catch2/catch.hpp>

#include <cmath>
#include <fstream>

#include "calibrate.h"
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
    };
    for (const auto& [files, expect] : bad) {
        INFO(files.first << "\n" << files.second);
        CHECK_THROWS_WITH(loadCalibrationSpec(write(files.first, files.second)), Catch::Contains("c.toml") && Catch::Contains(expect));
    }
    // With a truth, the targets need no value (the truth's simulations give it).
    const auto truth = loadCalibrationSpec(write("", params + "[calibrate.truth]\n\"model.seeding_probability\" = 0.002\n" +
                                                         "[[target]]\noutput = \"density@3\"\nsd = 0.1\n"));
    CHECK(truth.truth == std::vector<double>{0.002});
}
