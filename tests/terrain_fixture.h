// Shared by the terrain reader and writer tests (terrain_io_test.cpp) and those of
// `eco terrain` (terrain_io_cli_test.cpp): a sample terrain and a check for leftover files.
#pragma once

#include <cmath>
#include <filesystem>
#include <string>

#include "grid.h"
#include "test_util.h"

namespace eco::test {

/// Non-square terrain with values that are not exactly representable in short decimals.
inline Grid<float> sampleTerrain() {
    Grid<float> g(37, 23, 0.914, 512345.5, 4251000.25);
    for (int iy = 0; iy < g.height(); ++iy)
        for (int ix = 0; ix < g.width(); ++ix)
            g(ix, iy) = static_cast<float>(60.0 + 100.0 * std::sin(0.37 * ix) * std::cos(0.21 * iy) + 0.1 * ix * iy +
                                           1.0 / 3.0 + 100.0);
    return g;
}

inline bool leftovers(const TempDir& dir) {
    // Nothing but the files the test created itself: no temporary or partial outputs.
    for (const auto& e : std::filesystem::directory_iterator(dir.path()))
        if (e.path().filename().string().find(".tmp") != std::string::npos) return true;
    return false;
}

}  // namespace eco::test
