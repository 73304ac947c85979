// Approximate instancing (Deussen et al. 1998, section 6; issue 29 item 2): the plants of a
// scene are replaced by instances of a few representative plants (prototypes), so that a
// renderer keeps one model per prototype. Each species' plants are clustered by vector
// quantisation in a perceptually linear parameter space, (log height, log crown radius), by
// weighted k-means (k-means++ start, Lloyd iterations); the paper's importance weight is the
// crown area (large plants, more of the picture, pull the prototypes towards them) or 1.
// Every plant becomes its prototype placed at the plant, turned about the vertical and scaled
// uniformly to the plant's height. Deterministic for a seed, whatever the thread count.
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "biome.h"
#include "plants.h"

namespace eco::synth {

struct InstancingParams {
    int prototypesPerSpecies = 8;  ///< K (a species with fewer distinct plants gets fewer)
    bool weightByCrownArea = true; ///< Deussen's importance weight; false: every plant 1
    std::uint64_t seed = 1;        ///< k-means++ starts and the instances' rotations
    int maxIterations = 100;       ///< Lloyd iterations per species at most
};

struct Prototype {
    int id = 0;            ///< index in the prototype list
    int speciesId = 0;
    double heightM = 0, crownRadiusM = 0;  ///< the weighted geometric mean of its plants
    std::size_t count = 0;                 ///< instances
};

struct Instance {
    int prototype = 0;
    double xM = 0, yM = 0, groundZM = 0;
    double rotationDeg = 0;  ///< about the vertical, [0, 360)
    double scale = 1;        ///< uniform: plant height / prototype height
};

/// Errors of the approximation, relative to each plant's own size.
struct InstancingError {
    /// Without scaling (a renderer that places the prototype as it is): per plant the larger of
    /// |h_p - h| / h and |r_p - r| / r.
    double meanUnscaled = 0, maxUnscaled = 0;
    /// With the uniform scale to the plant's height: the height is exact, the crown radius
    /// off by |r_p h / h_p - r| / r (the prototype's shape against the plant's).
    double meanScaled = 0, maxScaled = 0;
    /// The means weighted by crown area: the error as much of the picture shows it (a
    /// seedling of a few millimetres, off by a factor of ten, is not seen).
    double areaMeanUnscaled = 0, areaMeanScaled = 0;
};

struct InstancingResult {
    std::vector<Prototype> prototypes;  ///< by species, then by height
    std::vector<Instance> instances;    ///< in the order of the input plants
    InstancingError error;
    std::vector<InstancingError> errorBySpecies;  ///< index = species id (zero when absent)
};

/// Quantise `plants` (any mix of species; height and crown radius > 0). ValidationError for
/// K < 1 or a plant without size.
InstancingResult quantisePlants(const std::vector<Plant>& plants, std::size_t speciesCount, const InstancingParams& params);

}  // namespace eco::synth

namespace eco::synth {

struct InstancingRun {
    std::string scene;    ///< an eco-scene file
    std::string biome;    ///< biome TOML; "" = the biome recorded in the scene
    std::string outDir;
    InstancingParams params;
    int curveMaxK = 0;    ///< error against K for K = 1 .. this (0: 2 K, at most 32)
    /// Called with (steps done, steps in all) after reading the scene, after the chosen K,
    /// after each K of the error curve and after the outputs; may be empty.
    std::function<void(int done, int total)> progress;
};

struct InstancingSummary {
    std::size_t plants = 0, prototypes = 0;
    InstancingError error;
    std::vector<std::string> files;
    std::string text;     ///< the summary table, printed
};

/// eco instance: quantises the scene's canopy and undergrowth plants and writes, together,
/// OUT/prototypes.csv, OUT/instances.csv, OUT/instancing.md and OUT/error_vs_k.png.
InstancingSummary runInstancing(const InstancingRun& run);

}  // namespace eco::synth
