// The fidelity protocol as a workflow (issue 24, docs/fidelity.md): produce what is missing of
// terrain, CHM, abiotics, canopy, simulations A and B, the database from A and the scene
// (each a pipeline stage, cached in the output folder with the command line it was made
// with), read the patterns and measure them (fidelity.h). `eco fidelity` parses flags into
// FidelityRunOptions and calls runFidelityProtocol.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <set>
#include <string>
#include <vector>

#include "fidelity.h"
#include "reporter.h"

namespace eco::validate {

struct FidelityRunOptions {
    std::string outDir;  ///< folder of the stages' files and the report; "" = out/fidelity
    // Existing files (any subset; the rest is produced).
    std::string terrain, chm, abiotics, canopy, reference, replicate, database, scene;
    std::string outMd, outCsv;  ///< "" = OUT_DIR/fidelity<variant>.md / .csv
    bool refine = false;
    int refineSweeps = 4;
    std::string synthMethod = "structured";
    // Settings (defaults reproduce configs/demo.toml's first scene and plot).
    std::int64_t terrainSeed = 1, seedA = 1, seedB = 2, synthSeed = 1, analyseSeed = 1;
    std::int64_t width = 512, height = 512, years = 150, kmax = 6;
    double cellSizeM = 0.914, sunStepMinutes = 10;
    std::string simConfig = "configs/sim-default.toml";
    /// Canopy placer parameters (a TOML as `eco canopy --config` reads it) for the generated
    /// canopy; "" = the placer's defaults. Its seed is replaced by terrainSeed.
    std::string canopyConfig;
    std::vector<std::string> canopyTargets = {"Douglas-Fir=0.3"};
    std::string crop = "100,60,220,180";  ///< the plot x0,y0,x1,y1 (m)
    FidelityParams params;
};

/// [fidelity] of a TOML configuration into `options`; an option named in `given` (as on the
/// command line, "--seed-a") keeps its value. ValidationError naming the file and key.
void readFidelityConfig(const std::string& path, FidelityRunOptions& options, const std::set<std::string>& given);

struct FidelityRunResult {
    FidelityReport report;
    std::string markdown;  ///< also printed on the reporter's out()
    std::string markdownPath, csvPath;
    std::string scenePath, referencePath, replicatePath, databasePath;  ///< the files measured (given or made; database "" when none)
};

/// Run the protocol. Messages go to `reporter`; each stage that runs gets its own reporter
/// from `stageReporter` (the command line sends the stages' results to stderr so that stdout
/// carries only the report).
FidelityRunResult runFidelityProtocol(const FidelityRunOptions& options, pipeline::Reporter& reporter,
                                      const std::function<std::unique_ptr<pipeline::Reporter>()>& stageReporter);

}  // namespace eco::validate
