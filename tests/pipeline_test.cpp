// The pipeline library: a run configuration planned into typed stages whose command lines
// are the ones `eco run` has always printed (users copy them from report.md), and the stages
// called directly with a Reporter.
#include <catch2/catch.hpp>

#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>

#include "database_build.h"
#include "simulate_stage.h"
#include "canopy_stage.h"
#include "generate.h"
#include "terrain_io.h"
#include "ensemble.h"
#include "run.h"
#include "stage_common.h"
#include "terrain_stages.h"
#include "test_util.h"

namespace {

using eco::pipeline::quotedCommand;

/// A Reporter that keeps what a stage prints.
class CapturingReporter : public eco::pipeline::SilentReporter {
public:
    std::ostream& out() override { return out_; }
    void info(const std::string& line) override { info_ += line + "\n"; }
    std::string printed() const { return out_.str(); }
    const std::string& messages() const { return info_; }

private:
    std::ostringstream out_;
    std::string info_;
};

/// Runs a scope from another working directory (the repository root: command-line paths such
/// as configs/demo.toml are relative to it; paths inside a configuration are relative to the
/// configuration's own directory).
class InDirectory {
public:
    explicit InDirectory(const std::string& dir) : previous_(std::filesystem::current_path()) {
        std::filesystem::current_path(dir);
    }
    ~InDirectory() { std::filesystem::current_path(previous_); }
    InDirectory(const InDirectory&) = delete;
    InDirectory& operator=(const InDirectory&) = delete;

private:
    std::filesystem::path previous_;
};

}  // namespace

TEST_CASE("pipeline: the demo configuration plans the stages and command lines eco run always printed", "[pipeline]") {
    eco::test::TempDir dir("pipeline_plan");
    const InDirectory root(eco::test::sourcePath(""));
    const std::string o = dir.file("demo");
    const eco::pipeline::RunPlan plan =
        eco::pipeline::planRun("configs/demo.toml", o);
    CHECK(plan.outDir == o);
    const std::vector<std::pair<std::string, std::string>> expected = {
        {"terrain", "eco terrain generate --out O/terrain.h5 --width 512 --height 512 --cell-size 0.914 --seed 1 --png O/png"},
        {"chm", "eco chm generate --terrain O/terrain.h5 --out O/chm.h5 --seed 1 --png O/png"},
        {"abiotics", "eco abiotics --terrain O/terrain.h5 --out O/abiotics.h5 --png O/png/abiotics --sun-step 10"},
        {"canopy", "eco canopy --terrain O/terrain.h5 --chm O/chm.h5 --abiotics O/abiotics.h5 --out O/canopy.h5 --png "
                   "O/png/canopy --csv O/canopy.csv --seed 1 --target Douglas-Fir=0.3"},
        {"simulate", "eco simulate --config configs/sim-default.toml --terrain O/terrain.h5 --abiotics O/abiotics.h5 "
                     "--canopy O/canopy.h5 --out O/simulation.h5 --csv O/undergrowth.csv --png O/png/simulation --seed 1 "
                     "--years 150 --crop 100,60,220,180"},
        {"analyse", "eco analyse O/simulation.h5 --out O/biome-db.h5 --seed 1 --kmax 6"},
        {"inspect", "eco inspect O/biome-db.h5 --png O/png/database --out O/database.txt"},
        {"target terrain", "eco terrain generate --out O/target/terrain.h5 --width 512 --height 512 --cell-size 0.914 "
                           "--seed 2 --png O/target/png"},
        {"target chm", "eco chm generate --terrain O/target/terrain.h5 --out O/target/chm.h5 --seed 2 --png O/target/png"},
        {"target abiotics", "eco abiotics --terrain O/target/terrain.h5 --out O/target/abiotics.h5 --png "
                            "O/target/png/abiotics --sun-step 10"},
        {"target canopy", "eco canopy --terrain O/target/terrain.h5 --chm O/target/chm.h5 --abiotics "
                          "O/target/abiotics.h5 --out O/target/canopy.h5 --png O/target/png/canopy --seed 2 --target "
                          "Douglas-Fir=0.3"},
        {"synth", "eco synth --terrain O/target/terrain.h5 --canopy O/target/canopy.h5 --database O/biome-db.h5 "
                  "--abiotics O/target/abiotics.h5 --out O/scene.h5 --png O/png/synth --csv O/scene.csv --pdb "
                  "O/scene.pdb --seed 2 --refine"},
        {"compare", "eco compare O/scene.h5 O/biome-db.h5 --png O/png/synth --out O/compare.md"},
    };
    REQUIRE(plan.stages.size() == expected.size());
    for (std::size_t i = 0; i < expected.size(); ++i) {
        std::string line = expected[i].second;
        for (std::size_t p = line.find("O/"); p != std::string::npos; p = line.find("O/", p + o.size()))
            line.replace(p, 1, o);
        INFO(expected[i].first);
        CHECK(plan.stages[i].name == expected[i].first);
        CHECK(quotedCommand(eco::pipeline::commandLine(plan.stages[i].options)) == line);
    }
}

TEST_CASE("pipeline: a stage's command line shows exactly the options given", "[pipeline]") {
    eco::pipeline::CanopyOptions c;
    c.terrain = "t.png";
    c.chm = "c.h5";
    c.out = "k.h5";
    CHECK(quotedCommand(eco::pipeline::commandLine(c)) == "eco canopy --terrain t.png --chm c.h5 --out k.h5");
    c.terrainRead.cellSizeM = 0.5;
    c.terrainRead.verticalScale = 1.0;  // given, even at the reader's default
    c.params.setSeed("seed", 7);
    c.params.set("ring_factor", 0.75);
    c.targets = {"Redwood=0.4", "Gray Pine=0.1"};
    CHECK(quotedCommand(eco::pipeline::commandLine(c)) ==
          "eco canopy --terrain t.png --chm c.h5 --out k.h5 --seed 7 --cell-size 0.5 --vertical-scale 1 --target "
          "Redwood=0.4 --target 'Gray Pine=0.1' --ring-factor 0.75");

    eco::pipeline::SynthOptions s;
    s.terrain = "t.h5";
    s.canopy = "k.h5";
    s.database = "db.h5";
    s.out = "s.h5";
    s.method = "darts";
    s.refine = true;
    s.refineWindow = "0,0,10,10";
    s.refineParams.set("refine_sweeps", 4);
    CHECK(quotedCommand(eco::pipeline::commandLine(s)) ==
          "eco synth --terrain t.h5 --canopy k.h5 --database db.h5 --out s.h5 --seed 1 --method darts --refine "
          "--refine-window 0,0,10,10 --refine-sweeps 4");
}

TEST_CASE("pipeline: parameter overrides reach the stage and its command line by their descriptions", "[pipeline]") {
    using Catch::Matchers::Contains;
    eco::pipeline::SimulateOptions o;
    o.abiotics = "a.h5";
    o.canopy = "c.h5";
    o.modelParams.set("seeding_month", 3);
    o.modelParams.set("cell_size_m", 0.25);
    o.canopyLimit = "canopy_only";
    const eco::sim::RunConfig cfg = eco::pipeline::simulateConfig(o);
    CHECK(cfg.params.cellSizeM == 0.25);
    CHECK(cfg.params.seedingMonth == 3);
    CHECK(cfg.params.canopyLimit == eco::sim::CanopyLimit::CanopyOnly);
    CHECK(cfg.params.minWaterDemandMm == eco::sim::SimParams{}.minWaterDemandMm);
    // The flags in the table's order, whatever the order given.
    CHECK(quotedCommand(eco::pipeline::commandLine(o)) ==
          "eco simulate --abiotics a.h5 --canopy c.h5 --canopy-limit canopy_only --cell-size-m 0.25 --seeding-month 3");
    // Every numeric [model] key has its flag, named from the key.
    REQUIRE(eco::pipeline::simParamFlags().size() == eco::sim::simParamFields().size());
    CHECK(eco::pipeline::simParamFlags()[0].flag == "--cell-size-m");
    o.modelParams.set("cell_size_m", 0);  // replaces the earlier value
    CHECK(o.modelParams.values().size() == 2);
    CHECK_THROWS_WITH(eco::pipeline::simulateConfig(o), Contains("cell_size_m") && Contains("(0.001, 10]"));
    o.modelParams.set("seed_outer_radius_factor", 1);  // below the inner radius of 4 crown radii
    o.modelParams.set("cell_size_m", 0.2);
    CHECK_THROWS_WITH(eco::pipeline::simulateConfig(o), Contains("radius"));
    eco::pipeline::SimulateOptions unknown = o;
    unknown.modelParams = {};
    unknown.modelParams.set("no_such_key", 1);
    CHECK_THROWS_WITH(eco::pipeline::simulateConfig(unknown), Contains("no_such_key") && Contains("cell_size_m"));
    CHECK_THROWS_AS(eco::pipeline::commandLine(unknown), std::logic_error);

    // The placer: overrides over the defaults, checked by the descriptions' ranges.
    eco::pipeline::CanopyOptions c;
    c.terrain = "t.png";
    c.chm = "c.h5";
    c.out = "k.h5";
    c.params.set("ring_factor", -1);
    CHECK_THROWS_WITH(eco::pipeline::checkCanopyOptions(c), Contains("ring_factor") && Contains("-1"));
    c.params.set("ring_factor", 0.5);
    c.params.setSeed("seed", 18446744073709551615ull);  // a seed keeps all its 64 bits
    CHECK_NOTHROW(eco::pipeline::checkCanopyOptions(c));
    CHECK(quotedCommand(eco::pipeline::commandLine(c)) ==
          "eco canopy --terrain t.png --chm c.h5 --out k.h5 --seed 18446744073709551615 --ring-factor 0.5");
}

TEST_CASE("pipeline: a number from a configuration reaches a stage as the command line gives it", "[pipeline]") {
    // %.10g keeps 10 digits: the stage gets the value of the printed text, not the TOML's.
    const double v = 0.12345678901234;
    CHECK(eco::pipeline::argNumber(v) == "0.123456789");
    CHECK(eco::pipeline::asOnCommandLine(v) == static_cast<double>(std::strtold("0.123456789", nullptr)));
    CHECK(eco::pipeline::asOnCommandLine(0.914) == 0.914);
}

TEST_CASE("pipeline: a stage called directly reports through its Reporter", "[pipeline]") {
    eco::test::TempDir dir("pipeline_stage");
    eco::pipeline::TerrainGenerateOptions o;
    o.out = dir.file("t.h5");
    o.params.width = 24;
    o.params.height = 16;
    CapturingReporter reporter;
    const eco::pipeline::TerrainResult r = eco::pipeline::generateTerrainStage(o, reporter);
    CHECK(r.terrain.width() == 24);
    CHECK(r.terrain.height() == 16);
    CHECK(r.written == std::vector<std::string>{o.out});
    CHECK(std::filesystem::exists(o.out));
    CHECK_THAT(reporter.printed(), Catch::StartsWith("wrote terrain: " + o.out + " (24 x 16 cells of 0.914 m, "));
    CHECK(reporter.messages().empty());

    o.out = dir.file("t.xyz");
    CHECK_THROWS_WITH(eco::pipeline::generateTerrainStage(o, reporter), Catch::Contains("unknown terrain format '.xyz'"));
}

TEST_CASE("pipeline: [run] gis = true asks every grid stage for GeoTIFFs and the plants as GeoPackages", "[pipeline]") {
    eco::test::TempDir dir("pipeline_gis");
    const InDirectory root(eco::test::sourcePath(""));
    const std::string config = dir.file("gis.toml"), o = dir.file("out");
    {
        std::ofstream f(config);
        f << "[run]\nout_dir = \"x\"\ngis = true\n[terrain]\n[chm]\n[abiotics]\n[canopy]\n"
             "[simulate]\nconfig = \"" << eco::test::sourcePath("configs/sim-default.toml") << "\"\n[analyse]\n[synth]\n";
    }
    const eco::pipeline::RunPlan plan = eco::pipeline::planRun(config, o);
    std::map<std::string, std::string> lines;
    for (const auto& s : plan.stages) lines[s.name] = quotedCommand(eco::pipeline::commandLine(s.options));
    CHECK_THAT(lines.at("abiotics"), Catch::EndsWith("--geotiff " + o + "/gis --sun-step 10"));
    CHECK_THAT(lines.at("canopy"), Catch::Contains("--gpkg " + o + "/gis/canopy.gpkg --geotiff " + o + "/gis"));
    CHECK_THAT(lines.at("target abiotics"), Catch::Contains("--geotiff " + o + "/target/gis"));
    CHECK_THAT(lines.at("target canopy"), Catch::Contains("--gpkg " + o + "/target/gis/canopy.gpkg --geotiff " + o + "/target/gis"));
    CHECK_THAT(lines.at("synth"), Catch::Contains("--gpkg " + o + "/gis/scene.gpkg --geotiff " + o + "/gis"));
    CHECK(lines.at("simulate").find("--geotiff") == std::string::npos);  // the simulation file has no maps of its own
}

TEST_CASE("ensemble: configs/ensemble.toml plans its members with their overrides", "[pipeline][ensemble]") {
    eco::test::TempDir dir("ensemble_plan");
    const InDirectory root(eco::test::sourcePath(""));
    const auto spec = eco::pipeline::loadEnsembleSpec(eco::test::sourcePath("configs/ensemble.toml"), dir.file("out"));
    REQUIRE(spec.members.size() == 5);
    CHECK(spec.members[0].id == "m01");
    CHECK(eco::pipeline::overridesText(spec.members[0]) == "canopy.targets = [Douglas-Fir=0.3], terrain.seed = 1");
    CHECK(eco::pipeline::overridesText(spec.members[3]) == "canopy.targets = [Douglas-Fir=0.6], terrain.seed = 2");
    CHECK(spec.members[4].id == "toyon-alpha");
    CHECK(spec.variedKeys == std::vector<std::string>{"biome.species.Toyon.alpha", "canopy.targets", "terrain.seed"});
    CHECK(spec.databasePath == dir.file("out") + "/biome-db.h5");
    // Loading (and checking) wrote nothing; once written, the biome override reached the
    // member's own biome file, and only that member's.
    CHECK_FALSE(std::filesystem::exists(dir.file("out")));
    for (std::size_t i = 0; i < spec.members.size(); ++i) eco::pipeline::writeMemberConfig(spec, i);
    const std::string biome = dir.file("out/members/toyon-alpha/biome.toml");
    REQUIRE(std::filesystem::exists(biome));
    const eco::Biome b = eco::loadBiome(biome);
    CHECK(b.species[static_cast<std::size_t>(b.speciesIndex("Toyon"))].alpha == 0.5);
    CHECK_FALSE(std::filesystem::exists(dir.file("out/members/m01/biome.toml")));
    for (std::size_t i = 0; i < spec.members.size(); ++i) CHECK(eco::pipeline::memberStatus(spec, i).state == "pending");
}

TEST_CASE("ensemble: a simulation override on a base that names the built-in simulation configuration", "[pipeline][ensemble]") {
    // [simulate] config = "embedded:sim-default.toml" is not a file: the member's simulate.toml
    // is the built-in text with the override (it was read as <folder>/embedded:sim-default.toml).
    eco::test::TempDir dir("ensemble_embedded");
    eco::test::writeText(dir.file("base.toml"), "[run]\nseed = 1\n[terrain]\nwidth = 32\nheight = 32\n[chm]\n[abiotics]\n"
                                                "[canopy]\n[simulate]\nconfig = \"embedded:sim-default.toml\"\nyears = 2\n");
    eco::test::writeText(dir.file("spec.toml"), "[ensemble]\nout_dir = \"out\"\nbase = \"base.toml\"\ndatabase = false\n"
                                                "[vary]\n\"simulation.run.checkpoint_every_years\" = [5, 7]\n");
    const auto spec = eco::pipeline::loadEnsembleSpec(dir.file("spec.toml"));
    REQUIRE(spec.members.size() == 2);
    for (std::size_t i = 0; i < spec.members.size(); ++i) eco::pipeline::writeMemberConfig(spec, i);
    const std::string simToml = dir.file("out/members/m02/simulate.toml");
    REQUIRE(std::filesystem::exists(simToml));
    const eco::sim::RunConfig c = eco::sim::loadRunConfig(simToml);
    CHECK(c.checkpointEveryYears == 7);
    CHECK(c.years == eco::sim::loadRunConfig("embedded:sim-default.toml").years);  // the rest is the built-in text
}

TEST_CASE("database build: one member per sub-biome combination and terrain, each with its canopy mix", "[pipeline][ensemble]") {
    const eco::Biome biome = eco::defaultBiome();
    // Sonoma: 4 sub-biomes with canopy species -> 15 combinations.
    for (int mask = 1; mask < 16; ++mask) {
        INFO("combination " << mask);
        double inMix = 0, outside = 0;
        for (const std::string& t : eco::pipeline::combinationTargets(biome, mask)) {
            const auto eq = t.find('=');
            const std::string species = t.substr(0, eq);
            const double share = std::stod(t.substr(eq + 1));
            bool in = false;
            for (std::size_t b = 0; b < biome.subBiomes.size(); ++b)
                for (const auto& s : biome.subBiomes[b].canopySpecies) in = in || (s == species && ((mask >> b) & 1));
            (in ? inMix : outside) += share;
            if (in) CHECK(share > 0);
        }
        CHECK(inMix == Approx(0.9));
        CHECK(outside == 0);
    }
    eco::test::TempDir dir("database_build");
    const InDirectory root(eco::test::sourcePath(""));
    eco::pipeline::DatabaseBuildOptions o;
    o.out = dir.file("db.h5");
    o.workDir = dir.file("work");
    o.simConfig = "configs/sim-default.toml";
    o.terrains = 2;
    const auto spec = eco::pipeline::loadEnsembleSpec(eco::pipeline::writeDatabaseBuildSpec(o));
    REQUIRE(spec.members.size() == 30);
    CHECK(spec.members.front().id == "c01-t1");
    CHECK(spec.members.back().id == "c15-t2");
    CHECK(spec.databasePath == o.out);
    // Generated terrains spread valley depth and base elevation from the first to the last.
    const auto number = [&](std::size_t member, const char* key) {
        const toml::node* v = spec.members[member].overrides.get(key);
        REQUIRE(v != nullptr);
        return v->is_integer() ? static_cast<double>(v->as_integer()->get()) : v->as_floating_point()->get();
    };
    CHECK(number(0, "terrain.valley_depth_m") == 8);
    CHECK(number(0, "terrain.base_elevation_m") == 0);
    CHECK(number(1, "terrain.valley_depth_m") == 60);
    CHECK(number(1, "terrain.base_elevation_m") == 600);
    CHECK(number(1, "terrain.width") == 160);
    o.plotM = 500;  // wider than the 146 m terrain
    CHECK_THROWS_WITH(eco::pipeline::writeDatabaseBuildSpec(o), Catch::Contains("--plot"));

    // Terrains of the user's: every combination on each, the plot centred in it.
    eco::Grid<float> own(120, 80, 0.5, 1000.0, 2000.0, 0.f);  // 60 m x 40 m at (1000, 2000)
    for (int y = 0; y < own.height(); ++y)
        for (int x = 0; x < own.width(); ++x) own(x, y) = static_cast<float>(100 + 0.2 * x + 0.1 * y);
    eco::writeAsc(dir.file("own.asc"), own);
    o.plotM = 30;
    o.terrains = 1;
    o.terrainFiles = {dir.file("own.asc")};
    const auto mixed = eco::pipeline::loadEnsembleSpec(eco::pipeline::writeDatabaseBuildSpec(o));
    REQUIRE(mixed.members.size() == 30);
    CHECK(mixed.members[0].id == "c01-t1");
    CHECK(mixed.members[1].id == "c01-f1");
    const toml::node* path = mixed.members[1].overrides.get("terrain.path");
    REQUIRE(path != nullptr);
    CHECK(std::filesystem::equivalent(path->as_string()->get(), dir.file("own.asc")));
    const toml::array* crop = mixed.members[1].overrides.get("simulate.crop")->as_array();
    REQUIRE(crop != nullptr);
    std::vector<double> c;
    for (const auto& v : *crop) c.push_back(v.value<double>().value());
    CHECK(c == std::vector<double>{1015, 2005, 1045, 2035});  // centre (1030, 2020)
    CHECK(mixed.members[1].overrides.get("terrain.seed") == nullptr);
    // One generated terrain takes the generator's defaults.
    CHECK(mixed.members[0].overrides.get("terrain.valley_depth_m")->value<double>().value() == eco::TerrainGenParams{}.valleyDepthM);
    // A terrain too small for the plot is refused, naming it.
    o.plotM = 45;
    CHECK_THROWS_WITH(eco::pipeline::writeDatabaseBuildSpec(o), Catch::Contains("own.asc") && Catch::Contains("--plot"));
    o.terrains = 0;
    o.terrainFiles.clear();
    CHECK_THROWS_WITH(eco::pipeline::writeDatabaseBuildSpec(o), Catch::Contains("at least one terrain"));
}
