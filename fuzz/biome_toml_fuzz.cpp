// The biome reader (core/biome.h parseBiome: TOML, every key's range). A biome that is read
// must also survive its own round trip: biomeToToml of it is read again without error.
#include <cstdio>
#include <cstdlib>

#include "biome.h"
#include "fuzz_common.h"

extern "C" int LLVMFuzzerInitialize(int* argc, char*** argv) {
    eco::fuzz::initialize(argc, argv);
    return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    const std::string text(reinterpret_cast<const char*>(data), size);
    return eco::fuzz::run([&] {
        const eco::Biome biome = eco::parseBiome(text, "fuzz.toml");
        const std::string written = eco::biomeToToml(biome);
        try {
            eco::parseBiome(written, "round-trip.toml");
        } catch (const eco::Error& e) {
            std::fprintf(stderr, "biome accepted but its biomeToToml is refused: %s\n--- written:\n%s\n", e.what(),
                         written.c_str());
            std::abort();
        }
    });
}
