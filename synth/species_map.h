// Species map (paper §5.1, SPEC §4): the dominant canopy species of every cell, from the
// annual-mean abiotics and the canopy height model, and the bisection on the vigour weights
// that meets user-given species proportions, globally or inside a brush mask.
//
// Vigour (Eq. 1): v_s(p) = w_s(p) * alpha_s * min_f g(|x_f - c_f| / r_f) over the factors
// (core/factors.h), with the biome's g (core/vigour.h, scalar form). alpha_s is the species' Table 3 alpha, which
// is also its light absorption (used by the canopy shading and the simulator); the user weight
// w_s (default 1) is what the target bisection changes, so that meeting a target never
// changes how much shade a species casts. The effective Eq. 1 weight is w_s * alpha_s.
//
// The map holds, per cell, argmax_s v_s over the canopy-capable species whose maximum height
// is at least the CHM there; -1 where every such vigour is <= 0 (or no species is tall
// enough). Ties go to the lower species index. Deterministic for any number of threads.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "abiotics.h"
#include "biome.h"
#include "grid.h"
#include "param_desc.h"

namespace eco::synth {

/// Annual-mean abiotic maps and the CHM, all on one geometry: what the species map reads.
struct SpeciesMapInputs {
    FactorGrids features;  ///< annual means per factor (factors.h units)
    Grid<float> chmM;      ///< canopy height, metres above ground
};

/// Annual means of the monthly maps of `abiotics`, with `chmM`. ValidationError when the
/// CHM and the abiotic maps differ in geometry.
SpeciesMapInputs speciesMapInputs(const Abiotics& abiotics, const Grid<float>& chmM);

/// Throws ValidationError unless all the grids share one non-empty geometry, hold finite
/// values, and the CHM is non-negative (the message names the map and the first bad cell).
void validateSpeciesMapInputs(const SpeciesMapInputs& in);

/// A brush: inside `mask` (cells != 0, same geometry as the maps) species `species` has the
/// user weight `weight` instead of the global one.
struct LocalWeight {
    int species = 0;
    double weight = 1.0;
    std::shared_ptr<const Grid<std::uint8_t>> mask;
    std::string maskName;  ///< where the mask came from (recorded in outputs)
};

/// Parameters of the species map and the target bisection (recorded in every output).
struct SpeciesMapParams {
    /// Forested area: cells with CHM >= this (metres). Target fractions are fractions of it.
    double canopyThresholdM = 3.0;
    /// Global user weight w_s per species (biome order); empty or shorter = 1 for the rest.
    std::vector<double> weights;
    /// Brush weights, applied in order (a later brush wins where masks overlap).
    std::vector<LocalWeight> localWeights;
    /// A target is met when |achieved - requested| <= this (fraction of the forested area).
    double targetTolerance = 0.01;
    /// Most evaluations of the fraction per bisection (bracketing included).
    int maxBisectionSteps = 80;
    /// Several targets are met one after another; this many rounds over all of them, stopping
    /// early when every target is met (later targets disturb earlier ones a little).
    int targetSweeps = 5;
};

/// One parameter of SpeciesMapParams (core/param_desc.h): key in canopy configs, canopy
/// files and docs/canopy.md's table, doc line and range.
using SpeciesMapParamField = ParamDesc<SpeciesMapParams>;
/// The target bisection's parameters, in record order: the one description of them. Not
/// listed: the weights (per species, from targets and brushes) and canopyThresholdM, which
/// is the canopy placer's canopy_threshold_m (canopyParamFields) copied here.
const std::vector<SpeciesMapParamField>& speciesMapParamFields();

/// ValidationError naming the field when a parameter is out of range.
void validateSpeciesMapParams(const SpeciesMapParams& p, const Biome& biome);

/// Indices of the canopy-capable species of the biome, in biome order.
std::vector<int> canopySpeciesOf(const Biome& biome);

/// Unweighted vigour alpha_s * min_f g(...) of species s (Eq. 1) at one set of abiotic
/// values. Equal to biome.vigourOf(...) (g is decreasing in |d| / r, so the minimum of the
/// responses is g at the largest normalised distance), at a quarter of the cost.
double unweightedVigour(const Biome& biome, int s, const Features& x);

/// The species map: per cell the canopy species of highest weighted vigour among those at
/// least as tall as the CHM there, -1 when none has positive vigour.
Grid<std::int32_t> computeSpeciesMap(const Biome& biome, const SpeciesMapInputs& in,
                                     const SpeciesMapParams& params = {});

/// Fraction of the forested cells (CHM >= canopyThresholdM) inside `mask` (all cells when
/// null) whose map value is `species`. 0 when there is no forested cell.
double speciesFraction(const Grid<std::int32_t>& speciesMap, const Grid<float>& chmM, int species,
                       double canopyThresholdM, const Grid<std::uint8_t>* mask = nullptr);

/// Number of forested cells inside `mask` (all when null).
std::size_t forestedCells(const Grid<float>& chmM, double canopyThresholdM, const Grid<std::uint8_t>* mask = nullptr);

/// A requested proportion: `fraction` of the forested area (inside the mask, if any) for one species.
struct SpeciesTarget {
    std::string species;
    double fraction = 0.0;
};

/// Parse "NAME=FRACTION" strictly: the name must be a canopy-capable species of the biome
/// (ValidationError listing them otherwise), the fraction a number in [0, 1] with nothing after it.
SpeciesTarget parseSpeciesTarget(const std::string& text, const Biome& biome);

/// Outcome of one target.
struct TargetResult {
    std::string species;
    double requested = 0;  ///< fraction asked for
    double achieved = 0;   ///< fraction of the forested area in the final map
    double reachable = 0;  ///< largest fraction this species can hold (it wins wherever it can grow)
    bool feasible = false; ///< |achieved - requested| <= targetTolerance
    double weight = 1;     ///< the user weight w_s found (global, or inside the mask)
    double alpha = 0;      ///< effective Eq. 1 weight w_s * alpha_s
    int iterations = 0;    ///< evaluations of the fraction (all sweeps)
};

/// Meet one target by bisection on the weight of `species` (global when mask is null, else
/// inside the mask, where it becomes or updates a LocalWeight of `params`). A_s(w) is
/// monotone in w, from 0 at w = 0 to the reachable fraction (the cells where the species has
/// positive vigour and is tall enough). When the target cannot be met the weight is set to
/// reach the closest fraction and `feasible` is false. ValidationError for a fraction outside
/// [0, 1], a species that is not canopy-capable, a mask of another geometry, or no forested
/// cell in the region.
TargetResult meetTarget(const Biome& biome, const SpeciesMapInputs& in, SpeciesMapParams& params, int species,
                        double fraction, const std::shared_ptr<const Grid<std::uint8_t>>& mask = nullptr,
                        const std::string& maskName = "");

/// Several targets one after another (params.targetSweeps rounds at most). Results report
/// the fractions of the final map. ValidationError for a repeated species or fractions that
/// sum to more than 1.
std::vector<TargetResult> meetTargets(const Biome& biome, const SpeciesMapInputs& in, SpeciesMapParams& params,
                                      const std::vector<SpeciesTarget>& targets,
                                      const std::shared_ptr<const Grid<std::uint8_t>>& mask = nullptr,
                                      const std::string& maskName = "");

/// A brush mask from a grey image (first channel; white = inside, >= 0.5), which must have
/// exactly the pixel size of `like` (image row 0 is the north edge). IoError / ValidationError
/// naming the file otherwise.
Grid<std::uint8_t> readMaskImage(const std::string& path, const Grid<float>& like);

}  // namespace eco::synth
