// A user's program built against the installed eco (tests/install/run.cmake): reads the embedded
// biome through eco::core and the default simulation configuration through eco::sim, and
// prints what it found, which the test compares with eco's own commands.
#include <iostream>

#include "biome.h"
#include "eco_version.h"
#include "sim_config.h"

int main() {
    const eco::Biome biome = eco::defaultBiome();
    const eco::sim::RunConfig config = eco::sim::parseRunConfig(eco::sim::defaultRunConfigToml(), "defaults");
    std::cout << "version " << ECO_VERSION_STRING << "\n"
              << "biome " << biome.name << " species " << biome.species.size() << "\n"
              << "years " << config.years << " seeding_probability " << config.params.seedingProbability << "\n";
    return 0;
}
