// eco simulate: parsing only; the stage is in pipeline/simulate_stage (the simulator in
// sim/), its progress line and signal handling in the CLI's reporter.
#include <memory>
#include <string>

#include "cli_common.h"
#include "sim_config.h"
#include "simulate_stage.h"

namespace eco::cli {

void registerSimulateCommand(CLI::App& app) {
    auto opt = std::make_shared<pipeline::SimulateOptions>();
    CLI::App* sub = app.add_subcommand(
        "simulate",
        "Undergrowth simulation under a fixed canopy (paper §6.1): monthly competition for sun and water, carbon "
        "pools, growth, mortality and yearly germination. Flags override the keys of --config (docs/simulator.md).");
    sub->add_option("--config", opt->config, "Run configuration TOML (configs/sim-*.toml; embedded:sim-default.toml: the copy built into eco, also "
                    "read when a file of that name is missing)");
    sub->add_option("--terrain", opt->terrain, "Terrain file (optional; default: the elevation of the abiotics)");
    sub->add_option("--abiotics", opt->abiotics, "Abiotics HDF5 (eco abiotics), without canopy shade");
    sub->add_option("--canopy", opt->canopy, "Canopy HDF5 (eco canopy): /canopy plants and /chm/height");
    sub->add_option("--biome", opt->biome, "Biome TOML (default: the embedded Sonoma biome)");
    sub->add_option("--years", opt->years, "Years to simulate")->check(positiveNumber());
    sub->add_option("--seed", opt->seed, "Random seed")->check(nonNegativeNumber());
    sub->add_option("--crop", opt->crop, "Area to simulate: x0,y0,x1,y1 in world metres")
        ->check(parsedBy("--crop", [](const std::string& t) { sim::parseArea(t, "--crop"); }));
    sub->add_option("--snapshot-years", opt->snapshotYears, "Years to snapshot, e.g. 25,50,75 (the last is always added)")
        ->check(parsedBy("--snapshot-years", [](const std::string& t) { sim::parseYearList(t, "--snapshot-years"); }));
    sub->add_option("--out", opt->out, "Output HDF5");
    sub->add_option("--csv", opt->csv, "CSV of the final plants");
    sub->add_option("--png", opt->png, "Directory for PNG renders of the snapshots and the species plot");
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
        ->check(parsedBy("--model", [](const std::string& t) { sim::parseModelKind(t, "--model"); }));
    sub->callback([opt] {
        CliReporter reporter;
        pipeline::simulateStage(*opt, reporter);
    });
}

}  // namespace eco::cli
