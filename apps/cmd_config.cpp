// eco biome show [BIOME.toml] and eco config defaults [COMMAND]: the built-in settings as TOML
// that eco reads back. Printing only: the texts come from core (biomeToToml), sim
// (defaultRunConfigToml) and the parameter descriptions of synth (paramTomlLines).
#include <iostream>
#include <memory>
#include <string>
#include <vector>

#include "biome.h"
#include "canopy_placer.h"
#include "cli_common.h"
#include "sim_config.h"
#include "species_map.h"

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
        "configs/sim-default.toml with every model constant at its default) or 'canopy' (the canopy placer's "
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
}

}  // namespace eco::cli
