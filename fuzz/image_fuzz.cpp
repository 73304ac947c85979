// The image terrain reader (core/terrain_io.h readTerrainImage: PNG, TIFF through
// OpenImageIO): headers, sizes checked against memory, truncation, pixel types.
#include <cstring>

#include "fuzz_common.h"
#include "terrain_io.h"

extern "C" int LLVMFuzzerInitialize(int* argc, char*** argv) {
    eco::fuzz::initialize(argc, argv);
    return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    // The reader picks the format by extension: take it from the magic bytes, as a user's
    // file would be named, so that mutations of a TIFF stay TIFFs.
    const bool tiff = size >= 4 && (std::memcmp(data, "II*", 3) == 0 || std::memcmp(data, "MM\0*", 4) == 0);
    const std::string path = eco::fuzz::writeInput(data, size, tiff ? "input.tif" : "input.png");
    eco::TerrainReadOptions options;
    options.cellSizeM = 1.0;
    return eco::fuzz::run([&] { eco::readTerrainImage(path, options); });
}
