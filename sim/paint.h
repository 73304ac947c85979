// The paint step of the monthly sweep: one plant taking its shares of a row span of cells
// (paper §6.1; SPEC §5). The per-cell formulas are those of processes.h; what this file adds
// is the cell record the sweep works on and the summation order.
//
// A plant's sun and water sums are kept in four lanes: the cell at position i of a row span
// goes into lane i mod 4, and the total is (lane 0 + lane 1) + (lane 2 + lane 3). This order
// is fixed by the data alone (never by the thread count or the instruction set), and four
// independent sums let the cells of a span be processed side by side instead of waiting on
// one chain of additions.
#pragma once

#include <cstddef>
#include <cstdint>

#include "processes.h"

namespace eco::sim {

/// What the occupants of one cell share during a month, and the state of the paint over it;
/// filled by the sweep's prepare pass. One record per cell (32 bytes, two to a cache line):
/// a plant painting a cell touches one line, where one array per field meant five, and the
/// height-ordered paint visits the cells of a band at random.
struct alignas(32) CellShare {
    double base;           // canopy-shaded sun
    double avail;          // water after the canopy trees
    double rest;           // remainder / (n + 1): every occupant's equal share and the seeding share
    float transmission;    // product of (1 - alpha) over the occupants painted so far
    std::int32_t painted;  // occupants painted so far (height rank of the next)
};
static_assert(sizeof(CellShare) == 32, "CellShare: two records per 64-byte line");

/// One plant's sums over its cells, in four lanes.
struct PaintLanes {
    double sun[4] = {0, 0, 0, 0}, water[4] = {0, 0, 0, 0};

    // The cell at position `lane` of a group of four (lane = position in the span mod 4).
    template <int lane>
    void cell(CellShare& s, float keep, double demand) {
        sun[lane] += s.base * static_cast<double>(s.transmission);
        water[lane] += waterDemandShareMm(s.avail, s.painted, demand) + s.rest;
        s.transmission *= keep;
        ++s.painted;
    }
    // Cells s[0] .. s[len - 1] of one row, for a plant whose species keeps `keep` of the light.
    void span(CellShare* s, std::size_t len, float keep, double demand) {
        std::size_t i = 0;
        for (; i + 4 <= len; i += 4) {
            cell<0>(s[i], keep, demand);
            cell<1>(s[i + 1], keep, demand);
            cell<2>(s[i + 2], keep, demand);
            cell<3>(s[i + 3], keep, demand);
        }
        const std::size_t tail = len - i;
        if (tail >= 1) cell<0>(s[i], keep, demand);
        if (tail >= 2) cell<1>(s[i + 1], keep, demand);
        if (tail >= 3) cell<2>(s[i + 2], keep, demand);
    }
    double sunTotal() const { return (sun[0] + sun[1]) + (sun[2] + sun[3]); }
    double waterTotal() const { return (water[0] + water[1]) + (water[2] + water[3]); }
};

}  // namespace eco::sim
