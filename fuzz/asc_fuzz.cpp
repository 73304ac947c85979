// The ESRI ASCII grid reader (core/terrain_io.h readAsc): header, sizes checked against
// memory, values, nodata.
#include "fuzz_common.h"
#include "terrain_io.h"

extern "C" int LLVMFuzzerInitialize(int* argc, char*** argv) {
    eco::fuzz::initialize(argc, argv);
    return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    const std::string path = eco::fuzz::writeInput(data, size, "input.asc");
    return eco::fuzz::run([&] { eco::readAsc(path); });
}
