// Stages that are reused when nothing changed: the fidelity protocol's plot and the members
// of an ensemble run their stages through a StageRunner, so that a rerun after a kill or an
// error redoes only what is missing.
#pragma once

#include <functional>
#include <memory>
#include <string>

#include "reporter.h"
#include "run.h"

namespace eco::pipeline {

/// The stages in order; a stage is reused when its output exists, the command it was made
/// with (recorded beside it as OUTPUT.cmd, with the code's version) is the same, and no
/// earlier stage was rerun. Lines go to `reporter` prefixed by `label` ("fidelity: ...");
/// each stage's own output to the reporter `stageReporter` makes.
class StageRunner {
public:
    StageRunner(std::string label, Reporter& reporter, std::function<std::unique_ptr<Reporter>()> stageReporter);

    /// Run (or reuse) one stage whose main output is `output`. A failing stage's Error is
    /// rethrown naming the stage. Returns true when the stage ran, false when reused.
    bool run(const std::string& name, const std::string& output, const StageOptions& options);

private:
    std::string label_;
    Reporter& reporter_;
    std::function<std::unique_ptr<Reporter>()> stageReporter_;
    bool rerun_ = false;
};

/// The main output file of a stage (the one its stamp sits beside).
std::string mainOutput(const StageOptions& options);

}  // namespace eco::pipeline
