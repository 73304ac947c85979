// eco fidelity: parsing only; the protocol (its stages, cached in the output folder, and the
// report) is in validate/fidelity_protocol, the measures in validate/fidelity.
#include <unistd.h>

#include <cstdio>
#include <iostream>
#include <memory>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "cli_common.h"
#include "fidelity_protocol.h"
#include "method_comparison.h"

namespace eco::cli {

namespace {

struct FidelityArgs {
    std::string config;
    validate::FidelityRunOptions options;
    std::set<std::string> given;  // options given on the command line (they override the config)
};

/// The reporter of one stage: as the command line's, but with stdout sent to stderr while it
/// lives, so that stdout carries only the report.
class StdoutToStderrReporter : public CliReporter {
public:
    StdoutToStderrReporter() {
        std::fflush(stdout);
        std::cout.flush();
        saved_ = dup(1);
        if (saved_ >= 0) dup2(2, 1);
    }
    ~StdoutToStderrReporter() override {
        std::fflush(stdout);
        std::cout.flush();
        if (saved_ >= 0) {
            dup2(saved_, 1);
            close(saved_);
        }
    }
    StdoutToStderrReporter(const StdoutToStderrReporter&) = delete;
    StdoutToStderrReporter& operator=(const StdoutToStderrReporter&) = delete;

private:
    int saved_ = -1;
};

void runFidelity(FidelityArgs& args) {
    if (!args.config.empty()) validate::readFidelityConfig(args.config, args.options, args.given);
    CliReporter reporter;
    const auto stageReporter = [] { return std::make_unique<StdoutToStderrReporter>(); };
    const std::vector<std::string> methods = validate::parseMethodList(args.options.synthMethod);
    if (methods.size() > 1) validate::runMethodComparison(args.options, methods, reporter, stageReporter);
    else validate::runFidelityProtocol(args.options, reporter, stageReporter);
}

}  // namespace

void registerFidelityCommand(CLI::App& app) {
    auto args = std::make_shared<FidelityArgs>();
    validate::FidelityRunOptions* a = &args->options;
    CLI::App* cmd = app.add_subcommand(
        "fidelity",
        "The fidelity protocol (docs/fidelity.md): simulate a plot with two seeds (A, B), build the database from A, "
        "synthesize on the same terrain, canopy and abiotics, and compare the scene with the held-out B inside the "
        "plot, each figure beside the replicate level d(A, B) and the CSR level, with a score (0 = replicate, 1 = "
        "CSR). Defaults reproduce configs/demo.toml's first scene and plot. Existing files can be given instead of "
        "any stage; stages are cached in --out-dir.");
    const auto opt = [&](const std::string& name, auto& var, const std::string& help) {
        CLI::Option* o = cmd->add_option(name, var, help);
        o->each([args, name](const std::string&) { args->given.insert(name); });
        return o;
    };
    opt("--config", args->config, "TOML with a [fidelity] table (keys as the options, with underscores; docs/fidelity.md)");
    opt("--out-dir", a->outDir, "Folder of the stages' files and the report (default out/fidelity)");
    opt("--terrain", a->terrain, "Existing terrain (else generated as the demo's)");
    opt("--chm", a->chm, "Existing canopy height model (else generated)");
    opt("--abiotics", a->abiotics, "Existing abiotics of the terrain (no canopy shade)");
    opt("--canopy", a->canopy, "Existing canopy file (eco canopy) of the terrain");
    opt("--reference", a->reference, "Existing simulation A (the database's source)");
    opt("--replicate", a->replicate, "Existing simulation B (held out; another seed)");
    opt("--database", a->database, "Existing database from A");
    opt("--scene", a->scene, "Existing scene (eco synth) on the same terrain and canopy; needs --reference and --replicate");
    opt("--out-md", a->outMd, "Markdown report (default OUT_DIR/fidelity.md)");
    opt("--out-csv", a->outCsv, "Every figure, value and curve as CSV (default OUT_DIR/fidelity.csv)");
    CLI::Option* refine = cmd->add_flag("--refine", a->refine, "Synthesize with --refine (inside the plot)");
    refine->each([args](const std::string&) { args->given.insert("--refine"); });
    opt("--refine-sweeps", a->refineSweeps, "Refinement sweeps")->capture_default_str()->check(CLI::PositiveNumber);
    opt("--synth-method", a->synthMethod,
        "Undergrowth sampler of the synthesis: structured (default), darts (the earlier one), deussen or xu2015 (its "
        "exemplar is simulation A); outputs of another than structured are named scene-METHOD*.h5, fidelity-METHOD*.md. "
        "A comma list or 'all' compares the methods: each one's scene and report, then OUT_DIR/methods.md and "
        "methods.csv side by side, with Xu et al.'s PCT.DEV and each sampler's time per million plants "
        "(--out-md / --out-csv then name these)")
        ->capture_default_str();
    opt("--seed-a", a->seedA, "Seed of simulation A")->capture_default_str()->check(nonNegativeNumber());
    opt("--seed-b", a->seedB, "Seed of simulation B")->capture_default_str()->check(nonNegativeNumber());
    opt("--synth-seed", a->synthSeed, "Seed of the synthesis")->capture_default_str()->check(nonNegativeNumber());
    opt("--terrain-seed", a->terrainSeed, "Seed of the generated terrain, CHM and canopy")->capture_default_str()->check(nonNegativeNumber());
    opt("--width", a->width, "Generated terrain: cells along x")->capture_default_str()->check(positiveNumber());
    opt("--height", a->height, "Generated terrain: cells along y")->capture_default_str()->check(positiveNumber());
    opt("--cell-size", a->cellSizeM, "Generated terrain: metres per cell")->capture_default_str()->check(cellSizeRange());
    opt("--sun-step", a->sunStepMinutes, "Abiotics: sun step, minutes")->capture_default_str()->check(positiveNumber());
    opt("--target", a->canopyTargets, "Canopy species targets, e.g. Douglas-Fir=0.3 (repeatable)");
    opt("--sim-config", a->simConfig, "Simulation configuration (model constants)")->capture_default_str();
    opt("--canopy-config", a->canopyConfig,
        "Canopy placer parameters for the generated canopy (a TOML as eco canopy --config reads, e.g. crown_fit_passes = 2 for the crown fit); "
        "default: the placer's defaults. Its seed is replaced by --terrain-seed");
    opt("--years", a->years, "Years simulated")->capture_default_str()->check(positiveNumber());
    opt("--kmax", a->kmax, "Analysis: largest k per combination")->capture_default_str()->check(positiveNumber());
    opt("--crop", a->crop, "The plot x0,y0,x1,y1 (m): simulated and compared")->capture_default_str();
    // The measures' parameters from their descriptions (validate/fidelity.cpp).
    for (const auto& [flag, key] : std::vector<std::pair<const char*, const char*>>{{"--edge-band", "edge_band_m"}, {"--csr-seed", "csr_seed"}})
        addParamOption(cmd, flag, a->params, validate::fidelityParamFields(), key)
            ->each([args, name = std::string(flag)](const std::string&) { args->given.insert(name); });
    cmd->callback([args] { runFidelity(*args); });
}

}  // namespace eco::cli
