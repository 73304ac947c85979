// Undergrowth synthesis (paper §6.2 "Sampling" and "Disk-based refinement", SPEC §7): from a
// target terrain's canopy and annual abiotics and a biome database (core/biome_db.h),
// undergrowth plants whose per-region density, species proportions and size histograms
// match the database, optionally refined towards its pair-correlation functions.
// docs/synth.md explains every step and parameter.
//
// 1. Cluster map. Every cell gets the sub-biome combination of the canopy trees whose
//    seeding disc (database seeding_radius_factor x crown radius) holds its centre, with
//    exactly the analyser's rule (docs/analysis.md), and the region of the database whose
//    centroid is nearest to the cell's annual-mean abiotics (BiomeDatabase::nearestRegion).
//    It also gets the seeding weight w in [0, 1]: min(1, sum over trees of k(d)), with the
//    simulator's kernel k = 1 within inner x r, falling linearly to 0 at the seeding radius.
// 2. Sampling (dart throwing). Region k is to hold N_k = round(density_k x area_k) plants.
//    In each pass every cell throws darts at a rate proportional to w (scaled so that the
//    pass brings about `candidateOversample` times what each region still lacks), uniform
//    inside the cell; darts on a canopy trunk are dropped; each region then accepts its darts
//    in random order while it is below N_k (the paper's "accept while the region's density is
//    below the expected density", without the scan-order bias of a sequential sweep).
//    Species: roulette on the region's proportions restricted to the species whose
//    sub-biomes meet the cell's combination; height and crown radius: inverse CDFs of the
//    region's histograms of that species at one common uniform (comonotone, so the
//    allometric order of height and radius is kept and both histograms are met).
// 3. Refinement (optional): greedy moves of undergrowth plants (displacements and position
//    swaps) that lower the distance between the scene's and the database's pair-correlation
//    functions; canopy trees count in the statistics but never move; a plant never leaves its
//    region.
//
// Determinism: every random number comes from Philox keyed by (seed, pass or sweep, cell or
// plant); reductions run in a fixed order. Results are bit-identical for any number of
// OpenMP threads (tested with 1 and 2).
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "abiotics.h"
#include "biome.h"
#include "biome_db.h"
#include "grid.h"
#include "param_desc.h"
#include "plants.h"
#include "point_pattern.h"
#include "seeding.h"

namespace eco::synth {

/// A parameter of a ParamDesc table as a typed HDF5 attribute (docs/hdf5.md): a real as
/// double, an integer as int64, a seed as int64 (the uint64's bits).
template <typename S>
h5::NamedAttr paramAttr(const ParamDesc<S>& f, const S& p) {
    switch (f.kind) {
        case ParamDesc<S>::Kind::Real: return {f.key, p.*(f.real)};
        case ParamDesc<S>::Kind::Integer: return {f.key, static_cast<std::int64_t>(p.*(f.integer))};
        case ParamDesc<S>::Kind::Seed: return {f.key, static_cast<std::int64_t>(p.*(f.seed))};
    }
    return {f.key, std::string()};
}

// ------------------------------------------------------------------------- inputs

// The annual abiotic maps of the target terrain are a FactorGrids (core/factors.h), made by
// annualFactors (core/abiotics.h), with the sun shaded by the canopy for the cluster map.

/// The biome a database was made with (its biome_toml). ValidationError when that biome's
/// species are not the database's species list, name for name.
Biome databaseBiome(const BiomeDatabase& db);

/// ValidationError naming `canopySource` and the first offending tree when a tree lies
/// outside the terrain's extent, has a species outside the biome, or a non-finite or
/// negative size.
void validateCanopy(const std::vector<Plant>& canopy, const Grid<float>& terrainM, const Biome& biome,
                    const std::string& canopySource);

// ------------------------------------------------------------------------- parameters

/// How undergrowth positions, species and sizes are drawn (docs/synth.md section 2).
enum class SynthMethod {
    /// Conditioned on the canopy and on each other (default): per species, density by canopy
    /// context (depth under the cover) and a clustered (two-scale Thomas) field fitted to
    /// the database's pair correlation; heights by context, below the crown above, crown
    /// radius by allometry. Needs a schema-3 database for the context statistics.
    Structured,
    /// The earlier sampler: uniform darts weighted by the seeding kernel, species by the
    /// region's shares, height and radius from their histograms at one uniform.
    Darts,
    /// Deussen et al. 1998: per species (largest first) the density map (the database's, or
    /// a user's density image) half-toned by Floyd-Steinberg error diffusion, each dot a
    /// plant, then Lloyd relaxation with minimum distances; canopy trees fixed obstacles;
    /// sizes as the structured sampler draws them (synth/deussen_sampler.cpp).
    Deussen,
    /// Xu et al. 2015: sample-based synthesis from an exemplar stand (a simulation snapshot or
    /// a plant CSV): neighbourhood histograms over shells x sectors, the pattern grown
    /// outwards from a seed by copying the neighbourhood of the best-matching exemplar
    /// element; sizes copied, canopy and cluster map respected (synth/xu2015_sampler.cpp).
    Xu2015,
};
const char* toString(SynthMethod m);
/// "structured", "darts", "deussen" or "xu2015"; ValidationError naming the value otherwise.
SynthMethod parseSynthMethod(const std::string& name);

/// Parameters of the Deussen 1998 sampler (docs/synth.md section 2c). Recorded in scene
/// files (keys deussen_*) only when that method runs.
struct DeussenParams {
    /// Lloyd relaxation steps (0: the half-toned positions as they are).
    int lloydIterations = 8;
    /// Half-toning grid: each terrain cell is split into k x k cells, k the smallest with at
    /// most this many expected plants of the species in a half-toning cell where it is densest.
    double halftoneFill = 0.5;
    /// Error diffusion runs in square tiles of this side (m), in parallel; the error does
    /// not cross a tile's border (the partition does not depend on the thread count).
    double halftoneTileM = 64.0;
    /// Two plants of one species stand at least this x the species' mean crown radius in the
    /// database apart (and any pair at least the database's hard-core distance).
    double minDistanceFactor = 0.5;
    /// Voronoi centroids are estimated from the centres of a samples x samples lattice ...
    int voronoiSamples = 8;
    /// ... in a square of half-side this / sqrt(the species' density at the plant).
    double voronoiRadiusFactor = 0.8;

    /// ValidationError naming the field when one is out of range (deussenParamFields).
    void validate() const;
    /// (key, value text) of every parameter, as recorded in scene files.
    std::vector<std::pair<std::string, std::string>> asParameters() const;
    /// The same, typed for the scene file's attributes (paramAttr).
    std::vector<h5::NamedAttr> asAttributes() const;
};
using DeussenParamField = ParamDesc<DeussenParams>;
/// Every parameter of DeussenParams, in record order (synth/synth_params.cpp).
const std::vector<DeussenParamField>& deussenParamFields();

/// Parameters of the Xu et al. 2015 sampler (docs/synth.md section 2d). Recorded in scene
/// files (keys xu_*) only when that method runs.
struct XuParams {
    /// Neighbourhood: a disc of radius R = radiusFactor / sqrt(the exemplar's density) (so
    /// about pi radiusFactor^2 neighbours on average), split into `shells` rings of equal
    /// width and `sectors` equal sectors (the paper: 3 x 8 = 24 grids).
    double radiusFactor = 2.5;
    int shells = 3;
    int sectors = 8;
    /// Adjacency smoothing of the histogram distance, a_ij = exp(-d(i, j) / sigma) with
    /// d = |shell_i - shell_j| + circular |sector_i - sector_j| (the paper's sigma = 5; 0 =
    /// no smoothing, A the identity).
    double sigma = 5.0;
    /// Exemplar elements compared per extension: a random subset of this many of the
    /// exemplar's interior elements (0 = all of them).
    int candidates = 128;
    /// Of the candidates, this many with the smallest histogram distance are tried and the
    /// one whose copy conflicts least (minimum distance) with the elements placed wins; 1 =
    /// the paper's choice, the smallest distance alone.
    int verifyBest = 8;
    /// Density feedback in that choice: the drift |count placed so far + the copy - the
    /// exemplar's density x the area covered| beyond this many expected neighbourhoods (the
    /// exemplar's plants per neighbourhood disc) is added to the score, in neighbourhoods
    /// (0 = no feedback: the density is whatever the matching gives).
    double densityTolerance = 2.0;
    /// A copied element is refused closer than this x the exemplar's shortest
    /// nearest-neighbour distance to an element already placed.
    double minDistanceFactor = 1.0;
    /// The target is grown in square tiles of this side (m), each from its own centre with its
    /// own random stream, in parallel; elements of a later tile that conflict with an
    /// earlier tile's across the border are dropped. 0 = one tile (serial).
    double tileM = 0.0;

    /// ValidationError naming the field when one is out of range (xuParamFields).
    void validate() const;
    /// (key, value text) of every parameter, as recorded in scene files.
    std::vector<std::pair<std::string, std::string>> asParameters() const;
    /// The same, typed for the scene file's attributes (paramAttr).
    std::vector<h5::NamedAttr> asAttributes() const;
};
using XuParamField = ParamDesc<XuParams>;
/// Every parameter of XuParams, in record order (synth/synth_params.cpp).
const std::vector<XuParamField>& xuParamFields();

/// Every parameter of the sampler (recorded in the scene file; docs/synth.md).
struct SynthParams {
    SynthMethod method = SynthMethod::Structured;
    std::uint64_t seed = 1;
    /// Seeding kernel: full weight within this factor x crown radius (the simulator's
    /// seed_inner_radius_factor); it falls linearly to 0 at the database's seeding radius factor.
    double seedInnerRadiusFactor = 4.0;
    /// No undergrowth plant stands within this factor x crown radius of a canopy trunk.
    double trunkExclusionFactor = 0.1;
    /// Largest number of dart-throwing passes.
    int maxPasses = 16;
    /// Darts thrown per pass per plant a region still lacks (> 1 so that one pass usually
    /// fills a region; the surplus is dropped uniformly at random).
    double candidateOversample = 1.25;
    // Structured sampler: the cluster fields' scales are searched on a log grid in
    // [clusterSigmaMinM, clusterSigmaMaxM] (Thomas kernel standard deviation, m).
    double clusterSigmaMinM = 0.2;
    double clusterSigmaMaxM = 3.0;
    /// Species with fewer plants in a region than this get the region's pooled clustering
    /// instead of a fit to their own (noisy) g.
    int clusterMinPlants = 50;
    /// Structured sampler: each (region, species) meets its expected count in every square
    /// tile of this side (m) of the terrain, not only over the whole region; 0 = whole region.
    double quotaTileM = 60.0;
    /// Inhibition: g below this in the leading bins of a species pair ...
    double hardCoreG = 0.25;
    /// ... where a Poisson pattern would have had at least this many pairs per bin.
    double hardCoreMinExpectedPairs = 10;
    /// The Deussen sampler's own parameters (used and recorded with that method only).
    DeussenParams deussen;
    /// The Xu 2015 sampler's own parameters (used and recorded with that method only).
    XuParams xu;

    /// ValidationError naming the field when one is out of range (synthParamFields,
    /// deussenParamFields, xuParamFields).
    void validate() const;
    /// (key, value text) of every parameter, as recorded in scene files: the method, then
    /// synthParamFields() in order, then with the Deussen method deussenParamFields(), with
    /// the Xu 2015 method xuParamFields().
    std::vector<std::pair<std::string, std::string>> asParameters() const;
    /// The same, typed for the scene file's attributes (paramAttr).
    std::vector<h5::NamedAttr> asAttributes() const;
};

/// One parameter of SynthParams (core/param_desc.h): its key in scene files and
/// docs/synth.md's table, its doc line and its range.
using SynthParamField = ParamDesc<SynthParams>;
/// Every numeric parameter of SynthParams (all but the method), in record order: the one
/// description of them (synth/synth_params.cpp).
const std::vector<SynthParamField>& synthParamFields();

// ------------------------------------------------------------------------- cluster map

struct ClusterMap {
    Grid<std::int32_t> combination;  ///< sub-biome bitmask of the seeding trees, 0 = none
    Grid<std::int32_t> region;       ///< database region index, -1 = none
    Grid<float> seedWeight;          ///< dart rate weight w in [0, 1] (0 where no species may grow)
};

/// The cluster map of a target terrain. `features` gives the geometry. ValidationError when
/// the feature grids differ in geometry or the database and biome disagree.
ClusterMap computeClusterMap(const BiomeDatabase& db, const Biome& biome, const std::vector<Plant>& canopy,
                             const FactorGrids& features, const SynthParams& params);

// ------------------------------------------------------------------------- sampling

/// An exemplar stand for the Xu 2015 sampler: its undergrowth plants (species of the target's
/// biome, sizes in metres) and the rectangle they were observed in.
struct XuExemplar {
    std::vector<Plant> plants;
    RectWindow window;
    std::string source;  ///< file (and snapshot) it was read from, for messages
};

/// Elements of a pattern grown by synthesizeXuPattern.
struct XuPattern {
    std::vector<double> x, y;            ///< world metres
    std::vector<std::uint32_t> source;   ///< exemplar element copied (type, size)
    double radiusM = 0;                  ///< neighbourhood radius R
    double minDistanceM = 0;             ///< conflict distance
    std::int64_t interiorCandidates = 0; ///< exemplar elements whose R-disc lies inside its window
    std::int64_t extensions = 0;         ///< extensions run (elements and hole seeds)
    std::int64_t holeSeeds = 0;          ///< extensions from an empty spot (no frontier element left)
    std::int64_t conflicts = 0;          ///< copies refused by the minimum distance
    std::int64_t seamDrops = 0;          ///< elements dropped at tile borders
    int tiles = 1;
};

/// Outcome of one database region on the target terrain.
struct RegionSampling {
    int region = 0;
    std::int64_t cells = 0;            ///< cells of the target terrain in the region
    double areaM2 = 0;
    double targetDensityPerM2 = 0;     ///< from the database
    std::int64_t targetCount = 0;      ///< round(density x area)
    std::int64_t placed = 0;           ///< plants placed
};

/// The structured sampler's model of one region, fitted to the database (docs/synth.md):
/// g_s(r) = g_context,s(r) x (1 + sum_k a_sk^2 B_k exp(-r^2 / (4 sigma_k^2))), species
/// sharing the cluster parents of scale k (cross terms a_sk a_tk B_k).
struct RegionStructure {
    int region = 0;
    int scales = 0;                       ///< cluster fields used (0, 1 or 2)
    double sigmaM[2] = {0, 0};            ///< Thomas kernel standard deviation of field k, m
    double parentsPerM2[2] = {0, 0};      ///< kappa_k
    double pooledAmplitude[2] = {0, 0};   ///< fitted excess of pooled g at r = 0 from field k
    std::vector<double> attachment;       ///< [nSpecies][2] a_sk: share of species s's plants in field k's clusters
    double pooledFitRms = 0;              ///< RMS of the pooled g fit over the database bins
    double pooledContextRms = 0;          ///< RMS of the context-only model (no clusters), for comparison
    /// [nSpecies][nSpecies] hard-core distance (m) between two plants of species s and t: the
    /// upper edge of the leading distance bins where the database's g_st is below
    /// `hardCoreG` although at least `hardCoreMinExpectedPairs` pairs were expected there
    /// (0: no inhibition). Empty when no pair shows one.
    std::vector<double> hardCoreM;
};

struct UndergrowthSample {
    std::vector<Plant> plants;              ///< sorted by cell (row-major), then pass, then dart
    std::vector<std::int32_t> plantRegion;  ///< region of each plant
    std::vector<RegionSampling> regions;    ///< one per database region, in database order
    int passes = 0;                         ///< passes run
    std::int64_t darts = 0;                 ///< darts thrown
    std::int64_t dartsOnTrunks = 0;         ///< dropped: on a canopy trunk
    double seconds = 0;
    std::vector<RegionStructure> structure; ///< structured sampler: the model of each region
    std::int64_t heightsLimitedByCrown = 0; ///< structured: plants whose height draw was capped below a crown
    std::int64_t dartsInhibited = 0;        ///< structured: candidates dropped by a hard-core distance;
                                            ///< Deussen: half-toned dots dropped by a minimum distance
    /// Deussen: per species in placement order, the species index, its half-toning cell (m),
    /// the dots half-toned, and per Lloyd iteration the mean displacement (m) and the moves
    /// refused (minimum distance, leaving the species' area, or onto a trunk).
    struct DeussenSpecies {
        int species = 0;
        double halftoneCellM = 0;
        double minDistanceM = 0;
        std::int64_t dots = 0, dropped = 0;
        double clarkEvansBefore = 0, clarkEvansAfter = 0;  ///< R of the species' plants (no edge correction)
        std::vector<double> meanMoveM;
        std::vector<std::int64_t> refused;
    };
    std::vector<DeussenSpecies> deussen;
    /// Xu 2015: the grown pattern's record (positions left empty) and what was dropped.
    XuPattern xu;
    std::int64_t xuDroppedOutsideRegion = 0;  ///< no region, or the species impossible there (cluster map)
    std::int64_t xuDroppedOnTrunk = 0;        ///< inside a canopy trunk's exclusion disc
    std::vector<std::string> warnings;      ///< e.g. an old database read with its known limits
    /// structured: time of each phase (summed over the passes), in order, for the benchmark
    struct Phase {
        std::string name;
        double wallS = 0, cpuS = 0;  ///< wall and process CPU seconds
    };
    std::vector<Phase> phases;
};

/// The structured sampler's model of database region `region` (see RegionStructure).
RegionStructure fitRegionStructure(const BiomeDatabase& db, int region, const SynthParams& params);

/// Context part of g(r) of a region: for every database distance bin, the g an inhomogeneous
/// Poisson pattern with the region's per-context densities would have (species `species`,
/// or all undergrowth pooled when species < 0). 1 everywhere for a database without context.
std::vector<double> contextPcf(const BiomeDatabase& db, int region, int species);

/// Xu et al. 2015's vector-pattern synthesis over `target` from the marked exemplar pattern
/// (types 0..typeNames.size()-1) observed in `exemplarWindow` (docs/synth.md 2d). Types matter
/// through per-type histograms of equal weight. Bit-identical for a seed whatever the thread
/// count. ValidationError naming `what` when the exemplar has fewer than 2 elements, a point
/// outside its window, or no element whose neighbourhood disc lies inside the window.
XuPattern synthesizeXuPattern(const PointPattern& exemplar, const RectWindow& exemplarWindow, const RectWindow& target,
                              const XuParams& params, std::uint64_t seed, const std::string& what = "exemplar");

/// Undergrowth by params.method (see the top of this file). terrainM gives each plant's
/// ground elevation and must share the cluster map's geometry. `densityImage` (Deussen
/// method only; ValidationError with another) reshapes the database's density map:
/// relative density of the whole undergrowth per terrain cell, >= 0 (readDensityImage); the
/// undergrowth keeps the map's total over the terrain. `exemplar` is required by the Xu 2015
/// method and refused by the others (ValidationError).
UndergrowthSample sampleUndergrowth(const BiomeDatabase& db, const Biome& biome, const std::vector<Plant>& canopy,
                                    const ClusterMap& map, const Grid<float>& terrainM, const SynthParams& params,
                                    const Grid<float>* densityImage = nullptr, const XuExemplar* exemplar = nullptr);

/// A user's density image for the Deussen sampler: a greyscale image (PNG, TIFF, ...; colour
/// channels averaged, alpha ignored) of exactly the terrain's size in pixels, its first row
/// the northern edge, value = relative density (black none, white densest; a float image's
/// values as stored). Returned on `like`'s grid. IoError / ValidationError naming the file
/// for a missing or unreadable file, another size, a negative or non-finite value
/// (with its pixel) or an image that is 0 everywhere.
Grid<float> readDensityImage(const std::string& path, const Grid<float>& like);

/// Height and crown radius from one uniform u in [0, 1): the inverse CDFs (linear inside
/// bins) of the two histograms at u. A histogram without counts returns -1.
double histogramQuantile(const DbHistogram& h, double u);

// ------------------------------------------------------------------------- pair correlation

/// Pair sums of a scene per database region, the annulus estimator of core/point_pattern.h
/// with translation edge correction on each region's window (the union of its cells, as the
/// analyser uses): both plants in the region, canopy trees included as categories
/// (category = layer x nSpecies + species, as in the database).
struct ScenePairStats {
    DistanceBins bins;
    int nCategories = 0;
    struct Region {
        double areaM2 = 0;
        std::vector<std::int64_t> count;  ///< [category] plants in the region
        std::vector<double> weighted;     ///< [i][j][bin] sum of |W| / gamma(u) over ordered pairs (from sampled sources, scaled)
        double sourceFraction = 1;        ///< share of the undergrowth used as sources (1 = all; see below)
        double g(int i, int j, int k, const DistanceBins& b, int nCat) const;
    };
    std::vector<Region> regions;  ///< per database region
};

/// Pair sums of the plants inside `window` (all when null) per region of `regionMap`
/// (labels 0..nRegions-1). With maxSourcesPerRegion > 0, a region of n > max undergrowth
/// plants uses a random share f = max / n of them as sources (every plant is still a
/// target; canopy trees are always sources) and divides its sums by f: an unbiased estimate
/// of S at a cost bounded per region (the sample is a pure function of `seed` and the plant
/// indices). Parallel over fixed chunks; identical for any number of threads.
ScenePairStats scenePairStatistics(const std::vector<Plant>& canopy, const std::vector<Plant>& undergrowth,
                                   const Grid<std::int32_t>& regionMap, int nRegions, int nSpecies,
                                   const DistanceBins& bins, const RectWindow* window = nullptr,
                                   std::size_t maxSourcesPerRegion = 0, std::uint64_t seed = 1);

/// Distance between a scene's pair correlation and the database's:
///   D^2 = sum over regions k, unordered category pairs {i, j} with an undergrowth member,
///         present in the scene region and stored in the database region,
///         of omega_kij x mean over bins of (g_scene - g_database)^2,
/// omega = the pair's share of all such point pairs (n_i n_j, or n_i (n_i - 1) for i = j),
/// so D is an RMS difference of g weighted by how many pairs each function rests on.
struct PcfDistance {
    double overall = 0;
    std::vector<double> perRegion;    ///< same formula inside each region (0 without pairs)
    std::vector<double> pairWeight;   ///< per region: its share of the pairs
};
PcfDistance pcfDistance(const ScenePairStats& scene, const BiomeDatabase& db);

// ------------------------------------------------------------------------- refinement

struct RefineParams {
    int sweeps = 4;                 ///< proposals per plant
    double moveRadiusM = 1.0;       ///< displacement proposals: uniform in a disc of this radius
    double swapRadiusM = 4.0;       ///< swap proposals: a partner within this distance
    double swapProbability = 0.5;   ///< share of proposals that are swaps
    /// Pair correlation matched up to this distance (metres). 0 = automatic: the largest
    /// database bin edge within which a plant of the densest region has about
    /// `autoNeighbours` neighbours (the cost of a move grows with that number).
    double rMaxM = 0;
    double autoNeighbours = 400;
    /// Refine only the plants inside this window (world metres) when set; the statistics are
    /// then those of the regions' cells inside it, and plants outside stay as they are.
    bool useWindow = false;
    RectWindow window;
    /// Sources per region for the before / after distances (scenePairStatistics).
    std::size_t distanceSources = 20000;
    std::uint64_t seed = 1;

    /// ValidationError naming the field when one is out of range (refineParamFields).
    void validate() const;
    /// (key, value text) of every parameter, as recorded in scene files: refineParamFields()
    /// in order, then refine_window, refine_distance_sources and refine_seed.
    std::vector<std::pair<std::string, std::string>> asParameters() const;
    /// The same, typed for the scene file's attributes (paramAttr).
    std::vector<h5::NamedAttr> asAttributes() const;
};

/// One parameter of RefineParams, keyed as scene files record it (refine_sweeps ...).
using RefineParamField = ParamDesc<RefineParams>;
/// The numeric parameters of RefineParams that users set (not the window, the number of
/// distance sources or the seed), in record order (synth/synth_params.cpp).
const std::vector<RefineParamField>& refineParamFields();

struct RefineResult {
    double distanceBefore = 0;             ///< pcfDistance over all database bins (sampled sources)
    double distanceAfter = 0;
    /// The objective: pcfDistance over the bins matched, exact; before, then after each sweep.
    std::vector<double> objectivePerSweep;
    std::int64_t movable = 0;              ///< plants that could move (in a region, and in the window)
    std::int64_t proposals = 0;
    std::int64_t accepted = 0;
    double rMaxM = 0;                      ///< range matched
    double seconds = 0;
};

/// Progress: sweep done (1-based) of total.
using RefineProgress = std::function<void(int sweep, int sweeps)>;

/// Move undergrowth plants to lower the pair-correlation distance to the database (see the
/// top of this file). Plants keep species and size; positions and ground elevation change;
/// each plant stays in its region, off trunks and inside the terrain. Canopy immutable.
RefineResult refineUndergrowth(std::vector<Plant>& undergrowth, const std::vector<Plant>& canopy,
                               const ClusterMap& map, const Grid<float>& terrainM, const BiomeDatabase& db,
                               const SynthParams& synth, const RefineParams& params,
                               const RefineProgress& progress = {});

}  // namespace eco::synth
