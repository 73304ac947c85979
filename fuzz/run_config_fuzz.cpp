// The pipeline configuration of `eco run` (pipeline/run.h planRun): every table and key, and
// the stages' own configuration files it names (read relative to the working directory, so
// a seed naming configs/sim-default.toml reaches them when run from the repository root).
// The output folder is overridden into the scratch folder: planning creates it.
#include "fuzz_common.h"
#include "run.h"

extern "C" int LLVMFuzzerInitialize(int* argc, char*** argv) {
    eco::fuzz::initialize(argc, argv);
    return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    const std::string path = eco::fuzz::writeInput(data, size, "run.toml");
    return eco::fuzz::run([&] { eco::pipeline::planRun(path, eco::fuzz::scratchDir() + "/out"); });
}
