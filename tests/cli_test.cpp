// The command-line front end as a user meets it: --help, --version, and one clear error
// line with a non-zero exit for bad input, leaving no output behind.
#include <catch2/catch.hpp>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include "abiotics.h"
#include "eco_version.h"
#include "h5io.h"
#include "test_util.h"

using eco::test::runEco;

namespace {

using eco::test::lineCount;

}  // namespace

TEST_CASE("eco --version and --help", "[cli]") {
    const auto v = runEco("--version");
    CHECK(v.exitCode == 0);
    CHECK_THAT(v.output, Catch::Contains(ECO_VERSION_STRING));
    const auto h = runEco("--help");
    CHECK(h.exitCode == 0);
    for (const char* cmd : {"terrain", "chm", "abiotics", "canopy", "simulate", "analyse", "inspect", "pcf", "synth",
                            "compare", "validate", "run"})
        CHECK_THAT(h.output, Catch::Contains(cmd));
}

namespace {

/// The subcommand names listed in a help text's "Subcommands:" section.
std::vector<std::string> subcommandsIn(const std::string& help) {
    std::vector<std::string> names;
    std::istringstream in(help);
    bool on = false;
    for (std::string line; std::getline(in, line);) {
        if (line.rfind("Subcommands:", 0) == 0) {
            on = true;
            continue;
        }
        if (!on) continue;
        if (line.empty()) break;
        // "  name    description": a name starts in column 2; continuation lines are indented further.
        if (line.size() > 2 && line[0] == ' ' && line[1] == ' ' && line[2] != ' ') names.push_back(line.substr(2, line.find(' ', 2) - 2));
    }
    return names;
}

}  // namespace

TEST_CASE("every command has --help", "[cli]") {
    // Every command eco lists, and the subcommands they list (terrain generate, database build, ...).
    const auto top = runEco("--help");
    REQUIRE(top.exitCode == 0);
    std::vector<std::string> commands;
    for (const std::string& c : subcommandsIn(top.output)) {
        const auto r = runEco(c + " --help");
        INFO(c << "\n" << r.output);
        CHECK(r.exitCode == 0);
        CHECK_THAT(r.output, Catch::Contains("Usage") || Catch::Contains("usage"));
        commands.push_back(c);
        for (const std::string& sub : subcommandsIn(r.output)) {
            const auto rs = runEco(c + " " + sub + " --help");
            INFO(c << " " << sub << "\n" << rs.output);
            CHECK(rs.exitCode == 0);
            CHECK_THAT(rs.output, Catch::Contains("Usage") || Catch::Contains("usage"));
            commands.push_back(c + " " + sub);
        }
    }
    // The list was read: the pipeline's commands and the newer ones are among them.
    for (const char* expected : {"terrain generate", "terrain convert", "chm generate", "abiotics", "canopy", "simulate", "analyse",
                                 "inspect", "pcf", "synth", "compare", "validate", "run", "fidelity", "ensemble", "database build",
                                 "sensitivity", "calibrate", "instance", "biome show", "config defaults"}) {
        INFO(expected);
        CHECK(std::find(commands.begin(), commands.end(), expected) != commands.end());
    }
}

TEST_CASE("no command or an unknown one is an error", "[cli]") {
    CHECK(runEco("").exitCode == 2);
    const auto r = runEco("frobnicate");
    CHECK(r.exitCode == 2);
}

TEST_CASE("usage errors exit 2 whatever CLI11 calls them, bad data exits 1", "[cli]") {
    // CLI11 gives 105-109 for these; eco documents one code (eco --help, README).
    for (const char* args : {"simulate --no-such-flag", "terrain generate --width", "terrain generate --width abc --out x.h5",
                             "canopy --chm c.h5", "--threads 100000 pcf pts.csv", "--threads -1 pcf pts.csv",
                             "--threads 0 biome show",  // 0: the help says 1..1024; it was taken as "all cores"
                             "validate --threads 0 --only ecomod --out v0", "validate --threads 2000 --only ecomod --out v0"}) {
        const auto r = runEco(args);
        INFO(args << "\n" << r.output);
        CHECK(r.exitCode == 2);
    }
    const auto threads = runEco("--threads 100000 terrain generate --out x.h5");  // was a stack overflow in libgomp
    CHECK_THAT(threads.output, Catch::Contains("--threads") && Catch::Contains("1024"));
    CHECK_FALSE(std::filesystem::exists("x.h5"));
    CHECK(runEco("terrain convert /no/such/file.asc out.h5").exitCode == 1);
    const auto help = runEco("--help");
    CHECK(help.exitCode == 0);
    CHECK_THAT(help.output, Catch::Contains("Exit status") && Catch::Contains("2 usage error"));
}

TEST_CASE("a bad number for a flag names the flag and the value", "[cli]") {
    const auto notNumber = runEco("simulate --years abc");
    CHECK(notNumber.exitCode != 0);
    CHECK_THAT(notNumber.output, Catch::Contains("--years: 'abc' is not a number"));
    CHECK_THAT(notNumber.output, !Catch::Contains("179769"));  // not CLI11's whole double range
    const auto negative = runEco("simulate --years -3");
    CHECK(negative.exitCode != 0);
    CHECK_THAT(negative.output, Catch::Contains("--years: must be > 0, got -3"));
    const auto zero = runEco("terrain generate --cell-size 0 --out unused.h5");
    CHECK(zero.exitCode != 0);
    CHECK_THAT(zero.output, Catch::Contains("--cell-size: must lie in [0.001, 10000], got 0"));
    const auto huge = runEco("simulate --seed 1e400");
    CHECK(huge.exitCode != 0);
    CHECK_THAT(huge.output, Catch::Contains("--seed: '1e400' is not a number"));
    CHECK_FALSE(std::filesystem::exists("unused.h5"));
}

TEST_CASE("a missing terrain gives one line naming it and leaves no output", "[cli]") {
    eco::test::TempDir dir("cli");
    const std::string out = dir.file("abiotics.h5");
    const auto r = runEco("abiotics --terrain " + dir.file("nope.asc") + " --out " + out);
    CHECK(r.exitCode == 1);
    CHECK_THAT(r.output, Catch::StartsWith("eco: error: ") && Catch::Contains("nope.asc"));
    CHECK(lineCount(r.output) == 1);
    CHECK_FALSE(std::filesystem::exists(out));
    CHECK(std::distance(std::filesystem::directory_iterator(dir.path()), std::filesystem::directory_iterator()) == 0);
}

TEST_CASE("a bad biome file through the CLI names the file, species and field", "[cli]") {
    eco::test::TempDir dir("cli");
    const std::string terrain = dir.file("t.asc");
    {
        std::ofstream t(terrain);
        t << "ncols 4\nnrows 3\nxllcorner 0\nyllcorner 0\ncellsize 1\n";
        for (int i = 0; i < 3; ++i) t << "1 2 3 4\n";
    }
    std::ifstream in(eco::test::sourcePath("biomes/sonoma.toml"));
    std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    const auto p = text.find("alpha = 0.45");  // Redwood, the last species
    REQUIRE(p != std::string::npos);
    text.replace(p, 12, "alpha = 2.0");
    const std::string biome = dir.file("bad.toml");
    std::ofstream(biome) << text;
    const std::string out = dir.file("a.h5");
    const auto r = runEco("abiotics --terrain " + terrain + " --biome " + biome + " --out " + out);
    CHECK(r.exitCode == 1);
    CHECK_THAT(r.output, Catch::Contains("bad.toml") && Catch::Contains("species 'Redwood'") && Catch::Contains("alpha"));
    CHECK_FALSE(std::filesystem::exists(out));
}

TEST_CASE("eco abiotics --canopy shades the sun under the crowns, and the analyser refuses shaded input", "[cli][canopy]") {
    eco::test::TempDir dir("abiotics_canopy");
    const std::string t = dir.file("t.h5"), chm = dir.file("chm.h5"), c = dir.file("c.h5");
    REQUIRE(runEco("terrain generate --out " + t + " --width 96 --height 80 --seed 3").exitCode == 0);
    REQUIRE(runEco("chm generate --terrain " + t + " --out " + chm + " --seed 3").exitCode == 0);
    REQUIRE(runEco("canopy --terrain " + t + " --chm " + chm + " --out " + c).exitCode == 0);
    const std::string open = dir.file("open.h5"), shaded = dir.file("shaded.h5");
    REQUIRE(runEco("abiotics --terrain " + t + " --out " + open + " --sun-step 30").exitCode == 0);
    const auto r = runEco("abiotics --terrain " + t + " --out " + shaded + " --sun-step 30 --canopy " + c);
    REQUIRE(r.exitCode == 0);
    CHECK_THAT(r.output, Catch::Contains("under the canopy"));
    const eco::Abiotics a = eco::readAbiotics(open), b = eco::readAbiotics(shaded);
    CHECK(a.canopyShadeSource.empty());
    CHECK(b.canopyShadeSource == c);
    std::size_t darker = 0, brighter = 0;
    for (int m = 0; m < 12; ++m)
        for (std::size_t i = 0; i < a.sunHours[m].size(); ++i) {
            brighter += b.sunHours[m].data()[i] > a.sunHours[m].data()[i];
            darker += b.sunHours[m].data()[i] < a.sunHours[m].data()[i];
        }
    CHECK(brighter == 0);
    CHECK(darker > 0);
    CHECK(b.moistureMm[6].data() == a.moistureMm[6].data());
    // A canopy from another terrain is refused before any work.
    const std::string t2 = dir.file("t2.h5");
    REQUIRE(runEco("terrain generate --out " + t2 + " --width 64 --height 64").exitCode == 0);
    const auto bad = runEco("abiotics --terrain " + t2 + " --out " + dir.file("x.h5") + " --canopy " + c);
    CHECK(bad.exitCode != 0);
    CHECK_THAT(bad.output, Catch::Contains(c) && Catch::Contains("terrain"));
    CHECK_FALSE(std::filesystem::exists(dir.file("x.h5")));
}

TEST_CASE("eco run: the whole pipeline on a small scene, with --out-dir, writes the scene and the report", "[cli][run]") {
    eco::test::TempDir dir("run");
    const std::string cfg = dir.file("pipeline.toml");
    {
        std::ofstream f(cfg);
        f << "[run]\nout_dir = \"" << dir.file("unused") << "\"\nseed = 4\n"
          << "[terrain]\nwidth = 112\nheight = 96\ncell_size_m = 0.914\n"
          << "[chm]\n[abiotics]\nsun_step_minutes = 60\n"
          << "[canopy]\n"
          << "[simulate]\nconfig = \"" << eco::test::sourcePath("configs/sim-default.toml") << "\"\nyears = 4\n"
          << "crop = [10.0, 10.0, 70.0, 70.0]\n"
          << "[analyse]\nkmax = 3\n"
          << "[synth]\ntarget_seed = 9\nwidth = 96\nheight = 96\n";
    }
    const std::string out = dir.file("out");
    const auto r = runEco("run " + cfg + " --out-dir " + out);
    INFO(r.output);
    REQUIRE(r.exitCode == 0);
    CHECK_FALSE(std::filesystem::exists(dir.file("unused")));
    for (const char* file : {"terrain.h5", "chm.h5", "abiotics.h5", "canopy.h5", "simulation.h5", "biome-db.h5",
                             "target/terrain.h5", "target/canopy.h5", "scene.h5", "scene.csv", "scene.pdb",
                             "compare.md", "report.md", "png/synth/scene.png"}) {
        INFO(file);
        CHECK(std::filesystem::exists(out + "/" + file));
    }
    // Every HDF5 file of the run carries format, schema_version and code_version at its root
    // (docs/hdf5.md; terrain and CHM files had none), and its format names its kind.
    const std::map<std::string, std::string> formats = {
        {"terrain.h5", "eco-terrain"},     {"chm.h5", "eco-chm"},           {"abiotics.h5", "eco-abiotics"},
        {"canopy.h5", "eco-canopy"},       {"simulation.h5", "eco-simulation"}, {"biome-db.h5", "eco-biome-db"},
        {"target/terrain.h5", "eco-terrain"}, {"scene.h5", "eco-scene"}};
    int h5files = 0;
    for (const auto& e : std::filesystem::recursive_directory_iterator(out)) {
        if (e.path().extension() != ".h5") continue;
        ++h5files;
        const std::string rel = std::filesystem::relative(e.path(), out).string();
        INFO(rel);
        const eco::h5::File f = eco::h5::File::openRead(e.path().string());
        CHECK(f.hasAttr("/", "schema_version"));
        CHECK(f.hasAttr("/", "code_version"));
        REQUIRE(f.hasAttr("/", "format"));
        if (formats.count(rel)) CHECK(f.attrString("/", "format") == formats.at(rel));
    }
    CHECK(h5files >= 9);
    std::ifstream in(out + "/report.md");
    const std::string report((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    CHECK_THAT(report, Catch::Contains("| synth |") && Catch::Contains("## Synthesized against the database") &&
                           Catch::Contains("png/synth/scene.png"));
    // The simulation's pictures: the last simulated year (4), not the empty start (year 0).
    CHECK_THAT(report, Catch::Contains("png/simulation/plants_year_0004.png") &&
                           !Catch::Contains("plants_year_0000.png"));
    CHECK_THAT(r.output, Catch::Contains("report.md"));
}

TEST_CASE("eco run: a stage without what it needs is a clear error before anything runs", "[cli][run]") {
    eco::test::TempDir dir("run_bad");
    const std::string cfg = dir.file("bad.toml");
    {
        std::ofstream f(cfg);
        f << "[run]\nout_dir = \"" << dir.file("out") << "\"\n[terrain]\n[chm]\n[abiotics]\n[canopy]\n"
          << "[synth]\ntarget_seed = 2\n";
    }
    const auto r = runEco("run " + cfg);
    CHECK(r.exitCode != 0);
    CHECK_THAT(r.output, Catch::Contains("bad.toml") && Catch::Contains("[synth]") && Catch::Contains("analyse"));
    CHECK_FALSE(std::filesystem::exists(dir.file("out/terrain.h5")));

    // A bad value in a stage's own configuration file (or a target species the biome does not
    // have) is found before the first stage, not when that stage starts (issue 26).
    const std::string simCfg = dir.file("sim.toml");
    {
        std::ofstream f(simCfg);
        f << "[run]\nyears = 5\n[model]\nseeding_probability = -1\n";
    }
    {
        std::ofstream f(cfg);
        f << "[run]\nout_dir = \"" << dir.file("out") << "\"\n[terrain]\n[chm]\n[abiotics]\n[canopy]\n"
          << "[simulate]\nconfig = \"" << simCfg << "\"\n";
    }
    const auto sim = runEco("run " + cfg);
    CHECK(sim.exitCode == 1);
    CHECK_THAT(sim.output, Catch::Contains("stage 'simulate'") && Catch::Contains("sim.toml") &&
                               Catch::Contains("seeding_probability") && Catch::Contains("-1"));
    CHECK_FALSE(std::filesystem::exists(dir.file("out/terrain.h5")));
    {
        std::ofstream f(cfg);
        f << "[run]\nout_dir = \"" << dir.file("out") << "\"\n[terrain]\n[chm]\n[abiotics]\n[canopy]\n"
          << "targets = [\"Baobab=0.3\"]\n";
    }
    const auto target = runEco("run " + cfg + " --dry-run");
    CHECK(target.exitCode == 1);
    CHECK_THAT(target.output, Catch::Contains("stage 'canopy'") && Catch::Contains("Baobab"));
}

TEST_CASE("sizes beyond the memory are refused before allocating, with what they need", "[cli][errors]") {
    // Under a 3 GB address-space limit (the check takes the smaller of it and the machine's
    // available memory), each of these was a bad_alloc or an abort inside a parallel region.
    constexpr long kLimitKb = 3L * 1024 * 1024;
    eco::test::TempDir dir("cli_memory");
    const auto terrain = runEco("terrain generate --width 65536 --height 65536 --out " + dir.file("t.h5"), kLimitKb);
    CHECK(terrain.exitCode == 1);
    CHECK_THAT(terrain.output, Catch::Contains("65536 x 65536 cells needs about") && Catch::Contains("GB available") &&
                                   Catch::Contains("--width"));
    CHECK_FALSE(std::filesystem::exists(dir.file("t.h5")));

    REQUIRE(runEco("terrain generate --width 64 --height 64 --out " + dir.file("small.h5")).exitCode == 0);
    const auto chm = runEco("chm generate --terrain " + dir.file("small.h5") + " --dense-spacing 0.001 --out " + dir.file("c.h5"), kLimitKb);
    CHECK(chm.exitCode == 1);
    CHECK_THAT(chm.output, Catch::Contains("tree candidates") && Catch::Contains("needs about") && Catch::Contains("--dense-spacing"));
    CHECK_FALSE(std::filesystem::exists(dir.file("c.h5")));

    const std::string asc = dir.file("huge.asc");
    {
        std::ofstream f(asc);
        f << "ncols 100000\nnrows 100000\nxllcorner 0\nyllcorner 0\ncellsize 1\n1 2 3\n";
    }
    const auto big = runEco("terrain convert " + asc + " " + dir.file("h.h5"), kLimitKb);
    CHECK(big.exitCode == 1);
    CHECK_THAT(big.output, Catch::Contains("huge.asc: a grid of 100000 x 100000 cells needs about 80 GB"));
    {
        std::ofstream f(asc);
        f << "ncols 2e9\nnrows 3\nxllcorner 0\nyllcorner 0\ncellsize 1\n1 2 3\n";
    }
    const auto side = runEco("terrain convert " + asc + " " + dir.file("h.h5"));
    CHECK(side.exitCode == 1);
    CHECK_THAT(side.output, Catch::Contains("ncols = 2e+09 is larger than eco reads (at most 10000000 a side)"));
    CHECK_FALSE(std::filesystem::exists(dir.file("h.h5")));
}

TEST_CASE("values that were accepted with exit 0 are refused (issue 26)", "[cli][errors]") {
    eco::test::TempDir dir("cli_accepted");
    const auto tiny = runEco("terrain generate --cell-size 1e-300 --width 8 --height 8 --out " + dir.file("t.h5"));
    CHECK(tiny.exitCode == 2);
    CHECK_THAT(tiny.output, Catch::Contains("--cell-size: must lie in [0.001, 10000], got 1e-300"));
    CHECK_FALSE(std::filesystem::exists(dir.file("t.h5")));
    for (const char* n : {"0", "1"}) {
        const std::string csv = dir.file(std::string("p") + n + ".csv");
        {
            std::ofstream f(csv);
            f << "x,y\n";
            if (std::string(n) == "1") f << "3,4\n";
        }
        const auto r = runEco("pcf " + csv + " --window 0,0,10,10 --out " + dir.file("g.csv"));
        INFO(r.output);
        CHECK(r.exitCode == 1);
        CHECK_THAT(r.output, Catch::Contains(std::string(n) + " point(s) inside the window") && Catch::Contains("at least 2"));
        CHECK_FALSE(std::filesystem::exists(dir.file("g.csv")));
    }
    const auto sources = runEco("compare scene.h5 db.h5 --pcf-sources -1");
    CHECK(sources.exitCode == 2);
    CHECK_THAT(sources.output, Catch::Contains("--pcf-sources: must lie in [0, 1000000000], got -1"));
}

// ======================================================================== CLI conventions (issue 31 item 5)

namespace {

/// eco run in working directory `cwd` (stdout and stderr together, and ECO_TEST_BINARY, as runEco).
eco::test::CommandResult runEcoIn(const std::string& cwd, const std::string& args) {
    const char* other = std::getenv("ECO_TEST_BINARY");
    const std::string binary = other != nullptr && *other != '\0' ? other : ECO_BINARY;
    const std::string cmd = "cd '" + cwd + "' && " + binary + " " + args + " 2>&1";
    eco::test::CommandResult r;
    FILE* pipe = ::popen(cmd.c_str(), "r");
    if (!pipe) return r;
    char buf[4096];
    std::size_t n;
    while ((n = std::fread(buf, 1, sizeof buf, pipe)) > 0) r.output.append(buf, n);
    const int status = ::pclose(pipe);
    r.exitCode = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
    return r;
}

/// The text after the first line (eco biome show's header comment names the source).
std::string withoutFirstLine(const std::string& s) { return s.substr(std::min(s.size(), s.find('\n') + 1)); }

}  // namespace

TEST_CASE("eco run: paths in a configuration are relative to the configuration's directory", "[cli][run]") {
    // A tiny pipeline (terrain, CHM, abiotics) whose configuration names its output folder
    // relatively, run from another working directory with the configuration given by a
    // relative path: the outputs land beside the configuration, nothing where eco ran.
    eco::test::TempDir dir("run_cwd");
    std::filesystem::create_directories(dir.file("cfg"));
    std::filesystem::create_directories(dir.file("elsewhere"));
    std::ofstream(dir.file("cfg/pipeline.toml")) << "[run]\nout_dir = \"result\"\nseed = 3\n"
                                                 << "[terrain]\nwidth = 16\nheight = 16\n"
                                                 << "[chm]\n[abiotics]\nsun_step_minutes = 120\n";
    const auto r = runEcoIn(dir.file("elsewhere"), "--quiet run ../cfg/pipeline.toml");
    INFO(r.output);
    REQUIRE(r.exitCode == 0);
    for (const char* file : {"cfg/result/terrain.h5", "cfg/result/abiotics.h5", "cfg/result/report.md"}) {
        INFO(file);
        CHECK(std::filesystem::exists(dir.file(file)));
    }
    CHECK(std::filesystem::is_empty(dir.file("elsewhere")));
    // A configuration it names (the canopy placer's) is found beside it; had the path been read
    // relative to the working directory, it would not be, and a missing one is named resolved.
    std::ofstream(dir.file("cfg/placer.toml")) << "[canopy]\nmax_iterations = 2\n";
    std::ofstream(dir.file("cfg/canopy.toml")) << "[run]\nout_dir = \"../plan\"\n[terrain]\nwidth = 16\nheight = 16\n"
                                               << "[chm]\n[abiotics]\n[canopy]\nconfig = \"placer.toml\"\n";
    const auto plan = runEcoIn(dir.file("elsewhere"), "run ../cfg/canopy.toml --dry-run");
    INFO(plan.output);
    CHECK(plan.exitCode == 0);
    CHECK_THAT(plan.output, Catch::Contains("--config ../cfg/placer.toml"));
    std::filesystem::remove(dir.file("cfg/placer.toml"));
    const auto missing = runEcoIn(dir.file("elsewhere"), "run ../cfg/canopy.toml --dry-run");
    INFO(missing.output);
    CHECK(missing.exitCode == 1);
    CHECK_THAT(missing.output, Catch::Contains("../cfg/placer.toml"));
}

TEST_CASE("eco run: the shipped demo configuration plans the same stages from any directory", "[cli][run]") {
    // configs/demo.toml names configs/sim-default.toml as "sim-default.toml" (beside it); from
    // the repository root the outputs stay in out/demo, from elsewhere --out-dir decides.
    eco::test::TempDir dir("run_demo_cwd");
    const auto fromElsewhere =
        runEcoIn(dir.path().string(), "run " + eco::test::sourcePath("configs/demo.toml") + " --dry-run --out-dir plan");
    INFO(fromElsewhere.output);
    REQUIRE(fromElsewhere.exitCode == 0);
    CHECK_THAT(fromElsewhere.output, Catch::Contains("--config " + eco::test::sourcePath("configs/sim-default.toml")));
    CHECK_THAT(fromElsewhere.output, Catch::Contains("--out plan/simulation.h5"));
    const auto fromRoot = runEcoIn(eco::test::sourcePath(""), "run configs/demo.toml --dry-run --out-dir " + dir.file("plan2"));
    INFO(fromRoot.output);
    REQUIRE(fromRoot.exitCode == 0);
    CHECK_THAT(fromRoot.output, Catch::Contains("--config configs/sim-default.toml "));
}

TEST_CASE("eco run: a demo-like configuration copied alone into an empty directory runs on the built-in sim-default.toml", "[cli][run]") {
    // configs/sim-default.toml is built into eco (issue 31 item 5): the demo configuration,
    // copied without it, still plans; a small demo-like one (the same [simulate] config key)
    // runs, reading the built-in copy with a line saying so and recording it as such.
    eco::test::TempDir dir("run_alone");
    std::filesystem::copy_file(eco::test::sourcePath("configs/demo.toml"), dir.file("demo.toml"));
    const auto plan = runEcoIn(dir.path().string(), "run demo.toml --dry-run --out-dir plan");
    INFO(plan.output);
    REQUIRE(plan.exitCode == 0);
    CHECK_THAT(plan.output, Catch::Contains("--config sim-default.toml"));
    std::ofstream(dir.file("small.toml")) << "[run]\nout_dir = \"out\"\nseed = 3\n"
                                          << "[terrain]\nwidth = 48\nheight = 48\ncell_size_m = 0.914\n"
                                          << "[chm]\n[abiotics]\nsun_step_minutes = 120\n[canopy]\n"
                                          << "[simulate]\nconfig = \"sim-default.toml\"\nyears = 2\n"
                                          << "crop = [5.0, 5.0, 25.0, 25.0]\n";
    const auto r = runEcoIn(dir.path().string(), "run small.toml");
    INFO(r.output);
    REQUIRE(r.exitCode == 0);
    CHECK_THAT(r.output, Catch::Contains("sim-default.toml not found: using the copy of configs/sim-default.toml built into eco"));
    REQUIRE(std::filesystem::exists(dir.file("out/simulation.h5")));
    const eco::h5::File sim = eco::h5::File::openRead(dir.file("out/simulation.h5"));
    CHECK(sim.attrString("/", "config_path") == "embedded:sim-default.toml");
    // The explicit form, and a name that is not built in: an error listing what is.
    std::ofstream(dir.file("explicit.toml")) << "[run]\nout_dir = \"out2\"\n[terrain]\nwidth = 16\nheight = 16\n"
                                             << "[chm]\n[abiotics]\n[canopy]\n[simulate]\nconfig = \"embedded:sim-default.toml\"\n";
    const auto explicitPlan = runEcoIn(dir.path().string(), "run explicit.toml --dry-run");
    INFO(explicitPlan.output);
    CHECK(explicitPlan.exitCode == 0);
    CHECK_THAT(explicitPlan.output, Catch::Contains("--config embedded:sim-default.toml"));
    const auto unknown = runEcoIn(dir.path().string(), "simulate --config embedded:nope.toml");
    CHECK(unknown.exitCode == 1);
    CHECK_THAT(unknown.output, Catch::Contains("embedded:nope.toml: no such configuration built into eco (built in: embedded:sim-default.toml)"));
    // Only a missing file of an embedded name falls back: another missing file is an error.
    const auto missing = runEcoIn(dir.path().string(), "simulate --config other.toml");
    CHECK(missing.exitCode == 1);
    CHECK_THAT(missing.output, Catch::Contains("other.toml: cannot open run configuration"));
}

TEST_CASE("eco --quiet prints nothing on success and still prints errors, --verbose adds detail", "[cli]") {
    eco::test::TempDir dir("quiet");
    const auto quiet = runEco("--quiet terrain generate --width 16 --height 16 --out " + dir.file("t.h5") + " --png " + dir.file("png"));
    CHECK(quiet.exitCode == 0);
    CHECK(quiet.output.empty());
    CHECK(std::filesystem::exists(dir.file("t.h5")));
    const auto verbose = runEco("--verbose terrain generate --width 16 --height 16 --out " + dir.file("t2.h5"));
    CHECK(verbose.exitCode == 0);
    CHECK_THAT(verbose.output, Catch::Contains("t2.h5"));  // the test can fail: without --quiet there is output
    const auto error = runEco("--quiet terrain convert " + dir.file("no-such.asc") + " " + dir.file("o.h5"));
    CHECK(error.exitCode == 1);
    CHECK_THAT(error.output, Catch::Contains("eco: error:") && Catch::Contains("no-such.asc"));
    const auto usage = runEco("--quiet terrain generate --width abc --out " + dir.file("x.h5"));
    CHECK(usage.exitCode == 2);
    CHECK_THAT(usage.output, Catch::Contains("--width"));
    const auto both = runEco("--quiet --verbose terrain generate --out " + dir.file("y.h5"));
    INFO(both.output);
    CHECK(both.exitCode == 2);
    CHECK_THAT(both.output, Catch::Contains("--quiet") && Catch::Contains("--verbose"));
}

TEST_CASE("eco biome show prints a biome that eco reads back identically", "[cli]") {
    eco::test::TempDir dir("biome_show");
    const auto embedded = runEco("--quiet biome show");  // the result prints with --quiet too
    REQUIRE(embedded.exitCode == 0);
    CHECK_THAT(embedded.output, Catch::Contains("[[species]]") && Catch::Contains("Redwood"));
    std::ofstream(dir.file("a.toml")) << embedded.output;
    const auto again = runEco("biome show " + dir.file("a.toml"));
    REQUIRE(again.exitCode == 0);
    CHECK(withoutFirstLine(again.output) == withoutFirstLine(embedded.output));
    // The shipped file reads to the same biome as the embedded copy.
    const auto shipped = runEco("biome show " + eco::test::sourcePath("biomes/sonoma.toml"));
    REQUIRE(shipped.exitCode == 0);
    CHECK(withoutFirstLine(shipped.output) == withoutFirstLine(embedded.output));
    // Errors: a missing file is a usage error, a bad value names file and field.
    CHECK(runEco("biome show " + dir.file("none.toml")).exitCode == 2);
    std::string text = withoutFirstLine(embedded.output);
    const std::size_t at = text.find("max_height_m = ");
    REQUIRE(at != std::string::npos);
    text.replace(at, std::string("max_height_m = ").size(), "max_height_m = -");
    std::ofstream(dir.file("bad.toml")) << text;
    const auto bad = runEco("biome show " + dir.file("bad.toml"));
    INFO(bad.output);
    CHECK(bad.exitCode == 1);
    CHECK_THAT(bad.output, Catch::Contains("bad.toml") && Catch::Contains("max_height_m"));
}

TEST_CASE("eco config defaults prints configurations that eco reads", "[cli]") {
    eco::test::TempDir dir("config_defaults");
    const auto sim = runEco("--quiet config defaults simulate");  // simulate is the default; printed with --quiet
    REQUIRE(sim.exitCode == 0);
    CHECK_THAT(sim.output, Catch::Contains("[inputs]") && Catch::Contains("[model]") && Catch::Contains("canopy_limit = "));
    std::ofstream(dir.file("sim.toml")) << sim.output;
    const auto canopy = runEco("config defaults canopy");
    REQUIRE(canopy.exitCode == 0);
    CHECK_THAT(canopy.output, Catch::Contains("[canopy]"));
    std::ofstream(dir.file("placer.toml")) << canopy.output;
    // eco run checks both files when it plans (strict: an unknown key or a bad value fails).
    std::ofstream(dir.file("run.toml")) << "[run]\nout_dir = \"out\"\n[terrain]\n[chm]\n[abiotics]\n"
                                        << "[canopy]\nconfig = \"placer.toml\"\n[simulate]\nconfig = \"sim.toml\"\n";
    const auto plan = runEco("run " + dir.file("run.toml") + " --dry-run");
    INFO(plan.output);
    CHECK(plan.exitCode == 0);
    const auto wrong = runEco("config defaults synthesis");
    CHECK(wrong.exitCode == 2);
    CHECK_THAT(wrong.output, Catch::Contains("synthesis"));
}
