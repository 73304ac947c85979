#include "run.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <ostream>
#include <sstream>
#include <tuple>

#include "abiotics.h"
#include "atomic_file.h"
#include "biome_db.h"
#include "eco_version.h"
#include "error.h"
#include "provenance.h"
#include "run_html.h"
#include "strict_toml.h"
#include "text_format.h"

namespace eco::pipeline {

namespace {

template <class... F>
struct Overloaded : F... {
    using F::operator()...;
};
template <class... F>
Overloaded(F...) -> Overloaded<F...>;

/// An integer the stage's command line would accept in [lo, hi].
std::int64_t integerIn(StrictTable& t, const std::string& key, std::int64_t value, std::int64_t lo, std::int64_t hi) {
    if (value < lo || value > hi)
        t.fail(key, "value " + std::to_string(value) + " must be in " + std::to_string(lo) + " .. " + std::to_string(hi));
    return value;
}

std::uint64_t seedValue(StrictTable& t, const std::string& key, std::int64_t value) {
    if (value < 0) t.fail(key, "must not be negative");
    return static_cast<std::uint64_t>(value);
}

}  // namespace

std::vector<std::string> commandLine(const StageOptions& options) {
    return std::visit([](const auto& o) { return commandLine(o); }, options);
}

void runStage(const StageOptions& options, Reporter& reporter) {
    std::visit(Overloaded{[&](const TerrainGenerateOptions& o) { generateTerrainStage(o, reporter); },
                          [&](const ChmGenerateOptions& o) { generateChmStage(o, reporter); },
                          [&](const AbioticsOptions& o) { abioticsStage(o, reporter); },
                          [&](const CanopyOptions& o) { canopyStage(o, reporter); },
                          [&](const SimulateOptions& o) { simulateStage(o, reporter); },
                          [&](const AnalyseOptions& o) { analyseStage(o, reporter); },
                          [&](const InspectOptions& o) { inspectStage(o, reporter); },
                          [&](const SynthOptions& o) { synthStage(o, reporter); },
                          [&](const CompareOptions& o) { compareStage(o, reporter); }},
               options);
}

const std::vector<std::pair<std::string, std::string>>& pipelineConfigPathKeys() {
    static const std::vector<std::pair<std::string, std::string>> keys = {
        {"run", "out_dir"},   {"run", "biome"},        {"terrain", "path"},   {"chm", "path"}, {"chm", "sketch"},
        {"canopy", "config"}, {"simulate", "config"}, {"synth", "terrain"}, {"synth", "chm"}};
    return keys;
}

RunPlan planRun(const std::string& configPath, const std::string& outOverride) {
    const toml::table root = parseTomlFile(configPath);
    StrictTable top(root, configPath, "");
    std::vector<PlannedStage> stages;

    StrictTable run(top.table("run"), configPath, "[run]");
    // Every path the file sets is relative to the file's directory (docs: eco run), so that a
    // configuration runs from any working directory; --out-dir is relative to the working one.
    const auto relative = [&](const std::string& value) { return pathRelativeToConfig(configPath, value); };
    const std::string configuredOut = relative(run.string("out_dir"));
    const std::string out = outOverride.empty() ? configuredOut : outOverride;
    const std::int64_t seed = run.integerOr("seed", 1);
    if (seed < 0) run.fail("seed", "must not be negative");
    const std::string biome = relative(run.stringOr("biome", ""));
    // GIS outputs: every grid of abiotics, canopy and scene as GeoTIFF and the plants as
    // GeoPackage, in gis/ (and target/gis/), in the inputs' CRS.
    const bool gis = run.booleanOr("gis", false);
    run.finish();
    ensureDirectory(out);
    const auto at = [&](const std::string& name) { return (std::filesystem::path(out) / name).string(); };

    // The stages of one scene, the simulated one (dir "") or the synthesis target (dir
    // "target/"): the same options, each scene in its own folder. Filled in below as the
    // tables are read.
    double sunStepMinutes = 10;
    std::string canopyConfig;
    std::vector<std::string> canopyTargets;
    const auto generatedTerrain = [&](const std::string& dir, const TerrainGenParams& params) {
        TerrainGenerateOptions o;
        o.out = at(dir + "terrain.h5");
        o.params = params;
        o.pngDir = at(dir + "png");
        return o;
    };
    const auto generatedChm = [&](const std::string& dir, const std::string& terrainPath, const TerrainReadFlags& read,
                                  std::uint64_t chmSeed) {
        ChmGenerateOptions o;
        o.terrain = terrainPath;
        o.out = at(dir + "chm.h5");
        o.chm.seed = chmSeed;
        o.pngDir = at(dir + "png");
        o.terrainRead = read;
        return o;
    };
    const auto abioticsOf = [&](const std::string& dir, const std::string& terrainPath, const TerrainReadFlags& read) {
        AbioticsOptions o;
        o.terrain = terrainPath;
        o.out = at(dir + "abiotics.h5");
        o.pngDir = at(dir + "png/abiotics");
        if (gis) o.geotiffDir = at(dir + "gis");
        o.sunStepMinutes = sunStepMinutes;
        o.terrainRead = read;
        o.biome = biome;
        return o;
    };
    const auto canopyOf = [&](const std::string& dir, const std::string& terrainPath, const std::string& chmPath,
                              const TerrainReadFlags& read, std::uint64_t canopySeed) {
        CanopyOptions o;
        o.terrain = terrainPath;
        o.chm = chmPath;
        o.abiotics = at(dir + "abiotics.h5");
        o.out = at(dir + "canopy.h5");
        o.pngDir = at(dir + "png/canopy");
        if (gis) {
            o.geotiffDir = at(dir + "gis");
            o.gpkg = at(dir + "gis/canopy.gpkg");
        }
        o.params.setSeed("seed", canopySeed);
        o.terrainRead = read;
        o.config = canopyConfig;
        o.targets = canopyTargets;
        o.biome = biome;
        return o;
    };

    // Terrain: a given file, or the generated default.
    std::string terrain = at("terrain.h5");
    TerrainReadFlags terrainRead;
    TerrainGenParams terrainParams;
    {
        StrictTable t(top.table("terrain"), configPath, "[terrain]");
        if (t.has("path")) {
            terrain = relative(t.string("path"));
            if (t.has("cell_size_m")) terrainRead.cellSizeM = asOnCommandLine(t.numberIn("cell_size_m", kMinCellSizeM, kMaxCellSizeM));
            if (t.has("vertical_scale")) terrainRead.verticalScale = asOnCommandLine(t.positive("vertical_scale"));
        } else {
            terrainParams.width = static_cast<int>(integerIn(t, "width", t.integerOr("width", 512), 2, 1 << 16));
            terrainParams.height = static_cast<int>(integerIn(t, "height", t.integerOr("height", 512), 2, 1 << 16));
            terrainParams.cellSizeM = asOnCommandLine(t.numberInOr("cell_size_m", kMinCellSizeM, kMaxCellSizeM, 0.914));
            terrainParams.seed = seedValue(t, "seed", t.integerOr("seed", seed));
            terrainParams.reliefM = asOnCommandLine(t.numberInOr("relief_m", 0.0, 5000.0, terrainParams.reliefM));
            terrainParams.valleyDepthM = asOnCommandLine(t.numberInOr("valley_depth_m", 0.01, 5000.0, terrainParams.valleyDepthM));
            terrainParams.baseElevationM =
                asOnCommandLine(t.numberInOr("base_elevation_m", -500.0, 9000.0, terrainParams.baseElevationM));
            stages.push_back({"terrain", generatedTerrain("", terrainParams)});
        }
        t.finish();
    }
    // Canopy height model: a given file, or generated from a density sketch.
    std::string chm = at("chm.h5");
    {
        StrictTable t(top.table("chm"), configPath, "[chm]");
        if (t.has("path")) {
            chm = relative(t.string("path"));
        } else {
            ChmGenerateOptions o = generatedChm("", terrain, terrainRead, seedValue(t, "seed", t.integerOr("seed", seed)));
            if (t.has("sketch")) o.sketchImage = relative(t.string("sketch"));
            stages.push_back({"chm", o});
        }
        t.finish();
    }
    // Abiotics.
    const std::string abiotics = at("abiotics.h5");
    {
        StrictTable t(top.table("abiotics"), configPath, "[abiotics]");
        const ParamDesc<SunParams>& step = paramField(sunParamFields(), "sun_step_minutes");
        sunStepMinutes = asOnCommandLine(t.numberOr(step.key, sunStepMinutes));
        if (!step.range.contains(sunStepMinutes))
            t.fail(step.key, "value " + formatNumber(sunStepMinutes) + " " + step.ruleText() + " (minutes)");
        stages.push_back({"abiotics", abioticsOf("", terrain, terrainRead)});
        t.finish();
    }
    // Canopy trees from the CHM.
    const std::string canopy = at("canopy.h5");
    const bool placesCanopy = top.has("canopy");
    if (const toml::table* tt = top.optionalTable("canopy")) {
        StrictTable t(*tt, configPath, "[canopy]");
        if (t.has("config")) canopyConfig = relative(t.string("config"));
        if (t.has("targets")) canopyTargets = t.strings("targets");
        CanopyOptions o = canopyOf("", terrain, chm, terrainRead, static_cast<std::uint64_t>(seed));
        o.csv = at("canopy.csv");
        stages.push_back({"canopy", o});
        t.finish();
    }
    // Undergrowth simulation on part of the scene.
    const std::string simulation = at("simulation.h5");
    bool simulated = false, analysed = false;
    if (const toml::table* tt = top.optionalTable("simulate")) {
        StrictTable t(*tt, configPath, "[simulate]");
        if (!placesCanopy) t.fail("config", "the simulation needs a [canopy] stage for its canopy trees");
        SimulateOptions o;
        o.config = relative(t.string("config"));
        o.terrain = terrain;
        o.abiotics = abiotics;
        o.canopy = canopy;
        o.out = simulation;
        o.csv = at("undergrowth.csv");
        o.png = at("png/simulation");
        o.seed = seed;
        if (t.has("years")) o.years = static_cast<int>(integerIn(t, "years", t.integer("years"), 1, 1 << 30));
        if (t.has("crop")) {
            const auto c = t.numbers("crop", 4);
            o.crop = argNumber(c[0]) + "," + argNumber(c[1]) + "," + argNumber(c[2]) + "," + argNumber(c[3]);
        }
        o.biome = biome;
        stages.push_back({"simulate", o});
        simulated = true;
        t.finish();
    }
    // Statistics of the simulation: the biome database.
    const std::string database = at("biome-db.h5");
    if (const toml::table* tt = top.optionalTable("analyse")) {
        StrictTable t(*tt, configPath, "[analyse]");
        if (!simulated) t.fail("analyse", "needs a [simulate] stage to analyse");
        AnalyseOptions o;
        o.simulations = {simulation};
        o.out = database;
        o.seed = seed;
        if (t.has("kmax")) o.kMax = static_cast<int>(integerIn(t, "kmax", t.integer("kmax"), 1, 64));
        stages.push_back({"analyse", o});
        InspectOptions inspect;
        inspect.database = database;
        inspect.pngDir = at("png/database");
        inspect.out = at("database.txt");
        stages.push_back({"inspect", inspect});
        analysed = true;
        t.finish();
    }
    // Synthesis on a different target terrain, from the database, and its comparison.
    if (const toml::table* tt = top.optionalTable("synth")) {
        StrictTable t(*tt, configPath, "[synth]");
        if (!analysed) t.fail("synth", "needs an [analyse] stage for its biome database");
        const std::int64_t targetSeed = t.integerOr("target_seed", seed + 1);
        if (targetSeed < 0) t.fail("target_seed", "must not be negative");
        const auto ts = static_cast<std::uint64_t>(targetSeed);
        std::string targetTerrain = at("target/terrain.h5");
        TerrainReadFlags targetRead;
        ensureDirectory(at("target"));
        if (t.has("terrain")) {
            targetTerrain = relative(t.string("terrain"));
            if (t.has("cell_size_m")) targetRead.cellSizeM = asOnCommandLine(t.numberIn("cell_size_m", kMinCellSizeM, kMaxCellSizeM));
        } else {
            TerrainGenParams p;
            p.width = static_cast<int>(integerIn(t, "width", t.integerOr("width", terrainParams.width), 2, 1 << 16));
            p.height = static_cast<int>(integerIn(t, "height", t.integerOr("height", terrainParams.height), 2, 1 << 16));
            p.cellSizeM = asOnCommandLine(t.numberInOr("cell_size_m", kMinCellSizeM, kMaxCellSizeM, terrainParams.cellSizeM));
            p.seed = ts;
            stages.push_back({"target terrain", generatedTerrain("target/", p)});
        }
        std::string targetChm = at("target/chm.h5");
        if (t.has("chm")) targetChm = relative(t.string("chm"));
        else stages.push_back({"target chm", generatedChm("target/", targetTerrain, targetRead, ts)});
        const std::string targetAbiotics = at("target/abiotics.h5");
        stages.push_back({"target abiotics", abioticsOf("target/", targetTerrain, targetRead)});
        const std::string targetCanopy = at("target/canopy.h5");
        stages.push_back({"target canopy", canopyOf("target/", targetTerrain, targetChm, targetRead, ts)});
        const std::string scene = at("scene.h5");
        {
            SynthOptions o;
            o.terrain = targetTerrain;
            o.canopy = targetCanopy;
            o.database = database;
            o.abiotics = targetAbiotics;
            o.out = scene;
            o.pngDir = at("png/synth");
            o.csv = at("scene.csv");
            o.pdb = at("scene.pdb");
            if (gis) {
                o.geotiffDir = at("gis");
                o.gpkg = at("gis/scene.gpkg");
            }
            o.params.seed = ts;
            o.terrainRead = targetRead;
            o.refine = t.booleanOr("refine", false);
            stages.push_back({"synth", o});
        }
        CompareOptions compare;
        compare.scene = scene;
        compare.database = database;
        compare.pngDir = at("png/synth");
        compare.out = at("compare.md");
        stages.push_back({"compare", compare});
        t.finish();
    }
    top.finish();
    // Every stage's own settings (the simulation's and the placer's configuration files, the
    // biome, the targets) checked now, not when the stage starts minutes into the run.
    if (!biome.empty()) loadBiome(biome);
    for (const PlannedStage& s : stages) {
        try {
            if (const auto* o = std::get_if<SimulateOptions>(&s.options)) simulateConfig(*o);
            if (const auto* o = std::get_if<CanopyOptions>(&s.options)) checkCanopyOptions(*o);
        } catch (const Error& e) {
            throw ValidationError(configPath + ": stage '" + s.name + "': " + e.what());
        }
    }
    return {configPath, out, stages};
}

namespace {

std::string fmtNumber(double v) { return argNumber(v); }

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


/// The simulator's plants_year_NNNN.png pictures of a folder, at most `limit`: the last
/// simulated year always, year 0 (the start, before the first year's seeding) only when it is
/// the only one, the rest evenly spaced between; a line says which are left out.
void yearPictures(std::ostringstream& md, const std::filesystem::path& outDir, const std::string& relDir,
                  std::size_t limit) {
    const std::filesystem::path dir = outDir / relDir;
    if (!std::filesystem::is_directory(dir) || limit == 0) return;
    std::vector<std::pair<int, std::string>> years;  // year, file name
    for (const auto& e : std::filesystem::directory_iterator(dir)) {
        const std::string n = e.path().filename().string();
        int year = -1;
        char tail = 0;
        if (e.is_regular_file() && e.path().extension() == ".png" &&
            std::sscanf(n.c_str(), "plants_year_%d.pn%c", &year, &tail) == 2 && tail == 'g' &&
            year >= 0)
            years.emplace_back(year, n);
    }
    if (years.empty()) return;
    std::sort(years.begin(), years.end());
    const std::size_t total = years.size();
    const bool dropStart = years.front().first == 0 && years.size() > 1;
    if (dropStart) years.erase(years.begin());
    std::vector<std::pair<int, std::string>> shown;
    if (years.size() <= limit) {
        shown = years;
    } else {
        for (std::size_t i = 0; i < limit; ++i) {  // first and last included
            const std::size_t k = limit == 1 ? years.size() - 1
                                             : static_cast<std::size_t>(std::lround(static_cast<double>(i) *
                                                                                    static_cast<double>(years.size() - 1) /
                                                                                    static_cast<double>(limit - 1)));
            if (shown.empty() || shown.back().first != years[k].first) shown.push_back(years[k]);
        }
    }
    if (shown.size() < total) {
        md << "(" << shown.size() << " of " << total << " plant pictures in `" << relDir << "/`: years";
        for (std::size_t i = 0; i < shown.size(); ++i) md << (i ? ", " : " ") << shown[i].first;
        md << (dropStart ? "; year 0, the start before any undergrowth, left out" : "") << ")\n\n";
    }
    for (const auto& [year, name] : shown)
        picture(md, outDir, relDir + "/" + name, "undergrowth after " + std::to_string(year) + " years");
}

/// out_dir/report.md: what ran, how long each stage took, the pictures and the comparison;
/// and out_dir/report.html, the same self-contained (pictures embedded) with the interactive
/// views (run_html.h) after the stage table. Both written together, atomically.
std::pair<std::string, std::string> writeReport(const RunPlan& plan, const std::vector<double>& seconds,
                                                double totalSeconds) {
    const std::filesystem::path outDir(plan.outDir);
    std::ostringstream md;
    const std::string summary = "Configuration `" + plan.configPath + "`, eco " + ECO_VERSION_STRING + ", finished " +
                                utcTimestamp() + ", " + fmtNumber(std::round(totalSeconds * 10) / 10) + " s in all.";
    md << "# eco run report\n\n" << summary << "\n\n"
       << "| stage | seconds | command |\n|---|---:|---|\n";
    std::vector<std::vector<std::string>> stageRows;
    for (std::size_t i = 0; i < plan.stages.size(); ++i) {
        char secs[32];
        std::snprintf(secs, sizeof secs, "%.1f", seconds[i]);
        const std::string command = quotedCommand(commandLine(plan.stages[i].options));
        md << "| " << plan.stages[i].name << " | " << secs << " | `" << command << "` |\n";
        stageRows.push_back({plan.stages[i].name, secs, command});  // "eco ..." already
    }
    const std::size_t afterStages = md.str().size();
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
        yearPictures(md, outDir, "png/simulation", 6);
    }
    if (std::filesystem::exists(outDir / "database.txt"))
        md << "## Biome database\n\n```\n" << readTextFile((outDir / "database.txt").string()) << "```\n\n";
    pictures(md, outDir, "png/database", 4);
    if (std::filesystem::is_directory(outDir / "png/synth")) {
        md << "## Synthesis on the target terrain\n\n";
        picture(md, outDir, "target/png/terrain_hillshade.png", "target terrain");
        pictures(md, outDir, "target/png/canopy", 4);
        pictures(md, outDir, "png/synth", 8);
    }
    if (std::filesystem::exists(outDir / "compare.md"))
        md << "## Synthesized against the database\n\n" << readTextFile((outDir / "compare.md").string()) << "\n";
    const std::string path = (outDir / "report.md").string(), htmlPath = (outDir / "report.html").string();
    html::Document page("eco run report: " + plan.configPath);
    page.heading(1, "eco run report");
    page.markdown(summary + " The Markdown version of this report is `report.md` beside it.");
    page.table({"stage", "seconds", "command"}, stageRows, {false, true, false});
    addRunViews(page, plan);
    page.markdown(md.str().substr(afterStages), plan.outDir);
    AtomicOutputSet outputs;  // the two reports together
    writeTextFile(path, md.str());
    html::writeDocument(htmlPath, page);
    outputs.commit();
    return {path, htmlPath};
}

std::string stageHeading(const RunPlan& plan, std::size_t i) {
    return "\n== stage " + std::to_string(i + 1) + "/" + std::to_string(plan.stages.size()) + ": " + plan.stages[i].name +
           "\n   " + quotedCommand(commandLine(plan.stages[i].options));
}

}  // namespace

void printPlan(const RunPlan& plan, Reporter& reporter) {
    for (std::size_t i = 0; i < plan.stages.size(); ++i) reporter.info(stageHeading(plan, i));
}

RunResult runPlan(const RunPlan& plan, Reporter& reporter) {
    using Clock = std::chrono::steady_clock;
    const auto start = Clock::now();
    RunResult result;
    for (std::size_t i = 0; i < plan.stages.size(); ++i) {
        reporter.info(stageHeading(plan, i));
        const auto t0 = Clock::now();
        try {
            runStage(plan.stages[i].options, reporter);
        } catch (const Error& e) {
            throw Error("stage '" + plan.stages[i].name + "' failed: " + e.what());
        }
        reporter.out().flush();
        result.stageSeconds.push_back(std::chrono::duration<double>(Clock::now() - t0).count());
        char line[200];
        std::snprintf(line, sizeof line, "== %s done in %.1f s", plan.stages[i].name.c_str(), result.stageSeconds.back());
        reporter.info(line);
    }
    result.totalSeconds = std::chrono::duration<double>(Clock::now() - start).count();
    std::tie(result.reportPath, result.htmlReportPath) = writeReport(plan, result.stageSeconds, result.totalSeconds);
    char line[100];
    std::snprintf(line, sizeof line, "\npipeline finished in %.1f s", result.totalSeconds);
    reporter.info(line);
    return result;
}

}  // namespace eco::pipeline
