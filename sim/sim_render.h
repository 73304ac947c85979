// Pictures of a simulation: a top-down render of the plants (discs coloured by species, as
// the paper's Fig. 14) and a plot of plants per species per year (as Fig. 15).
#pragma once

#include <string>
#include <vector>

#include "simulator.h"

namespace eco::sim {

/// Top-down render north-up: canopy crowns as grey outlines, undergrowth as discs coloured
/// by species (largest first, so small plants stay visible), legend of the species present.
/// At most maxSidePx pixels along the longer side. Atomic PNG.
void renderPlantsPng(const std::string& path, const std::vector<UndergrowthPlant>& plants,
                     const std::vector<Plant>& canopy, const SimArea& area, const Biome& biome,
                     const std::string& title, int maxSidePx = 1600);

/// The same picture with a disturbance event's mask (sim_file.h DisturbanceMask) under the
/// plants: the struck cells tinted on the ground (fire orange, storm blue) and the mask's
/// boundary drawn over the plants. `plants` are those of a census after the event (the
/// regrowth) or before it. Atomic PNG.
void renderDisturbancePng(const std::string& path, const DisturbanceRecord& event,
                          const std::vector<UndergrowthPlant>& plants, const std::vector<Plant>& canopy,
                          const SimArea& area, const Biome& biome, const std::string& title, int maxSidePx = 1200);

/// Line plot of the number of plants of each species per year, with axes, ticks and a
/// legend of the species that ever occur. Atomic PNG.
void plotSpeciesCountsPng(const std::string& path, const std::vector<YearRecord>& timeseries,
                          const Biome& biome, const std::string& title);

}  // namespace eco::sim
