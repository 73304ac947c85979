// eco sensitivity SPEC.toml: parsing only; the design, the members' specification and the
// report are in pipeline/sensitivity, the run is eco ensemble's (in parallel, restartable,
// on MPI).
#include <cstdio>
#include <memory>
#include <string>

#include "cli_common.h"
#include "sensitivity.h"

namespace eco::cli {

namespace {

struct SensitivityArgs {
    std::string spec, outDir;
    bool dryRun = false;
};

void runSensitivity(const SensitivityArgs& a) {
    const pipeline::SensitivitySpec spec = pipeline::loadSensitivitySpec(a.spec, a.outDir);
    const std::string k = std::to_string(spec.parameters.size());
    if (spec.method == pipeline::SensitivitySpec::Method::Sobol) {
        const pipeline::SobolDesign design = pipeline::sobolDesign(spec);
        const std::string members = pipeline::writeSobolEnsemble(spec, design);
        info("sensitivity: Sobol indices of " + std::to_string(spec.outputs.size()) + " outputs for " + k + " parameters: N = " +
             std::to_string(spec.samples) + " x " + std::to_string(spec.parameters.size() + 2) + " matrices x " + std::to_string(spec.replicates) +
             " replicates (" + (spec.sampling == pipeline::SensitivitySpec::Sampling::QuasiRandom ? "quasi-random" : "pseudo-random") + "), run as the ensemble " + members);
        if (runEnsembleFile(members, "", a.dryRun) != 0 || a.dryRun) return;
        const pipeline::SensitivityReport r = pipeline::writeSobolReport(spec, design);
        printResult("first-order S and total ST by output (largest ST first):\n%s%s\n%s\n", r.summary.c_str(), r.markdownPath.c_str(), r.csvPath.c_str());
        std::fflush(stdout);
        return;
    }
    const pipeline::MorrisDesign design =
        pipeline::morrisDesign(static_cast<int>(spec.parameters.size()), spec.trajectories, spec.levels, spec.seed);
    const std::string members = pipeline::writeSensitivityEnsemble(spec, design);
    info("sensitivity: Morris screening of " + std::to_string(spec.outputs.size()) + " outputs to " + k + " parameters: " +
         std::to_string(spec.trajectories) + " trajectories x " + std::to_string(spec.parameters.size() + 1) + " points x " +
         std::to_string(spec.replicates) + " replicates, run as the ensemble " + members);
    if (runEnsembleFile(members, "", a.dryRun) != 0 || a.dryRun) return;
    const pipeline::SensitivityReport r = pipeline::writeSensitivityReport(spec, design);
    printResult("mu* by output (largest first):\n%s%s\n%s\n", r.summary.c_str(), r.markdownPath.c_str(), r.csvPath.c_str());
    std::fflush(stdout);
}

}  // namespace

void registerSensitivityCommand(CLI::App& app) {
    auto a = std::make_shared<SensitivityArgs>();
    CLI::App* sub = app.add_subcommand(
        "sensitivity",
        "Global sensitivity of simulation outputs (species shares, density, mean height, cover at a year; the "
        "coefficient of variation of the plant count over a window; height quantiles of a snapshot) to species "
        "parameters and model constants: Morris elementary effects (method = \"morris\", a screening) or Sobol "
        "first-order and total indices with bootstrap intervals (method = \"sobol\", for a chosen few), with "
        "replicate seeds to tell effects from seed noise. The design's simulations run as an eco ensemble "
        "(OUT/ensemble: parallel, restartable, MPI); the report is OUT/sensitivity.md with OUT/sensitivity.csv and one "
        "picture per output (docs/sensitivity.md).");
    sub->add_option("spec", a->spec, "Sensitivity specification (TOML; configs/sensitivity.toml is an example)")
        ->required()
        ->check(CLI::ExistingFile);
    sub->add_option("--out-dir", a->outDir, "Override [sensitivity] out_dir");
    sub->add_flag("--dry-run", a->dryRun, "Write the design and the members' specification and list them without running");
    sub->callback([a] { runSensitivity(*a); });
}

}  // namespace eco::cli
