// The ecological regression suite (issue 7; paper §7.2, Figs. 13-15 and 20; Deussen et al.
// 1998 §4.2): scenarios that run the simulator (or, for Deussen's circle test, a small
// standalone model) and turn emergent behaviour into numbers with stated expectations:
// self-thinning, succession, dynamic equilibrium, gap dynamics, abiotic gradients, the
// comparison with Deussen's competition, Deussen's own self-thinning test, and the fidelity
// of synthesis against a held-out simulation (issue 24).
// docs/validation.md defines every measure. The front end is `eco validate`.
#pragma once

#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "html_report.h"
#include "validate_config.h"

namespace eco::validate {

/// The outcome of one check.
struct CheckResult {
    std::string scenario;  ///< scenario name
    CheckSpec spec;
    std::string title;     ///< what was measured, one line
    double value = 0.0;    ///< NaN when it could not be evaluated (see note)
    bool pass = false;     ///< the value meets the bound
    std::string note;      ///< e.g. why a value is missing (of the first replicate)
    /// The value of each replicate (seed), in replicate order; `value` is their mean and
    /// [ciLow, ciHigh] its 95 % interval (Student's t; the value itself for one replicate).
    std::vector<double> replicateValues;
    double ciLow = 0.0, ciHigh = 0.0;

    /// A failing check whose configuration declares it a known deviation of the model
    /// (CheckSpec::knownDeviation): reported, but it does not fail the suite.
    bool knownDeviation() const { return !pass && !spec.knownDeviation.empty(); }
    /// "pass", "fail" or "known_deviation" (results.csv).
    const char* outcome() const { return pass ? "pass" : knownDeviation() ? "known_deviation" : "fail"; }
};

/// A picture of a scenario, written into the output directory, and what report.html shows
/// of it: the picture, or an interactive view with the picture folded away under it.
struct Figure {
    Figure() = default;
    Figure(std::string file_, std::string caption_, html::LinePlot plot_ = {})
        : file(std::move(file_)), caption(std::move(caption_)), plot(std::move(plot_)) {}
    Figure(std::string file_, std::string caption_, html::SceneView scene_)
        : file(std::move(file_)), caption(std::move(caption_)), scene(std::move(scene_)) {}
    /// Relative to the output directory; "" = no picture: an interactive view of report.html
    /// only (report.md names it in a line).
    std::string file;
    std::string caption;
    /// The picture's data as an interactive plot for report.html (no groups: none).
    html::LinePlot plot;
    /// Plants to show from above in report.html (pan and zoom; docs/report.md).
    std::optional<html::SceneView> scene;
};

struct ScenarioResult {
    std::string name, title, description, configPath, kind;
    double seconds = 0.0;
    bool sharesSimulation = false;  ///< uses the forest scene, whose runs are shared between scenarios
    int replicates = 1;             ///< replicates (seeds) run; each check has one value per replicate
    std::vector<CheckResult> checks;
    std::vector<Figure> figures;
    std::vector<std::string> details;  ///< Markdown lines: supporting numbers, definitions
};

/// Replicate k of a scenario runs with every seed of its configuration plus k x this.
constexpr std::uint64_t kReplicateSeedStep = 1000;

struct SuiteOptions {
    Mode mode = Mode::Full;
    /// Replicates of every scenario (`--replicates`, 1 .. kMaxReplicates), overriding the
    /// scenario files' counts; 0 = each scenario's own (ScenarioConfig::replicateCount:
    /// [scenario] quick_replicates / replicates, else kDefaultReplicates). Replicate k adds
    /// k x kReplicateSeedStep to every seed its configuration gives. Figures and detail lines
    /// are those of replicate 0.
    int replicates = 0;
    std::string outDir = "validation";
    ConfigSource configs;
    std::vector<std::string> only;  ///< scenario names to run; empty = all
    /// Biome TOML the scenarios simulate; "" = the built-in Sonoma biome (defaultBiome).
    std::string biomePath;
    /// Progress and informational lines (stderr in the CLI).
    std::function<void(const std::string&)> log;
};

struct SuiteResult {
    Mode mode = Mode::Full;
    /// SuiteOptions::replicates: the count every scenario ran when --replicates was given,
    /// 0 when each ran its own (ScenarioResult::replicates).
    int replicates = 0;
    std::string configSource;
    std::string biomeName;
    int threads = 1;
    double seconds = 0.0;
    std::string startedUtc;
    std::vector<ScenarioResult> scenarios;

    int checkCount() const;
    int failedCount() const;          ///< failing checks, not counting known deviations
    int knownDeviationCount() const;  ///< failing checks declared known deviations
    bool allPassed() const { return failedCount() == 0; }
};

/// Exit status of `eco validate`: 0 when every check passed (or failed as a declared known
/// deviation), kChecksFailedExit otherwise.
/// (Errors in the input exit with 1 through the CLI's error path, internal errors with 2.)
constexpr int kChecksFailedExit = 3;
int exitStatus(const SuiteResult& result);

/// One check measured on several replicates (same scenario, spec and id, in replicate
/// order), as one result: value = the mean of the replicates' values, [ciLow, ciHigh] = the
/// 95 % Student-t interval of the mean, pass when the whole interval lies inside the accepted
/// region (CheckSpec::intervalPasses). A replicate without a value (NaN) fails the check,
/// with a note. Title and note are the first replicate's.
CheckResult combineReplicates(const std::vector<CheckResult>& replicates);

/// The two-sided 95 % quantile of Student's t with `dof` degrees of freedom (>= 1).
double studentT975(int dof);

/// Load the configurations (every file, so a bad file is reported before anything runs),
/// run the selected scenarios, and write the report into options.outDir. ValidationError
/// for a bad configuration or an unknown --only name.
SuiteResult runSuite(const SuiteOptions& options);

/// DIR/report.md (summary table, per-scenario sections with the figures), its
/// self-contained twin DIR/report.html (pictures embedded, interactive plots where a figure
/// carries one; docs/report.md) and DIR/results.csv (one row per check), all three written
/// together, atomically. Returns the paths written.
std::vector<std::string> writeReport(const SuiteResult& result, const std::string& outDir);

}  // namespace eco::validate
