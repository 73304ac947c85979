// Reading a simulation file (written by `eco simulate`, layout in docs/simulator.md) into
// an AnalysisInput: a snapshot of the undergrowth, the canopy, the simulated area, and the
// annual-mean abiotics of the abiotics file the simulation names.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "analysis.h"

namespace eco::analysis {

struct SimulationReadOptions {
    int year = -1;             ///< snapshot year to analyse; -1 = the last one
    std::string abioticsPath;  ///< overrides the abiotics file the simulation names
};

struct LoadedSimulation {
    std::shared_ptr<const Biome> biome;  ///< owns what input.biome points to
    AnalysisInput input;
    std::vector<int> years;              ///< snapshot years in the file, ascending
    /// The simulation's seeding disc factor (seed_outer_radius_factor), 0 when not recorded.
    double seedOuterRadiusFactor = 0;
};

/// Read one simulation. IoError naming the file and the dataset or attribute when it is
/// not an eco-simulation file, has another schema version, has no snapshots or not the
/// requested year (the message lists the years present), lacks a plant dataset, or when
/// the abiotics file cannot be read. A relative abiotics path is tried as given, then
/// relative to the simulation file's folder.
LoadedSimulation readSimulation(const std::string& path, const SimulationReadOptions& options);

}  // namespace eco::analysis
