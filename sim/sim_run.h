// Running a simulation from a run configuration: reading the inputs, the yearly loop with
// snapshots, time series and checkpoints, and the outputs (HDF5, CSV, PNG). The HDF5
// layout is documented in docs/simulator.md. HDF5 calls happen on the calling thread only.
#pragma once

#include <functional>
#include <string>
#include <utility>
#include <vector>

#include "simulator.h"

namespace eco::sim {

/// Read the files a run configuration names (abiotics, canopy with CHM, optional terrain,
/// biome). IoError / ValidationError naming the file and the missing dataset.
SimInputs loadSimInputs(const RunConfig& config, Biome biome);
/// The biome of a run configuration: the file, or the embedded Sonoma biome.
Biome loadRunBiome(const RunConfig& config);

/// Initial undergrowth: a CSV with a header naming at least x_m, y_m, height_m and species
/// (name) or species_id (the CSV written by `eco simulate` and writePlantsCsv both qualify),
/// or an HDF5 plant group "file.h5[:/group]" (default group: the last snapshot of an
/// eco-simulation file, else /undergrowth). Species are mapped by name onto the biome.
std::vector<UndergrowthPlant> readInitialPlants(const std::string& spec, const Biome& biome);

// Snapshots, time series and the undergrowth CSV are written by core (sim_file.h: writeSnapshot,
// readSnapshot, writeTimeseries; plants.h: writeUndergrowthCsv).

/// What a run accumulates besides the simulation state.
struct RunRecord {
    std::vector<YearRecord> timeseries;  ///< one per complete year, from year 0
    SnapshotList snapshots;
    /// Per disturbance event (sim.disturbances()' order), when pictures are asked for: the PNG
    /// bytes of its picture, drawn at the end of its year over the plants just after it ("":
    /// none, e.g. a run resumed from a checkpoint written without pictures). Kept in the
    /// checkpoint, so that a resumed run writes the same pictures.
    std::vector<std::string> eventPictures;
    double wallSecondsBefore = 0;  ///< wall time of earlier processes (resumed runs)
    int resumedFromYear = -1;      ///< -1 when not resumed
};

/// Write the simulation file (core/sim_file.h, atomic): metadata, snapshots, time series, canopy.
void writeSimulationH5(const std::string& path, const Simulation& sim, const RunRecord& record,
                       const RunConfig& config, double wallSeconds, int threads);
/// Write a checkpoint (atomic): simulation state and the record so far.
void writeCheckpoint(const std::string& path, const Simulation& sim, const RunRecord& record);
/// Restore a checkpoint into `sim` (built from the same configuration) and `record`.
/// IoError when the file is not a checkpoint of this run.
void readCheckpoint(const std::string& path, Simulation& sim, RunRecord& record);

/// One line of progress for a disturbance event ("year 40 Aug: fire from (x, y) burnt A m2,
/// killed K plants").
std::string describeDisturbance(const DisturbanceRecord& event);

/// Callbacks of runSimulation (called on the calling thread).
struct RunHooks {
    /// After every simulated year (also after the restored year of a resumed run).
    std::function<void(const Simulation& sim, const RunRecord& record)> onYear;
    /// Informational messages.
    std::function<void(const std::string& line)> log;
    /// Asked after every year; returning true stops the run after writing a checkpoint
    /// (when checkpoints are enabled) and WITHOUT writing the outputs (tests, signals).
    std::function<bool()> stopRequested;
};

struct RunSummary {
    int years = 0;                  ///< years simulated in total
    std::size_t finalPlants = 0;
    double wallSeconds = 0;         ///< this process
    std::int64_t plantMonths = 0;   ///< this process
    bool stoppedEarly = false;
    std::vector<std::string> written;  ///< output files
};

/// Run a configuration end to end. With `resume`, continue from the checkpoint when it
/// exists (a missing checkpoint starts from the beginning, with a log line).
RunSummary runSimulation(const RunConfig& config, bool resume, const RunHooks& hooks = {});

}  // namespace eco::sim
