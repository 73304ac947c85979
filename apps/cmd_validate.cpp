// eco validate: the ecological regression suite (validate/). Parsing, progress and the exit
// status only; scenarios, checks and the report are in validate/validate.h.
#include <omp.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include "cli_common.h"
#include "sim_config.h"
#include "error.h"
#include "validate.h"

namespace eco::cli {

namespace {

struct ValidateOptions {
    bool quick = false;
    std::string out = "validation";
    std::string configs;
    std::vector<std::string> only;
    int threads = 0;
    int replicates = 0;  ///< 0 = not given: each scenario's own count
    std::vector<std::string> model;  ///< KEY=VALUE
    std::string biome;               ///< "" = the built-in biome
};

void runValidate(const ValidateOptions& o) {
    if (o.threads > 0) omp_set_num_threads(o.threads);
    validate::SuiteOptions so;
    so.mode = o.quick ? validate::Mode::Quick : validate::Mode::Full;
    so.outDir = o.out;
    so.replicates = o.replicates;
    so.biomePath = o.biome;
    for (const std::string& kv : o.model) {
        const auto eq = kv.find('=');
        if (eq == std::string::npos || eq == 0)
            throw ValidationError("--model " + kv + ": expected KEY=VALUE, e.g. growth_rule=literal");
        const std::string key = kv.substr(0, eq), value = kv.substr(eq + 1);
        char* end = nullptr;
        std::strtod(value.c_str(), &end);
        const bool bare = (!value.empty() && end && *end == '\0') || value == "true" || value == "false";
        so.configs.modelOverrides.push_back(key + " = " + (bare ? value : "\"" + value + "\""));
    }
    if (!so.configs.modelOverrides.empty()) {  // a bad key or value is refused before anything runs
        std::string text = "[model]\n";
        for (const std::string& line : so.configs.modelOverrides) text += line + "\n";
        sim::parseRunConfig(text, "--model");
    }
    if (!o.configs.empty()) {
        if (!std::filesystem::is_directory(o.configs)) throw IoError(o.configs + ": --configs: not a directory");
        so.configs.directory = o.configs;
    } else if (std::filesystem::is_directory("configs/validation")) {
        so.configs.directory = "configs/validation";
    }  // else: the copies embedded at build time
    for (const std::string& item : o.only) {  // --only a,b and --only a --only b
        std::stringstream ss(item);
        std::string name;
        while (std::getline(ss, name, ','))
            if (!name.empty()) so.only.push_back(name);
    }
    so.log = [](const std::string& line) { info(line); };
    info("validate: " + std::string(validate::modeName(so.mode)) + " run, " +
         (so.replicates > 0 ? std::to_string(so.replicates) + " replicate(s) per scenario"
                            : std::string("each scenario's replicates (its file's, default ") +
                                  std::to_string(validate::kDefaultReplicates) + ")") +
         ", " + std::to_string(omp_get_max_threads()) + " threads, configurations from " + so.configs.describe() + ", output " + so.outDir);
    const validate::SuiteResult result = validate::runSuite(so);
    const auto written = validate::writeReport(result, so.outDir);
    char line[200];
    std::snprintf(line, sizeof line, "validate: %d of %d checks passed in %.1f s",
                  result.checkCount() - result.failedCount() - result.knownDeviationCount(), result.checkCount(), result.seconds);
    info(line);
    for (const auto& s : result.scenarios)
        for (const auto& c : s.checks) {
            if (c.knownDeviation()) info("validate: known deviation (reported, not failing) " + s.name + "/" + c.spec.id);
            else if (!c.pass) info("validate: FAILED " + s.name + "/" + c.spec.id);
        }
    for (const auto& f : written) printResult("%s\n", f.c_str());
    std::fflush(stdout);
    const int status = validate::exitStatus(result);
    if (status != 0) throw ExitStatus(status, std::to_string(result.failedCount()) + " validation check(s) failed; see " + written.front());
}

}  // namespace

void registerValidateCommand(CLI::App& app) {
    auto opt = std::make_shared<ValidateOptions>();
    CLI::App* sub = app.add_subcommand(
        "validate",
        "Ecological regression suite (paper §7.2, Figs. 13-15 and 20; Deussen et al. 1998; Zamuda & Brest): "
        "self-thinning, succession, dynamic equilibrium, gap dynamics, abiotic gradients, the Deussen comparison, "
        "Deussen's circle test, synthesis fidelity and EcoMod's afforestation of empty ground (docs/ecomod.md). Writes "
        "DIR/report.md, its self-contained twin DIR/report.html (pictures embedded, interactive plots) and DIR/results.csv. Exit status: 0 all checks passed (a check its configuration declares a known "
        "deviation of the model is reported but does not fail), 3 a check failed, 1 bad input or error "
        "(docs/validation.md).");
    sub->add_flag("--quick", opt->quick, "Small plots and short spans (CI: a few minutes on 2 cores)");
    sub->add_option("--out", opt->out, "Output directory for report.md, report.html, results.csv and the PNGs (default: validation)");
    sub->add_option("--configs", opt->configs,
                    "Directory of scenario configurations (default: configs/validation if it exists here, else the "
                    "copies embedded at build time)");
    sub->add_option("--replicates", opt->replicates,
                    "Seeds of every scenario, overriding the scenario files' counts (default: each file's [scenario] "
                    "replicates, or quick_replicates with --quick, else " +
                        std::to_string(validate::kDefaultReplicates) +
                        "): each check is judged on the 95 % interval of its mean over them; 1 judges single values")
        ->check(CLI::Range(1, validate::kMaxReplicates));
    sub->add_option("--model", opt->model,
                    "KEY=VALUE (repeatable): replace a [model] key in every scenario and scene, e.g. growth_rule=literal, "
                    "germination_cells=every, germination_vigour=mean_vigour, canopy_limit=canopy_only "
                    "(docs/validation.md, \"Readings of the paper\")");
    sub->add_option("--biome", opt->biome,
                    "Biome TOML whose species every scenario simulates (default: the embedded Sonoma biome): the suite "
                    "on tuned parameters. The scenarios name species (e.g. California Laurel), which the biome must have")
        ->check(CLI::ExistingFile);
    sub->add_option("--only", opt->only, "Run only these scenarios (names, comma-separated or repeated)");
    sub->add_option("--threads", opt->threads, "OpenMP threads, 1..1024 (default: all cores); results do not depend on it")
        ->check(CLI::Range(1, 1024));
    sub->callback([opt] { runValidate(*opt); });
}

}  // namespace eco::cli
