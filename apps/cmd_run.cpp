// eco run CONFIG: the whole pipeline on one configuration, each stage run exactly as the
// user would run its own command (so a stage can be rerun by hand with the printed line).
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "atomic_file.h"
#include "biome_db.h"
#include "cli_common.h"
#include "eco_version.h"
#include "error.h"
#include "strict_toml.h"

namespace eco::cli {

namespace {

struct RunArgs {
    std::string config;
    std::string outDir;  // overrides [run] out_dir
    bool dryRun = false;
};

struct Stage {
    std::string name;
    std::vector<std::string> args;
};

std::string fmtNumber(double v) {
    char buf[64];
    std::snprintf(buf, sizeof buf, "%.10g", v);
    return buf;
}

std::string quoted(const std::vector<std::string>& args) {
    std::string s = "eco";
    for (const auto& a : args) s += " " + (a.find(' ') == std::string::npos ? a : "'" + a + "'");
    return s;
}

/// Resolve a path from the config: relative paths are relative to the working directory
/// (configs are run from the repository root, as the README shows).
std::string pathFrom(StrictTable& t, const std::string& key) { return t.string(key); }

struct Plan {
    std::string outDir;
    std::vector<Stage> stages;
};

Plan planStages(const std::string& configPath, const std::string& outOverride) {
    const toml::table root = parseTomlFile(configPath);
    StrictTable top(root, configPath, "");
    std::vector<Stage> stages;

    StrictTable run(top.table("run"), configPath, "[run]");
    const std::string configuredOut = run.string("out_dir");
    const std::string out = outOverride.empty() ? configuredOut : outOverride;
    const std::int64_t seed = run.integerOr("seed", 1);
    if (seed < 0) run.fail("seed", "must not be negative");
    const std::string biome = run.stringOr("biome", "");
    run.finish();
    ensureDirectory(out);
    const auto at = [&](const std::string& name) { return (std::filesystem::path(out) / name).string(); };
    const auto withBiome = [&](std::vector<std::string> a) {
        if (!biome.empty()) a.insert(a.end(), {"--biome", biome});
        return a;
    };

    // Terrain: a given file, or the generated default.
    std::string terrain = at("terrain.h5");
    std::vector<std::string> terrainReadFlags;
    std::int64_t terrainWidth = 512, terrainHeight = 512;
    double terrainCellM = 0.914;
    {
        StrictTable t(top.table("terrain"), configPath, "[terrain]");
        if (t.has("path")) {
            terrain = pathFrom(t, "path");
            if (t.has("cell_size_m")) terrainReadFlags = {"--cell-size", fmtNumber(t.positive("cell_size_m"))};
            if (t.has("vertical_scale"))
                terrainReadFlags.insert(terrainReadFlags.end(), {"--vertical-scale", fmtNumber(t.positive("vertical_scale"))});
        } else {
            terrainWidth = t.integerOr("width", terrainWidth);
            terrainHeight = t.integerOr("height", terrainHeight);
            terrainCellM = t.positiveOr("cell_size_m", terrainCellM);
            stages.push_back({"terrain", {"terrain", "generate", "--out", terrain, "--width",
                                          std::to_string(terrainWidth), "--height", std::to_string(terrainHeight),
                                          "--cell-size", fmtNumber(terrainCellM), "--seed",
                                          std::to_string(t.integerOr("seed", seed)), "--png", at("png")}});
        }
        t.finish();
    }
    // Canopy height model: a given file, or generated from a density sketch.
    std::string chm = at("chm.h5");
    {
        StrictTable t(top.table("chm"), configPath, "[chm]");
        if (t.has("path")) {
            chm = pathFrom(t, "path");
        } else {
            std::vector<std::string> a = {"chm", "generate", "--terrain", terrain, "--out", chm,
                                          "--seed", std::to_string(t.integerOr("seed", seed)), "--png", at("png")};
            a.insert(a.end(), terrainReadFlags.begin(), terrainReadFlags.end());
            if (t.has("sketch")) a.insert(a.end(), {"--sketch", pathFrom(t, "sketch")});
            stages.push_back({"chm", a});
        }
        t.finish();
    }
    // Abiotics.
    const std::string abiotics = at("abiotics.h5");
    double sunStepMinutes = 10;
    {
        StrictTable t(top.table("abiotics"), configPath, "[abiotics]");
        sunStepMinutes = t.positiveOr("sun_step_minutes", sunStepMinutes);
        std::vector<std::string> a = {"abiotics", "--terrain", terrain, "--out", abiotics, "--png", at("png/abiotics"),
                                      "--sun-step", fmtNumber(sunStepMinutes)};
        a.insert(a.end(), terrainReadFlags.begin(), terrainReadFlags.end());
        stages.push_back({"abiotics", withBiome(a)});
        t.finish();
    }
    // Canopy trees from the CHM.
    const std::string canopy = at("canopy.h5");
    std::string canopyConfig;
    std::vector<std::string> canopyTargets;
    const bool placesCanopy = top.has("canopy");
    if (const toml::table* tt = top.optionalTable("canopy")) {
        StrictTable t(*tt, configPath, "[canopy]");
        std::vector<std::string> a = {"canopy", "--terrain", terrain, "--chm", chm, "--abiotics", abiotics,
                                      "--out", canopy, "--png", at("png/canopy"), "--csv", at("canopy.csv"),
                                      "--seed", std::to_string(seed)};
        a.insert(a.end(), terrainReadFlags.begin(), terrainReadFlags.end());
        if (t.has("config")) {
            canopyConfig = t.string("config");
            a.insert(a.end(), {"--config", canopyConfig});
        }
        if (t.has("targets")) canopyTargets = t.strings("targets");
        for (const auto& target : canopyTargets) a.insert(a.end(), {"--target", target});
        stages.push_back({"canopy", withBiome(a)});
        t.finish();
    }
    // Undergrowth simulation on part of the scene.
    const std::string simulation = at("simulation.h5");
    bool simulated = false, analysed = false;
    if (const toml::table* tt = top.optionalTable("simulate")) {
        StrictTable t(*tt, configPath, "[simulate]");
        if (!placesCanopy) t.fail("config", "the simulation needs a [canopy] stage for its canopy trees");
        std::vector<std::string> a = {"simulate", "--config", t.string("config"), "--terrain", terrain,
                                      "--abiotics", abiotics, "--canopy", canopy, "--out", simulation,
                                      "--csv", at("undergrowth.csv"), "--png", at("png/simulation"),
                                      "--seed", std::to_string(seed)};
        if (t.has("years")) a.insert(a.end(), {"--years", std::to_string(t.integer("years"))});
        if (t.has("crop")) {
            const auto c = t.numbers("crop", 4);
            a.insert(a.end(), {"--crop", fmtNumber(c[0]) + "," + fmtNumber(c[1]) + "," + fmtNumber(c[2]) + "," + fmtNumber(c[3])});
        }
        stages.push_back({"simulate", withBiome(a)});
        simulated = true;
        t.finish();
    }
    // Statistics of the simulation: the biome database.
    const std::string database = at("biome-db.h5");
    if (const toml::table* tt = top.optionalTable("analyse")) {
        StrictTable t(*tt, configPath, "[analyse]");
        if (!simulated) t.fail("analyse", "needs a [simulate] stage to analyse");
        std::vector<std::string> a = {"analyse", simulation, "--out", database, "--seed", std::to_string(seed)};
        if (t.has("kmax")) a.insert(a.end(), {"--kmax", std::to_string(t.integer("kmax"))});
        stages.push_back({"analyse", a});
        stages.push_back({"inspect", {"inspect", database, "--png", at("png/database"), "--out", at("database.txt")}});
        analysed = true;
        t.finish();
    }
    // Synthesis on a different target terrain, from the database, and its comparison.
    if (const toml::table* tt = top.optionalTable("synth")) {
        StrictTable t(*tt, configPath, "[synth]");
        if (!analysed) t.fail("synth", "needs an [analyse] stage for its biome database");
        const std::int64_t targetSeed = t.integerOr("target_seed", seed + 1);
        if (targetSeed < 0) t.fail("target_seed", "must not be negative");
        const std::string ts = std::to_string(targetSeed);
        std::string targetTerrain = at("target/terrain.h5");
        std::vector<std::string> targetReadFlags;
        ensureDirectory(at("target"));
        if (t.has("terrain")) {
            targetTerrain = pathFrom(t, "terrain");
            if (t.has("cell_size_m")) targetReadFlags = {"--cell-size", fmtNumber(t.positive("cell_size_m"))};
        } else {
            stages.push_back({"target terrain",
                              {"terrain", "generate", "--out", targetTerrain, "--width",
                               std::to_string(t.integerOr("width", terrainWidth)), "--height",
                               std::to_string(t.integerOr("height", terrainHeight)), "--cell-size",
                               fmtNumber(t.positiveOr("cell_size_m", terrainCellM)), "--seed", ts, "--png",
                               at("target/png")}});
        }
        std::string targetChm = at("target/chm.h5");
        if (t.has("chm")) {
            targetChm = pathFrom(t, "chm");
        } else {
            std::vector<std::string> a = {"chm", "generate", "--terrain", targetTerrain, "--out", targetChm,
                                          "--seed", ts, "--png", at("target/png")};
            a.insert(a.end(), targetReadFlags.begin(), targetReadFlags.end());
            stages.push_back({"target chm", a});
        }
        const std::string targetAbiotics = at("target/abiotics.h5");
        {
            std::vector<std::string> a = {"abiotics", "--terrain", targetTerrain, "--out", targetAbiotics,
                                          "--png", at("target/png/abiotics"), "--sun-step", fmtNumber(sunStepMinutes)};
            a.insert(a.end(), targetReadFlags.begin(), targetReadFlags.end());
            stages.push_back({"target abiotics", withBiome(a)});
        }
        const std::string targetCanopy = at("target/canopy.h5");
        {
            std::vector<std::string> a = {"canopy", "--terrain", targetTerrain, "--chm", targetChm,
                                          "--abiotics", targetAbiotics, "--out", targetCanopy,
                                          "--png", at("target/png/canopy"), "--seed", ts};
            a.insert(a.end(), targetReadFlags.begin(), targetReadFlags.end());
            if (!canopyConfig.empty()) a.insert(a.end(), {"--config", canopyConfig});
            for (const auto& target : canopyTargets) a.insert(a.end(), {"--target", target});
            stages.push_back({"target canopy", withBiome(a)});
        }
        const std::string scene = at("scene.h5");
        {
            std::vector<std::string> a = {"synth", "--terrain", targetTerrain, "--canopy", targetCanopy,
                                          "--database", database, "--abiotics", targetAbiotics, "--out", scene,
                                          "--png", at("png/synth"), "--csv", at("scene.csv"),
                                          "--pdb", at("scene.pdb"), "--seed", ts};
            a.insert(a.end(), targetReadFlags.begin(), targetReadFlags.end());
            if (t.booleanOr("refine", false)) a.push_back("--refine");
            stages.push_back({"synth", a});
        }
        stages.push_back({"compare", {"compare", scene, database, "--png", at("png/synth/compare.png"), "--out",
                                      at("compare.md")}});
        t.finish();
    }
    top.finish();
    return {out, stages};
}

/// A picture line of the report when the file exists (paths relative to the report).
void picture(std::ostringstream& md, const std::filesystem::path& outDir, const std::string& rel,
             const std::string& caption) {
    if (std::filesystem::exists(outDir / rel)) md << "![" << caption << "](" << rel << ")\n\n";
}

/// Every PNG of a folder (sorted), at most `limit`.
void pictures(std::ostringstream& md, const std::filesystem::path& outDir, const std::string& relDir,
              std::size_t limit) {
    const std::filesystem::path dir = outDir / relDir;
    if (!std::filesystem::is_directory(dir)) return;
    std::vector<std::string> names;
    for (const auto& e : std::filesystem::directory_iterator(dir))
        if (e.is_regular_file() && e.path().extension() == ".png") names.push_back(e.path().filename().string());
    std::sort(names.begin(), names.end());
    if (names.size() > limit) {
        md << "(" << limit << " of " << names.size() << " pictures in `" << relDir << "/`)\n\n";
        names.resize(limit);
    }
    for (const auto& n : names) picture(md, outDir, relDir + "/" + n, n);
}

std::string fileText(const std::filesystem::path& p) {
    std::ifstream in(p);
    std::ostringstream s;
    s << in.rdbuf();
    return s.str();
}

/// out_dir/report.md: what ran, how long each stage took, the pictures and the comparison.
void writeReport(const std::string& configPath, const Plan& plan, const std::vector<double>& seconds,
                 double totalSeconds) {
    const std::filesystem::path outDir(plan.outDir);
    std::ostringstream md;
    md << "# eco run report\n\n"
       << "Configuration `" << configPath << "`, eco " << ECO_VERSION_STRING << ", finished " << utcTimestamp()
       << ", " << fmtNumber(std::round(totalSeconds * 10) / 10) << " s in all.\n\n"
       << "| stage | seconds | command |\n|---|---:|---|\n";
    for (std::size_t i = 0; i < plan.stages.size(); ++i) {
        char secs[32];
        std::snprintf(secs, sizeof secs, "%.1f", seconds[i]);
        md << "| " << plan.stages[i].name << " | " << secs << " | `" << quoted(plan.stages[i].args) << "` |\n";
    }
    md << "\n## Source terrain, canopy height model and abiotics\n\n";
    picture(md, outDir, "png/terrain_hillshade.png", "terrain");
    picture(md, outDir, "png/sketch.png", "density sketch");
    picture(md, outDir, "png/chm.png", "canopy height model");
    for (const char* name : {"sun_07_jul", "moisture_01_jan", "temperature_07_jul", "slope"})
        picture(md, outDir, std::string("png/abiotics/") + name + ".png", name);
    if (std::filesystem::is_directory(outDir / "png/canopy")) {
        md << "## Canopy trees\n\n";
        pictures(md, outDir, "png/canopy", 8);
    }
    if (std::filesystem::is_directory(outDir / "png/simulation")) {
        md << "## Undergrowth simulation\n\n";
        picture(md, outDir, "png/simulation/species_counts.png", "plants per species and year");
        pictures(md, outDir, "png/simulation", 6);
    }
    if (std::filesystem::exists(outDir / "database.txt"))
        md << "## Biome database\n\n```\n" << fileText(outDir / "database.txt") << "```\n\n";
    pictures(md, outDir, "png/database", 4);
    if (std::filesystem::is_directory(outDir / "png/synth")) {
        md << "## Synthesis on the target terrain\n\n";
        picture(md, outDir, "target/png/terrain_hillshade.png", "target terrain");
        pictures(md, outDir, "target/png/canopy", 4);
        pictures(md, outDir, "png/synth", 8);
    }
    if (std::filesystem::exists(outDir / "compare.md"))
        md << "## Synthesized against the database\n\n" << fileText(outDir / "compare.md") << "\n";
    writeTextFile((outDir / "report.md").string(), md.str());
}

void runPipeline(const RunArgs& args) {
    const Plan plan = planStages(args.config, args.outDir);
    const std::vector<Stage>& stages = plan.stages;
    const auto start = std::chrono::steady_clock::now();
    std::vector<double> seconds;
    for (std::size_t i = 0; i < stages.size(); ++i) {
        std::fprintf(stderr, "\n== stage %zu/%zu: %s\n   %s\n", i + 1, stages.size(), stages[i].name.c_str(),
                     quoted(stages[i].args).c_str());
        if (args.dryRun) continue;
        const auto t0 = std::chrono::steady_clock::now();
        try {
            runCommand(stages[i].args);
        } catch (const Error& e) {
            throw Error("stage '" + stages[i].name + "' failed: " + e.what());
        }
        std::fflush(stdout);
        seconds.push_back(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
        std::fprintf(stderr, "== %s done in %.1f s\n", stages[i].name.c_str(), seconds.back());
    }
    if (args.dryRun) return;
    const double total = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    writeReport(args.config, plan, seconds, total);
    std::fprintf(stderr, "\npipeline finished in %.1f s\n", total);
    std::printf("outputs in %s/ ; report: %s/report.md\n", plan.outDir.c_str(), plan.outDir.c_str());
}

}  // namespace

void registerRunCommand(CLI::App& app) {
    auto a = std::make_shared<RunArgs>();
    CLI::App* sub = app.add_subcommand(
        "run", "Run the whole pipeline from one configuration (configs/demo.toml: the embedded default data).\n"
               "Each stage is an ordinary eco command; its command line is printed so it can be rerun alone.");
    sub->add_option("config", a->config, "Pipeline configuration (TOML)")->required();
    sub->add_option("--out-dir", a->outDir, "Override [run] out_dir");
    sub->add_flag("--dry-run", a->dryRun, "Print the stages without running them");
    sub->callback([a] { runPipeline(*a); });
}

}  // namespace eco::cli
