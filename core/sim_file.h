// The simulation file ("eco-simulation"): written by the simulator (`eco simulate`), read by
// the analyser and as initial plants. Its one home: the format name, the schema version, the
// writer and the reader (as biome_db.h is the database's). docs/simulator.md describes it.
//
// Layout, one HDF5 file:
//   /snapshots/year_NNNN  undergrowth plant tables (plants.h: the Plant columns plus id, age,
//                         growth_age, vigour, pool, sun_share, water_share), attribute year
//   /timeseries           year int32 [ny], count int32 [ny][ns], mean_height, mean_vigour,
//                         crown_area float64 [ny][ns], species_names
//   /canopy               the canopy trees that influence the area (plants.h layout)
//   /species_names        the biome's species names
//   /disturbance          only when disturbance is configured: one row per event (year, month,
//                         kind, area, x, y, killed [event][species]) and, since 2026-11-27, each
//                         event's burn / damage mask (mask_offset, mask_cells and the mask grid's
//                         geometry per event); a file without the mask datasets still reads.
//                         Schema version unchanged: the masks are optional datasets, an older
//                         reader ignores them (docs/disturbance.md "Output").
//   /provenance           attributes wall_time_s, threads, resumed_from_year (core/provenance.h;
//                         absent with eco --no-provenance; files written before
//                         the group have them at the root)
//   root attributes: format = "eco-simulation", schema_version = 1, code_version, seed, years,
//   the area x0, y0, x1, y1, every model parameter by key, model_toml, biome_name,
//   biome_toml, the input paths (terrain_path, abiotics_path, canopy_path, biome_path,
//   initial_path, config_path) and the run's counters.
#pragma once

#include <cstdint>
#include <array>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "biome.h"
#include "grid.h"
#include "h5io.h"
#include "plants.h"

namespace eco {

inline constexpr const char* kSimulationFormat = "eco-simulation";
/// 2 since issue 31: plant ids int64 (1: float64, still read), the model's choices as HDF5
/// enums, units and dimension scales (docs/hdf5.md).
inline constexpr std::int64_t kSimulationSchemaVersion = 2;

/// Per-species figures of one year (index = species id): one row of /timeseries.
struct YearRecord {
    int year = 0;                        ///< complete years simulated (0 = initial state)
    std::vector<std::int32_t> count;
    std::vector<double> meanHeightM;     ///< 0 when count is 0
    std::vector<double> meanVigour;
    std::vector<double> crownAreaM2;     ///< sum of pi r^2
};

/// The cells an event struck (its burn mask, or a storm's damage mask) on the grid of its
/// event ground (sim/disturbance.h: the abiotics cells covering the simulated area): a fire's
/// burnt cells, a storm's cells in which at least one plant was thrown. Stored sparse: the
/// cell indices iy * width + ix, ascending (row iy = 0 is the southern row, core/grid.h).
struct DisturbanceMask {
    int width = 0, height = 0;           ///< the event grid's columns (x) and rows (y); 0 = no mask
    double originX = 0, originY = 0;     ///< its lower-left corner, world metres
    double cellSizeM = 0;
    std::vector<std::int32_t> cells;     ///< struck cells, iy * width + ix, ascending
    bool present() const { return width > 0 && height > 0; }
    /// 1 for each struck cell on the event grid (empty grid when no mask is recorded).
    Grid<std::uint8_t> grid() const;
    /// True when world point (x, y) lies in a struck cell.
    bool contains(double xM, double yM) const;
};

/// A disturbance event of a run (sim/disturbance.h, docs/disturbance.md): one row of the
/// /disturbance table.
struct DisturbanceRecord {
    int year = 0;                        ///< simulated year in which it struck (0 = the first)
    int month = 0;                       ///< 0 = January; at the end of this month
    std::string kind;                    ///< "fire" or "storm"
    double areaM2 = 0;                   ///< burnt (fire) or damaged (storm) area, m^2
    double xM = 0, yM = 0;               ///< fire: ignition point, world metres; storm: the area's centre
    std::vector<std::int32_t> killed;    ///< plants killed per species (index = species id)
    DisturbanceMask mask;                ///< the struck cells (files written before 2026-11-27: none)
};

/// Write / read the disturbance table (layout in docs/disturbance.md) under `group`, with the
/// events' masks (datasets mask_*; a table without them, as written before the masks, reads
/// with masks not present).
void writeDisturbanceTable(h5::File& file, const std::string& group, const std::vector<DisturbanceRecord>& events,
                           const Biome& biome);
std::vector<DisturbanceRecord> readDisturbanceTable(const h5::File& file, const std::string& group, std::size_t speciesCount);

/// Undergrowth snapshots of a run: (year, plants), in the order taken.
using SnapshotList = std::vector<std::pair<int, std::vector<UndergrowthPlant>>>;

/// The root attributes of a simulation file besides its format and biome.
struct SimulationFileInfo {
    std::uint64_t seed = 0;
    int years = 0;                   ///< complete years simulated
    double wallSeconds = 0;          ///< provenance: wall time of every process of the run
    int threads = 0;                 ///< provenance: OpenMP threads of the last process
    int resumedFromYear = -1;        ///< provenance: -1 when not resumed
    double x0 = 0, y0 = 0, x1 = 0, y1 = 0;  ///< simulated area, world metres
    std::vector<h5::NamedAttr> parameters;  ///< model parameters by key, typed (choices as enums)
    std::string modelToml;
    std::string terrainPath, abioticsPath, canopyPath, biomePath, initialPath, configPath;
    std::int64_t germinated = 0, diedBackgroundOrStress = 0, diedAtCanopy = 0, diedDominated = 0;
    std::int64_t plantMonths = 0, plantCellMonths = 0;
    /// Disturbance (sim/disturbance.h): written only when configured ("" = off), so that a
    /// run without it writes the bytes it wrote before the feature.
    std::string disturbanceToml;
    std::int64_t diedDisturbance = 0;
    std::vector<DisturbanceRecord> disturbances;
};

/// Snapshot group name of a year: parent + "/year_NNNN".
std::string snapshotGroup(const std::string& parent, int year);

/// A snapshot group (the undergrowth plant table, plants.h) with its year and units.
void writeSnapshot(h5::File& file, const std::string& group, int year, const std::vector<UndergrowthPlant>& plants,
                   const Biome& biome);
/// Read a snapshot group (or any plant group: the state columns are optional).
std::vector<UndergrowthPlant> readSnapshot(const h5::File& file, const std::string& group, const Biome& biome);

/// The time series group (layout above).
void writeTimeseries(h5::File& file, const std::string& group, const std::vector<YearRecord>& timeseries,
                     const Biome& biome);
/// IoError naming the file and group when the arrays' shapes disagree with each other or `speciesCount`.
std::vector<YearRecord> readTimeseries(const h5::File& file, const std::string& group, std::size_t speciesCount);

/// Write a simulation file atomically (the parent folder is created).
void writeSimulationFile(const std::string& path, const SimulationFileInfo& info, const Biome& biome,
                         const SnapshotList& snapshots, const std::vector<YearRecord>& timeseries,
                         const std::vector<Plant>& canopy);

/// What the analyser reads back from a simulation file: one snapshot and the context.
struct SimulationFileData {
    Biome biome;                          ///< from the root attribute biome_toml
    std::vector<int> years;               ///< snapshot years in the file, ascending
    int year = -1;                        ///< the year read
    std::vector<Plant> undergrowth;       ///< that snapshot, species mapped onto `biome`
    std::vector<Plant> canopy;
    std::optional<std::array<double, 4>> area;  ///< x0, y0, x1, y1 when recorded
    std::string abioticsPath;             ///< as recorded ("" when not)
    std::string terrainPath, canopyPath;
    std::uint64_t seed = 0;
    std::string modelToml;
    double seedOuterRadiusFactor = 0;     ///< 0 when not recorded
    /// The disturbance events with their masks (empty when the run had none configured).
    std::vector<DisturbanceRecord> disturbances;
};

/// Read one snapshot (`year`, or the last one when year < 0) of a simulation file. IoError
/// naming the file and the dataset or attribute when it is not an eco-simulation file, has
/// another schema version, has no snapshots or not the requested year (the message lists
/// the years present), or lacks a plant dataset.
SimulationFileData readSimulationFile(const std::string& path, int year = -1);

/// The snapshot group a plant list in a simulation file is read from by default: the last
/// snapshot, or "" when the file has none.
std::string lastSnapshotGroup(const h5::File& file);

}  // namespace eco
