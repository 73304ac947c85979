// eco calibrate end to end (issue 28 item 4) on a tiny scene: the seeding probability
// recovered from the density that simulations at a known value gave (other seeds), within 10 %;
// the report, history and best configuration written; the same command again replays the
// search over the finished simulations and gives the same history.
#include <catch2/catch.hpp>

#include <filesystem>
#include <fstream>
#include <sstream>

#include "atomic_file.h"
#include "test_util.h"

using namespace eco;

TEST_CASE("eco calibrate: recovers a known seeding probability, and a rerun replays the finished search", "[calibrate][cli]") {
    namespace fs = std::filesystem;
    test::TempDir dir("calibrate_cli");
    const std::string spec = dir.file("calibrate.toml");
    std::ofstream(spec) << "[calibrate]\nout_dir = \"" << dir.file("out") << "\"\nmax_evaluations = 12\nreplicates = 1\n"
                        << "[calibrate.parameters]\n\"model.seeding_probability\" = [0.0005, 0.004]\n"
                        << "[calibrate.truth]\n\"model.seeding_probability\" = 0.0015\n"
                        << "[calibrate.base.run]\nout_dir = \"unused\"\n"
                        << "[calibrate.base.terrain]\nwidth = 48\nheight = 48\n"
                        << "[calibrate.base.chm]\n[calibrate.base.abiotics]\nsun_step_minutes = 60\n[calibrate.base.canopy]\n"
                        << "[calibrate.base.simulate]\nconfig = \"" << test::sourcePath("configs/sim-default.toml") << "\"\n"
                        << "years = 3\ncrop = [4.0, 4.0, 40.0, 40.0]\n"
                        << "[[target]]\noutput = \"density@3\"\nsd = 0.02\n";
    const auto r = test::runEco("calibrate " + spec);
    INFO(r.output);
    REQUIRE(r.exitCode == 0);
    for (const char* f : {"calibration.md", "history.csv", "best-simulate.toml", "png/chi2.png"}) CHECK(fs::exists(dir.file(std::string("out/") + f)));
    CHECK_FALSE(fs::exists(dir.file("out/best-biome.toml")));  // no biome key was fitted
    // The best value, from the history: the row of least chi2 among the search's.
    std::ifstream in(dir.file("out/history.csv"));
    std::string line;
    std::getline(in, line);
    CHECK(line == "evaluation,purpose,model.seeding_probability,density@3,chi2");
    double bestChi2 = 1e300, best = 0;
    int rows = 0;
    while (std::getline(in, line)) {
        std::stringstream ls(line);
        std::string index, purpose, value, density, chi2;
        std::getline(ls, index, ',');
        std::getline(ls, purpose, ',');
        std::getline(ls, value, ',');
        std::getline(ls, density, ',');
        std::getline(ls, chi2, ',');
        ++rows;
        if (purpose == "search" && std::stod(chi2) < bestChi2) {
            bestChi2 = std::stod(chi2);
            best = std::stod(value);
        }
    }
    CHECK(rows >= 5);
    CHECK(best == Approx(0.0015).epsilon(0.10));
    CHECK(readTextFile(dir.file("out/best-simulate.toml")).find("seeding_probability") != std::string::npos);
    const std::string report = readTextFile(dir.file("out/calibration.md"));
    CHECK(report.find("| truth | best - truth |") != std::string::npos);

    // Again: the optimiser replays the same evaluations over the finished simulations.
    const std::string history = readTextFile(dir.file("out/history.csv"));
    const auto again = test::runEco("calibrate " + spec);
    INFO(again.output);
    REQUIRE(again.exitCode == 0);
    CHECK(again.output.find("started") == std::string::npos);
    CHECK(readTextFile(dir.file("out/history.csv")) == history);
}
