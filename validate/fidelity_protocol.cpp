#include "fidelity_protocol.h"

#include <algorithm>
#include <chrono>
#include <climits>
#include <filesystem>
#include <fstream>
#include <ostream>
#include <sstream>

#include "atomic_file.h"
#include "biome_db.h"
#include "canopy_placer.h"
#include "eco_version.h"
#include "error.h"
#include "provenance.h"
#include "run.h"
#include "scene.h"
#include "sim_input.h"
#include "stage_common.h"
#include "stage_runner.h"
#include "strict_toml.h"
#include "text_format.h"
#include "undergrowth.h"

namespace eco::validate {

namespace {

std::string fmt(double v) { return formatNumber(v, 10); }

/// Settings the stages accept (the limits of their own command lines), checked before any runs.
void checkStageSettings(const FidelityRunOptions& a) {
    const auto within = [](const char* option, std::int64_t v, std::int64_t lo, std::int64_t hi) {
        if (v < lo || v > hi)
            throw ValidationError(std::string(option) + ": must be in " + std::to_string(lo) + " .. " + std::to_string(hi) +
                                  ", got " + std::to_string(v));
    };
    if (a.terrain.empty()) {
        within("--width", a.width, 2, 1 << 16);
        within("--height", a.height, 2, 1 << 16);
    }
    if (a.reference.empty() || a.replicate.empty()) within("--years", a.years, 1, INT_MAX);
    if (a.database.empty()) within("--kmax", a.kmax, 1, 64);
    if (a.refine) within("--refine-sweeps", a.refineSweeps, 1, INT_MAX);
    if (a.abiotics.empty() && !(a.sunStepMinutes >= 0.1 && a.sunStepMinutes <= 720))
        throw ValidationError("--sun-step: must be in 0.1 .. 720 minutes, got " + fmt(a.sunStepMinutes));
}

void requireFile(const std::string& path, const std::string& option) {
    if (!std::filesystem::exists(path))
        throw IoError(option + " '" + path + "': no such file");
}

}  // namespace

void readFidelityConfig(const std::string& path, FidelityRunOptions& a, const std::set<std::string>& given) {
    const auto set = [&](const std::string& option) { return given.count(option) > 0; };
    const toml::table root = parseTomlFile(path);
    StrictTable top(root, path, "");
    StrictTable t(top.table("fidelity"), path, "[fidelity]");
    // Every string key is a path: relative to this file's directory (flags: to the working one).
    const auto str = [&](const char* key, const char* option, std::string& v) {
        if (!t.has(key)) return;
        const std::string x = pathRelativeToConfig(path, t.string(key));
        if (!set(option)) v = x;
    };
    const auto integer = [&](const char* key, const char* option, std::int64_t& v, std::int64_t lo) {
        if (!t.has(key)) return;
        const std::int64_t x = t.integer(key);
        if (x < lo) t.fail(key, "value " + std::to_string(x) + " must be >= " + std::to_string(lo));
        if (!set(option)) v = x;
    };
    const auto positive = [&](const char* key, const char* option, double& v) {
        if (!t.has(key)) return;
        const double x = t.positive(key);
        if (!set(option)) v = x;
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
    str("canopy_config", "--canopy-config", a.canopyConfig);
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
        if (!set("--crop")) a.crop = fmt(c[0]) + "," + fmt(c[1]) + "," + fmt(c[2]) + "," + fmt(c[3]);
    }
    if (t.has("canopy_targets")) {
        const auto v = t.strings("canopy_targets");
        if (!set("--target")) a.canopyTargets = v;
    }
    if (t.has("refine")) {
        const bool x = t.boolean("refine");
        if (!set("--refine")) a.refine = x;
    }
    std::int64_t csrSeed = 1;
    integer("csr_seed", "--csr-seed", csrSeed, 0);
    if (t.has("csr_seed") && !set("--csr-seed")) a.params.csrSeed = static_cast<std::uint64_t>(csrSeed);
    std::int64_t sweeps = a.refineSweeps;
    integer("refine_sweeps", "--refine-sweeps", sweeps, 1);
    a.refineSweeps = static_cast<int>(sweeps);
    if (t.has("synth_method")) {
        const std::string m = t.string("synth_method");
        if (!set("--synth-method")) a.synthMethod = m;
    }
    positive("edge_band_m", "--edge-band", a.params.edgeBandM);
    t.finish();
    top.finish();
}


FidelityRunResult runFidelityProtocol(const FidelityRunOptions& options, pipeline::Reporter& reporter,
                                      const std::function<std::unique_ptr<pipeline::Reporter>()>& stageReporter) {
    FidelityRunOptions a = options;
    if (a.outDir.empty()) a.outDir = "out/fidelity";
    FidelityParams params = a.params;
    params.window = pipeline::parseWindow(a.crop, "--crop");
    params.validate();
    synth::parseSynthMethod(a.synthMethod);  // an unknown --synth-method is refused before any stage runs
    for (const auto& [path, option] : std::vector<std::pair<std::string, std::string>>{
             {a.terrain, "--terrain"}, {a.chm, "--chm"}, {a.abiotics, "--abiotics"}, {a.canopy, "--canopy"},
             {a.reference, "--reference"}, {a.replicate, "--replicate"}, {a.database, "--database"}, {a.scene, "--scene"},
             {a.canopyConfig, "--canopy-config"}})
        if (!path.empty()) requireFile(path, option);
    if (!a.canopyConfig.empty() && !a.canopy.empty())
        throw ValidationError("--canopy-config '" + a.canopyConfig + "' and --canopy '" + a.canopy +
                              "': the placer's settings apply only to a canopy the protocol places; give one of them");
    if (!a.canopyConfig.empty()) {  // read now: a bad key or value is refused before any stage runs
        synth::CanopyParams canopyParams;
        synth::SpeciesMapParams speciesParams;
        synth::loadCanopyConfig(a.canopyConfig, canopyParams, speciesParams);
        synth::validateCanopyParams(canopyParams);
    }
    if (a.seedA == a.seedB && a.reference.empty() && a.replicate.empty())
        throw ValidationError("--seed-a and --seed-b are both " + std::to_string(a.seedA) +
                              ": the replicate must be another seed");
    if (!a.scene.empty() && (a.reference.empty() || a.replicate.empty()))
        throw ValidationError("--scene needs --reference A.h5 and --replicate B.h5 (the simulations it is compared with)");
    checkStageSettings(a);
    ensureDirectory(a.outDir);
    const auto at = [&](const std::string& n) { return (std::filesystem::path(a.outDir) / n).string(); };
    pipeline::StageRunner stages("fidelity", reporter, stageReporter);

    // Inputs of the plot: terrain, CHM, abiotics, canopy (as configs/demo.toml makes them).
    const bool needRun = a.scene.empty() || a.reference.empty() || a.replicate.empty();
    std::string terrain = a.terrain, chm = a.chm, abiotics = a.abiotics, canopy = a.canopy;
    if (needRun) {
        if (terrain.empty()) {
            terrain = at("terrain.h5");
            pipeline::TerrainGenerateOptions o;
            o.out = terrain;
            o.params.width = static_cast<int>(a.width);
            o.params.height = static_cast<int>(a.height);
            o.params.cellSizeM = pipeline::asOnCommandLine(a.cellSizeM);
            o.params.seed = static_cast<std::uint64_t>(a.terrainSeed);
            stages.run("terrain", terrain, o);
        }
        if (canopy.empty() && chm.empty()) {
            chm = at("chm.h5");
            pipeline::ChmGenerateOptions o;
            o.terrain = terrain;
            o.out = chm;
            o.chm.seed = static_cast<std::uint64_t>(a.terrainSeed);
            stages.run("chm", chm, o);
        }
        if (abiotics.empty()) {
            abiotics = at("abiotics.h5");
            pipeline::AbioticsOptions o;
            o.terrain = terrain;
            o.out = abiotics;
            o.sunStepMinutes = pipeline::asOnCommandLine(a.sunStepMinutes);
            stages.run("abiotics", abiotics, o);
        }
        if (canopy.empty()) {
            canopy = at("canopy.h5");
            pipeline::CanopyOptions o;
            o.terrain = terrain;
            o.chm = chm;
            o.abiotics = abiotics;
            o.out = canopy;
            o.config = a.canopyConfig;
            o.params.setSeed("seed", static_cast<std::uint64_t>(a.terrainSeed));
            o.targets = a.canopyTargets;
            stages.run("canopy", canopy, o);
        }
    }
    // The two simulations of the plot. Every output path is given, so that none of the
    // simulation configuration's own [outputs] (out/demo/... in sim-default.toml) is written.
    const auto simulate = [&](const std::string& label, std::int64_t seed) {
        const std::string out = at("sim-" + label + ".h5");
        pipeline::SimulateOptions o;
        o.config = a.simConfig;
        o.terrain = terrain;
        o.abiotics = abiotics;
        o.canopy = canopy;
        o.out = out;
        o.csv = at("sim-" + label + ".csv");
        o.png = at("png/sim-" + label);
        o.seed = seed;
        o.years = static_cast<int>(a.years);
        o.crop = a.crop;
        o.checkpointEvery = 0;
        stages.run("simulation " + label + " (seed " + std::to_string(seed) + ")", out, o);
        return out;
    };
    const std::string simA = a.reference.empty() ? simulate("A", a.seedA) : a.reference;
    const std::string simB = a.replicate.empty() ? simulate("B", a.seedB) : a.replicate;
    // Database from A, and the scene on the same terrain, canopy and abiotics.
    std::string database = a.database;
    if (database.empty() && a.scene.empty()) {
        database = at("biome-db.h5");
        pipeline::AnalyseOptions o;
        o.simulations = {simA};
        o.out = database;
        o.seed = a.analyseSeed;
        o.kMax = static_cast<int>(a.kmax);
        stages.run("database from A", database, o);
    }
    // Output names: fidelity.md, fidelity-refined.md (4 sweeps), fidelity-refined-32sweeps.md ...
    std::string variant =
        a.refine && a.scene.empty() ? (a.refineSweeps == 4 ? std::string("-refined") : "-refined-" + std::to_string(a.refineSweeps) + "sweeps")
                 : std::string();
    if (a.scene.empty() && a.synthMethod != "structured") variant = "-" + a.synthMethod + variant;
    std::string scene = a.scene;
    if (scene.empty()) {
        scene = at("scene" + variant + ".h5");
        pipeline::SynthOptions o;
        o.terrain = terrain;
        o.canopy = canopy;
        o.database = database;
        o.abiotics = abiotics;
        o.out = scene;
        o.params.seed = static_cast<std::uint64_t>(a.synthSeed);
        o.method = a.synthMethod;
        // Xu 2015 copies an exemplar stand: the database's own source, simulation A.
        if (a.synthMethod == "xu2015") o.exemplar = simA;
        if (a.refine) {
            o.refine = true;
            o.refineWindow = a.crop;
            o.refineParams.set("refine_sweeps", a.refineSweeps);
        }
        stages.run(a.refine ? "synthesis (refined in the plot)" : "synthesis", scene, o);
    }

    // Read the patterns.
    reporter.info("fidelity: reading the patterns");
    std::shared_ptr<const Biome> biomeOwner;
    BiomeDatabase db;
    const bool haveDb = !database.empty();
    if (haveDb) {
        db = readBiomeDatabase(database);
        biomeOwner = std::make_shared<Biome>(synth::databaseBiome(db));
    }
    analysis::SimulationReadOptions readOptions;
    analysis::LoadedSimulation A = analysis::readSimulation(simA, readOptions);
    analysis::LoadedSimulation B = analysis::readSimulation(simB, readOptions);
    if (!biomeOwner) biomeOwner = B.biome;
    const Biome& biome = *biomeOwner;
    for (const auto* sim : {&A, &B})
        if (sim->biome->species.size() != biome.species.size())
            throw ValidationError("fidelity: the simulations and the database have different species lists");
    const synth::SceneData sceneData = synth::readSceneFile(scene, biome);

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
        reporter.info("fidelity: no --canopy file: heights against the CHM are not measured");
    }
    for (const auto& [w, name] : std::vector<std::pair<RectWindow, std::string>>{{A.input.window, simA}, {B.input.window, simB}})
        if (w.x0 > params.window.x0 + 1e-6 || w.y0 > params.window.y0 + 1e-6 || w.x1 < params.window.x1 - 1e-6 ||
            w.y1 < params.window.y1 - 1e-6)
            throw ValidationError("--crop " + a.crop + ": the plot is not inside the simulated area " + fmt(w.x0) + "," +
                                  fmt(w.y0) + "," + fmt(w.x1) + "," + fmt(w.y1) + " of '" + name + "'");

    reporter.info("fidelity: measuring (scene " + std::to_string(sceneData.undergrowth.size()) + " plants on the terrain, A " +
         std::to_string(A.input.undergrowth.size()) + ", B " + std::to_string(B.input.undergrowth.size()) + ")");
    const auto t0 = std::chrono::steady_clock::now();
    const FidelityReport report = evaluateFidelity(sceneData.undergrowth, A.input.undergrowth, B.input.undergrowth, ctx, params);
    reporter.info("fidelity: measured in " +
         formatNumber(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(), 3) + " s");

    std::ostringstream heading;
    heading << "## Fidelity: " << scene << " against held-out " << simB << "\n\n"
            << "eco " << ECO_VERSION_STRING << ", " << utcTimestamp() << ". Reference A: " << simA
            << (haveDb ? "; database: " + database : std::string()) << (a.refine ? "; refined in the plot, " + std::to_string(a.refineSweeps) + " sweeps" : std::string()) << ".";
    const std::string md = fidelityMarkdown(report, heading.str());
    reporter.out() << md;
    const std::string outMd = a.outMd.empty() ? at("fidelity" + variant + ".md") : a.outMd;
    const std::string outCsv = a.outCsv.empty() ? at("fidelity" + variant + ".csv") : a.outCsv;
    AtomicOutputSet outputs;  // the report and its table together
    writeTextFile(outMd, md);
    writeFidelityCsv(outCsv, report);
    outputs.commit();
    reporter.info("fidelity: wrote " + outMd + " and " + outCsv);
    return {report, md, outMd, outCsv, scene, simA, simB, database};
}


}  // namespace eco::validate
