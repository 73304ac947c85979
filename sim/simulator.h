// The undergrowth simulator (paper §6.1, Algorithm 2; SPEC §5).
//
// A static canopy shades and drinks; undergrowth plants compete monthly for sunlight and
// moisture on a fine grid (20 cm cells by default), fill a carbon pool with their vigour,
// grow from its overflow, die from background and stress mortality or on reaching the
// canopy, and germinate once a year from a seedbank precomputed around the canopy trees.
// docs/simulator.md describes the model, every interpretation, and how the monthly sweep is
// parallelised without races. Results are bit-identical for any number of OpenMP threads.
//
// Coordinates are world metres (x east, y north, grid.h); ages in years; heights and radii
// in metres; sunlight hours/day; moisture mm/month; vigour dimensionless (Eq. 1).
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "abiotics.h"
#include "biome.h"
#include "disturbance.h"
#include "grid.h"
#include "h5io.h"
#include "plants.h"
#include "sim_config.h"
#include "sim_file.h"

namespace eco::sim {

class EcoModel;

/// Everything the simulation reads; no files needed (the CLI fills it from files).
struct SimInputs {
    Biome biome;
    /// Monthly sun (hours/day, WITHOUT canopy shade: the simulator applies the canopy),
    /// moisture (mm), temperature (C), slope (degrees) and elevation (m), one geometry.
    Abiotics abiotics;
    /// Canopy height model, metres above ground; any geometry covering the area. Empty: the
    /// height of the tallest canopy tree whose crown covers the point (0 where none does).
    Grid<float> chmM;
    /// Static canopy trees (shade, water, seeds); trees outside the area still seed into it.
    std::vector<Plant> canopy;
    /// Area to simulate; none = the whole abiotics extent. Must lie inside the abiotics grid.
    std::optional<SimArea> area;
};

/// An undergrowth plant at the API (core/plants.h; the engine keeps a structure of arrays)
/// and the per-species figures of one year (core/sim_file.h): the rows of a simulation file.
using eco::UndergrowthPlant;
using eco::YearRecord;

/// Counters of the run (for progress and benchmarks).
struct SimCounters {
    std::int64_t plantMonths = 0;   ///< sum over simulated months of the plants alive in it
    std::int64_t plantCellMonths = 0;  ///< sum over months and plants of the cells each occupied (sweep work)
    std::int64_t germinated = 0;
    std::int64_t diedBackgroundOrStress = 0;
    std::int64_t diedAtCanopy = 0;
    std::int64_t diedDominated = 0;  ///< Deussen competition mode: dominated plants that died
    std::int64_t diedDisturbance = 0;  ///< killed by fire or windthrow (setDisturbance)
};

/// Wall-clock seconds spent in each phase of the monthly step since construction (for
/// benchmarks and tuning; not part of the state, not saved in checkpoints).
struct SimPhaseSeconds {
    double footprints = 0;  ///< rows and row spans of every plant's crown, its slots and band-list entries
    double ordering = 0;    ///< height order within each band
    double sweep = 0;       ///< resource sweep: occupancy count, shares, leftovers
    double plants = 0;      ///< vigour, pool, growth, mortality
    double competition = 0; ///< Deussen mode: pairwise domination
    double compaction = 0;  ///< removal of the dead
    double germination = 0; ///< yearly seeding
};

/// Loops over fewer plants (cells) than these run on one thread, because a fork and join
/// costs more than the work. Results never depend on it; tests pass 0 to exercise the
/// parallel paths on small scenes. Not thread-safe: call before running simulations.
void setParallelThresholds(std::size_t plants, std::size_t cells);
/// The defaults of setParallelThresholds (measured on the benchmark hectare, docs/simulator.md).
inline constexpr std::size_t kDefaultParallelPlants = 5000, kDefaultParallelCells = 50000;

/// The simulator: the monthly model of the paper (this class's own engine), or, when
/// params.kind is ModelKind::EcoMod, Zamuda & Brest's yearly EcoMod model (ecomod.h), to which
/// every member below delegates. The members marked "monthly model only" throw
/// ValidationError for an EcoMod simulation.
class Simulation {
public:
    /// Prepares the grids (canopy shade and water, seedbank) and places `initial` plants
    /// (those outside the area are dropped and counted in droppedInitialPlants()). Growth
    /// age is derived from height; crown radius from allometry. ValidationError for bad
    /// parameters, an area outside the abiotics, a species id outside the biome.
    Simulation(SimInputs inputs, SimParams params, std::uint64_t seed,
               const std::vector<UndergrowthPlant>& initial = {});
    ~Simulation();
    Simulation(const Simulation&) = delete;
    Simulation& operator=(const Simulation&) = delete;

    /// Fire and windthrow events (sim/disturbance.h, docs/disturbance.md); off by default.
    /// Both models (EcoMod: at the end of each year, EcoModel::setDisturbance). Call before the first step (part of the fingerprint when enabled). ValidationError for
    /// bad settings.
    void setDisturbance(const DisturbanceSettings& settings);
    const DisturbanceSettings& disturbance() const;
    /// The events so far, in the order they struck (saved in checkpoints).
    const std::vector<DisturbanceRecord>& disturbances() const;

    /// One month of Algorithm 2: resource sweep, vigour, pool, growth, mortality; after the
    /// seeding month also germination. Monthly model only.
    void stepMonth();
    /// Twelve months.
    void stepYear();

    std::int64_t monthsDone() const;
    int yearsDone() const { return static_cast<int>(monthsDone() / 12); }
    std::size_t plantCount() const;
    std::vector<UndergrowthPlant> plants() const;
    /// Census of the current state, recorded as year yearsDone().
    YearRecord census() const;
    const SimCounters& counters() const;
    const SimPhaseSeconds& phaseSeconds() const;
    std::size_t droppedInitialPlants() const;

    const SimParams& params() const;
    const Biome& biome() const;
    std::uint64_t seed() const;
    SimArea area() const;
    /// The simulation grid's geometry (values unused).
    const Grid<float>& gridGeometry() const;
    /// Canopy trees that influence the area (crown or 12 r seeding disc reaches it).
    const std::vector<Plant>& relevantCanopy() const;

    /// The EcoMod engine, or nullptr for the monthly model.
    const EcoModel* ecomod() const { return eco_.get(); }
    EcoModel* ecomod() { return eco_.get(); }

    /// Seedbank (monthly model only): yearly germination probability per cell (sum of the kernels, at most 1).
    const Grid<float>& seedProbability() const;
    /// Seedbank: bit b set when sub-biome b + 1 seeds the cell.
    Grid<std::int32_t> seedPackages() const;
    /// Canopy transmission per cell: product of (1 - alpha) over covering canopy trees.
    const Grid<float>& canopyTransmission() const;
    /// Mean unexploited (sun hours/day, water mm) of cell (ix, iy) over the months of growth
    /// period `period` (index into biome().growthPeriods) accumulated since the last
    /// germination; false when none was accumulated.
    bool leftoverMeans(int ix, int iy, int period, double& sunHours, double& waterMm) const;
    /// Roulette weights of every species at cell (ix, iy) now (0 outside its seed package).
    std::vector<double> germinationWeights(int ix, int iy) const;

    /// Hash of everything that determines the run except its length: parameters, seed,
    /// biome, area and the input data. A checkpoint resumes only into the same fingerprint.
    std::uint64_t fingerprint() const;
    /// Write / restore the dynamic state (plants, pools, accumulators, counters) into /
    /// from an HDF5 group. loadState throws IoError when the fingerprint differs.
    void saveState(h5::File& file, const std::string& group) const;
    void loadState(const h5::File& file, const std::string& group);

    /// Approximate memory of the engine: per-cell bytes and per-plant bytes (benchmarks).
    std::size_t bytesPerCell() const;
    std::size_t bytesPerPlant() const;

private:
    struct Impl;
    std::unique_ptr<Impl> impl_;
    std::unique_ptr<EcoModel> eco_;
    void requireMonthly(const char* what) const;
};

}  // namespace eco::sim
