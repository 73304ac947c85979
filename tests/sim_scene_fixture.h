// The small demonstration scene of the simulator tests (simulator_test.cpp) and of
// `eco simulate` (simulator_cli_test.cpp).
#pragma once

#include "biome.h"
#include "demo_scene.h"
#include "simulator.h"

namespace eco::test {

/// A 48-cell demonstration scene of the default biome, seed 11.
inline sim::SimInputs smallDemoScene() {
    sim::DemoSceneParams p;
    p.cells = 48;
    p.seed = 11;
    return sim::makeDemoScene(p, defaultBiome());
}

}  // namespace eco::test
