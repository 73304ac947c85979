// Canopy placer (paper §5.2, Algorithm 1; SPEC §4): individual canopy trees from a canopy
// height model (CHM), on CPU cores.
//
//   1. Seed a tree at every strict local maximum of the CHM that is >= minSeedHeightM.
//   2. Iterate: render every crown top-down into a depth / tree-id buffer at CHM resolution;
//      remove trees whose visible crown (on the CHM footprint) is below minVisibleFraction of
//      their disc; move every other tree toward the centroid of its visible pixels; add trees
//      at the maxima of the CHM cells no crown explains (residual apices), then on a ring
//      around each tree where the CHM is uncovered, each new crown supported by unexplained
//      cells. Stop when the coverage of the CHM footprint gains less than coverageEpsilon, or
//      after maxIterations.
//   3. Move every added tree onto the CHM apex of the cells its crown shows on (within
//      apexSnapRadiusFraction), then fit each of them as the sphere that best explains what the
//      other crowns leave of the CHM, and drop those whose fitted apex is hidden under another
//      crown (crownFitPasses). Remove starved trees of the last render, seeded trees without a saddle between them
//      and a taller one close to its trunk (seedMergeSaddleM, seedMergeRadiusFraction), and
//      duplicates (trunks closer than
//      minTrunkDistanceM; crowns whose sphere lies entirely inside a larger one).
//
// A tree is a sphere of crown radius r (species allometry, Eq. 2) with its apex at the
// tree's height h; its surface above the ground is z = h - r + sqrt(r^2 - d^2) inside the
// disc d < r. Crowns are rendered in heights above the ground, as the CHM is (a CHM is a
// surface model minus the terrain), so the rendered surface and the CHM compare cell by cell.
//
// Attributes of a tree at (x, y): height = CHM there (bilinear over the footprint cells
// around it), species = species map at its cell, crown radius = that species' allometry at
// that height, ground elevation = terrain (bilinear). Where the species map holds -1 (no
// canopy species can grow there) the tree takes the species of the NEAREST mapped cell
// (exact Euclidean distance between cell centres; ties broken by a fixed rule): it continues the
// neighbouring stand, needs nothing beyond the map, and is recorded as such in
// CanopyResult::fallbackTrees. A map with no species at all gives the tallest canopy species.
//
// Determinism: the result is a pure function of the inputs and CanopyParams (seed
// included): identical bits for any number of OpenMP threads. The render splits the grid
// into bands of rows, each written by one thread, trees in index order, depth ties to the
// lower tree index; per-tree sums are integers; random numbers come from Philox keyed by
// (seed, iteration, tree id); new trees and duplicates are decided in a fixed order (the
// conflicts with earlier items listed in parallel over fixed blocks, then one serial pass:
// the one-by-one result).
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "biome.h"
#include "canopy_file.h"
#include "grid.h"
#include "param_desc.h"
#include "plants.h"
#include "species_map.h"

namespace eco {
class StrictTable;  // core/strict_toml.h
}

namespace eco::synth {

/// Every threshold of the placer. Written into every output (see canopyParamFields()).
struct CanopyParams {
    /// CHM footprint: cells with CHM >= this (metres) are canopy; coverage, RMSE and the
    /// visible part of each crown are measured on them.
    double canopyThresholdM = 3.0;
    /// Trees are seeded, and may move, only where the CHM is >= this (metres).
    double minSeedHeightM = 3.0;
    /// Initial seeds are strict maxima of the CHM over a (2R + 1) x (2R + 1) window (cells).
    int localMaximumRadiusCells = 1;
    /// A tree whose visible crown (on the footprint) is less than this fraction of its
    /// disc is sun-starved and removed (paper: "an area threshold").
    double minVisibleFraction = 0.2;
    /// Iteration cap of Algorithm 1.
    int maxIterations = 30;
    /// Fraction of the way to the centroid of its visible crown a tree moves per iteration.
    /// 1 is the paper's full move; a half move keeps overlapping crowns closer to the CHM's
    /// peaks (less Lloyd-style drift) and converged faster in our tests (docs/canopy.md).
    double moveFactor = 0.5;
    /// Candidate new trees per existing tree and iteration, evenly spaced on the ring with a
    /// random rotation.
    int ringSamples = 8;
    /// Ring radius = ringFactor * (r_i + r_new): 1 places the new crown tangent to tree i's;
    /// below 1 the new crown overlaps it, which reaches the crescents a hidden neighbour
    /// leaves uncovered beside a crown (docs/canopy.md).
    double ringFactor = 0.8;
    /// 1: trees seeded at CHM maxima stay at their apex with the CHM's height (on real lidar
    /// the visible-centroid move pulls them off it); 0: they move like added trees.
    int anchorApexTrees = 1;
    /// Final clean-up: of two trees seeded at CHM maxima whose trunks are less than 2 cells
    /// apart and between which the CHM never drops more than this (metres) below the lower
    /// one, the lower goes: one crown top, two maxima of its lidar noise. 0: off.
    double seedMergeSaddleM = 0.5;
    /// The seed merge also needs the two trunks closer than this fraction of the taller
    /// tree's crown radius: two maxima of one top's noise lie well inside its crown, two
    /// small crowns side by side (a noise-free CHM) about a radius apart. 10: no such limit.
    double seedMergeRadiusFraction = 0.6;
    /// 1: each iteration also adds a tree at every residual apex: a strict 3 x 3 maximum of
    /// the CHM among the footprint cells no crown explains (see residualToleranceM), with
    /// the CHM's height there, anchored like a seed. The top of a tree beside a taller
    /// neighbour is often no maximum of the CHM (the neighbour's flank rises past it) but is
    /// one of that set. 0: added trees come from the ring only (the paper).
    int residualApices = 1;
    /// A footprint cell is explained by the crowns when it is covered and stands at most this
    /// much (metres) above the rendered surface (lidar noise and crown shapes other than
    /// spheres leave small excesses that are no tree of their own).
    double residualToleranceM = 0.3;
    /// An added tree (residual apex or ring) needs at least this fraction of the cells of its
    /// crown disc unexplained: a crown of its own in the CHM, not a rim that an existing
    /// crown, slightly off, leaves uncovered. 0: any uncovered cell will do (the paper).
    double supportFraction = 0.3;
    /// 1: a tree added at a residual apex takes the sphere of the crown model (radius from
    /// the allometry) that stays under the CHM and touches the most unexplained cells around
    /// it, its apex up to 2 cells from the residual apex, when that sphere touches the apex
    /// cell (within residualApexFitToleranceM): the top of a crescent that a taller
    /// neighbour leaves of a crown is no apex, the crown's own apex lies under the neighbour.
    /// A tree whose fitted apex is hidden (the CHM there more than residualToleranceM above
    /// its sphere) explains its crescent during the iterations but is not output: its top is
    /// not in the CHM. A ring candidate is first moved to the highest unexplained cell within
    /// half its crown radius and fitted there the same way (it still moves afterwards).
    /// 0 (the default): trees at the residual apex cell, ring candidates where the ring put
    /// them. Off by default: it raises the precision of tree tops on dense CHMs (0.79 -> 0.83
    /// on bench_canopy_accuracy's sphere scene) but lowers recall, coverage and the fit to
    /// the CHM and makes placement about 1.6x slower (docs/canopy.md).
    int residualApexFit = 0;
    /// Residual apex fit: a cell is touched when the sphere is at most this much (metres)
    /// below the CHM there.
    double residualApexFitToleranceM = 0.1;
    /// Final: every tree the iterations added (residual apex or ring) moves onto the highest
    /// strict 3 x 3 maximum of the CHM among the cells its crown shows on in the last render
    /// (the CHM apex it explains) whose centre lies within this fraction of its crown radius
    /// of its trunk, refined to sub-cell precision by the parabolas of the seeding, with the
    /// CHM's height there; the duplicate removal then drops the lower of two trees that land
    /// on one apex. A ring tree ends at the centroid of its visible crown, which a taller
    /// neighbour pushes off the apex (away from the neighbour). 0: off. 0.5 raised the
    /// precision of tree tops on bench_canopy_accuracy's sphere scenes by 0.012 for 0.2-0.3
    /// points of coverage; 0.75 by 0.02 for 1 point; 1 lost recall on the lidar scenes
    /// (docs/canopy.md).
    double apexSnapRadiusFraction = 0.5;
    /// Final, after the apex snap: passes of the crown fit. In each pass every tree the
    /// iterations added takes the sphere of the crown model (apex within crownFitReachM, any
    /// height, allometric radius) that minimises sum (max(other crowns, sphere) - CHM)^2
    /// around it, on a render of the last pass; then the trees whose fitted apex lies more
    /// than the hidden margin under the CHM are not output: they explain the crescent of a
    /// crown whose top is hidden under a taller one. The hidden margin is the larger of
    /// crownFitHiddenM and 2 x the 90 % quantile of the same margin on every 8th seed (seeds
    /// stand on true tops: the quantile measures how far this CHM's crowns are from spheres).
    /// 0: off. 2 raised bench_canopy_accuracy's sphere scenes from precision / recall 0.803 /
    /// 0.873 to 0.865 / 0.876 (seeds 11-14: 0.789 / 0.858 to 0.863 / 0.859; docs/canopy.md),
    /// It doubles the placement's time (1024^2 on 2 idle cores, 2026-11-28: 0.21 s -> 0.42 s,
    /// within issue 25's 0.43 s) and takes bench_synth's 3072^2 canopy placement + sampling
    /// from 5.8-6.1 s to 8.3-8.6 s, over issue 24's 6.98 s; on the lidar-like scenes (noise,
    /// gaps, negative cells) the placer reaches 0.85 without it. So it is off by default: set
    /// it for dense, noise-free CHMs where the tree count matters more than the time.
    int crownFitPasses = 0;
    /// Crown fit: apex positions searched within this distance (metres) of the tree.
    double crownFitReachM = 0.5;
    /// Crown fit: smallest hidden margin (metres).
    double crownFitHiddenM = 1.0;
    /// 1: the placer ends in the state of highest coverage when later iterations lost some.
    int keepBestState = 1;
    /// Final duplicate removal: of two trunks closer than this (metres) the lower tree goes.
    double minTrunkDistanceM = 1.0;
    /// Stop when an iteration raises the footprint coverage by less than this (fraction).
    double coverageEpsilon = 0.0005;
    /// Seed of the ring sampling.
    std::uint64_t seed = 1;
};

/// One named, documented parameter of CanopyParams (core/param_desc.h): its key for configs,
/// flags and output attributes, its doc line (docs/canopy.md's table) and its range.
using CanopyParamField = ParamDesc<CanopyParams>;
/// All fields of CanopyParams, in declaration order: the one description of them.
const std::vector<CanopyParamField>& canopyParamFields();
/// Value of a field as a double (seeds above 2^53 lose precision; write them separately).
double canopyParamValue(const CanopyParams& p, const CanopyParamField& f);
/// Set a field by key from a number; ValidationError for an unknown key or a non-integer
/// value of an integer field (the message lists the keys).
void setCanopyParam(CanopyParams& p, const std::string& key, double value);

/// ValidationError naming the field when a parameter is outside its range (canopyParamFields).
void validateCanopyParams(const CanopyParams& p);

/// Statistics of one iteration (iteration 0 = the initial seeding), measured on the render
/// that ends it.
// IterationStats, one row of a canopy file's /iterations: core/canopy_file.h.

struct CanopyResult {
    std::vector<Plant> trees;
    std::vector<IterationStats> iterations;  ///< 0 = initial seeding, then one per iteration
    IterationStats final;        ///< after the final clean-up (starved trees, duplicates)
    std::size_t initialSeeds = 0;
    std::size_t seedsMerged = 0;         ///< seeded trees merged into a taller one (seedMergeSaddleM)
    std::size_t duplicatesRemoved = 0;   ///< trunks too close or crowns inside larger crowns
    std::size_t apexSnapped = 0;         ///< added trees moved onto their CHM apex (apexSnapRadiusFraction)
    std::size_t hiddenApexTrees = 0;     ///< fitted trees with their apex under another crown, not output (residualApexFit, crownFitPasses)
    std::size_t crownFitHidden = 0;      ///< added trees whose crown-fit apex is hidden, not output (crownFitPasses)
    double crownFitHiddenMarginM = 0;    ///< the crown fit's hidden margin on this CHM (metres)
    std::size_t fallbackTrees = 0;       ///< final trees whose cell has no species (nearest mapped)
    std::string stopReason;      ///< "coverage gain below epsilon" or "iteration cap"
    double seconds = 0;          ///< whole placement, wall time
};

/// Called after each iteration (and for the final clean-up, with iteration = -1) from the
/// calling thread.
using CanopyProgress = std::function<void(const IterationStats&)>;

/// Place canopy trees on a CHM (metres above ground). terrainM gives the trees' ground
/// elevation; speciesMap (from computeSpeciesMap, -1 = none) their species. All three grids
/// must share one geometry (ValidationError naming them otherwise); CHM heights must be
/// finite and >= 0; species ids must be canopy species of `biome` or -1.
CanopyResult placeCanopy(const Grid<float>& chmM, const Grid<float>& terrainM, const Grid<std::int32_t>& speciesMap,
                         const Biome& biome, const CanopyParams& params, const CanopyProgress& progress = {});

/// A top-down render of crowns (spheres) at the resolution of `like`.
struct CrownRender {
    Grid<float> surfaceM;        ///< crown surface above ground; 0 where uncovered
    Grid<std::int32_t> treeIndex;  ///< index into the plant list of the top crown; -1 where none
};

/// Render plants as the placer does (depth ties to the lower index). Parallel, deterministic.
CrownRender renderCrowns(const std::vector<Plant>& plants, const Grid<float>& like);

/// Remove duplicates from a plant list, tallest first (ties: larger crown, then lower index):
/// a plant goes when its trunk is closer than minTrunkDistanceM to a kept one's, or when its
/// crown sphere lies entirely inside a kept one's. Order of the survivors is kept. Returns
/// the number removed. Uses a uniform grid of bucket size max(crown radius, distance).
std::size_t removeDuplicateTrees(std::vector<Plant>& plants, double minTrunkDistanceM);

/// Strict local maxima of the CHM >= minHeightM over a (2R + 1)^2 window, as cell indices in
/// row order. On a plateau of equal values the cell of lowest index wins, so a flat top gives
/// one seed, not none.
std::vector<std::size_t> chmLocalMaxima(const Grid<float>& chmM, double minHeightM, int radiusCells);

// ------------------------------------------------------------------------- configuration

/// Read canopy and species-map parameters from a strict TOML table (keys of
/// canopyParamFields() and speciesMapParamFields(); canopy_threshold_m sets both structs).
/// Keys absent keep their values; unknown keys are errors (the caller's StrictTable::finish
/// reports them); values outside their ranges are errors naming the file and key.
void readCanopyConfig(StrictTable& table, CanopyParams& canopy, SpeciesMapParams& speciesMap);
/// Same from a file: its [canopy] table when there is one (other tables belong to other
/// stages), else its top level. IoError / ValidationError naming the file, line and key.
void loadCanopyConfig(const std::string& path, CanopyParams& canopy, SpeciesMapParams& speciesMap);

// ------------------------------------------------------------------------- files

/// Everything a canopy run records: the canopy file's contents (core/canopy_file.h, the
/// format's one home, documents the layout) before they are flattened for the writer.
struct CanopyRecord {
    CanopyResult result;
    Grid<std::int32_t> speciesMap;
    Grid<float> chmM;
    Grid<float> terrainM;
    CanopyParams params;
    SpeciesMapParams speciesParams;
    std::vector<TargetResult> targets;
    std::string terrainSource, chmSource, abioticsSource, biomeSource, maskSource;
};

/// Write a canopy file (core/canopy_file.h) atomically. IoError on failure. Canopy files
/// are read with core's readCanopyFile.
void writeCanopyFile(const std::string& path, const CanopyRecord& record, const Biome& biome);

/// Picture of the crowns drawn top-down over a hillshade of the terrain, each crown in its
/// species' categoryColour, shaded by the crown surface, with a legend (species and counts);
/// the title gets the tree count appended.
/// North up; scaled down to at most 1024 pixels a side. Atomic PNG.
void writeCanopyPng(const std::string& path, const std::vector<Plant>& trees, const Grid<float>& terrainM,
                    const Biome& biome, const std::string& title = "Canopy trees");

}  // namespace eco::synth
