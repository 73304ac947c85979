// The simulation file reader (core/sim_file.h readSimulationFile): format, schema, snapshots, plant datasets.
// The input is the bytes of an HDF5 file; the seeds are small files of the kind made by our
// own writer (fuzz/make_seeds.sh), so mutations reach our checks of attributes, shapes and
// values. Inputs on which the HDF5 library itself crashes are skipped (fuzz_common.h).
#include "fuzz_common.h"
#include "sim_file.h"

extern "C" int LLVMFuzzerInitialize(int* argc, char*** argv) {
    eco::fuzz::initialize(argc, argv);
    return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    const std::string path = eco::fuzz::writeInput(data, size, "input.h5");
    return eco::fuzz::runHdf5(path, [&] { eco::readSimulationFile(path); });
}
