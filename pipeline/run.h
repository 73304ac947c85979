// eco run CONFIG: the whole pipeline of one configuration as a plan of typed stages, run in
// order, with out_dir/report.md and its self-contained HTML twin report.html. Each stage also has its equivalent eco command line, which
// the run prints and the report shows, so that a stage can be rerun alone by hand.
#pragma once

#include <string>
#include <variant>
#include <vector>

#include "abiotics_stage.h"
#include "analyse_stages.h"
#include "canopy_stage.h"
#include "reporter.h"
#include "simulate_stage.h"
#include "synth_stages.h"
#include "terrain_stages.h"

namespace eco::pipeline {

using StageOptions = std::variant<TerrainGenerateOptions, ChmGenerateOptions, AbioticsOptions, CanopyOptions,
                                  SimulateOptions, AnalyseOptions, InspectOptions, SynthOptions, CompareOptions>;

struct PlannedStage {
    std::string name;  ///< "terrain", "target canopy", ...
    StageOptions options;
};

/// The equivalent eco command line of a stage (without "eco").
std::vector<std::string> commandLine(const StageOptions& options);
/// Run one stage.
void runStage(const StageOptions& options, Reporter& reporter);

struct RunPlan {
    std::string configPath;
    std::string outDir;
    std::vector<PlannedStage> stages;
};

/// The stages of a pipeline configuration (TOML: [run], [terrain], [chm], [abiotics],
/// [canopy], [simulate], [analyse], [synth]); `outDirOverride` replaces [run] out_dir when
/// not empty. Creates the output folders. ValidationError naming the file and key.
RunPlan planRun(const std::string& configPath, const std::string& outDirOverride = "");

/// The path-valued keys of a pipeline configuration ({table, key}), which planRun resolves
/// relative to the configuration's directory; for absolutizeConfigPaths (ensemble members).
const std::vector<std::pair<std::string, std::string>>& pipelineConfigPathKeys();

struct RunResult {
    std::vector<double> stageSeconds;
    double totalSeconds = 0;
    std::string reportPath;      ///< out_dir/report.md
    std::string htmlReportPath;  ///< out_dir/report.html (docs/report.md)
};
/// Run the stages in order ("== stage i/n" lines and timings through the reporter; a failing
/// stage's Error is rethrown naming it), then write out_dir/report.md and report.html.
RunResult runPlan(const RunPlan& plan, Reporter& reporter);
/// Print the stages without running them.
void printPlan(const RunPlan& plan, Reporter& reporter);

}  // namespace eco::pipeline
