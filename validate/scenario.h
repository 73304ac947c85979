// Kinds of validation scenario, chosen by name (pbrt-v4's integrators and paramdict): each
// kind is a class deriving from Scenario, in its own file validate/scenarios/<kind>.cpp,
// whose constructor reads the kind's own tables of a configuration file, and a factory
// `create<Kind>(const ScenarioParse&)` at the end of that file. The registry
// (validate/scenarios/registry.cpp) lists the factories under the name a file gives as
// [scenario] kind. The parser (validate_config.cpp) reads the keys every kind shares and
// asks the registry for the rest; the suite (validate.cpp) calls run(). Adding a kind = one
// file + its entry in the registry; docs/validation.md, "Adding a scenario kind", shows how.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "sim_config.h"
#include "validate_config.h"

namespace eco {
class StrictTable;
}

namespace eco::validate {

struct ScenarioResult;
class ScenarioContext;  // scenarios/scenario_context.h: the biome, the forest runs, output files

/// What a kind's factory reads: the file's root table, of which the kind consumes its own
/// tables (the parser has consumed [scenario], [checks] and, for forest kinds, the optional
/// [quick] / [full] `years`; it reports any table nobody consumed).
struct ScenarioParse {
    StrictTable& top;         ///< the root table of the file
    const std::string& text;  ///< the whole file, for model()
    const std::string& path;  ///< shown in messages
    /// "key = value" lines replacing keys of the [model] table (ConfigSource::modelOverrides).
    const std::vector<std::string>* modelOverrides = nullptr;

    /// The [model] table (optional), read by the simulator's own strict parser, with the
    /// keys, ranges, messages and line numbers of a run configuration.
    sim::SimParams model() const;
    /// Reads the required [quick] and [full] tables with read(mode, table), then rejects
    /// keys read() did not consume.
    void sizes(const std::function<void(Mode, StrictTable&)>& read) const;
};

/// Checked readers for a kind's tables; messages name the file, table, key and value.
int integerIn(StrictTable& s, const std::string& key, int lo, int hi);  ///< an integer in [lo, hi]
std::uint64_t seedOf(StrictTable& s, const std::string& key);         ///< a non-negative integer
std::vector<std::string> nonEmptyStrings(StrictTable& s, const std::string& key);  ///< at least one species name

/// One kind of scenario: its settings (read by its factory) and its measures.
class Scenario {
public:
    virtual ~Scenario() = default;

    /// The checks it computes, in report order; a file of this kind needs a [checks.ID]
    /// table for each, and run() appends one CheckResult for each (ScenarioContext::check).
    virtual std::vector<std::string> checkIds() const = 0;
    /// Species its settings name, as ("[table] key", species name): each must exist in the
    /// biome (checked when the suite loads, before anything runs).
    virtual std::vector<std::pair<std::string, std::string>> speciesNamed() const { return {}; }

    // Forest kinds only (ScenarioKind::usesForestScene):
    /// Years of the window it averages over; must not exceed the years it measures.
    virtual int windowYears() const { return 0; }
    /// Competition modes in which the scene must be simulated for it.
    virtual std::vector<sim::CompetitionMode> forestModes() const { return {sim::CompetitionMode::Resources}; }
    /// Cross-checks of its settings against the scene; ValidationError naming `shown`.
    virtual void checkScene(const ForestSceneConfig& scene, const std::string& shown) const {}

    /// Measure: append the checks (in checkIds() order), Markdown detail lines and figures
    /// (PNGs written through ctx.file()) to r. `sc` is the file this object was made from.
    virtual void run(const ScenarioConfig& sc, ScenarioContext& ctx, ScenarioResult& r) const = 0;
};

/// A registry entry: a kind by name.
/// One numeric key of a kind's own tables as the docs show it (eco config describe
/// --markdown validate-KIND; scenarios/scenario_keys.h builds them from the kind's
/// ParamDesc tables, the same tables its reader reads).
struct ScenarioKeyDoc {
    std::string table;    ///< "[circles]", or "[quick], [full]" for the per-size keys
    std::string key;
    std::string unit;     ///< "-" for none
    std::string doc;      ///< the meaning, one line
    std::string allowed;  ///< the allowed values ("integer, [1, 64]", "> 0")
};

struct ScenarioKind {
    const char* name;      ///< the value of [scenario] kind
    bool usesForestScene;  ///< runs the shared forest scene: [scenario] scene is required
    std::unique_ptr<Scenario> (*create)(const ScenarioParse& in);  ///< reads the kind's own tables
    std::vector<ScenarioKeyDoc> (*keys)();  ///< its numeric keys, described (docs/validation.md)
};

/// Every kind, in the order listed in messages.
const std::vector<ScenarioKind>& scenarioKinds();
/// The kind called `name`, or nullptr.
const ScenarioKind* findScenarioKind(const std::string& name);

}  // namespace eco::validate
