// Synthetic scenes for tests, benchmarks and demos of the simulator, built in memory from
// core's procedural terrain and CHM generators and the abiotics model (no files needed).
// Canopy species are assigned by a simple stand-in for the species map (the canopy-capable
// species of highest annual-mean vigour that can reach the tree's height); the real
// species map and canopy placer live in synth/.
#pragma once

#include <cstdint>

#include "simulator.h"

namespace eco::sim {

struct DemoSceneParams {
    int cells = 128;              ///< terrain cells along each side
    double cellSizeM = 0.914;     ///< terrain / abiotics cell size, metres
    std::uint64_t seed = 1;
    double emptyFraction = 0.2;   ///< density sketch: share without canopy
    double denseFraction = 0.5;   ///< share of dense canopy
    bool uniformAbiotics = false; ///< true: skip the sun and moisture models (flat, constant climate maps)
};

/// Terrain, abiotics (without canopy shade), CHM and canopy trees of a procedural scene.
SimInputs makeDemoScene(const DemoSceneParams& params, const Biome& biome);

}  // namespace eco::sim
