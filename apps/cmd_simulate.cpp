// eco simulate: parsing only; the stage is in pipeline/simulate_stage (the simulator in
// sim/), its progress line and signal handling in the CLI's reporter.
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "cli_common.h"
#include "sim_config.h"
#include "simulate_stage.h"

namespace eco::cli {

namespace {

struct SimulateArgs {
    pipeline::SimulateOptions options;
    sim::SimParams model;  // the [model] flags' values (defaults shown in --help)
    std::vector<std::pair<std::string, CLI::Option*>> modelOpts;  // key, option
};

}  // namespace

void registerSimulateCommand(CLI::App& app) {
    auto args = std::make_shared<SimulateArgs>();
    pipeline::SimulateOptions* opt = &args->options;
    CLI::App* sub = app.add_subcommand(
        "simulate",
        "Undergrowth simulation under a fixed canopy (paper §6.1): monthly competition for sun and water, carbon "
        "pools, growth, mortality and yearly germination (docs/simulator.md). --model ecomod ([model] kind = \"ecomod\"): "
        "Zamuda & Brest's yearly EcoMod model instead, trees of every species colonising the ground under the canopy or "
        "empty ground ([inputs] canopy = \"\") (docs/ecomod.md). Either model with fire and windthrow storms: the "
        "[disturbance.fire] and [disturbance.storm] tables of --config (docs/disturbance.md). Flags override the keys "
        "of --config.");
    sub->add_option("--config", opt->config, "Run configuration TOML (configs/sim-*.toml; embedded:sim-default.toml: the copy built into eco, also "
                    "read when a file of that name is missing)");
    sub->add_option("--terrain", opt->terrain, "Terrain file (optional; default: the elevation of the abiotics)");
    sub->add_option("--abiotics", opt->abiotics, "Abiotics HDF5 (eco abiotics), without canopy shade");
    sub->add_option("--canopy", opt->canopy, "Canopy HDF5 (eco canopy): /canopy plants and /chm/height. EcoMod only: [inputs] canopy = \"\" in --config "
                    "means empty ground (an empty --canopy keeps the configuration's)");
    sub->add_option("--biome", opt->biome, "Biome TOML (default: the embedded Sonoma biome)");
    sub->add_option("--years", opt->years, "Years to simulate")->check(positiveNumber());
    sub->add_option("--seed", opt->seed, "Random seed")->check(nonNegativeNumber());
    sub->add_option("--crop", opt->crop, "Area to simulate: x0,y0,x1,y1 in world metres")
        ->check(parsedBy("--crop", [](const std::string& t) { sim::parseArea(t, "--crop"); }));
    sub->add_option("--snapshot-years", opt->snapshotYears, "Years to snapshot, e.g. 25,50,75 (the last is always added)")
        ->check(parsedBy("--snapshot-years", [](const std::string& t) { sim::parseYearList(t, "--snapshot-years"); }));
    sub->add_option("--out", opt->out, "Output HDF5");
    sub->add_option("--csv", opt->csv, "CSV of the final plants");
    sub->add_option("--png", opt->png, "Directory for PNG renders of the snapshots and the species plot, and with disturbance one picture per event "
                    "(disturbance_EEE_year_YYYY_KIND.png, EEE the event's row: its struck cells under the plants)");
    sub->add_option("--checkpoint-every", opt->checkpointEvery, "Write a checkpoint every N years (0 = never)")
        ->check(nonNegativeNumber());
    sub->add_flag("--resume", opt->resume, "Continue from the checkpoint of this run when it exists");
    sub->add_option("--initial", opt->initial, "Initial undergrowth: PLANTS.csv or PLANTS.h5[:/group]");
    sub->add_option("--growth-rule", opt->growthRule, "Overflow-to-growth rule: ideal (default) or literal ([model] growth_rule)")
        ->check(parsedBy("--growth-rule", [](const std::string& t) { sim::parseGrowthRule(t, "--growth-rule"); }));
    sub->add_option("--competition", opt->competition, "Competition model: resources (default) or deussen ([model] competition)")
        ->check(parsedBy("--competition", [](const std::string& t) { sim::parseCompetitionMode(t, "--competition"); }));
    sub->add_option("--model", opt->model,
                    "Simulator model: monthly (default, the paper's) or ecomod (Zamuda & Brest's yearly afforestation "
                    "model, docs/ecomod.md) ([model] kind)")
        ->check(parsedBy("--model", [](const std::string& t) { sim::parseModelKind(t, "--model"); }))
        ->check(oneOf(sim::modelKindNames()));  // never fails after parsedBy; its choices go to the completion
    sub->add_option("--germination-cells", opt->germinationCells,
                    "Cells tested for germination: uncovered (default: no undergrowth crown over them) or every (the "
                    "paper's wording) ([model] germination_cells)")
        ->check(parsedBy("--germination-cells", [](const std::string& t) { sim::parseGerminationCells(t, "--germination-cells"); }));
    sub->add_option("--germination-vigour", opt->germinationVigour,
                    "Vigour of the germination roulette: mean_resources (default: Eq. 1 on the season's mean leftovers) "
                    "or mean_vigour ([model] germination_vigour)")
        ->check(parsedBy("--germination-vigour", [](const std::string& t) { sim::parseGerminationVigour(t, "--germination-vigour"); }));
    sub->add_option("--canopy-limit", opt->canopyLimit,
                    "Where undergrowth dies at the canopy: chm_or_threshold (default) or canopy_only ([model] canopy_limit)")
        ->check(parsedBy("--canopy-limit", [](const std::string& t) { sim::parseCanopyLimit(t, "--canopy-limit"); }));
    // Every numeric [model] key as a flag, from its description (sim/sim_config.cpp).
    args->modelOpts = addParamOptions(sub, pipeline::simParamFlags(), args->model, sim::simParamFields(), "[model] ");
    sub->callback([args] {
        setGivenParams(args->options.modelParams, args->modelOpts, args->model, sim::simParamFields());
        CliReporter reporter;
        pipeline::simulateStage(args->options, reporter);
    });
}

}  // namespace eco::cli
