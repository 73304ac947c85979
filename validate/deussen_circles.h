// Deussen et al. 1998, §4.2: the self-thinning test of circles. Plants are circles placed
// uniformly at random in a square field with random initial radii; every step all radii
// grow by the same amount; when two circles intersect the smaller plant dies; a plant that
// reaches the limit radius is old and dies. Log mean area against log density then falls
// on a line of slope about -1 (area ~ 1 / density: the field stays about equally covered),
// i.e. -3/2 for mass ~ area^(3/2). Standalone: no simulator involved.
#pragma once

#include <cstdint>
#include <vector>

#include "fit.h"

namespace eco::validate {

struct CirclesParams {
    int plantCount = 62500;           ///< plants placed at the start (Deussen: 62,500)
    double fieldSideM = 250.0;        ///< side of the square field, metres
    double initialRadiusMinM = 0.01;  ///< initial radii uniform in [min, max], metres
    double initialRadiusMaxM = 0.10;
    double growthPerStepM = 0.01;     ///< radius increment of every plant per step, metres
    double limitRadiusM = 3.0;        ///< plants reaching this radius are old and die, metres
    int maxSteps = 400;               ///< the run stops earlier when every plant is dead
    std::uint64_t seed = 1;
    /// Thinning phase used for the fit: from the first step at which this fraction of the
    /// initial plants has died of competition ...
    double onsetKilledFraction = 0.2;
    /// ... to the last step before the first plant dies old, or while at least this many
    /// plants live (few plants make a noisy mean).
    int minPlantsInFit = 100;

    /// ValidationError naming the parameter when a value is out of range.
    void validate() const;
};

/// State after one step (step 0 = the initial placement after removing its overlaps).
struct CirclesStep {
    int step = 0;
    std::int64_t alive = 0;
    double densityPerM2 = 0;
    double meanAreaM2 = 0;           ///< mean of pi r^2 over the living plants
    double coveredFraction = 0;      ///< sum of pi r^2 over the field area
    std::int64_t killedByCompetition = 0;  ///< in this step
    std::int64_t diedOld = 0;              ///< in this step
};

struct CirclesResult {
    std::vector<CirclesStep> steps;
    int fitFirstStep = -1, fitLastStep = -1;  ///< inclusive range of the fit; -1 when none
    LineFit fit;                              ///< log10 mean area against log10 density
    bool fitted = false;
};

/// Run the test. Deterministic: positions and radii come from the counter-based generator
/// keyed by (seed, plant index); the smaller-dies rule is resolved largest plant first
/// (ties: lower index first), so a plant dies only when it meets a surviving larger one.
/// Intersections are found through a uniform grid of cell side 2 x limitRadiusM.
CirclesResult runDeussenCircles(const CirclesParams& params);

}  // namespace eco::validate
