// eco run CONFIG: the whole pipeline on one configuration, each stage run exactly as the
// user would run its own command (so a stage can be rerun by hand with the printed line).
#include <chrono>
#include <cstdio>
#include <filesystem>

#include "atomic_file.h"
#include "cli_common.h"
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

std::vector<Stage> planStages(const std::string& configPath, const std::string& outOverride) {
    const toml::table root = parseTomlFile(configPath);
    StrictTable top(root, configPath, "");
    std::vector<Stage> stages;

    StrictTable run(top.table("run"), configPath, "[run]");
    const std::string out = outOverride.empty() ? run.string("out_dir") : outOverride;
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
    {
        StrictTable t(top.table("terrain"), configPath, "[terrain]");
        if (t.has("path")) {
            terrain = pathFrom(t, "path");
            if (t.has("cell_size_m")) terrainReadFlags = {"--cell-size", fmtNumber(t.positive("cell_size_m"))};
            if (t.has("vertical_scale"))
                terrainReadFlags.insert(terrainReadFlags.end(), {"--vertical-scale", fmtNumber(t.positive("vertical_scale"))});
        } else {
            stages.push_back({"terrain", {"terrain", "generate", "--out", terrain, "--width",
                                          std::to_string(t.integerOr("width", 512)), "--height",
                                          std::to_string(t.integerOr("height", 512)), "--cell-size",
                                          fmtNumber(t.positiveOr("cell_size_m", 0.914)), "--seed",
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
    {
        StrictTable t(top.table("abiotics"), configPath, "[abiotics]");
        std::vector<std::string> a = {"abiotics", "--terrain", terrain, "--out", abiotics, "--png", at("png/abiotics"),
                                      "--sun-step", fmtNumber(t.positiveOr("sun_step_minutes", 10))};
        a.insert(a.end(), terrainReadFlags.begin(), terrainReadFlags.end());
        stages.push_back({"abiotics", withBiome(a)});
        t.finish();
    }
    top.finish();
    return stages;
}

void runPipeline(const RunArgs& args) {
    const std::vector<Stage> stages = planStages(args.config, args.outDir);
    const auto start = std::chrono::steady_clock::now();
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
        std::fprintf(stderr, "== %s done in %.1f s\n", stages[i].name.c_str(),
                     std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
    }
    std::fprintf(stderr, "\npipeline finished in %.1f s\n",
                 std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
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
