// Xu et al. 2015's quantitative evaluation of a sample-based synthesis (§B "Quantitative
// evaluation"; docs/synth.md 2d): the density and Ripley's aggregation index of the exemplar
// (the "sample", unit area) against the same indices of square patches of k x k exemplar areas
// (k = 3, 6, 10) drawn at random from a synthesized pattern ("M", 15 x 15 in the paper),
// averaged over 10 patches per size, each compared as PCT.DEV = |I - I_s| / |I_s| x 100
// (fidelity.h pctDev, our reading of the lost formula). The aggregation index is the mean
// of L(r) - r over distance bins (translation edge correction, fidelity.h ripleyLMinusR):
// < 0 regular, 0 random, > 0 aggregated, as the paper describes Ripley's index.
//
// Deterministic: patches are Philox keyed by (seed, size, patch); countPairs is identical for
// any number of threads.
#pragma once

#include <cstdint>
#include <vector>

#include "point_pattern.h"

namespace eco::validate {

/// The two indices of an unmarked pattern in a window.
struct XuIndices {
    double densityPerM2 = 0;
    double ripleyIndexM = 0;  ///< mean of L(r) - r over the bins, metres
};

/// Density and aggregation index of the points of (x, y) inside `window` (others ignored).
/// `bins.rMaxM` must be at most half the window's shorter side (countPairs).
XuIndices xuIndices(const std::vector<double>& x, const std::vector<double>& y, const RectWindow& window,
                    const DistanceBins& bins);

/// One enlargement of the evaluation.
struct XuEnlargement {
    int factor = 0;          ///< k: patches of k x k exemplar areas
    int patches = 0;
    XuIndices mean;          ///< indices averaged over the patches
    double pctDevDensity = 0, pctDevRipley = 0;  ///< against the exemplar's, %
};

struct XuEvaluation {
    XuIndices exemplar;
    std::vector<XuEnlargement> enlargements;
    double meanPctDevDensity = 0, meanPctDevRipley = 0;  ///< over the enlargements (the paper's D, our reading)
};

/// The evaluation of a synthesized pattern (sx, sy) covering `synthWindow` against the exemplar
/// (ex, ey) observed in `exemplarWindow`: for every factor k, `patches` patches of side k x the
/// exemplar's sides, placed uniformly at random inside synthWindow. ValidationError when a
/// patch does not fit or rMax exceeds half the exemplar's shorter side.
XuEvaluation evaluateXu(const std::vector<double>& ex, const std::vector<double>& ey, const RectWindow& exemplarWindow,
                        const std::vector<double>& sx, const std::vector<double>& sy, const RectWindow& synthWindow,
                        const DistanceBins& bins, const std::vector<int>& factors = {3, 6, 10}, int patches = 10,
                        std::uint64_t seed = 1);

}  // namespace eco::validate
