// eco calibrate SPEC.toml: parsing only; the search, the uncertainty and the report are in
// pipeline/calibrate, the simulations run as eco ensemble's members.
#include <cmath>
#include <cstdio>
#include <memory>
#include <string>

#include "calibrate.h"
#include "calibration_scene.h"
#include "cli_common.h"

namespace eco::cli {

namespace {

struct CalibrateArgs {
    std::string spec, outDir;
};

void runCalibrate(const CalibrateArgs& a) {
    const pipeline::CalibrationSpec spec = pipeline::loadCalibrationSpec(a.spec, a.outDir);
    info("calibrate: " + std::to_string(spec.parameters.size()) + " parameters to " + std::to_string(spec.targets.size()) +
         " targets, NLopt " + spec.algorithm + ", at most " + std::to_string(spec.maxEvaluations) + " evaluations of " +
         std::to_string(spec.replicates) + " simulations; in " + spec.outDir);
    // [calibrate.scene]: check the scene file, biome and model lines before any simulation.
    if (!spec.scene.file.empty()) validate::checkCalibrationScene(spec.scene);
    CliReporter reporter;
    // Each evaluation's simulations (or a round's, or the uncertainty's) run as members of one
    // ensemble (OUT/ensemble.toml, written again with every run: finished members are skipped),
    // shared by members_at_once children or the MPI ranks; under MPI every rank runs the same
    // search, and rank 0 writes the outputs. stdout keeps the result.
    const pipeline::CalibrationResult r =
        pipeline::calibrate(
            spec, [&](const std::string& members) { return runEnsembleFile(members, "", false, false) == 0; }, reporter,
            [&](const pipeline::CalibrationScene& scene, const std::vector<pipeline::SceneMember>& members) {
                validate::runCalibrationScene(scene, members, [&](const std::string& line) { reporter.info(line); });
            });
    if (!r.writer) return;
    const pipeline::Evaluation& best = r.history[r.best];
    printResult("best of %zu evaluations (%s): chi2 = %g\n", r.history.size(), r.stopReason.c_str(), best.chi2);
    for (std::size_t i = 0; i < spec.parameters.size(); ++i)
        printResult("  %s = %g%s\n", spec.parameters[i].key.c_str(), best.values[i],
                    std::isfinite(r.parameterSd[i]) ? (" +- " + formatNumber(r.parameterSd[i], 3)).c_str() : "");
    printResult("%s\n%s\n", r.reportPath.c_str(), r.historyPath.c_str());
    if (!r.bestBiome.empty()) printResult("%s\n", r.bestBiome.c_str());
    if (!r.bestSimulation.empty()) printResult("%s\n", r.bestSimulation.c_str());
    std::fflush(stdout);
}

}  // namespace

void registerCalibrateCommand(CLI::App& app) {
    auto a = std::make_shared<CalibrateArgs>();
    CLI::App* sub = app.add_subcommand(
        "calibrate",
        "Fit species parameters and model constants within bounds (linear, log-scaled or integer) to observations "
        "(species shares at a year or over a window, density, mean heights, cover, height quantiles at a year; cv of the plant count; a species' count ratio between two years; a field "
        "stem map's pair correlation g(r)), each with its sd: a derivative-free search (NLopt; local, or global: "
        "multistart, our controlled random search in rounds of points evaluated together, CRS2 or ISRES, seeded) of chi2 over simulations averaged over replicate seeds, run as an eco ensemble (in "
        "members_at_once child processes or across MPI ranks: mpirun -n N eco calibrate SPEC; the same history for any number; a killed calibration "
        "run again continues where it stopped), or over eco validate's forest scene ([calibrate.scene]: one scene seed per replicate). "
        "Targets may be one-sided (min or max). Writes OUT/calibration.md, OUT/history.csv, OUT/best-biome.toml and "
        "OUT/best-simulate.toml, and a linearised uncertainty of each parameter (docs/calibration.md).");
    sub->add_option("spec", a->spec, "Calibration specification (TOML; configs/calibrate.toml is an example)")
        ->required()
        ->check(CLI::ExistingFile);
    sub->add_option("--out-dir", a->outDir, "Override [calibrate] out_dir");
    sub->callback([a] { runCalibrate(*a); });
}

}  // namespace eco::cli
