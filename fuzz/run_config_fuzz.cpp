// The pipeline configuration of `eco run` (pipeline/run.h planRun): every table and key, and
// the stages' own configuration files it names. Paths in a configuration are relative to its
// own directory, so the input is written where the seeds lie in the repository
// (<scratch>/fuzz/corpus/run_config/run.toml) and the built-in configs/sim-default.toml is
// put where the seeds name it: tiny.toml's ../../../configs/sim-default.toml and demo.toml's
// sim-default.toml (beside it) both reach the simulation configuration's reader.
// The output folder is overridden into the scratch folder: planning creates it.
#include <filesystem>
#include <fstream>

#include "fuzz_common.h"
#include "run.h"
#include "sim_config.h"

namespace {
const char* const kInputName = "fuzz/corpus/run_config/run.toml";
}

extern "C" int LLVMFuzzerInitialize(int* argc, char*** argv) {
    eco::fuzz::initialize(argc, argv);
    const std::filesystem::path scratch(eco::fuzz::scratchDir());
    std::filesystem::create_directories(scratch / "fuzz/corpus/run_config");
    std::filesystem::create_directories(scratch / "configs");
    for (const auto& at : {scratch / "configs/sim-default.toml", scratch / "fuzz/corpus/run_config/sim-default.toml"})
        std::ofstream(at) << eco::sim::embeddedDefaultRunConfigToml();
    return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    const std::string path = eco::fuzz::writeInput(data, size, kInputName);
    return eco::fuzz::run([&] { eco::pipeline::planRun(path, eco::fuzz::scratchDir() + "/out"); });
}
