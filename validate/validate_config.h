// Configurations of the ecological regression suite (configs/validation/*.toml, one file
// per scenario, docs/validation.md). Parsing is strict: every key is typed and ranged, an
// unknown key is an error naming the file, the line and the key. Every check states its
// expectation and tolerance in the file; nothing is hidden in code.
#pragma once

#include <cstdint>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "biome.h"
#include "sim_config.h"

namespace eco::validate {

/// Which sizes and spans to use: small and short for CI, or the paper's set-up.
enum class Mode { Quick, Full };
const char* modeName(Mode m);

/// One check's expectation, read from a [checks.NAME] table with exactly one of
///   expected = E, tolerance = T    pass when |value - E| <= T
///   min = B                        pass when value >= B
///   max = B                        pass when value <= B
/// A value that is not a number (e.g. a species that never occurred) always fails.
struct CheckSpec {
    enum class Kind { Approx, AtLeast, AtMost };
    std::string id;
    Kind kind = Kind::AtLeast;
    double target = 0.0;     ///< E or B
    double tolerance = 0.0;  ///< T (Approx only)
    std::string units;       ///< optional, for the report
    std::string why;         ///< optional justification of the bound, for the report
    /// Optional: why the model as specified is known not to meet this bound. Such a check is
    /// still measured and reported with its value, as "known deviation" when it fails, but
    /// does not fail the suite (the reason is in the report and in docs/validation.md).
    std::string knownDeviation;
    /// Optional looser bound of a --quick run (smaller plots, shorter spans, noisier
    /// figures): [checks.ID] quick_min, quick_max or quick_expected + quick_tolerance, of the
    /// same kind as the main bound and not stricter, with quick_why saying why.
    bool hasQuickBound = false;
    double quickTarget = 0.0, quickTolerance = 0.0;
    std::string quickWhy;

    /// The bound that applies in mode m: in quick mode the quick bound when there is one
    /// (its `why` is quick_why, followed by the full run's bound).
    CheckSpec forMode(Mode m) const;
    bool passes(double value) const;
    /// An interval of values [lo, hi] passes when it lies wholly inside the accepted region
    /// (an equivalence test for approx, a one-sided test for min and max). NaN fails.
    bool intervalPasses(double lo, double hi) const;
    /// "-1.5 ± 0.5", ">= 1.2", "<= 0.1".
    std::string expectedText() const;
    const char* comparator() const;  ///< "approx", "min", "max"
};

/// Procedural forest scene shared by several scenarios (the paper's Figs. 14-15 set-up:
/// undergrowth under a Douglas-Fir / Redwood canopy). Built with sim/demo_scene.h; the
/// canopy trees' species are reassigned to `canopySpecies` by weight.
struct ForestSceneConfig {
    std::string path;
    std::string title;
    double terrainCellSizeM = 0.914;
    double emptyFraction = 0.2;
    double denseFraction = 0.5;
    bool uniformAbiotics = false;
    std::vector<std::string> canopySpecies;
    std::vector<double> canopyWeights;
    int snapshotEveryYears = 5;  ///< plant lists kept every this many years (and the last)
    struct Size {
        double plotSizeM = 40;
        int years = 150;
        std::uint64_t seed = 1;
    };
    Size quick, full;
    const Size& size(Mode m) const { return m == Mode::Quick ? quick : full; }
    sim::SimParams params;  ///< [model] of the scene (competition must be "resources")
};

class Scenario;  // scenario.h: one kind of scenario, created by name from the registry

/// Replicates (seeds) of a scenario whose file gives no count and when `eco validate` is not
/// given --replicates: each check is measured on each and judged on the 95 % interval of
/// their mean (issue 28).
constexpr int kDefaultReplicates = 5;
/// The largest replicate count a scenario file (or --replicates) may ask for.
constexpr int kMaxReplicates = 1000;

/// One scenario file: the keys every kind has ([scenario], [checks], the forest scene's
/// [quick] / [full] `years`), and the kind's own settings and measures in `scenario`.
struct ScenarioConfig {
    std::string path;
    std::string name;         ///< [scenario] name: used by --only and in the report
    std::string kind;         ///< [scenario] kind: a name in the registry (scenarioKinds(), scenario.h)
    std::string title;
    std::string description;
    int order = 0;            ///< [scenario] order: position in the report
    /// [scenario] replicates (every mode) and quick_replicates (--quick only), in
    /// [1, kMaxReplicates]; 0 = not given. `eco validate --replicates N` overrides both.
    int replicates = 0, quickReplicates = 0;
    /// The scenario's own replicate count in mode m: quick_replicates in a quick run when
    /// given, else replicates, else kDefaultReplicates.
    int replicateCount(Mode m) const {
        if (m == Mode::Quick && quickReplicates > 0) return quickReplicates;
        return replicates > 0 ? replicates : kDefaultReplicates;
    }
    bool forestScene = false; ///< the kind runs the shared forest scene (ScenarioKind::usesForestScene)
    std::string scenePath;    ///< resolved path of the forest scene (forest-based kinds)
    /// Forest-based kinds: the year at which the scenario measures, from its optional
    /// [quick] / [full] `years`; 0 = the scene's own `years`. The scene is simulated as long as
    /// the longest of its scenarios needs, and each scenario reads the run up to its year.
    int yearsQuick = 0, yearsFull = 0;
    /// The year at which this scenario measures in mode m (its own, else the scene's).
    int measureYear(Mode m, const ForestSceneConfig& scene) const {
        const int own = m == Mode::Quick ? yearsQuick : yearsFull;
        return own > 0 ? own : scene.size(m).years;
    }
    /// The kind's settings (its own tables) and measures, made by its factory.
    std::shared_ptr<const Scenario> scenario;
    std::vector<CheckSpec> checks;  ///< in the order the kind defines them (Scenario::checkIds)

    const CheckSpec& check(const std::string& id) const;
    /// True for the kinds that run the shared forest scene.
    bool usesForestScene() const { return forestScene; }
};

/// Parse one scenario file from text; `path` is used in messages and to resolve the scene.
/// `modelOverrides` ("key = value" TOML lines) replace keys of every [model] table.
ScenarioConfig parseScenarioConfig(const std::string& text, const std::string& path,
                                   const std::vector<std::string>& modelOverrides = {});
/// Parse a forest scene file from text.
ForestSceneConfig parseForestSceneConfig(const std::string& text, const std::string& path,
                                         const std::vector<std::string>& modelOverrides = {});

/// Where the configurations come from: a directory, or the copies embedded at build time.
struct ConfigSource {
    std::string directory;  ///< "" = embedded
    /// "key = value" TOML lines that replace those keys in every [model] table (the scene's,
    /// self-thinning's, fidelity's): `eco validate --model KEY=VALUE`, e.g. growth_rule = "literal".
    std::vector<std::string> modelOverrides;
    /// Text of file `name` (e.g. "succession.toml"); IoError naming it when missing.
    std::string read(const std::string& name) const;
    /// Scenario files (*.toml except scene_*.toml), sorted by name.
    std::vector<std::string> scenarioFiles() const;
    /// "configs/validation" or "embedded copy of configs/validation".
    std::string describe() const;
    /// Path shown in messages for file `name`.
    std::string displayPath(const std::string& name) const;
};

/// The embedded copies of configs/validation/*.toml: (file name, text), sorted by name.
const std::vector<std::pair<std::string, std::string>>& embeddedConfigs();

/// Every scenario and scene of a source, parsed and cross-checked (scene files exist,
/// names are unique, species exist in `biome`). Scenarios sorted by order, then name.
struct SuiteConfig {
    std::vector<ScenarioConfig> scenarios;
    std::map<std::string, ForestSceneConfig> scenes;  ///< by scene file name
};
SuiteConfig loadSuiteConfig(const ConfigSource& source, const Biome& biome);

}  // namespace eco::validate
