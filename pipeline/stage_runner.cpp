#include "stage_runner.h"

#include <chrono>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "atomic_file.h"
#include "biome_db.h"
#include "eco_version.h"
#include "error.h"
#include "provenance.h"
#include "stage_common.h"
#include "text_format.h"

namespace eco::pipeline {

StageRunner::StageRunner(std::string label, Reporter& reporter, std::function<std::unique_ptr<Reporter>()> stageReporter)
    : label_(std::move(label)), reporter_(reporter), stageReporter_(std::move(stageReporter)) {}

bool StageRunner::run(const std::string& name, const std::string& output, const StageOptions& options) {
    const std::string stamp = output + ".cmd";
    // The code's identity joins the command: a database of an older schema (or files of
    // another eco version) is made again rather than reused.
    const std::string cmd = quotedCommand(commandLine(options)) + "\n# eco " + ECO_VERSION_STRING +
                            ", biome database schema " + std::to_string(kBiomeDbSchemaVersion);
    if (!rerun_ && std::filesystem::exists(output) && std::filesystem::exists(stamp) && readTextFile(stamp) == cmd + "\n") {
        reporter_.info(label_ + ": " + name + ": reusing " + output + " (made with the same settings)");
        return false;
    }
    reporter_.info(label_ + ": " + name + ":\n   " + cmd);
    const auto t0 = std::chrono::steady_clock::now();
    {
        const std::unique_ptr<Reporter> stageReporter = stageReporter_();
        try {
            // The stage's files record its command line and the inputs it read.
            beginStage(quotedCommand(commandLine(options)));
            runStage(options, *stageReporter);
            beginStage("");
        } catch (const Error& e) {
            throw Error(label_ + " stage '" + name + "' failed: " + e.what());
        }
    }
    writeTextFile(stamp, cmd + "\n");
    rerun_ = true;
    reporter_.info(label_ + ": " + name + " done in " +
                   formatNumber(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(), 3) + " s");
    return true;
}

std::string mainOutput(const StageOptions& options) {
    return std::visit([](const auto& o) { return o.out; }, options);
}

}  // namespace eco::pipeline
