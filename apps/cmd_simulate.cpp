// eco simulate: the undergrowth simulation (sim/). Parsing, progress and messages only.
#include <omp.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <algorithm>
#include <memory>
#include <string>

#include "cli_common.h"
#include "error.h"
#include "sim_run.h"

namespace eco::cli {

namespace {

std::atomic<bool> gStop{false};
extern "C" void onSimulateSignal(int) { gStop = true; }

struct SimulateOptions {
    std::string config, terrain, abiotics, canopy, biome, crop, snapshotYears, out, csv, png, initial, growthRule, competition;
    int years = -1;
    long long seed = -1;
    int checkpointEvery = -1;
    bool resume = false;
};

// Progress line: year, plants alive, plant-months per second, time left.
class SimProgress {
public:
    explicit SimProgress(int totalYears) : total_(totalYears), tty_(::isatty(STDERR_FILENO) != 0) {}
    void update(const sim::Simulation& s) {
        const auto now = std::chrono::steady_clock::now();
        if (!started_) {
            started_ = true;
            start_ = now;
            startYear_ = s.yearsDone();
            startPlantMonths_ = s.counters().plantMonths;
        }
        const double elapsed = std::chrono::duration<double>(now - start_).count();
        const int year = s.yearsDone();
        const double rate = elapsed > 0 ? static_cast<double>(s.counters().plantMonths - startPlantMonths_) / elapsed : 0.0;
        const int doneHere = year - startYear_;
        const double left = doneHere > 0 ? elapsed / doneHere * (total_ - year) : 0.0;
        const int filled = total_ > 0 ? std::min(20, 20 * year / total_) : 20;
        const std::string bar = std::string(static_cast<std::size_t>(filled), '#') + std::string(static_cast<std::size_t>(20 - filled), '.');
        char line[256];
        std::snprintf(line, sizeof line, "simulate [%s] year %d/%d  plants %zu  %.2fM plant-months/s  ~%.0fs left", bar.c_str(),
                      year, total_, s.plantCount(), rate / 1e6, left);
        if (tty_) {
            std::fprintf(stderr, "\r\033[K%s", line);
        } else if (year == total_ || elapsed - lastPrint_ >= 5.0 || year == startYear_) {
            std::fprintf(stderr, "%s\n", line);
            lastPrint_ = elapsed;
        }
        std::fflush(stderr);
    }
    void finish() {
        if (tty_ && started_) std::fprintf(stderr, "\n");
    }

private:
    int total_;
    bool tty_;
    bool started_ = false;
    std::chrono::steady_clock::time_point start_;
    int startYear_ = 0;
    long long startPlantMonths_ = 0;
    double lastPrint_ = -1e9;
};

void runSimulate(const SimulateOptions& o) {
    sim::RunConfig cfg = o.config.empty() ? sim::RunConfig{} : sim::loadRunConfig(o.config);
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
    cfg.validate();

    info("simulate: " + std::to_string(cfg.years) + " years, seed " + std::to_string(cfg.seed) + ", " +
         std::to_string(omp_get_max_threads()) + " threads, growth rule " + sim::growthRuleName(cfg.params.growthRule) +
         ", competition " + sim::competitionModeName(cfg.params.competition) + ", output " + cfg.outputPath);
    SimProgress progress(cfg.years);
    sim::RunHooks hooks;
    hooks.log = [&](const std::string& s) { info("simulate: " + s); };
    hooks.onYear = [&](const sim::Simulation& s, const sim::RunRecord&) { progress.update(s); };
    hooks.stopRequested = [] { return gStop.load(); };
    gStop = false;
    auto previousInt = std::signal(SIGINT, onSimulateSignal);
    auto previousTerm = std::signal(SIGTERM, onSimulateSignal);
    sim::RunSummary summary;
    try {
        summary = sim::runSimulation(cfg, o.resume, hooks);
    } catch (...) {
        progress.finish();
        std::signal(SIGINT, previousInt);
        std::signal(SIGTERM, previousTerm);
        throw;
    }
    progress.finish();
    std::signal(SIGINT, previousInt);
    std::signal(SIGTERM, previousTerm);
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
    info(line);
    for (const auto& f : summary.written) std::printf("%s\n", f.c_str());
}

}  // namespace

void registerSimulateCommand(CLI::App& app) {
    auto opt = std::make_shared<SimulateOptions>();
    CLI::App* sub = app.add_subcommand(
        "simulate",
        "Undergrowth simulation under a fixed canopy (paper §6.1): monthly competition for sun and water, carbon "
        "pools, growth, mortality and yearly germination. Flags override the keys of --config (docs/simulator.md).");
    sub->add_option("--config", opt->config, "Run configuration TOML (configs/sim-*.toml)");
    sub->add_option("--terrain", opt->terrain, "Terrain file (optional; default: the elevation of the abiotics)");
    sub->add_option("--abiotics", opt->abiotics, "Abiotics HDF5 (eco abiotics), without canopy shade");
    sub->add_option("--canopy", opt->canopy, "Canopy HDF5 (eco canopy): /canopy plants and /chm/height");
    sub->add_option("--biome", opt->biome, "Biome TOML (default: the embedded Sonoma biome)");
    sub->add_option("--years", opt->years, "Years to simulate")->check(positiveNumber());
    sub->add_option("--seed", opt->seed, "Random seed")->check(nonNegativeNumber());
    sub->add_option("--crop", opt->crop, "Area to simulate: x0,y0,x1,y1 in world metres");
    sub->add_option("--snapshot-years", opt->snapshotYears, "Years to snapshot, e.g. 25,50,75 (the last is always added)");
    sub->add_option("--out", opt->out, "Output HDF5");
    sub->add_option("--csv", opt->csv, "CSV of the final plants");
    sub->add_option("--png", opt->png, "Directory for PNG renders of the snapshots and the species plot");
    sub->add_option("--checkpoint-every", opt->checkpointEvery, "Write a checkpoint every N years (0 = never)")
        ->check(nonNegativeNumber());
    sub->add_flag("--resume", opt->resume, "Continue from the checkpoint of this run when it exists");
    sub->add_option("--initial", opt->initial, "Initial undergrowth: PLANTS.csv or PLANTS.h5[:/group]");
    sub->add_option("--growth-rule", opt->growthRule, "Overflow-to-growth rule: ideal (default) or literal ([model] growth_rule)");
    sub->add_option("--competition", opt->competition, "Competition model: resources (default) or deussen ([model] competition)");
    sub->callback([opt] { runSimulate(*opt); });
}

}  // namespace eco::cli
