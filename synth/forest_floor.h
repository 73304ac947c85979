// Forest floor (paper §6.3, SPEC §7): density maps of grasses / forbs and of litter at the
// terrain's resolution, for a renderer to instance ground cover from.
//
//   grass(p)  = suitability(p) x product over crowns covering p of (1 - alpha_s)
//   litter(p) = min(1, (sum over crowns covering p of alpha_s) / litterFullAlpha)
//
// suitability is Eq. 1's response shape (the biome's VigourShape g) of a grass "species"
// whose optimum and range per abiotic are parameters (the paper gives none; ours are in
// docs/synth.md), min over the four annual-mean abiotics, clamped to [0, 1]. A crown covers
// the cells whose centre lies inside (or on) its disc, as applyCanopyShade does; canopy
// trees and, by default, undergrowth plants shade and drop litter. Both maps are unitless
// densities in [0, 1]. Deterministic for any number of threads.
#pragma once

#include <string>
#include <utility>
#include <vector>

#include "biome.h"
#include "grid.h"
#include "param_desc.h"
#include "plants.h"
#include "undergrowth.h"

namespace eco::synth {

struct ForestFloorParams {
    /// Per factor (factors.h order; parameters grass_<factor>_c / _r): sun 11.5 / 7 hours/day
    /// (open, sunny ground suits grass best), moisture 76 / 128 mm, temperature 13.5 / 43 degC,
    /// slope 0 / 50 degrees (flat ground holds soil and grass); indifferent to wind and to any
    /// factor not named here (an indifferent response is neither checked nor recorded).
    Responses grass = responsesFor({{Factor::Sun, {11.5, 7.0}},
                                    {Factor::Moisture, {76.0, 128.0}},
                                    {Factor::Temperature, {13.5, 43.0}},
                                    {Factor::Slope, {0.0, 50.0}}});
    Response& grassResponse(Factor f) { return grass[factorIndex(f)]; }
    const Response& grassResponse(Factor f) const { return grass[factorIndex(f)]; }
    bool undergrowthShades = true;          ///< undergrowth crowns shade grass and drop litter too
    double litterFullAlpha = 2.0;           ///< cumulative alpha at which litter density reaches 1

    /// ValidationError naming the parameter: the grass responses (finite c, positive r),
    /// then forestFloorParamFields().
    void validate() const;
    /// (key, value text) as recorded in scene files: grass_<factor>_c / _r per factor,
    /// undergrowth_shades, then forestFloorParamFields() in order.
    std::vector<std::pair<std::string, std::string>> asParameters() const;
    /// The same, typed for the scene file's attributes (undergrowth_shades a boolean).
    std::vector<h5::NamedAttr> asAttributes() const;
};

/// The numeric fields of ForestFloorParams (core/param_desc.h), keyed as scene files and
/// docs/synth.md's table have them; the grass responses are one pair per factor, named by
/// the factor table, and undergrowth_shades a choice.
const std::vector<ParamDesc<ForestFloorParams>>& forestFloorParamFields();

struct ForestFloor {
    Grid<float> grass;           ///< grass / forb density, [0, 1]
    Grid<float> litter;          ///< litter density, [0, 1]
    Grid<float> suitability;     ///< grass density before shading, [0, 1]
    Grid<float> cumulativeAlpha; ///< sum of the alphas of the crowns over each cell
};

/// Forest floor maps on the geometry of `features`. Plants' species index `biome.species`.
ForestFloor computeForestFloor(const FactorGrids& features, const std::vector<Plant>& canopy,
                               const std::vector<Plant>& undergrowth, const Biome& biome,
                               const ForestFloorParams& params);

}  // namespace eco::synth
