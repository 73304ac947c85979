// A user's program built against the installed eco (tests/install/run.cmake): reads the embedded
// biome through eco::core and the default simulation configuration through eco::sim, and
// prints what it found, which the test compares with eco's own commands; draws a PNG (argv[1])
// through the OpenImageIO plugin.
#include <iostream>

#include "biome.h"
#include "eco_version.h"
#include "image_out.h"
#include "sim_config.h"

int main(int argc, char** argv) {
    const eco::Biome biome = eco::defaultBiome();
    const eco::sim::RunConfig config = eco::sim::parseRunConfig(eco::sim::defaultRunConfigToml(), "defaults");
    std::cout << "version " << ECO_VERSION_STRING << "\n"
              << "biome " << biome.name << " species " << biome.species.size() << "\n"
              << "years " << config.years << " seeding_probability " << config.params.seedingProbability << "\n";
    if (argc > 1) {
        eco::Canvas canvas(40, 20, {1.f, 1.f, 1.f});
        canvas.fillDisc(20, 10, 6, {0.f, 0.5f, 0.f});
        canvas.writePng(argv[1]);
    }
    return 0;
}
