// eco biome show [BIOME.toml] and eco config defaults [COMMAND]: the built-in settings as TOML
// that eco reads back. Printing only: the texts come from core (biomeToToml), sim
// (defaultRunConfigToml) and the parameter descriptions of synth (paramTomlLines).
// eco config describe [--markdown] [TABLE] (hidden): every parameter table (core/param_desc.h)
// as the docs' tables, which tools/param_docs.py writes into docs/ and a test compares.
#include <algorithm>
#include <functional>
#include <iostream>
#include <memory>
#include <string>
#include <vector>

#include "abiotics.h"
#include "analysis.h"
#include "biome.h"
#include "canopy_placer.h"
#include "cli_common.h"
#include "fidelity.h"
#include "scenario.h"
#include "forest_floor.h"
#include "sim_config.h"
#include "species_map.h"
#include "undergrowth.h"

namespace eco::cli {

namespace {

/// Every key of a canopy placer configuration (eco canopy --config, [canopy] config of eco
/// run) with its default: the placer's and the species map's parameter descriptions.
std::string canopyDefaultsToml() {
    std::string text =
        "# Canopy placer configuration (eco canopy --config FILE; docs/canopy.md): every key at its default.\n"
        "[canopy]\n" +
        paramTomlLines(synth::CanopyParams{}, synth::canopyParamFields());
    // canopy_threshold_m is one key for both structs (readCanopyConfig copies it).
    std::vector<ParamDesc<synth::SpeciesMapParams>> speciesMapKeys;
    for (const auto& f : synth::speciesMapParamFields()) {
        bool shared = false;
        for (const auto& c : synth::canopyParamFields()) shared = shared || std::string(c.key) == f.key;
        if (!shared) speciesMapKeys.push_back(f);
    }
    return text + paramTomlLines(synth::SpeciesMapParams{}, speciesMapKeys);
}

// ------------------------------------------------------------------ eco config describe

/// One parameter as the docs show it.
struct DescribedParam {
    std::string key;
    std::string docRow;   ///< the descriptor's own row (paramDocRow / speciesDocRow), which unit tests find in the docs
    std::string allowed;  ///< allowed values (ParamRange::valuesText)
    std::string doc;      ///< the one-line meaning
    std::string unit;     ///< "-" for none
    const void* table;    ///< the descriptor table (the flags made by addParamOption name it)
};

/// A parameter table: its struct, where its keys are set, its docs page and the commands
/// whose flags set some of its keys.
struct DescribedTable {
    std::string name;      ///< eco config describe NAME
    std::string type;      ///< the struct
    std::string fields;    ///< the descriptor table's function
    std::string where;     ///< where the keys are read from (TOML table, record)
    std::string docs;      ///< the docs page holding the generated table
    std::vector<std::string> commands;  ///< subcommands searched for the keys' flags
    bool species;          ///< the biome's species keys (speciesDocRow's columns)
    std::function<std::vector<DescribedParam>()> params;
    bool scenario = false;  ///< a validation scenario kind's keys (ScenarioKeyDoc's columns; no default, no flag)
};

template <typename S>
std::vector<DescribedParam> describe(const std::vector<ParamDesc<S>>& fields) {
    std::vector<DescribedParam> out;
    for (const auto& f : fields) {
        const std::string allowed = f.kind == ParamDesc<S>::Kind::Seed ? "[0, 2^53)" : f.range.valuesText();
        out.push_back({f.key, paramDocRow(f), allowed, f.doc, paramUnitText(f), &fields});
    }
    return out;
}

/// A [disturbance.*] table's keys (sim/disturbance.h): the numbers and the keys that are not one number.
template <typename S>
std::vector<DescribedParam> describe(const std::vector<sim::DisturbanceField<S>>& fields) {
    std::vector<DescribedParam> out;
    for (const auto& f : fields) {
        const std::string unit = *f.unit() ? f.unit() : "-";
        out.push_back({f.key(), f.docRow(), f.allowedText(), f.doc(), unit, &fields});
    }
    return out;
}

const std::vector<DescribedTable>& describedTables() {
    static const std::vector<DescribedTable> tables = {
        {"simulate", "sim::SimParams", "simParamFields()", "`[model]` of a simulation config (eco simulate --config, [simulate] of eco run); simulation file attributes",
         "docs/simulator.md", {"simulate"}, false, [] { return describe(sim::simParamFields()); }},
        {"disturbance-fire", "sim::FireSettings", "fireFields()",
         "`[disturbance.fire]` of a simulation config (either model); the simulation file's `disturbance_toml`",
         "docs/disturbance.md", {}, false, [] { return describe(sim::fireFields()); }},
        {"disturbance-storm", "sim::StormSettings", "stormFields()",
         "`[disturbance.storm]` of a simulation config (either model); the simulation file's `disturbance_toml`",
         "docs/disturbance.md", {}, false, [] { return describe(sim::stormFields()); }},
        {"canopy", "synth::CanopyParams", "canopyParamFields()", "`[canopy]` of eco canopy --config; canopy file attributes", "docs/canopy.md",
         {"canopy"}, false, [] { return describe(synth::canopyParamFields()); }},
        {"species-map", "synth::SpeciesMapParams", "speciesMapParamFields()", "`[canopy]` of eco canopy --config; canopy file attributes",
         "docs/canopy.md", {"canopy"}, false, [] { return describe(synth::speciesMapParamFields()); }},
        {"synth", "synth::SynthParams", "synthParamFields()", "eco synth flags; scene file attributes", "docs/synth.md", {"synth"}, false,
         [] { return describe(synth::synthParamFields()); }},
        {"refine", "synth::RefineParams", "refineParamFields()", "eco synth flags; scene file attributes", "docs/synth.md", {"synth"}, false,
         [] { return describe(synth::refineParamFields()); }},
        {"forest-floor", "synth::ForestFloorParams", "forestFloorParamFields()", "eco synth flags; scene file attributes", "docs/synth.md",
         {"synth"}, false, [] { return describe(synth::forestFloorParamFields()); }},
        {"deussen", "synth::DeussenParams", "deussenParamFields()", "eco synth --method deussen flags; scene file attributes", "docs/synth.md",
         {"synth"}, false, [] { return describe(synth::deussenParamFields()); }},
        {"xu2015", "synth::XuParams", "xuParamFields()", "eco synth --method xu2015 flags; scene file attributes", "docs/synth.md", {"synth"},
         false, [] { return describe(synth::xuParamFields()); }},
        {"analysis", "analysis::AnalysisParams", "analysisParamFields()", "eco analyse flags; the database's `/parameters`", "docs/analysis.md",
         {"analyse"}, false, [] { return describe(analysis::analysisParamFields()); }},
        {"sun", "SunParams", "sunParamFields()", "eco abiotics flags; abiotics file attributes", "docs/abiotics.md", {"abiotics"}, false,
         [] { return describe(sunParamFields()); }},
        {"abiotics", "AbioticParams", "abioticParamFields()", "eco abiotics flags; abiotics file attributes", "docs/abiotics.md", {"abiotics"},
         false, [] { return describe(abioticParamFields()); }},
        {"climate", "Climate", "climateFields()", "`[climate]` of a biome TOML (the scalar keys); every output's biome record",
         "docs/biome.md", {}, false, [] { return describe(climateFields()); }},
        {"soil", "Soil", "soilFields()", "`[soil]` of a biome TOML; every output's biome record", "docs/biome.md", {}, false,
         [] { return describe(soilFields()); }},
        {"vigour", "VigourShape", "vigourFields()", "`[vigour]` of a biome TOML; every output's biome record", "docs/biome.md", {},
         false, [] { return describe(vigourFields()); }},
        {"ecomod-species", "EcoModSpecies", "ecomodSpeciesFields()",
         "the `ecomod = { ... }` table of a biome's `[[species]]`; the biome record (the keys given)", "docs/ecomod.md", {}, false,
         [] { return describe(ecomodSpeciesFields()); }},
        {"wind", "Wind", "windFields()", "`[wind]` of a biome TOML (optional); the biome record when given", "docs/biome.md", {},
         false, [] { return describe(windFields()); }},
        {"fidelity", "validate::FidelityParams", "fidelityParamFields()",
         "the measures of eco fidelity and of eco validate's fidelity scenario; the report's parameters", "docs/fidelity.md",
         {"fidelity"}, false, [] { return describe(validate::fidelityParamFields()); }},
        {"species", "Species", "speciesFields()", "`[[species]]` of a biome TOML (`--biome`); every output's biome record", "docs/biome.md", {},
         true,
         [] {
             std::vector<DescribedParam> out;
             for (const auto& f : speciesFields()) out.push_back({f.key, speciesDocRow(f), f.allowedText(), f.doc, f.unit.empty() ? "-" : f.unit, nullptr});
             return out;
         }},
    };
    // The validation scenarios' own keys, one table per kind (validate/scenarios/scenario_keys.h).
    static const std::vector<DescribedTable> all = [] {
        std::vector<DescribedTable> t = tables;
        for (const validate::ScenarioKind& k : validate::scenarioKinds())
            t.push_back({std::string("validate-") + k.name, std::string("scenario ") + k.name,
                         "ScenarioKind::keys (scenarios/" + std::string(k.name) + ".cpp)",
                         std::string("the kind's own tables of a `kind = \"") + k.name +
                             "\"` scenario file (configs/validation/)",
                         "docs/validation.md", {}, false,
                         [&k] {
                             std::vector<DescribedParam> out;
                             for (const validate::ScenarioKeyDoc& d : k.keys())
                                 out.push_back({d.key, "| `" + d.key + "` | `" + d.table + "` | " + d.unit + " | " + d.doc + " |",
                                                d.allowed, d.doc, d.unit, nullptr});
                             return out;
                         },
                         true});
        return t;
    }();
    return all;
}

/// The flags (as "`eco CMD --flag`") that set `key`: the options of the table's commands (or
/// their subcommands) that addParamOption made for the key; else (a flag declared by hand)
/// an option named after the key, or whose help text is the key's doc line (paramHelp), with
/// or without a prefix.
std::string flagsOf(const CLI::App& root, const DescribedTable& t, const DescribedParam& p) {
    auto lowerFirst = [](std::string s) {
        if (!s.empty() && s[0] >= 'A' && s[0] <= 'Z') s[0] = static_cast<char>(s[0] - 'A' + 'a');
        return s;
    };
    std::string dashed = p.key;
    std::replace(dashed.begin(), dashed.end(), '_', '-');
    const std::string doc = lowerFirst(p.doc);
    std::vector<std::string> found;
    std::function<void(const CLI::App&, const std::string&)> visit = [&](const CLI::App& app, const std::string& path) {
        for (const CLI::Option* o : app.get_options()) {
            const std::vector<std::string>& names = o->get_lnames();
            if (names.empty()) continue;
            const std::string desc = o->get_description();
            if (const ParamFlag* pf = paramFlagOf(o)) {  // declared from a descriptor: exact
                if (pf->table == p.table && pf->key == p.key) found.push_back("`" + path + " --" + names.front() + "`");
                continue;
            }
            bool match = std::find(names.begin(), names.end(), dashed) != names.end();
            if (!match && doc.size() >= 12 && desc.size() >= doc.size()) {
                std::string tail = desc.substr(desc.size() - doc.size());
                if (desc.size() == doc.size()) tail = lowerFirst(tail);
                match = tail == doc;
            }
            if (match) found.push_back("`" + path + " --" + names.front() + "`");
        }
        for (const CLI::App* sub : app.get_subcommands([](const CLI::App*) { return true; }))
            visit(*sub, path + " " + sub->get_name());
    };
    for (const std::string& c : t.commands)
        for (const CLI::App* sub : root.get_subcommands([&](const CLI::App* a) { return a->get_name() == c; }))
            visit(*sub, "eco " + c);
    std::string out;
    for (const auto& f : found) out += (out.empty() ? "" : ", ") + f;
    return out.empty() ? "-" : out;
}

/// A table as the docs show it (the generated block between the markers of
/// tools/param_docs.py), or as tab-separated text.
std::string describeTable(const CLI::App& root, const DescribedTable& t, bool markdown) {
    std::string out;
    const std::vector<DescribedParam> params = t.params();
    if (markdown) {
        if (t.species)
            out += "| key | meaning | unit | allowed values |\n|---|---|---|---|\n";
        else if (t.scenario)
            out += "| key | table | unit | meaning | allowed values |\n|---|---|---|---|---|\n";
        else
            out += "| key | default | unit | meaning | allowed values | flag |\n|---|---|---|---|---|---|\n";
        for (const auto& p : params)
            out += t.species ? p.docRow + "\n"
                   : t.scenario ? p.docRow + " " + p.allowed + " |\n"
                                : p.docRow + " " + p.allowed + " | " + flagsOf(root, t, p) + " |\n";
    } else {
        for (const auto& p : params)
            out += t.name + "\t" + p.key + "\t" + p.allowed + "\t" + (t.species || t.scenario ? "" : flagsOf(root, t, p)) + "\t" + p.doc +
                   (p.unit.empty() || p.unit == "-" ? "" : " (" + p.unit + ")") + "\n";
    }
    return out;
}

/// The index of the tables (docs/factors.md): struct, descriptor, where read and recorded, docs.
std::string describeIndex() {
    std::string out = "| table (`eco config describe`) | struct | descriptor | keys | read from; recorded in | docs |\n|---|---|---|---|---|---|\n";
    for (const auto& t : describedTables())
        out += std::string("| `") + t.name + "` | `" + t.type + "` | `" + t.fields + "` | " + std::to_string(t.params().size()) + " | " +
               t.where + " | `" + t.docs + "` |\n";
    return out;
}

}  // namespace

void registerConfigCommands(CLI::App& app) {
    // eco biome show
    CLI::App* biome = app.add_subcommand("biome", "The biome: eco biome show [BIOME.toml]");
    biome->require_subcommand(1);
    auto biomePath = std::make_shared<std::string>();
    CLI::App* show = biome->add_subcommand(
        "show",
        "Print a biome as TOML (the embedded Sonoma biome, or BIOME.toml as eco reads it: every key, species and "
        "sub-biome written out). The text reads back to the same biome: 'eco biome show > my.toml', edit, then "
        "--biome my.toml. Printed also with --quiet (it is the result).");
    show->add_option("biome", *biomePath, "Biome TOML (default: the embedded Sonoma biome)")->check(CLI::ExistingFile);
    show->callback([biomePath] {
        const Biome b = biomePath->empty() ? defaultBiome() : loadBiome(*biomePath);
        std::cout << "# Biome '" << b.name << "' (" << (biomePath->empty() ? std::string("embedded Sonoma biome") : *biomePath)
                  << "), as eco reads it; docs/biome.md describes every key.\n"
                  << biomeToToml(b);
        std::cout.flush();
    });

    // eco config defaults
    CLI::App* config = app.add_subcommand("config", "Built-in settings: eco config defaults [simulate|canopy]");
    config->require_subcommand(1);
    auto which = std::make_shared<std::string>("simulate");
    CLI::App* defaults = config->add_subcommand(
        "defaults",
        "Print every key of a configuration file with its default, as TOML that eco reads: 'simulate' (the "
        "simulation configuration of eco simulate --config and [simulate] config of eco run: the built-in "
        "configs/sim-default.toml with every model constant at its default, and the [disturbance.fire] and "
        "[disturbance.storm] tables at their defaults, commented out) or 'canopy' (the canopy placer's "
        "configuration, eco canopy --config). Printed also with --quiet (it is the result).");
    defaults->add_option("command", *which, "Which configuration: simulate or canopy")
        ->capture_default_str()
        ->check(oneOf({"simulate", "canopy"}));
    defaults->callback([which] {
        std::cout << (*which == "canopy" ? canopyDefaultsToml()
                                         : "# eco config defaults simulate: the simulation configuration (docs/simulator.md)\n" +
                                               sim::defaultRunConfigToml());
        std::cout.flush();
    });

    // eco config describe (hidden: for the docs and their test)
    struct DescribeArgs {
        std::string table;
        bool markdown = false;
        bool index = false;
    };
    auto d = std::make_shared<DescribeArgs>();
    CLI::App* describeCmd = config->add_subcommand(
        "describe",
        "Print the parameter tables (core/param_desc.h: key, default, unit, meaning, allowed values, flags) as the "
        "docs show them; tools/param_docs.py writes them into docs/ and a test checks that the docs hold them.");
    describeCmd->group("");  // hidden: a tool for the docs
    std::string names;
    for (const auto& t : describedTables()) names += (names.empty() ? "" : ", ") + std::string(t.name);
    describeCmd->add_option("table", d->table, "One table (" + names + "); default: every table");
    describeCmd->add_flag("--markdown", d->markdown, "Markdown tables, as in docs/ (default: tab-separated lines)");
    describeCmd->add_flag("--index", d->index, "The list of tables (docs/factors.md) instead of their rows");
    const CLI::App* root = &app;
    describeCmd->callback([d, root] {
        if (d->index) {
            std::cout << describeIndex();
            return;
        }
        bool any = false;
        for (const auto& t : describedTables()) {
            if (!d->table.empty() && d->table != t.name) continue;
            if (d->table.empty() && d->markdown) std::cout << "### " << t.name << " (`" << t.type << "`, " << t.docs << ")\n\n";
            std::cout << describeTable(*root, t, d->markdown);
            if (d->table.empty() && d->markdown) std::cout << "\n";
            any = true;
        }
        if (!any) usageError("table", "unknown parameter table '" + d->table + "'");
        std::cout.flush();
    });
}

}  // namespace eco::cli
