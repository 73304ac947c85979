#include "simulate_stage.h"
#include "stage_common.h"

#include <omp.h>

#include <cstdio>
#include <ostream>

#include "error.h"
#include "text_format.h"

namespace eco::pipeline {

sim::RunConfig simulateConfig(const SimulateOptions& o, const std::function<void(const std::string&)>& note) {
    sim::RunConfig cfg = o.config.empty() ? sim::RunConfig{} : sim::loadRunConfig(o.config, note);
    if (!o.terrain.empty()) cfg.terrainPath = o.terrain;
    if (!o.abiotics.empty()) cfg.abioticsPath = o.abiotics;
    if (!o.canopy.empty()) cfg.canopyPath = o.canopy;
    if (!o.biome.empty()) cfg.biomePath = o.biome;
    if (!o.initial.empty()) cfg.initialPath = o.initial;
    if (o.years >= 0) cfg.years = o.years;
    if (o.seed >= 0) cfg.seed = static_cast<std::uint64_t>(o.seed);
    if (!o.crop.empty()) cfg.crop = sim::parseArea(o.crop, "--crop");
    if (!o.snapshotYears.empty()) cfg.snapshotYears = sim::parseYearList(o.snapshotYears, "--snapshot-years");
    if (!o.out.empty()) cfg.outputPath = o.out;
    if (!o.csv.empty()) cfg.csvPath = o.csv;
    if (!o.png.empty()) cfg.pngDir = o.png;
    if (o.checkpointEvery >= 0) cfg.checkpointEveryYears = o.checkpointEvery;
    if (!o.growthRule.empty()) cfg.params.growthRule = sim::parseGrowthRule(o.growthRule, "--growth-rule");
    if (!o.competition.empty()) cfg.params.competition = sim::parseCompetitionMode(o.competition, "--competition");
    if (!o.model.empty()) cfg.params.kind = sim::parseModelKind(o.model, "--model");
    if (!o.germinationCells.empty())
        cfg.params.germinationCells = sim::parseGerminationCells(o.germinationCells, "--germination-cells");
    if (!o.germinationVigour.empty())
        cfg.params.germinationVigour = sim::parseGerminationVigour(o.germinationVigour, "--germination-vigour");
    if (!o.canopyLimit.empty()) cfg.params.canopyLimit = sim::parseCanopyLimit(o.canopyLimit, "--canopy-limit");
    if (!o.modelParams.empty()) {
        o.modelParams.applyTo(cfg.params, sim::simParamFields(), "[model] key");
        cfg.params.validate("[model] keys given as flags");
    }
    cfg.validate();
    return cfg;
}

SimulateResult simulateStage(const SimulateOptions& o, Reporter& reporter) {
    sim::RunConfig cfg = simulateConfig(o, [&](const std::string& line) { reporter.info("simulate: " + line); });
    requireOutputsNotInputs({{"--out", cfg.outputPath}, {"--csv", cfg.csvPath}},
                            {o.config, cfg.abioticsPath, cfg.canopyPath, cfg.terrainPath, cfg.biomePath, cfg.initialPath});

    reporter.info("simulate: " + std::to_string(cfg.years) + " years, seed " + std::to_string(cfg.seed) + ", " +
                  std::to_string(omp_get_max_threads()) + " threads, " +
                  (cfg.params.kind == sim::ModelKind::EcoMod
                       ? std::string("model ecomod (yearly; docs/ecomod.md)")
                       : std::string("growth rule ") + sim::growthRuleName(cfg.params.growthRule) + ", competition " +
                             sim::competitionModeName(cfg.params.competition)) +
                  ", output " + cfg.outputPath);
    if (cfg.disturbance.enabled()) {
        auto timing = [](const sim::EventTiming& t) {
            std::string s = "probability " + formatNumber(t.probabilityPerYear, 4) + "/year";
            for (std::size_t i = 0; i < t.forcedYears.size(); ++i) s += (i ? ", " : ", forced in years ") + std::to_string(t.forcedYears[i]);
            return s;
        };
        // Settings that cannot give an event in this run are said (as snapshot years beyond it).
        auto never = [&](const char* kind, const sim::EventTiming& t) {
            std::string beyond;
            bool forcedInRun = false;
            for (const int y : t.forcedYears) {
                if (y < cfg.years) forcedInRun = true;
                else beyond += (beyond.empty() ? "" : ", ") + std::to_string(y);
            }
            if (!beyond.empty())
                reporter.info(std::string("simulate: disturbance: ") + kind + " forced in years beyond the " +
                              std::to_string(cfg.years) + " simulated years (0 = the first) never happens: " + beyond);
            if (t.probabilityPerYear == 0 && !forcedInRun)
                reporter.info(std::string("simulate: disturbance: no ") + kind +
                              " can happen in this run (probability 0 and no forced year within it; set "
                              "probability_per_year, return_interval_years or years)");
        };
        std::string d;
        if (cfg.disturbance.fire.enabled) d += "fire (" + timing(cfg.disturbance.fire.timing) + ")";
        if (cfg.disturbance.storm.enabled) d += std::string(d.empty() ? "" : ", ") + "storms (" + timing(cfg.disturbance.storm.timing) + ")";
        reporter.info("simulate: disturbance: " + d + "; each event is logged and recorded in /disturbance");
        if (cfg.disturbance.fire.enabled) never("fire", cfg.disturbance.fire.timing);
        if (cfg.disturbance.storm.enabled) never("storm", cfg.disturbance.storm.timing);
    }
    std::unique_ptr<SimulationProgress> progress = reporter.simulationProgress(cfg.years);
    sim::RunHooks hooks;
    hooks.log = [&](const std::string& s) { reporter.info("simulate: " + s); };
    hooks.onYear = [&](const sim::Simulation& s, const sim::RunRecord&) {
        if (progress) progress->update(s);
    };
    hooks.stopRequested = [&] { return reporter.stopRequested(); };
    SimulateResult result;
    try {
        result.summary = sim::runSimulation(cfg, o.resume, hooks);
    } catch (...) {
        if (progress) progress->finish();
        throw;
    }
    if (progress) progress->finish();
    progress.reset();
    const sim::RunSummary& summary = result.summary;
    if (summary.stoppedEarly) {
        throw Error("interrupted after year " + std::to_string(summary.years) +
                    (cfg.checkpointEveryYears > 0 ? "; checkpoint written to " + cfg.effectiveCheckpointPath() +
                                                        " (continue with --resume)"
                                                  : "; no checkpoint (use --checkpoint-every N)"));
    }
    char line[200];
    std::snprintf(line, sizeof line, "simulate: %d years, %zu plants at the end, %.1f s in all (with input and output), %.2fM plant-months/s overall", summary.years,
                  summary.finalPlants, summary.wallSeconds,
                  summary.wallSeconds > 0 ? summary.plantMonths / summary.wallSeconds / 1e6 : 0.0);
    reporter.info(line);
    for (const auto& f : summary.written) reporter.out() << f << "\n";
    result.config = std::move(cfg);
    return result;
}

const std::vector<ParamFlagName>& simParamFlags() {
    static const std::vector<ParamFlagName> flags = hyphenatedParamFlags(sim::simParamFields());
    return flags;
}

std::vector<std::string> commandLine(const SimulateOptions& o) {
    std::vector<std::string> args = {"simulate"};
    const auto str = [&](const char* flag, const std::string& v) {
        if (!v.empty()) args.insert(args.end(), {flag, v});
    };
    str("--config", o.config);
    str("--terrain", o.terrain);
    str("--abiotics", o.abiotics);
    str("--canopy", o.canopy);
    str("--out", o.out);
    str("--csv", o.csv);
    str("--png", o.png);
    if (o.seed >= 0) args.insert(args.end(), {"--seed", std::to_string(o.seed)});
    if (o.years >= 0) args.insert(args.end(), {"--years", std::to_string(o.years)});
    str("--crop", o.crop);
    if (o.checkpointEvery >= 0) args.insert(args.end(), {"--checkpoint-every", std::to_string(o.checkpointEvery)});
    str("--snapshot-years", o.snapshotYears);
    str("--initial", o.initial);
    str("--growth-rule", o.growthRule);
    str("--competition", o.competition);
    str("--model", o.model);
    str("--germination-cells", o.germinationCells);
    str("--germination-vigour", o.germinationVigour);
    str("--canopy-limit", o.canopyLimit);
    checkParamFlags(o.modelParams, simParamFlags());
    appendParamArgs(args, o.modelParams, simParamFlags());
    if (o.resume) args.push_back("--resume");
    str("--biome", o.biome);
    return args;
}

}  // namespace eco::pipeline
