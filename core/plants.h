// Plant lists shared by every stage: canopy trees (written by the canopy placer, read by
// the simulator, the analyser and the synthesizer), undergrowth plants with their simulation
// state, and their HDF5 and CSV forms. The one plant-table writer and reader: every file
// format stores its plant lists through these (canopy_file.h, sim_file.h, synth's scene).
//
// HDF5 layout of a plant group G (e.g. /canopy in canopy.h5), one entry per plant:
//   G/species_id   int32 [n]    index into G/species_names
//   G/x, G/y       float64 [n]  metres, world coordinates (x east, y north)
//   G/ground_z     float64 [n]  metres, terrain elevation at (x, y)
//   G/height       float64 [n]  metres above ground
//   G/crown_radius float64 [n]  metres
//   G/species_names string [nspecies]  the biome's species names, in biome order
// Attributes of G: count, units = "m".
// An undergrowth table adds the state columns: id (int64 [n]; float64 in files written before
// issue 31, exact below 2^53) and (float64 [n]) age and
// growth_age (years), vigour, pool, sun_share (hours/day), water_share (mm/month); a reader
// of plain plants ignores them, and they are optional to the undergrowth reader.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "biome.h"
#include "h5io.h"

namespace eco {

/// A plant at the API: plain struct; the simulator keeps its own structure of arrays.
struct Plant {
    int speciesId = 0;
    double xM = 0, yM = 0;        ///< world coordinates
    double groundZM = 0;          ///< terrain elevation at (x, y)
    double heightM = 0;           ///< above ground
    double crownRadiusM = 0;
};

/// An undergrowth plant with its simulation state (the simulator's API type and a row of a
/// simulation snapshot; the simulator keeps its own structure of arrays).
struct UndergrowthPlant {
    std::uint64_t id = 0;       ///< unique, assigned in a fixed order (input, then seedlings by cell)
    int speciesId = 0;
    double xM = 0, yM = 0;      ///< root position, world metres
    double groundZM = 0;        ///< terrain elevation at the root
    double heightM = 0;
    double crownRadiusM = 0;
    double ageYears = 0;
    double growthAgeYears = 0;  ///< idealised-growth age (Eq. 3); lags ageYears under stress
    double vigour = 0;          ///< last month's vigour (Eq. 1 on its resource shares)
    double pool = 0;            ///< carbon pool R_i
    double sunShare = 0;        ///< last month's mean sun share over its cells, hours/day
    double waterShare = 0;      ///< last month's mean water share over its cells, mm
};

/// Write plants into group `group` of an open file (see the layout above).
void writePlants(h5::File& file, const std::string& group, const std::vector<Plant>& plants,
                 const Biome& biome);

/// Read plants from group `group`; species are mapped by NAME onto `biome`, so a file
/// written with another species order still reads correctly. IoError names the file and
/// the dataset when one is missing or the arrays differ in length; ValidationError when
/// a species is not in the biome or a value is not finite / negative.
std::vector<Plant> readPlants(const h5::File& file, const std::string& group, const Biome& biome);

/// Write an undergrowth table: the plant columns, then the state columns (layout above).
void writeUndergrowthPlants(h5::File& file, const std::string& group, const std::vector<UndergrowthPlant>& plants,
                            const Biome& biome);
/// Read an undergrowth table (or any plant group; missing state columns read as 0). The
/// errors of readPlants, and IoError naming the dataset when a state column's length differs.
std::vector<UndergrowthPlant> readUndergrowthPlants(const h5::File& file, const std::string& group, const Biome& biome);

/// CSV with a header: species_id,species,x_m,y_m,ground_z_m,height_m,crown_radius_m (+ extra
/// column `layer` when given). Atomic.
void writePlantsCsv(const std::string& path, const std::vector<Plant>& plants, const Biome& biome,
                    const std::string& layer = "");

/// A named list of plants of a layered CSV.
struct PlantLayer {
    std::string name;  ///< e.g. "canopy", "undergrowth"
    const std::vector<Plant>* plants = nullptr;
};
/// CSV of several layers: the columns of writePlantsCsv after a first column `layer`, the
/// layers one after the other. Atomic.
void writePlantLayersCsv(const std::string& path, const std::vector<PlantLayer>& layers, const Biome& biome);

/// CSV of undergrowth plants: the columns of writePlantsCsv (positions to 0.1 mm, height and
/// radius to 10 um) followed by id, age_years, growth_age_years, vigour, pool. Atomic.
void writeUndergrowthCsv(const std::string& path, const std::vector<UndergrowthPlant>& plants, const Biome& biome);

/// Plants from a CSV file (a field stem map, or our own CSVs: writePlantsCsv, eco simulate's
/// undergrowth CSV, eco synth's scene CSV). The header names at least the columns x (or x_m),
/// y (or y_m), species (a species NAME of `biome`), height (or height_m) and crown_radius (or
/// crown_radius_m), in any order and case; other columns (species_id, ground_z_m, the
/// simulator's state) are ignored; ground_z is read when present, else 0. With a column
/// `layer` and a non-empty `layer` argument only the rows of that layer are read (eco synth's
/// CSV: "undergrowth"). Blank lines and lines starting with '#' are skipped; fields may be
/// "quoted". IoError "FILE:LINE: ..." naming the column and value for a missing file or
/// column, a row of another length, a number that is not finite, a negative size or a species
/// that is not in the biome.
std::vector<Plant> readPlantsCsv(const std::string& path, const Biome& biome, const std::string& layer = "");

}  // namespace eco
