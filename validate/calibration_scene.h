// eco calibrate's [calibrate.scene] (issue 28, docs/calibration.md): the members simulate eco
// validate's forest scene (configs/validation/scene_*.toml) with a member's biome and
// [model], at the calibration's plot size, years and scene seed. Here because the scene
// (its configuration and how it is built) belongs to validate, above the pipeline.
#pragma once

#include <functional>
#include <string>
#include <vector>

#include "biome.h"
#include "calibrate.h"
#include "simulator.h"
#include "validate_config.h"

namespace eco::validate {

/// The terrain, abiotics, CHM and canopy of the forest scene on a plot of side plotSizeM with
/// scene seed `seed` (eco validate's scene: the demo scene, canopy species reassigned by the
/// scene's weights among the listed species tall enough for each tree).
sim::SimInputs forestSceneInputs(const ForestSceneConfig& scene, double plotSizeM, std::uint64_t seed, const Biome& biome);

/// Reads the scene file with `model` lines over its [model] (ValidationError naming the file
/// and key), and checks that its canopy species are in `biome`.
ForestSceneConfig loadCalibrationScene(const std::string& file, const std::vector<std::string>& model, const Biome& biome);

/// Checks a [calibrate.scene] before anything is simulated: the scene file, the base biome and
/// the model lines (ValidationError naming the file, key and value).
void checkCalibrationScene(const pipeline::CalibrationScene& scene);

/// Simulates each member (the scene as eco validate builds it, seed = the member's scene
/// seed, scene.years years) into member.dir/simulation.h5 with its time series; a member whose
/// simulation.h5 was written for the same inputs is skipped. Members run one after another
/// (each simulation uses the OpenMP threads).
void runCalibrationScene(const pipeline::CalibrationScene& scene, const std::vector<pipeline::SceneMember>& members,
                         const std::function<void(const std::string&)>& log = {});

}  // namespace eco::validate
