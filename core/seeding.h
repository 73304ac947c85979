// Which canopy sub-biomes seed each cell: the labels both the analyser (regions of a
// simulation) and the synthesizer (cluster map of a target terrain) make, so that a
// region means the same cells in both.
#pragma once

#include <cstdint>
#include <vector>

#include "grid.h"
#include "plants.h"

namespace eco {

/// Combination label of each cell: the OR of speciesMask[species] (bit b-1 for sub-biome b)
/// of every canopy tree whose disc of radius seedingRadiusFactor x crown radius holds the cell centre
/// (distance <= radius). Also returns, in `seedWeight` when not null, min(1, sum of the
/// kernel) with full weight within innerFactor x r. Parallel over bands of rows; identical
/// for any number of threads.
Grid<std::int32_t> seedingLabels(const Grid<float>& geometry, const std::vector<Plant>& canopy,
                                 const std::vector<int>& speciesMask, double seedingRadiusFactor,
                                 double innerFactor = 0.0, Grid<float>* seedWeight = nullptr);

}  // namespace eco
