// eco calibrate end to end (issue 28 item 4) on a tiny scene: the seeding probability
// recovered from the density that simulations at a known value gave (other seeds), within 10 %;
// the report, history and best configuration written; the same command again replays the
// search over the finished simulations and gives the same history. The global search options
// on the command line (recorded, refused when bad, replayed for the same seed), and parallel
// starts over two MPI ranks (the history of one process).
#include <catch2/catch.hpp>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

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

namespace {

/// A calibration of the seeding probability on the smallest scene (32 x 32 cells, 2 years,
/// about 1 s per simulation), with `calibrate` added to its [calibrate] table.
std::string writeTinyCalibrationSpec(const test::TempDir& dir, const std::string& name, const std::string& calibrate) {
    const std::string spec = dir.file(name);
    std::ofstream(spec) << "[calibrate]\nout_dir = \"" << dir.file("out") << "\"\nuncertainty = false\n" << calibrate << "\n"
                        << "[calibrate.parameters]\n\"model.seeding_probability\" = [0.0005, 0.004]\n"
                        << "[calibrate.base.run]\nout_dir = \"unused\"\n"
                        << "[calibrate.base.terrain]\nwidth = 32\nheight = 32\n"
                        << "[calibrate.base.chm]\n[calibrate.base.abiotics]\nsun_step_minutes = 120\n[calibrate.base.canopy]\n"
                        << "[calibrate.base.simulate]\nconfig = \"" << test::sourcePath("configs/sim-default.toml") << "\"\n"
                        << "years = 2\ncrop = [2.0, 2.0, 26.0, 26.0]\n"
                        << "[[target]]\noutput = \"density@2\"\nvalue = 1.0\nsd = 0.1\n";
    return spec;
}

}  // namespace

TEST_CASE("eco calibrate: the global search is recorded, a bad setting is refused naming its key and value, the same seed replays", "[calibrate][cli]") {
    namespace fs = std::filesystem;
    test::TempDir dir("calibrate_global");
    // Bad settings: refused before anything runs (a value in a file: exit 1, docs/robustness.md),
    // one line naming the file, the key and the value given.
    const std::vector<std::pair<std::string, std::vector<std::string>>> bad = {
        {"global = \"anneal\"", {"field 'global'", "'anneal'", "multistart, crs, crs2, isres"}},
        {"global = \"crs\"\nmax_evaluations = 8\nglobal_evaluations = 4\npopulation = 5", {"field 'global_evaluations'", "at least the population (5", "got 4"}},
        {"global = \"crs\"\npopulation = 4\nbatch = 5", {"field 'batch'", "at most the population (4)", "got 5"}},
        {"global = \"multistart\"\nbatch = 2", {"field 'batch'", "\"crs\"", "\"multistart\""}},
        {"global = \"multistart\"\nstarts = 1", {"field 'starts'", "2 .. 100", "got 1"}},
        {"global = \"multistart\"\nstarts = 101", {"field 'starts'", "got 101"}},
        {"global = \"multistart\"\nstarts = 2.5", {"field 'starts'", "integer"}},
        {"global = \"crs2\"\nstarts = 4", {"field 'starts'", "multistart", "\"crs2\""}},
        {"global = \"isres\"\nmax_evaluations = 10\nglobal_evaluations = 10", {"field 'global_evaluations'", "2 .. 9", "got 10"}},
        {"global = \"multistart\"\nglobal_evaluations = 5", {"field 'global_evaluations'", "\"multistart\""}},
        {"global = \"crs2\"\nseed = -3", {"field 'seed'", "got -3"}},
        {"seed = 4", {"field 'seed'", "global search"}},
        {"global = \"multistart\"\nstarts = 3\nparallel_starts = true\nmax_evaluations = 5", {"field 'max_evaluations'", "2 x starts (6)", "got 5"}},
        {"global = \"multistart\"\nparallel_starts = \"yes\"", {"field 'parallel_starts'", "true or false"}},
        {"global = \"none\"\nparallel_starts = true", {"field 'parallel_starts'", "multistart"}},
    };
    for (const auto& [setting, fragments] : bad) {
        INFO(setting);
        const std::string spec = writeTinyCalibrationSpec(dir, "bad.toml", setting);
        const auto r = test::runEco("calibrate " + spec);
        INFO(r.output);
        CHECK(r.exitCode == 1);
        CHECK(r.output.find("eco: error: " + spec) != std::string::npos);
        for (const std::string& f : fragments) CHECK(r.output.find(f) != std::string::npos);
        CHECK_FALSE(fs::exists(dir.file("out")));
    }

    // Multistart from 2 starts with seed 7: the report names the method, the seed and each
    // start's run; the history has the budget's evaluations.
    const std::string multistart = writeTinyCalibrationSpec(dir, "multistart.toml", "global = \"multistart\"\nstarts = 2\nseed = 7\nmax_evaluations = 4\nreplicates = 1");
    const auto r = test::runEco("calibrate " + multistart);
    INFO(r.output);
    REQUIRE(r.exitCode == 0);
    const std::string report = readTextFile(dir.file("out/calibration.md"));
    CHECK(report.find("Multistart: 2 local searches (the start, then quasi-random points, seed 7) sharing the budget.") != std::string::npos);
    CHECK(report.find("## Search runs") != std::string::npos);
    CHECK(report.find("| 1 | sbplx | 0.5 |") != std::string::npos);  // the first start: the middle
    CHECK(report.find("| 2 | sbplx |") != std::string::npos);
    const std::string history = readTextFile(dir.file("out/history.csv"));
    CHECK(std::count(history.begin(), history.end(), '\n') == 5);  // header and 4 evaluations
    CHECK(history.find("\n1,search,0.00225,") != std::string::npos);  // the middle of the range first
    // The same seed again: the same points (nothing simulated again), the same history.
    const auto again = test::runEco("calibrate " + multistart);
    INFO(again.output);
    REQUIRE(again.exitCode == 0);
    CHECK(again.output.find("started") == std::string::npos);
    CHECK(readTextFile(dir.file("out/history.csv")) == history);
    CHECK(readTextFile(dir.file("out/calibration.md")) == report);

    // ISRES for 2 evaluations (the 1 left is too few for the local polish): recorded as such.
    const std::string isres = writeTinyCalibrationSpec(dir, "isres.toml", "global = \"isres\"\nseed = 5\nmax_evaluations = 3\nglobal_evaluations = 2\nreplicates = 1");
    const auto g = test::runEco("calibrate " + isres + " --out-dir " + dir.file("isres"));
    INFO(g.output);
    REQUIRE(g.exitCode == 0);
    const std::string isresReport = readTextFile(dir.file("isres/calibration.md"));
    CHECK(isresReport.find("Global search: NLopt GN_ISRES (seed 5) for 2 evaluations, then `sbplx` from its best.") != std::string::npos);
    CHECK(isresReport.find("| 1 | isres |") != std::string::npos);
    CHECK(isresReport.find("\n| 2 | ") == std::string::npos);  // no second run
    CHECK(readTextFile(dir.file("isres/history.csv")).find("\n2,search,") != std::string::npos);
}

// (Child processes, members_at_once, run a round through the same ensemble runner, whose
// bytes the test "eco ensemble: members in child processes and under MPI..." compares.)
TEST_CASE("eco calibrate: parallel starts over two MPI ranks give the history of one process", "[calibrate][mpi][cli]") {
    test::TempDir dir("calibrate_procs");
    // 2 starts side by side, 2 evaluations each (2 rounds), 1 replicate: 2 simulations a round,
    // one per rank under MPI (the test's cost is its simulations; CI time is bounded).
    const std::string settings = "global = \"multistart\"\nstarts = 2\nparallel_starts = true\nseed = 7\nmax_evaluations = 4\nreplicates = 1\n";
    const std::string spec = writeTinyCalibrationSpec(dir, "calibrate.toml", settings);
    const auto ref = test::runEco("--no-provenance --threads 1 calibrate " + spec + " --out-dir " + dir.file("ref"));
    INFO(ref.output);
    REQUIRE(ref.exitCode == 0);
    const std::string history = readTextFile(dir.file("ref/history.csv"));
    // Evaluations 1 and 2 are the rounds' first: the two starts' first points.
    CHECK(history.find("\n1,search,0.00225,") != std::string::npos);
    CHECK(std::count(history.begin(), history.end(), '\n') == 5);
    const std::string report = readTextFile(dir.file("ref/calibration.md"));
    CHECK(report.find("side by side (parallel_starts: in rounds, one evaluation of each start per round, 2 evaluations each)") != std::string::npos);
    const auto body = [](const std::string& md) { return md.substr(md.find("## Parameters")); };

#ifdef ECO_TEST_HAVE_MPI
    // Two MPI ranks: every rank runs the search, the ranks share each round's simulations, rank
    // 0 writes the outputs. (Before, the second ensemble run of one process initialised MPI
    // again, and eco calibrate under mpirun aborted at its second evaluation.)
    const auto mpi = test::runEcoMpi(2, "--no-provenance calibrate " + spec + " --out-dir " + dir.file("mpi"));
    const std::string& output = mpi.output;
    INFO(output);
    REQUIRE(mpi.exitCode == 0);
    CHECK(output.find("2 MPI ranks") != std::string::npos);
    CHECK(output.find("[rank 1]: member") != std::string::npos);
    CHECK(readTextFile(dir.file("mpi/history.csv")) == history);
    CHECK(body(readTextFile(dir.file("mpi/calibration.md"))) == body(report));
#else
    WARN("MPI part skipped: this build has no MPI (install libopenmpi-dev and configure again)");
#endif
}

// global = "crs": a round's trial points are independent, so their simulations run side by
// side; the history must not depend on how many run at once.
TEST_CASE("eco calibrate: crs rounds give the same history with 1 or 2 members at once, and under MPI", "[calibrate][mpi][cli]") {
    test::TempDir dir("calibrate_crs");
    // A population of 2 (the start and one quasi-random point), then a round of 2 trial
    // points: 4 evaluations of 1 replicate, no polish (max_evaluations = global_evaluations + 1).
    const std::string settings = "global = \"crs\"\npopulation = 2\nbatch = 2\nseed = 3\nmax_evaluations = 5\nglobal_evaluations = 4\nreplicates = 1\n";
    const std::string one = writeTinyCalibrationSpec(dir, "one.toml", settings + "members_at_once = 1\n");
    const std::string two = writeTinyCalibrationSpec(dir, "two.toml", settings + "members_at_once = 2\n");
    const auto ref = test::runEco("--no-provenance --threads 1 calibrate " + one + " --out-dir " + dir.file("one"));
    INFO(ref.output);
    REQUIRE(ref.exitCode == 0);
    const std::string history = readTextFile(dir.file("one/history.csv"));
    CHECK(std::count(history.begin(), history.end(), '\n') == 5);  // header and 4 evaluations
    CHECK(history.find("\n1,search,0.00225,") != std::string::npos);  // the start: the middle of the range
    const std::string report = readTextFile(dir.file("one/calibration.md"));
    CHECK(report.find("Global search: controlled random search in rounds (crs, seed 3): a population of 2 points, then rounds of 2 trial points evaluated together, for 4 evaluations") != std::string::npos);
    CHECK(report.find("| 1 | crs | 0.5 |") != std::string::npos);
    const auto body = [](const std::string& md) { return md.substr(md.find("## Parameters")); };
    const auto both = test::runEco("--no-provenance calibrate " + two + " --out-dir " + dir.file("two"));
    INFO(both.output);
    REQUIRE(both.exitCode == 0);
    CHECK(both.output.find("2 members at once") != std::string::npos);
    CHECK(readTextFile(dir.file("two/history.csv")) == history);
    CHECK(body(readTextFile(dir.file("two/calibration.md"))) == body(report));
#ifdef ECO_TEST_HAVE_MPI
    const auto mpi = test::runEcoMpi(2, "--no-provenance calibrate " + one + " --out-dir " + dir.file("mpi"));
    INFO(mpi.output);
    REQUIRE(mpi.exitCode == 0);
    CHECK(readTextFile(dir.file("mpi/history.csv")) == history);
#else
    WARN("MPI part skipped: this build has no MPI (install libopenmpi-dev and configure again)");
#endif
}

TEST_CASE("eco calibrate: [calibrate.scene] fits on eco validate's forest scene, end to end, and refuses a bad scene naming it", "[calibrate][cli]") {
    namespace fs = std::filesystem;
    test::TempDir dir("calibrate_scene_cli");
    const auto write = [&](const std::string& name, const std::string& scene, const std::string& model) {
        const std::string spec = dir.file(name);
        std::ofstream(spec) << "[calibrate]\nout_dir = \"" << dir.file("out-" + name) << "\"\nmax_evaluations = 3\nuncertainty = false\n"
                            << "[calibrate.scene]\nfile = \"" << scene << "\"\nplot_size_m = 12\nyears = 4\nseeds = [11, 12]\n" << model
                            << "[calibrate.parameters]\n\"biome.species.Toyon.alpha\" = { low = 0.3, high = 0.9, start = 0.6 }\n"
                            << "[[target]]\noutput = \"share:Toyon@4\"\nvalue = 0.2\nsd = 0.1\n"
                            << "[[target]]\noutput = \"ratio:Toyon@4/2\"\nmin = 1.0\nsd = 0.5\n";
        return spec;
    };
    const std::string scene = test::sourcePath("configs/validation/scene_conifer_forest.toml");
    const std::string spec = write("c.toml", scene, "model = { roulette_age_exponent = 1.1 }\n");
    const auto r = test::runEco("calibrate " + spec);
    INFO(r.output);
    REQUIRE(r.exitCode == 0);
    for (const char* f : {"calibration.md", "history.csv", "best-biome.toml"}) CHECK(fs::exists(dir.file(std::string("out-c.toml/") + f)));
    // Each replicate simulates the scene with its own seed: the two differ.
    const std::string a = dir.file("out-c.toml/ensemble/members/e0001-r01/simulation.h5"), b = dir.file("out-c.toml/ensemble/members/e0001-r02/simulation.h5");
    REQUIRE(fs::exists(a));
    REQUIRE(fs::exists(b));
    CHECK(readTextFile(a) != readTextFile(b));
    std::ifstream in(dir.file("out-c.toml/history.csv"));
    std::string header, first;
    std::getline(in, header);
    std::getline(in, first);
    CHECK(header == "evaluation,purpose,biome.species.Toyon.alpha,share:Toyon@4,ratio:Toyon@4/2,chi2");
    CHECK(first.rfind("1,search,0.6,", 0) == 0);
    CHECK(readTextFile(dir.file("out-c.toml/calibration.md")).find("scene seeds 11, 12") != std::string::npos);
    // The best biome holds the fitted value; a rerun replays the finished simulations.
    CHECK(readTextFile(dir.file("out-c.toml/best-biome.toml")).find("alpha") != std::string::npos);
    const std::string history = readTextFile(dir.file("out-c.toml/history.csv"));
    const auto again = test::runEco("calibrate " + spec);
    CHECK(again.exitCode == 0);
    CHECK(again.output.find("scene member") == std::string::npos);  // nothing simulated again
    CHECK(readTextFile(dir.file("out-c.toml/history.csv")) == history);
    // A scene file with an unknown key, or a [model] override the simulator does not know: refused
    // before anything is simulated, naming the file and the key.
    const std::string badScene = dir.file("scene_bad.toml");
    std::ofstream(badScene) << readTextFile(scene) << "\n[extra]\nkey = 1\n";
    const auto s = test::runEco("calibrate " + write("s.toml", badScene, ""));
    CHECK(s.exitCode != 0);
    CHECK(s.output.find("scene_bad.toml") != std::string::npos);
    CHECK(s.output.find("extra") != std::string::npos);
    CHECK_FALSE(fs::exists(dir.file("out-s.toml/ensemble")));
    const auto m = test::runEco("calibrate " + write("m.toml", scene, "model = { no_such_constant = 3 }\n"));
    CHECK(m.exitCode != 0);
    CHECK(m.output.find("no_such_constant") != std::string::npos);
}
