// Plant lists shared by every stage: canopy trees (written by the canopy placer, read by
// the simulator, the analyser and the synthesizer) and their HDF5 and CSV forms.
//
// HDF5 layout of a plant group G (e.g. /canopy in canopy.h5), one entry per plant:
//   G/species_id   int32 [n]    index into G/species_names
//   G/x, G/y       float64 [n]  metres, world coordinates (x east, y north)
//   G/ground_z     float64 [n]  metres, terrain elevation at (x, y)
//   G/height       float64 [n]  metres above ground
//   G/crown_radius float64 [n]  metres
//   G/species_names string [nspecies]  the biome's species names, in biome order
// Attributes of G: count, units = "m".
#pragma once

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

/// Write plants into group `group` of an open file (see the layout above).
void writePlants(h5::File& file, const std::string& group, const std::vector<Plant>& plants,
                 const Biome& biome);

/// Read plants from group `group`; species are mapped by NAME onto `biome`, so a file
/// written with another species order still reads correctly. IoError names the file and
/// the dataset when one is missing or the arrays differ in length; ValidationError when
/// a species is not in the biome or a value is not finite / negative.
std::vector<Plant> readPlants(const h5::File& file, const std::string& group, const Biome& biome);

/// CSV with a header: species_id,species,x_m,y_m,ground_z_m,height_m,crown_radius_m (+ extra
/// column `layer` when given). Atomic.
void writePlantsCsv(const std::string& path, const std::vector<Plant>& plants, const Biome& biome,
                    const std::string& layer = "");

}  // namespace eco
