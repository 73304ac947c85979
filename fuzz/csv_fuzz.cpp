// The text plant and point readers on the same bytes: the point-pattern CSV of `eco pcf`
// (core/point_pattern.h readPointPatternCsv), the initial undergrowth CSV of a simulation
// (sim/sim_run.h readInitialPlants) and the PDB plant list (synth/scene.h readPdb).
#include "biome.h"
#include "fuzz_common.h"
#include "point_pattern.h"
#include "scene.h"
#include "sim_run.h"

extern "C" int LLVMFuzzerInitialize(int* argc, char*** argv) {
    eco::fuzz::initialize(argc, argv);
    return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    static const eco::Biome biome = eco::defaultBiome();
    const std::string csv = eco::fuzz::writeInput(data, size, "plants.csv");
    eco::fuzz::run([&] { eco::readPointPatternCsv(csv); });
    const eco::RectWindow window{0, 0, 100, 100};
    eco::fuzz::run([&] { eco::readPointPatternCsv(csv, &window); });
    eco::fuzz::run([&] { eco::sim::readInitialPlants(csv, biome); });
    const std::string pdb = eco::fuzz::writeInput(data, size, "plants.pdb");
    return eco::fuzz::run([&] { eco::synth::readPdb(pdb); });
}
