// Byte-identical outputs (issue 26 item 7, docs/hdf5.md "Byte-identical outputs"): every
// command that writes HDF5, run on 1 and on 2 threads with --no-provenance, writes the same
// bytes; with provenance the files differ only inside /provenance; a simulation interrupted
// and resumed from its checkpoint writes the bytes of an uninterrupted one.
#include <catch2/catch.hpp>
#include <sys/wait.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "canopy_file.h"
#include "provenance.h"
#include "sim_config.h"
#include "sim_run.h"
#include "sim_scene_fixture.h"
#include "test_util.h"

using namespace eco;

namespace {

std::string bytesOf(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

/// Run `eco GLOBAL --threads N ARGS` for N = 1 and 2, in the same directory with the same
/// command line (paths recorded in a file are then the same), and check that every file of
/// `outputs` comes out with the same bytes. The 1-thread outputs are left in place as the
/// inputs of the next command.
void checkSameBytesOnOneAndTwoThreads(const std::string& global, const std::string& args,
                                      const std::vector<std::string>& outputs) {
    for (const int threads : {2, 1}) {
        const auto r = test::runEco(global + " --threads " + std::to_string(threads) + " " + args);
        INFO(args << "\n" << r.output);
        REQUIRE(r.exitCode == 0);
        for (const std::string& out : outputs)
            if (threads == 2) std::filesystem::rename(out, out + ".t2");
    }
    for (const std::string& out : outputs) {
        INFO(out);
        const std::string one = bytesOf(out), two = bytesOf(out + ".t2");
        CHECK(one.size() > 1000);
        CHECK(one == two);
    }
}

/// h5diff's verdict on two files with /provenance excluded: 0 the same, 1 different, -1 no h5diff.
int h5diffWithoutProvenance(const std::string& a, const std::string& b) {
    if (std::system("command -v h5diff > /dev/null 2>&1") != 0) return -1;
    const int status = std::system(("h5diff -q --exclude-path /provenance '" + a + "' '" + b + "' > /dev/null 2>&1").c_str());
    return WIFEXITED(status) ? WEXITSTATUS(status) : 2;
}

/// Turn provenance off for this scope (in-process tests).
struct NoProvenance {
    NoProvenance() { setProvenanceRecorded(false); }
    ~NoProvenance() { setProvenanceRecorded(true); }
};

}  // namespace

TEST_CASE("provenance: with --no-provenance every command writes the same bytes on 1 and 2 threads", "[cli][provenance]") {
    test::TempDir dir("bytes");
    const auto f = [&](const std::string& name) { return dir.file(name); };
    const std::string g = "--no-provenance";
    checkSameBytesOnOneAndTwoThreads(g, "terrain generate --out " + f("terrain.h5") + " --width 96 --height 96 --cell-size 1 --seed 4",
                                     {f("terrain.h5")});
    checkSameBytesOnOneAndTwoThreads(g, "chm generate --terrain " + f("terrain.h5") + " --out " + f("chm.h5") + " --seed 2 --sketch-seed 3",
                                     {f("chm.h5")});
    checkSameBytesOnOneAndTwoThreads(g, "abiotics --terrain " + f("terrain.h5") + " --out " + f("abiotics.h5") + " --sun-step 60",
                                     {f("abiotics.h5")});
    checkSameBytesOnOneAndTwoThreads(g, "canopy --terrain " + f("terrain.h5") + " --chm " + f("chm.h5") + " --abiotics " +
                                            f("abiotics.h5") + " --out " + f("canopy.h5"),
                                     {f("canopy.h5")});
    checkSameBytesOnOneAndTwoThreads(g, "simulate --abiotics " + f("abiotics.h5") + " --canopy " + f("canopy.h5") +
                                            " --terrain " + f("terrain.h5") + " --crop 20,20,60,60 --years 4 --seed 5 "
                                            "--snapshot-years 2 --checkpoint-every 2 --out " + f("sim.h5"),
                                     {f("sim.h5"), f("sim.h5.checkpoint.h5")});
    checkSameBytesOnOneAndTwoThreads(g, "analyse " + f("sim.h5") + " --out " + f("db.h5") + " --kmax 3", {f("db.h5")});
    checkSameBytesOnOneAndTwoThreads(g, "synth --terrain " + f("terrain.h5") + " --canopy " + f("canopy.h5") + " --database " +
                                            f("db.h5") + " --abiotics " + f("abiotics.h5") + " --refine --out " + f("scene.h5"),
                                     {f("scene.h5")});
    // Nothing measured is left in any of them.
    for (const char* name : {"terrain.h5", "chm.h5", "abiotics.h5", "canopy.h5", "sim.h5", "sim.h5.checkpoint.h5", "db.h5",
                             "scene.h5"}) {
        INFO(name);
        CHECK_FALSE(h5::File::openRead(f(name)).exists(kProvenanceGroup));
    }
    // A database without its creation date still reads, and says so.
    const auto r = test::runEco("inspect " + f("db.h5"));
    CHECK(r.exitCode == 0);
    CHECK_THAT(r.output, Catch::Contains("created (not recorded"));
}

TEST_CASE("provenance: with --no-provenance eco run writes the same bytes on 1 and 2 threads", "[cli][provenance][run]") {
    test::TempDir dir("runbytes");
    const std::string cfg = dir.file("pipeline.toml"), out = dir.file("out");
    {
        std::ofstream f(cfg);
        f << "[run]\nout_dir = \"" << out << "\"\nseed = 4\n"
          << "[terrain]\nwidth = 80\nheight = 80\ncell_size_m = 0.914\n"
          << "[chm]\n[abiotics]\nsun_step_minutes = 60\n[canopy]\n"
          << "[simulate]\nconfig = \"" << test::sourcePath("configs/sim-default.toml") << "\"\nyears = 3\n"
          << "crop = [10.0, 10.0, 50.0, 50.0]\n"
          << "[analyse]\nkmax = 3\n"
          << "[synth]\ntarget_seed = 9\nwidth = 64\nheight = 64\n";
    }
    // The same output folder both times: the files record their inputs' paths.
    for (const int threads : {2, 1}) {
        const auto r = test::runEco("--no-provenance --threads " + std::to_string(threads) + " run " + cfg);
        INFO(r.output);
        REQUIRE(r.exitCode == 0);
        if (threads == 2) std::filesystem::rename(out, dir.file("out2"));
    }
    int compared = 0;
    for (const auto& entry : std::filesystem::recursive_directory_iterator(out)) {
        if (entry.path().extension() != ".h5") continue;
        const std::string rel = std::filesystem::relative(entry.path(), out).string();
        INFO(rel);
        CHECK(bytesOf(entry.path().string()) == bytesOf(dir.file("out2/" + rel)));
        ++compared;
    }
    // terrain, chm, abiotics, canopy, simulation and its checkpoint, database, the target's
    // terrain, chm, abiotics and canopy, scene
    CHECK(compared == 12);
}

TEST_CASE("provenance: with it, two runs on 1 and 2 threads differ only inside /provenance", "[cli][provenance]") {
    test::TempDir dir("prov");
    const auto f = [&](const std::string& name) { return dir.file(name); };
    REQUIRE(test::runEco("terrain generate --out " + f("terrain.h5") + " --width 96 --height 96 --cell-size 1 --seed 4").exitCode == 0);
    REQUIRE(test::runEco("chm generate --terrain " + f("terrain.h5") + " --out " + f("chm.h5") + " --seed 2").exitCode == 0);
    REQUIRE(test::runEco("abiotics --terrain " + f("terrain.h5") + " --out " + f("abiotics.h5") + " --sun-step 60").exitCode == 0);
    const std::string canopy = "canopy --terrain " + f("terrain.h5") + " --chm " + f("chm.h5") + " --out " + f("canopy.h5");
    const std::string simulate = "simulate --abiotics " + f("abiotics.h5") + " --canopy " + f("canopy.h5") +
                                 " --crop 20,20,60,60 --years 3 --seed 5 --out " + f("sim.h5");
    for (const int threads : {2, 1}) {
        REQUIRE(test::runEco("--threads " + std::to_string(threads) + " " + canopy).exitCode == 0);
        REQUIRE(test::runEco("--threads " + std::to_string(threads) + " " + simulate).exitCode == 0);
        if (threads == 2) {
            std::filesystem::rename(f("canopy.h5"), f("canopy.t2.h5"));
            std::filesystem::rename(f("sim.h5"), f("sim.t2.h5"));
        }
    }
    // The measured values are where docs/hdf5.md says, and nowhere else.
    const auto one = h5::File::openRead(f("sim.h5")), two = h5::File::openRead(f("sim.t2.h5"));
    CHECK(one.attrInt(kProvenanceGroup, "threads") == 1);
    CHECK(two.attrInt(kProvenanceGroup, "threads") == 2);
    CHECK(one.attrDouble(kProvenanceGroup, "wall_time_s") > 0);
    CHECK(one.attrInt(kProvenanceGroup, "resumed_from_year") == -1);
    CHECK_FALSE(one.hasAttr("/", "wall_time_s"));
    CHECK_FALSE(one.hasAttr("/", "threads"));
    const auto canopyFile = h5::File::openRead(f("canopy.h5"));
    CHECK(canopyFile.attrInt("/", "schema_version") == kCanopySchemaVersion);
    CHECK(canopyFile.attrDoubles(kProvenanceGroup, "iteration_seconds").size() ==
          canopyFile.shape("/iterations/iteration")[0]);
    CHECK_FALSE(canopyFile.exists("/iterations/seconds"));
    CHECK(readCanopyFile(f("canopy.h5"), defaultBiome()).iterations.size() == canopyFile.shape("/iterations/iteration")[0]);
    // Every other dataset and attribute is the same (h5diff, from hdf5-tools, skips /provenance).
    for (const auto& [a, b] : {std::pair{f("sim.h5"), f("sim.t2.h5")}, std::pair{f("canopy.h5"), f("canopy.t2.h5")}}) {
        INFO(a);
        const int verdict = h5diffWithoutProvenance(a, b);
        if (verdict < 0) {
            WARN("h5diff not installed (Debian hdf5-tools): comparison skipped");
            break;
        }
        CHECK(verdict == 0);
    }
}

TEST_CASE("provenance: with --no-provenance a simulation stopped and resumed from its checkpoint writes the bytes of an uninterrupted one",
          "[sim][checkpoint][provenance]") {
    test::TempDir dir("resumebytes");
    const sim::SimInputs in = test::smallDemoScene();
    writeAbiotics(dir.file("abiotics.h5"), in.abiotics, in.biome, AbioticParams{});
    {
        auto c = h5::File::create(dir.file("canopy.h5"));
        setCanopyFormat(c);
        writePlants(c, "/canopy", in.canopy, in.biome);
        c.ensureGroup("/chm");
        c.writeGrid("/chm/height", in.chmM, "m");
    }
    const NoProvenance off;
    sim::RunConfig cfg;
    cfg.abioticsPath = dir.file("abiotics.h5");
    cfg.canopyPath = dir.file("canopy.h5");
    cfg.years = 6;
    cfg.seed = 4;
    cfg.crop = sim::SimArea{10, 10, 26, 26};
    cfg.snapshotYears = {2};
    cfg.checkpointEveryYears = 2;

    cfg.outputPath = dir.file("straight.h5");
    sim::runSimulation(cfg, false);

    cfg.outputPath = dir.file("resumed.h5");
    int yearsBeforeStop = 0;
    sim::RunHooks stopAfterThree;
    stopAfterThree.stopRequested = [&] { return ++yearsBeforeStop == 3; };
    const sim::RunSummary stopped = sim::runSimulation(cfg, false, stopAfterThree);
    REQUIRE(stopped.stoppedEarly);
    REQUIRE_FALSE(std::filesystem::exists(cfg.outputPath));
    const sim::RunSummary resumed = sim::runSimulation(cfg, true);
    REQUIRE(resumed.years == 6);

    const std::string a = bytesOf(dir.file("straight.h5")), b = bytesOf(dir.file("resumed.h5"));
    CHECK(a.size() > 1000);
    CHECK(a == b);
    CHECK(bytesOf(dir.file("straight.h5.checkpoint.h5")) == bytesOf(dir.file("resumed.h5.checkpoint.h5")));
}
