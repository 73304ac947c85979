// Terrains and an OpenMP thread-count guard for the tests of the abiotic maps
// (abiotics_test.cpp) and of `eco abiotics` (abiotics_cli_test.cpp); and the one way the
// tests build an Abiotics by hand (abioticsFrom, uniformAbiotics), a loop over kAbioticMaps,
// so that a new abiotic factor needs no line in any test (docs/factors.md).
#pragma once

#include <omp.h>

#include <algorithm>
#include <cmath>
#include <initializer_list>

#include "abiotics.h"
#include "factors.h"
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

/// An Abiotics on the geometry of `elevationM` (which it is) whose every map is its factor's
/// grid of `maps`: a static map that grid, a monthly map 12 copies of it (each month the same).
/// Every map of kAbioticMaps is filled, so a factor added later needs no edit here.
inline Abiotics abioticsFrom(const Grid<float>& elevationM, const FactorGrids& maps) {
    Abiotics a;
    a.elevationM = elevationM;
    for (const AbioticMapInfo& m : kAbioticMaps) {
        const Grid<float>& g = maps[m.factor];
        if (m.isMonthly())
            (a.*(m.monthly)).months.assign(12, g);
        else
            a.*(m.single) = g;
    }
    return a;
}

/// A factor's value in uniformAbiotics: {Factor::Sun, 8}.
struct FactorValue {
    Factor factor;
    double value;
};

/// An Abiotics with the geometry of `like`, the same everywhere and every month: the
/// elevation `elevationM`, each factor named in `values` its value, every other map 0 (or the
/// bound of its kAbioticMaps range nearest 0, so that a factor added later gets a value its
/// file accepts). A test that depends on a map's value names it.
inline Abiotics uniformAbiotics(const Grid<float>& like, double elevationM, std::initializer_list<FactorValue> values) {
    FactorGrids maps;
    for (const AbioticMapInfo& m : kAbioticMaps)
        maps[m.factor] = Grid<float>::like(like, static_cast<float>(std::clamp(0.0, m.lo, m.hi)));
    for (const FactorValue& v : values) maps[v.factor].fill(static_cast<float>(v.value));
    return abioticsFrom(Grid<float>::like(like, static_cast<float>(elevationM)), maps);
}

/// Restores the OpenMP thread count at scope exit.
struct ThreadCountGuard {
    int saved = omp_get_max_threads();
    ~ThreadCountGuard() { omp_set_num_threads(saved); }
};

}  // namespace eco::test
