// Measures of self-thinning that are not true by construction (issue 28 item 1; paper §7.2,
// Yoda et al. 1963; Westoby 1984): given the census of an even-aged stand, the thinning phase
// and, over it, (a) the slope of log mean plant volume on log density, with a volume that is
// not a function of crown area alone, (b) the closure exponent of log mean crown area on log
// density (-1 when the stand stays closed while it thins), (c) how far the density falls, and
// (d) whether competition kills the suppressed: the mean size rank, at the start of the phase,
// of the plants that die during it (1/2 for deaths that ignore size). Each is computed here
// from plain numbers so that the tests can give it constructed stands.
#pragma once

#include <cstdint>
#include <string>
#include <utility>
#include <vector>

namespace eco::validate {

/// The census of an even-aged stand in one year.
struct StandYear {
    int year = 0;
    double alive = 0;           ///< living plants
    double densityPerM2 = 0;    ///< living plants per m^2
    double meanVolumeM3 = 0;    ///< mean over the living of crown area x height (a cylinder), m^3
    double meanAreaM2 = 0;      ///< mean crown area, m^2
    double meanHeightM = 0;
    double coverFraction = 0;   ///< sum of crown areas / plot area
    double mortality = 0;       ///< deaths this year / plants alive at its start (NaN in year 0)
};

/// When the phase starts and ends.
struct ThinningRule {
    double onsetCoverFraction = 0.5;   ///< the crowns have closed: cover at least this
    double onsetMortalityFactor = 1;   ///< and mortality above this x the background rate
    double backgroundMortality = 0;    ///< yearly background rate 1 - P_s^(1/l)
    int minPlants = 30;                ///< the phase ends when fewer plants live
};

/// The thinning phase, years [first, last] (both -1 when there is none): from the first year
/// in which the cover is at least the onset cover and the mortality exceeds the onset factor x
/// background, for as long as the cover stays at least the onset cover and at least minPlants
/// live. With onsetCoverFraction = 0 it ignores closure.
std::pair<int, int> thinningPhase(const std::vector<StandYear>& stats, const ThinningRule& rule);

/// log10 of (density at the phase's first year / density at its last): how far the stand
/// thinned (0.301 = halved). NaN without a phase.
double densityDropLog10(const std::vector<StandYear>& stats, std::pair<int, int> phase);

/// Mean percentile rank by height, among the plants alive at the phase's start, of those not
/// alive at its end: ranks (i + 1/2) / n in order of height, ties sharing their mean rank.
/// About 1/2 when deaths ignore size, near 0 when the smallest die. `atStart` is (id, height)
/// of every living plant at the start, `aliveAtEnd` the ids alive at the end. NaN when
/// nobody died or nobody lived.
double deathSizeRank(const std::vector<std::pair<std::uint64_t, double>>& atStart, const std::vector<std::uint64_t>& aliveAtEnd);

}  // namespace eco::validate
