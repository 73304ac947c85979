// Crash tests that really kill (issue 26 item 5): `eco simulate`, `eco analyse` and `eco synth`
// run as child processes and are killed with SIGKILL, at times drawn from a fixed seed and,
// deterministically, at named points of their writers (ECO_TEST_PAUSE_AT: the child stops
// itself there with SIGSTOP and the test kills it; core/atomic_file.h testPausePoint). After
// each kill the previous outputs must be intact and a rerun must finish the job: a resumed
// simulation gives the uninterrupted run's file, a killed set commit is completed by the next
// run, and no temporary of a dead process stays. The tests only ever signal the children
// they started, by pid.
#include <catch2/catch.hpp>
#include <fcntl.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <map>
#include <random>
#include <thread>

#include "canopy_file.h"
#include "eco_child.h"
#include "h5_compare.h"
#include "sim_file_fixture.h"
#include "sim_run.h"
#include "sim_scene_fixture.h"
#include "synth_world_files.h"
#include "test_util.h"

using namespace eco;

namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;
using test::EcoChild;
using test::snapshotFiles;

std::string readLog(const std::string& path) { return test::fileBytes(path); }

/// The hidden files (temporaries `.x.tmp<pid>`, set journals `.x.set<pid>`) in `dir` and below.
std::vector<std::string> hiddenFiles(const fs::path& dir) {
    std::vector<std::string> out;
    for (const auto& e : fs::recursive_directory_iterator(dir))
        if (e.path().filename().string().rfind('.', 0) == 0) out.push_back(e.path().string());
    return out;
}

std::string tempOf(const std::string& finalPath, pid_t pid) {
    const fs::path p(finalPath);
    return (p.parent_path() / ("." + p.filename().string() + ".tmp" + std::to_string(pid))).string();
}

// Scene files of the simulator tests: abiotics.h5 and canopy.h5 (as simulator_cli_test.cpp).
void writeSimulationInputs(const test::TempDir& dir) {
    const sim::SimInputs in = test::smallDemoScene();
    writeAbiotics(dir.file("abiotics.h5"), in.abiotics, in.biome, AbioticParams{});
    auto f = h5::File::create(dir.file("canopy.h5"));
    setCanopyFormat(f);
    writePlants(f, "/canopy", in.canopy, in.biome);
    f.ensureGroup("/chm");
    f.writeGrid("/chm/height", in.chmM, "m");
}

}  // namespace

TEST_CASE("kill: eco simulate killed at random times and inside checkpoint writes resumes to the uninterrupted result",
          "[kill][sim][cli][checkpoint]") {
    test::TempDir dir("kill_sim");
    writeSimulationInputs(dir);
    fs::create_directories(dir.path() / "ref");
    fs::create_directories(dir.path() / "killed");
    // Every run, the first and the resumed ones, is the same command with --resume; a checkpoint
    // every year.
    auto command = [&](const std::string& sub) {
        return std::vector<std::string>{"--no-provenance", "--threads", "2", "simulate", "--abiotics", dir.file("abiotics.h5"),
                                        "--canopy", dir.file("canopy.h5"), "--crop", "4,4,40,40", "--seed", "4",
                                        "--years", "12", "--snapshot-years", "3,6,9", "--checkpoint-every", "1",
                                        "--resume", "--out", dir.file(sub + "/sim.h5"), "--csv", dir.file(sub + "/plants.csv")};
    };
    const std::string log = dir.file("log.txt");
    const auto t0 = Clock::now();
    {
        EcoChild ref(command("ref"), "", log);
        INFO(readLog(log));
        REQUIRE(ref.wait() == 0);
    }
    const auto runMs = std::chrono::duration_cast<std::chrono::milliseconds>(Clock::now() - t0).count();
    const std::string out = dir.file("killed/sim.h5"), checkpoint = dir.file("killed/sim.h5.checkpoint.h5");
    const std::string ckptName = "sim.h5.checkpoint.h5";

    // 1. Killed inside the third checkpoint write (its temporary open and partly written).
    pid_t deadWriter = 0;
    {
        EcoChild c(command("killed"), "write:" + ckptName + "#3", log);
        REQUIRE(c.killAtPausePoint());
        deadWriter = c.pid();
        CHECK(fs::exists(tempOf(checkpoint, deadWriter)));  // the kill landed inside the write
        CHECK(fs::exists(checkpoint));                       // the second year's checkpoint
        CHECK_FALSE(fs::exists(out));
    }
    // 2. Resumed and killed inside its first checkpoint write: by then the dead writer's
    //    temporary is gone (removed when this process started writing the checkpoint).
    {
        EcoChild c(command("killed"), "write:" + ckptName + "#1", log);
        REQUIRE(c.killAtPausePoint());
        CHECK_FALSE(fs::exists(tempOf(checkpoint, deadWriter)));
        CHECK(fs::exists(tempOf(checkpoint, c.pid())));
        CHECK_THAT(readLog(log), Catch::Contains("resumed from") && Catch::Contains("at year 2"));
    }
    // 3. Killed with a complete checkpoint temporary not yet renamed.
    {
        EcoChild c(command("killed"), "commit:" + ckptName + "#2", log);
        REQUIRE(c.killAtPausePoint());
        CHECK(fs::exists(tempOf(checkpoint, c.pid())));
    }
    // 4. Killed at times drawn from a fixed seed, spread over a run's length, until a run ends.
    std::mt19937 rng(26);
    // At most a third of a whole run each: every kill lands before the run could end.
    std::uniform_int_distribution<long> delayMs(runMs / 20, runMs / 3);
    int randomKills = 0, runs = 0;
    bool finished = false;
    for (; runs < 8 && !finished; ++runs) {
        EcoChild c(command("killed"), "", log);
        if (c.killAfter(std::chrono::milliseconds(delayMs(rng)))) {
            ++randomKills;
            CHECK(fs::exists(checkpoint));
        } else {
            INFO(readLog(log));
            REQUIRE(c.exitCode() == 0);
            finished = true;
        }
    }
    CHECK(randomKills >= 2);
    if (!finished) {
        EcoChild c(command("killed"), "", log);
        INFO(readLog(log));
        REQUIRE(c.wait() == 0);
    }
    // The killed and resumed run's outputs are the uninterrupted run's.
    CHECK(test::fileBytes(dir.file("killed/plants.csv")) == test::fileBytes(dir.file("ref/plants.csv")));
    const auto diffs = test::outputFileDifferences(dir.file("ref/sim.h5"), out);
    INFO(diffs.size() << " differences, first: " << (diffs.empty() ? "" : diffs.front()));
    CHECK(diffs.empty());
    CHECK(hiddenFiles(dir.path() / "killed").empty());
}

TEST_CASE("kill: eco analyse killed while writing leaves the previous database intact", "[kill][analysis][cli]") {
    test::TempDir dir("kill_analyse");
    const std::string simPath = dir.file("sim.h5");
    test::writeFakeSimulation(simPath, dir.file("abiotics.h5"));
    const std::string db = dir.file("out/db.h5"), log = dir.file("log.txt");
    auto command = [&](const std::string& kmax) {
        return std::vector<std::string>{"--no-provenance", "analyse", simPath, "--out", db, "--kmax", kmax};
    };
    {
        EcoChild first(command("3"), "", log);
        INFO(readLog(log));
        REQUIRE(first.wait() == 0);
    }
    const std::string previous = test::fileBytes(db);
    REQUIRE(previous.size() > 1000);
    const auto t0 = Clock::now();
    {
        // A reference of the new database elsewhere, for the run's length.
        EcoChild ref({"--no-provenance", "analyse", simPath, "--out", dir.file("ref/db.h5"), "--kmax", "2"}, "", log);
        REQUIRE(ref.wait() == 0);
    }
    const auto runMs = std::chrono::duration_cast<std::chrono::milliseconds>(Clock::now() - t0).count();
    for (const char* point : {"write:db.h5", "commit:db.h5"}) {
        EcoChild c(command("2"), point, log);
        INFO(point);
        REQUIRE(c.killAtPausePoint());
        CHECK(fs::exists(tempOf(db, c.pid())));
        CHECK(test::fileBytes(db) == previous);
    }
    std::mt19937 rng(5);
    std::uniform_int_distribution<long> delayMs(0, runMs);
    std::string expected = previous;  // until a run finishes
    for (int i = 0; i < 3; ++i) {
        EcoChild c(command("2"), "", log);
        if (c.killAfter(std::chrono::milliseconds(delayMs(rng)))) {
            // Killed: the previous database, or, when the kill came after the commit (the
            // process still exiting: slow under the sanitizers' leak check), the whole new
            // one; never anything else.
            const std::string now = test::fileBytes(db);
            const bool previousKept = now == expected;
            const bool newCommitted = !previousKept && test::outputFileDifferences(dir.file("ref/db.h5"), db).empty();
            CHECK((previousKept || newCommitted));
            if (newCommitted) expected = now;
        } else {
            REQUIRE(c.exitCode() == 0);
            expected = test::fileBytes(db);
        }
    }
    EcoChild last(command("2"), "", log);
    REQUIRE(last.wait() == 0);
    CHECK(test::outputFileDifferences(dir.file("ref/db.h5"), db).empty());
    CHECK(hiddenFiles(dir.path() / "out").empty());
}

TEST_CASE("kill: eco synth killed while writing leaves the previous outputs intact and commits its files as a set",
          "[kill][synth][cli]") {
    const test::World w = test::makeWorld();
    test::TempDir dir("kill_synth");
    const test::WorldFiles f = test::writeWorld(w, dir);
    const std::string log = dir.file("log.txt");
    // Outputs in two directories: the scene in out/, the side files and pictures in side/.
    auto command = [&](const std::string& root, const std::string& seed) {
        return std::vector<std::string>{"--no-provenance", "synth", "--terrain", f.terrain, "--canopy", f.canopy, "--database", f.db,
                                        "--abiotics", f.abiotics, "--seed", seed, "--out", dir.file(root + "/out/scene.h5"),
                                        "--csv", dir.file(root + "/side/plants.csv"), "--pdb", dir.file(root + "/side/plants.pdb"),
                                        "--png", dir.file(root + "/side/png")};
    };
    auto run = [&](const std::vector<std::string>& args) {
        EcoChild c(args, "", log);
        INFO(readLog(log));
        REQUIRE(c.wait() == 0);
    };
    run(command("run", "1"));  // the previous outputs
    const auto t0 = Clock::now();
    run(command("ref", "2"));  // what the killed command writes when it completes
    const auto runMs = std::chrono::duration_cast<std::chrono::milliseconds>(Clock::now() - t0).count();
    const fs::path root = dir.path() / "run", ref = dir.path() / "ref";
    auto previous = snapshotFiles(root);
    const auto fresh = snapshotFiles(ref);
    REQUIRE(previous.size() == 8);  // scene, CSV, PDB, five pictures
    REQUIRE(previous.at("side/plants.csv") != fresh.at("side/plants.csv"));
    // All outputs are the previous ones, or all the new ones (the scene file by content: it
    // records its creation time).
    auto setIs = [&](const std::map<std::string, std::string>& expected, const fs::path& expectedRoot) {
        const auto now = snapshotFiles(root);
        if (now.size() != expected.size()) return false;
        for (const auto& [name, bytes] : expected) {
            if (!now.count(name)) return false;
            if (name == "out/scene.h5") {
                if (!test::outputFileDifferences((expectedRoot / name).string(), (root / name).string()).empty()) return false;
            } else if (now.at(name) != bytes) {
                return false;
            }
        }
        return true;
    };
    const std::string scene = (root / "out/scene.h5").string();
    const std::vector<std::string> second = command("run", "2");

    // Killed with the scene, CSV and PDB written but nothing renamed (a kill inside the scene's
    // write comes below).
    {
        EcoChild c(second, "commit:plants.pdb", log);
        REQUIRE(c.killAtPausePoint());
        CHECK(snapshotFiles(root) == previous);
        CHECK(hiddenFiles(root).size() == 3);  // the dead writer's temporaries
    }
    // Killed at times drawn from a fixed seed: the outputs are one set or the other (or, if a
    // kill fell between two renames, the journal says the set is incomplete).
    std::mt19937 rng(9);
    std::uniform_int_distribution<long> delayMs(runMs / 10, runMs);
    for (int i = 0; i < 2; ++i) {
        bool journal = false;
        {
            EcoChild c(second, "", log);
            c.killAfter(std::chrono::milliseconds(delayMs(rng)));
            journal = fs::exists(root / ("out/.scene.h5.set" + std::to_string(c.pid())));
        }
        if (snapshotFiles(root) == previous) continue;
        CHECK((setIs(fresh, ref) || journal));
        run(command("run", "1"));  // back to a set of the previous outputs
        previous = snapshotFiles(root);
    }
    // Killed between two renames of the set: the scene is new, the CSV still the old one, and
    // the journal beside the scene says the set is incomplete.
    pid_t killedInCommit = 0;
    {
        EcoChild c(second, "rename:plants.csv", log);
        REQUIRE(c.killAtPausePoint());
        killedInCommit = c.pid();
    }
    CHECK(fs::exists(root / ("out/.scene.h5.set" + std::to_string(killedInCommit))));
    CHECK(snapshotFiles(root).at("side/plants.csv") == previous.at("side/plants.csv"));
    const auto sceneDiffs = test::outputFileDifferences((ref / "out/scene.h5").string(), scene);
    INFO(sceneDiffs.size() << " differences, first: " << (sceneDiffs.empty() ? "" : sceneDiffs.front()));
    CHECK(sceneDiffs.empty());
    // The next run completes the set when it starts (stopped and killed inside the write of its
    // scene file: by then the dead process's set is whole and its temporaries and journal are
    // gone; the kill leaves that set intact).
    {
        EcoChild c(second, "write:scene.h5", log);
        REQUIRE(c.killAtPausePoint());
        for (const std::string& h : hiddenFiles(root)) CHECK(h == tempOf(scene, c.pid()));
    }
    CHECK(setIs(fresh, ref));
    run(second);
    CHECK(setIs(fresh, ref));
    CHECK(hiddenFiles(root).empty());
}
