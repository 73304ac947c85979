// eco fidelity: the fidelity protocol of issue 24 (docs/fidelity.md). Parsing, the stages
// that produce the patterns (each an ordinary eco command, cached in the output folder) and
// the report; the measures are in validate/fidelity.
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <memory>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "atomic_file.h"
#include "biome_db.h"
#include "canopy_placer.h"
#include "cli_common.h"
#include "eco_version.h"
#include "error.h"
#include "fidelity.h"
#include "scene.h"
#include "sim_input.h"
#include "strict_toml.h"
#include "text_format.h"
#include "undergrowth.h"

namespace eco::cli {

namespace {

std::string fmt(double v) { return formatNumber(v, 10); }

struct FidelityArgs {
    std::string config;
    std::string outDir;
    // Reuse of existing files (any subset; the rest is produced).
    std::string terrain, chm, abiotics, canopy, reference, replicate, database, scene;
    std::string outMd, outCsv;
    bool refine = false;
    int refineSweeps = 4;
    std::string synthMethod = "structured";
    // Settings (defaults reproduce configs/demo.toml's first scene and plot).
    std::int64_t terrainSeed = 1, seedA = 1, seedB = 2, synthSeed = 1, analyseSeed = 1;
    std::int64_t width = 512, height = 512, years = 150, kmax = 6;
    double cellSizeM = 0.914, sunStepMinutes = 10;
    std::string simConfig = "configs/sim-default.toml";
    std::vector<std::string> canopyTargets = {"Douglas-Fir=0.3"};
    std::string crop = "100,60,220,180";
    FidelityParams params;
    bool set(const std::string& name) const { return given.count(name) > 0; }
    std::set<std::string> given;  // options given on the command line (they override the config)
};


/// [fidelity] of a TOML configuration; options given on the command line win.
void readConfig(FidelityArgs& a) {
    const toml::table root = parseTomlFile(a.config);
    StrictTable top(root, a.config, "");
    StrictTable t(top.table("fidelity"), a.config, "[fidelity]");
    const auto str = [&](const char* key, const char* option, std::string& v) {
        if (!t.has(key)) return;
        const std::string x = t.string(key);
        if (!a.set(option)) v = x;
    };
    const auto integer = [&](const char* key, const char* option, std::int64_t& v, std::int64_t lo) {
        if (!t.has(key)) return;
        const std::int64_t x = t.integer(key);
        if (x < lo) t.fail(key, "value " + std::to_string(x) + " must be >= " + std::to_string(lo));
        if (!a.set(option)) v = x;
    };
    const auto positive = [&](const char* key, const char* option, double& v) {
        if (!t.has(key)) return;
        const double x = t.positive(key);
        if (!a.set(option)) v = x;
    };
    str("out_dir", "--out-dir", a.outDir);
    str("terrain", "--terrain", a.terrain);
    str("chm", "--chm", a.chm);
    str("abiotics", "--abiotics", a.abiotics);
    str("canopy", "--canopy", a.canopy);
    str("reference", "--reference", a.reference);
    str("replicate", "--replicate", a.replicate);
    str("database", "--database", a.database);
    str("scene", "--scene", a.scene);
    str("sim_config", "--sim-config", a.simConfig);
    integer("terrain_seed", "--terrain-seed", a.terrainSeed, 0);
    integer("seed_a", "--seed-a", a.seedA, 0);
    integer("seed_b", "--seed-b", a.seedB, 0);
    integer("synth_seed", "--synth-seed", a.synthSeed, 0);
    integer("width", "--width", a.width, 1);
    integer("height", "--height", a.height, 1);
    integer("years", "--years", a.years, 1);
    integer("kmax", "--kmax", a.kmax, 1);
    positive("cell_size_m", "--cell-size", a.cellSizeM);
    positive("sun_step_minutes", "--sun-step", a.sunStepMinutes);
    if (t.has("crop")) {
        const auto c = t.numbers("crop", 4);
        if (!a.set("--crop")) a.crop = fmt(c[0]) + "," + fmt(c[1]) + "," + fmt(c[2]) + "," + fmt(c[3]);
    }
    if (t.has("canopy_targets")) {
        const auto v = t.strings("canopy_targets");
        if (!a.set("--target")) a.canopyTargets = v;
    }
    if (t.has("refine")) {
        const bool x = t.boolean("refine");
        if (!a.set("--refine")) a.refine = x;
    }
    std::int64_t csrSeed = 1;
    integer("csr_seed", "--csr-seed", csrSeed, 0);
    if (t.has("csr_seed") && !a.set("--csr-seed")) a.params.csrSeed = static_cast<std::uint64_t>(csrSeed);
    std::int64_t sweeps = a.refineSweeps;
    integer("refine_sweeps", "--refine-sweeps", sweeps, 1);
    a.refineSweeps = static_cast<int>(sweeps);
    if (t.has("synth_method")) {
        const std::string m = t.string("synth_method");
        if (!a.set("--synth-method")) a.synthMethod = m;
    }
    positive("edge_band_m", "--edge-band", a.params.edgeBandM);
    t.finish();
    top.finish();
}

/// Run eco sub-commands with their stdout sent to stderr, so that stdout carries only the
/// report.
class StdoutToStderr {
public:
    StdoutToStderr() {
        std::fflush(stdout);
        std::cout.flush();
        saved_ = dup(1);
        if (saved_ >= 0) dup2(2, 1);
    }
    ~StdoutToStderr() {
        std::fflush(stdout);
        std::cout.flush();
        if (saved_ >= 0) {
            dup2(saved_, 1);
            close(saved_);
        }
    }
    StdoutToStderr(const StdoutToStderr&) = delete;
    StdoutToStderr& operator=(const StdoutToStderr&) = delete;

private:
    int saved_ = -1;
};

std::string quoted(const std::vector<std::string>& args) {
    std::string s = "eco";
    for (const auto& x : args) s += " " + (x.find(' ') == std::string::npos ? x : "'" + x + "'");
    return s;
}

std::string readText(const std::string& path) {
    std::ifstream in(path);
    std::ostringstream s;
    s << in.rdbuf();
    return s.str();
}

/// The stages in order; a stage is reused when its output exists, the command it was made
/// with (recorded beside it as OUTPUT.cmd) is the same, and no earlier stage was rerun.
class StageRunner {
public:
    void run(const std::string& name, const std::string& output, const std::vector<std::string>& args) {
        const std::string stamp = output + ".cmd";
        // The code's identity joins the command: a database of an older schema (or files of
        // another eco version) is made again rather than reused.
        const std::string cmd = quoted(args) + "\n# eco " + ECO_VERSION_STRING + ", biome database schema " +
                                std::to_string(kBiomeDbSchemaVersion);
        if (!rerun_ && std::filesystem::exists(output) && std::filesystem::exists(stamp) && readText(stamp) == cmd + "\n") {
            info("fidelity: " + name + ": reusing " + output + " (made with the same settings)");
            return;
        }
        info("fidelity: " + name + ":\n   " + cmd);
        const auto t0 = std::chrono::steady_clock::now();
        {
            StdoutToStderr redirect;
            try {
                runCommand(args);
            } catch (const Error& e) {
                throw Error("fidelity stage '" + name + "' failed: " + e.what());
            }
        }
        writeTextFile(stamp, cmd + "\n");
        rerun_ = true;
        info("fidelity: " + name + " done in " +
             formatNumber(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(), 3) + " s");
    }

private:
    bool rerun_ = false;
};

void requireFile(const std::string& path, const std::string& option) {
    if (!std::filesystem::exists(path))
        throw IoError(option + " '" + path + "': no such file");
}

void runFidelity(FidelityArgs a) {
    if (!a.config.empty()) readConfig(a);
    if (a.outDir.empty()) a.outDir = "out/fidelity";
    FidelityParams params = a.params;
    params.window = parseWindow(a.crop, "--crop");
    params.validate();
    parseSynthMethod(a.synthMethod);  // an unknown --synth-method is refused before any stage runs
    for (const auto& [path, option] : std::vector<std::pair<std::string, std::string>>{
             {a.terrain, "--terrain"}, {a.chm, "--chm"}, {a.abiotics, "--abiotics"}, {a.canopy, "--canopy"},
             {a.reference, "--reference"}, {a.replicate, "--replicate"}, {a.database, "--database"}, {a.scene, "--scene"}})
        if (!path.empty()) requireFile(path, option);
    if (a.seedA == a.seedB && a.reference.empty() && a.replicate.empty())
        throw ValidationError("--seed-a and --seed-b are both " + std::to_string(a.seedA) +
                              ": the replicate must be another seed");
    if (!a.scene.empty() && (a.reference.empty() || a.replicate.empty()))
        throw ValidationError("--scene needs --reference A.h5 and --replicate B.h5 (the simulations it is compared with)");
    ensureDirectory(a.outDir);
    const auto at = [&](const std::string& n) { return (std::filesystem::path(a.outDir) / n).string(); };
    StageRunner stages;

    // Inputs of the plot: terrain, CHM, abiotics, canopy (as configs/demo.toml makes them).
    const bool needRun = a.scene.empty() || a.reference.empty() || a.replicate.empty();
    std::string terrain = a.terrain, chm = a.chm, abiotics = a.abiotics, canopy = a.canopy;
    if (needRun) {
        if (terrain.empty()) {
            terrain = at("terrain.h5");
            stages.run("terrain", terrain,
                       {"terrain", "generate", "--out", terrain, "--width", std::to_string(a.width), "--height",
                        std::to_string(a.height), "--cell-size", fmt(a.cellSizeM), "--seed", std::to_string(a.terrainSeed)});
        }
        if (canopy.empty() && chm.empty()) {
            chm = at("chm.h5");
            stages.run("chm", chm, {"chm", "generate", "--terrain", terrain, "--out", chm, "--seed", std::to_string(a.terrainSeed)});
        }
        if (abiotics.empty()) {
            abiotics = at("abiotics.h5");
            stages.run("abiotics", abiotics, {"abiotics", "--terrain", terrain, "--out", abiotics, "--sun-step", fmt(a.sunStepMinutes)});
        }
        if (canopy.empty()) {
            canopy = at("canopy.h5");
            std::vector<std::string> c = {"canopy", "--terrain", terrain, "--chm", chm, "--abiotics", abiotics,
                                          "--out", canopy, "--seed", std::to_string(a.terrainSeed)};
            for (const auto& t : a.canopyTargets) c.insert(c.end(), {"--target", t});
            stages.run("canopy", canopy, c);
        }
    }
    // The two simulations of the plot. Every output path is given, so that none of the
    // simulation configuration's own [outputs] (out/demo/... in sim-default.toml) is written.
    const auto simulate = [&](const std::string& label, std::int64_t seed) {
        const std::string out = at("sim-" + label + ".h5");
        stages.run("simulation " + label + " (seed " + std::to_string(seed) + ")", out,
                   {"simulate", "--config", a.simConfig, "--terrain", terrain, "--abiotics", abiotics, "--canopy", canopy,
                    "--out", out, "--csv", at("sim-" + label + ".csv"), "--png", at("png/sim-" + label), "--seed", std::to_string(seed), "--years",
                    std::to_string(a.years), "--crop", a.crop, "--checkpoint-every", "0"});
        return out;
    };
    const std::string simA = a.reference.empty() ? simulate("A", a.seedA) : a.reference;
    const std::string simB = a.replicate.empty() ? simulate("B", a.seedB) : a.replicate;
    // Database from A, and the scene on the same terrain, canopy and abiotics.
    std::string database = a.database;
    if (database.empty() && a.scene.empty()) {
        database = at("biome-db.h5");
        stages.run("database from A", database,
                   {"analyse", simA, "--out", database, "--seed", std::to_string(a.analyseSeed), "--kmax", std::to_string(a.kmax)});
    }
    // Output names: fidelity.md, fidelity-refined.md (4 sweeps), fidelity-refined-32sweeps.md ...
    std::string variant =
        a.refine && a.scene.empty() ? (a.refineSweeps == 4 ? std::string("-refined") : "-refined-" + std::to_string(a.refineSweeps) + "sweeps")
                 : std::string();
    if (a.scene.empty() && a.synthMethod != "structured") variant = "-" + a.synthMethod + variant;
    std::string scene = a.scene;
    if (scene.empty()) {
        scene = at("scene" + variant + ".h5");
        std::vector<std::string> s = {"synth", "--terrain", terrain, "--canopy", canopy, "--database", database,
                                      "--abiotics", abiotics, "--out", scene, "--seed", std::to_string(a.synthSeed),
                                      "--method", a.synthMethod};
        if (a.refine)
            s.insert(s.end(), {"--refine", "--refine-window", a.crop, "--refine-sweeps", std::to_string(a.refineSweeps)});
        stages.run(a.refine ? "synthesis (refined in the plot)" : "synthesis", scene, s);
    }

    // Read the patterns.
    info("fidelity: reading the patterns");
    std::shared_ptr<const Biome> biomeOwner;
    BiomeDatabase db;
    const bool haveDb = !database.empty();
    if (haveDb) {
        db = readBiomeDatabase(database);
        biomeOwner = std::make_shared<Biome>(databaseBiome(db));
    }
    SimulationReadOptions readOptions;
    LoadedSimulation A = readSimulation(simA, readOptions);
    LoadedSimulation B = readSimulation(simB, readOptions);
    if (!biomeOwner) biomeOwner = B.biome;
    const Biome& biome = *biomeOwner;
    for (const auto* sim : {&A, &B})
        if (sim->biome->species.size() != biome.species.size())
            throw ValidationError("fidelity: the simulations and the database have different species lists");
    const SceneData sceneData = readSceneFile(scene, biome);

    FidelityContext ctx;
    ctx.biome = &biome;
    ctx.canopy = sceneData.canopy;
    ctx.regionMap = sceneData.clusterMap;
    int maxLabel = -1;
    for (std::size_t i = 0; i < ctx.regionMap.size(); ++i) maxLabel = std::max(maxLabel, ctx.regionMap.data()[i]);
    ctx.nRegions = haveDb ? static_cast<int>(db.regions.size()) : maxLabel + 1;
    for (int r = 0; r < ctx.nRegions; ++r)
        ctx.regionNames.push_back(haveDb ? "region " + std::to_string(r) + " (" +
                                               db.combinationName(db.regions[static_cast<std::size_t>(r)].combination) +
                                               " / " + std::to_string(db.regions[static_cast<std::size_t>(r)].cluster) + ")"
                                         : "region " + std::to_string(r));
    if (!canopy.empty()) {
        const CanopyFileData cf = readCanopyFile(canopy, biome);
        ctx.chmM = cf.chmM;
    } else {
        info("fidelity: no --canopy file: heights against the CHM are not measured");
    }
    for (const auto& [w, name] : std::vector<std::pair<RectWindow, std::string>>{{A.input.window, simA}, {B.input.window, simB}})
        if (w.x0 > params.window.x0 + 1e-6 || w.y0 > params.window.y0 + 1e-6 || w.x1 < params.window.x1 - 1e-6 ||
            w.y1 < params.window.y1 - 1e-6)
            throw ValidationError("--crop " + a.crop + ": the plot is not inside the simulated area " + fmt(w.x0) + "," +
                                  fmt(w.y0) + "," + fmt(w.x1) + "," + fmt(w.y1) + " of '" + name + "'");

    info("fidelity: measuring (scene " + std::to_string(sceneData.undergrowth.size()) + " plants on the terrain, A " +
         std::to_string(A.input.undergrowth.size()) + ", B " + std::to_string(B.input.undergrowth.size()) + ")");
    const auto t0 = std::chrono::steady_clock::now();
    const FidelityReport report = evaluateFidelity(sceneData.undergrowth, A.input.undergrowth, B.input.undergrowth, ctx, params);
    info("fidelity: measured in " +
         formatNumber(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(), 3) + " s");

    std::ostringstream heading;
    heading << "## Fidelity: " << scene << " against held-out " << simB << "\n\n"
            << "eco " << ECO_VERSION_STRING << ", " << utcTimestamp() << ". Reference A: " << simA
            << (haveDb ? "; database: " + database : std::string()) << (a.refine ? "; refined in the plot, " + std::to_string(a.refineSweeps) + " sweeps" : std::string()) << ".";
    const std::string md = fidelityMarkdown(report, heading.str());
    std::cout << md;
    const std::string outMd = a.outMd.empty() ? at("fidelity" + variant + ".md") : a.outMd;
    const std::string outCsv = a.outCsv.empty() ? at("fidelity" + variant + ".csv") : a.outCsv;
    writeTextFile(outMd, md);
    writeFidelityCsv(outCsv, report);
    info("fidelity: wrote " + outMd + " and " + outCsv);
}

}  // namespace

void registerFidelityCommand(CLI::App& app) {
    auto a = std::make_shared<FidelityArgs>();
    CLI::App* cmd = app.add_subcommand(
        "fidelity",
        "The fidelity protocol (docs/fidelity.md): simulate a plot with two seeds (A, B), build the database from A, "
        "synthesize on the same terrain, canopy and abiotics, and compare the scene with the held-out B inside the "
        "plot, each figure beside the replicate level d(A, B) and the CSR level, with a score (0 = replicate, 1 = "
        "CSR). Defaults reproduce configs/demo.toml's first scene and plot. Existing files can be given instead of "
        "any stage; stages are cached in --out-dir.");
    const auto opt = [&](const std::string& name, auto& var, const std::string& help) {
        CLI::Option* o = cmd->add_option(name, var, help);
        o->each([a, name](const std::string&) { a->given.insert(name); });
        return o;
    };
    opt("--config", a->config, "TOML with a [fidelity] table (keys as the options, with underscores; docs/fidelity.md)");
    opt("--out-dir", a->outDir, "Folder of the stages' files and the report (default out/fidelity)");
    opt("--terrain", a->terrain, "Existing terrain (else generated as the demo's)");
    opt("--chm", a->chm, "Existing canopy height model (else generated)");
    opt("--abiotics", a->abiotics, "Existing abiotics of the terrain (no canopy shade)");
    opt("--canopy", a->canopy, "Existing canopy file (eco canopy) of the terrain");
    opt("--reference", a->reference, "Existing simulation A (the database's source)");
    opt("--replicate", a->replicate, "Existing simulation B (held out; another seed)");
    opt("--database", a->database, "Existing database from A");
    opt("--scene", a->scene, "Existing scene (eco synth) on the same terrain and canopy; needs --reference and --replicate");
    opt("--out-md", a->outMd, "Markdown report (default OUT_DIR/fidelity.md)");
    opt("--out-csv", a->outCsv, "Every figure, value and curve as CSV (default OUT_DIR/fidelity.csv)");
    CLI::Option* refine = cmd->add_flag("--refine", a->refine, "Synthesize with --refine (inside the plot)");
    refine->each([a](const std::string&) { a->given.insert("--refine"); });
    opt("--refine-sweeps", a->refineSweeps, "Refinement sweeps")->capture_default_str()->check(CLI::PositiveNumber);
    opt("--synth-method", a->synthMethod,
        "Undergrowth sampler of the synthesis: structured (default) or darts (the earlier one); outputs of darts are "
        "named scene-darts*.h5, fidelity-darts*.md")
        ->capture_default_str();
    opt("--seed-a", a->seedA, "Seed of simulation A")->capture_default_str()->check(nonNegativeNumber());
    opt("--seed-b", a->seedB, "Seed of simulation B")->capture_default_str()->check(nonNegativeNumber());
    opt("--synth-seed", a->synthSeed, "Seed of the synthesis")->capture_default_str()->check(nonNegativeNumber());
    opt("--terrain-seed", a->terrainSeed, "Seed of the generated terrain, CHM and canopy")->capture_default_str()->check(nonNegativeNumber());
    opt("--width", a->width, "Generated terrain: cells along x")->capture_default_str()->check(positiveNumber());
    opt("--height", a->height, "Generated terrain: cells along y")->capture_default_str()->check(positiveNumber());
    opt("--cell-size", a->cellSizeM, "Generated terrain: metres per cell")->capture_default_str()->check(positiveNumber());
    opt("--sun-step", a->sunStepMinutes, "Abiotics: sun step, minutes")->capture_default_str()->check(positiveNumber());
    opt("--target", a->canopyTargets, "Canopy species targets, e.g. Douglas-Fir=0.3 (repeatable)");
    opt("--sim-config", a->simConfig, "Simulation configuration (model constants)")->capture_default_str();
    opt("--years", a->years, "Years simulated")->capture_default_str()->check(positiveNumber());
    opt("--kmax", a->kmax, "Analysis: largest k per combination")->capture_default_str()->check(positiveNumber());
    opt("--crop", a->crop, "The plot x0,y0,x1,y1 (m): simulated and compared")->capture_default_str();
    opt("--edge-band", a->params.edgeBandM, "Gap-edge band, m (either side of the crown-cover edge)")
        ->capture_default_str()
        ->check(positiveNumber());
    opt("--csr-seed", a->params.csrSeed, "Seed of the CSR reference pattern")->capture_default_str();
    cmd->callback([a] { runFidelity(*a); });
}

}  // namespace eco::cli
