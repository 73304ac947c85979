// eco simulate: the undergrowth simulation (sim/) from a run configuration and overrides.
#pragma once

#include <functional>
#include <string>
#include <vector>

#include "param_desc.h"
#include "reporter.h"
#include "sim_run.h"

namespace eco::pipeline {

/// Overrides of the run configuration `config` (empty / negative: the configuration's value).
struct SimulateOptions {
    std::string config;  ///< run configuration TOML; "" = the defaults
    std::string terrain, abiotics, canopy, biome, initial;
    std::string crop;           ///< "x0,y0,x1,y1" in world metres
    std::string snapshotYears;  ///< "25,50,75"
    std::string out, csv, png;
    std::string growthRule, competition;  ///< model choices by name
    std::string model;          ///< "monthly" or "ecomod" ([model] kind); "" = the configuration's
    /// The readings of the paper by name ([model] germination_cells, germination_vigour,
    /// canopy_limit); "" = the configuration's.
    std::string germinationCells, germinationVigour, canopyLimit;
    /// Numeric [model] keys set over the configuration's, by key of sim::simParamFields(); on
    /// the command line as the flags of simParamFlags() (--cell-size-m, ...).
    ParamOverrides<sim::SimParams> modelParams;
    int years = -1;
    long long seed = -1;
    int checkpointEvery = -1;  ///< years between checkpoints (0 = never)
    bool resume = false;       ///< continue from this run's checkpoint when it exists
};
struct SimulateResult {
    sim::RunConfig config;  ///< as run (configuration file and overrides)
    sim::RunSummary summary;
};
/// Run the simulation; progress through reporter.simulationProgress, stopped (with an Error
/// naming the checkpoint) when reporter.stopRequested().
SimulateResult simulateStage(const SimulateOptions& options, Reporter& reporter);
/// The run configuration the stage would use (its file read, the options applied, checked):
/// ValidationError naming the file and key. Reads no input data (eco run checks every stage
/// with it before the first runs). `note` gets a line when a missing configuration file is read
/// from the copy built into eco (sim::loadRunConfig).
sim::RunConfig simulateConfig(const SimulateOptions& options, const std::function<void(const std::string&)>& note = {});
std::vector<std::string> commandLine(const SimulateOptions& options);
/// eco simulate's flags for the numeric [model] keys: "--" and the key with hyphens, unit
/// suffix kept (cell_size_m: --cell-size-m), in the table's order.
const std::vector<ParamFlagName>& simParamFlags();

}  // namespace eco::pipeline
