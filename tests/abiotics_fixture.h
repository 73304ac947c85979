// Terrains and an OpenMP thread-count guard for the tests of the abiotic maps
// (abiotics_test.cpp) and of `eco abiotics` (abiotics_cli_test.cpp).
#pragma once

#include <omp.h>

#include <cmath>

#include "grid.h"

namespace eco::test {

/// A grid filled from a function of world (x, y) at the cell centres.
template <class F>
inline Grid<float> makeTerrain(int w, int h, double cell, F f, double ox = 0, double oy = 0) {
    Grid<float> g(w, h, cell, ox, oy);
    for (int iy = 0; iy < h; ++iy)
        for (int ix = 0; ix < w; ++ix) g(ix, iy) = static_cast<float>(f(g.cellCentreX(ix), g.cellCentreY(iy)));
    return g;
}

/// Rough hills with pits and a ridge: exercises every code path of the sweeps and routing.
inline Grid<float> roughTerrain(int w, int h, double cell) {
    return makeTerrain(w, h, cell, [](double x, double y) {
        return 40 + 12 * std::sin(0.11 * x) * std::cos(0.07 * y) + 6 * std::sin(0.31 * x + 0.17 * y) +
               3 * std::cos(0.53 * y - 0.2 * x) - 15 * std::exp(-((x - 50) * (x - 50) + (y - 30) * (y - 30)) / 40.0);
    });
}

/// Restores the OpenMP thread count at scope exit.
struct ThreadCountGuard {
    int saved = omp_get_max_threads();
    ~ThreadCountGuard() { omp_set_num_threads(saved); }
};

}  // namespace eco::test
