// eco analyse and eco inspect: simulations into a biome database (analysis/), and a
// readable summary of a database with its plots.
#pragma once

#include <string>
#include <vector>

#include "biome_db.h"
#include "reporter.h"

namespace eco::pipeline {

/// Unset values (0, negative, empty) take the analysis defaults or the simulation's own.
struct AnalyseOptions {
    std::vector<std::string> simulations;  ///< analysed together
    std::vector<std::string> abiotics;     ///< one for all simulations, one per simulation, or none
    std::string out;                       ///< biome database (atomic)
    int kMax = 0;
    int year = -1;         ///< snapshot year; -1 = the last
    long long seed = -1;
    double rMaxM = 0;
    int bins = 0;
    double seedingRadiusFactor = 0;  ///< 0 = the simulation's, else 12
    bool speciesSubBiomes = false;
};
struct AnalyseResult {
    BiomeDatabase database;
};
AnalyseResult analyseStage(const AnalyseOptions& options, Reporter& reporter);
std::vector<std::string> commandLine(const AnalyseOptions& options);

struct InspectOptions {
    std::string database;
    std::string pngDir;  ///< "" = no plots; else region_NNNN_pcf.png, region_NNNN_heights.png
    std::string out;     ///< "" = summary on the reporter only; else also this text file
    int maxPairs = 8;    ///< species pairs per g(r) plot
};
struct InspectResult {
    std::string summary;
};
InspectResult inspectStage(const InspectOptions& options, Reporter& reporter);
std::vector<std::string> commandLine(const InspectOptions& options);

}  // namespace eco::pipeline
