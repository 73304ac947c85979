// Parameters and run configuration of the undergrowth simulator (SPEC §5, paper §6.1).
//
// SimParams holds every model constant of the simulation that is not a species property
// (species properties live in the biome). It is read from the [model] table of a run
// configuration, validated, and written into every output (HDF5 attributes, checkpoints).
// RunConfig is the whole run configuration file (configs/sim-*.toml): inputs, run settings,
// outputs and model parameters. Parsing is strict: an unknown key is an error naming the
// file and the key. docs/simulator.md describes every key.
#pragma once

#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "disturbance.h"
#include "h5io.h"
#include "param_desc.h"

namespace eco::sim {

/// Which simulator model runs ([model] kind).
enum class ModelKind {
    /// The monthly undergrowth model of the paper (§6.1; this file's other parameters).
    Monthly,
    /// Zamuda & Brest's EcoMod: yearly agents, competitive ability, under-dispersion seeding,
    /// polyline growth, domination (sim/ecomod.h, docs/ecomod.md; species parameters in the biome).
    EcoMod,
};

/// How carbon-pool overflow becomes growth age ([model] growth_rule).
enum class GrowthRule {
    /// Overflow normalised so that a plant at its species' maximum vigour through the whole
    /// growth period gains exactly 12 months of growth age per year (docs/simulator.md).
    Ideal,
    /// The paper's literal rule: growth age += 1 month x overflow, in the growth period only.
    Literal,
};

/// How undergrowth plants compete ([model] competition).
enum class CompetitionMode {
    /// Per-cell sharing of sunlight and moisture among the occupants (paper §6.1, default).
    Resources,
    /// Deussen et al. 1998: vigour on the unshared resources, then every pair of plants whose
    /// crown circles intersect is compared; the weaker may die (docs/simulator.md).
    Deussen,
};

/// Which cells are tested for germination each year ([model] germination_cells; issue 28
/// item 2: the paper's "each grid cell is tested" against our reading).
enum class GerminationCells {
    /// Only cells no undergrowth crown covers at germination time (our reading, default).
    Uncovered,
    /// Every seeded cell, covered or not (the paper's wording).
    Every,
};

/// What "the species vigour averaged over the previous growing season based on the
/// unexploited resources" averages ([model] germination_vigour).
enum class GerminationVigour {
    /// Eq. 1 on the season's mean leftover sun and water (default: one evaluation per species).
    MeanResources,
    /// The mean over the season's months of Eq. 1 on each month's leftovers.
    MeanVigour,
};

/// Where undergrowth dies at the canopy ([model] canopy_limit): "we summarily kill off any
/// undergrowth that reaches canopy height".
enum class CanopyLimit {
    /// The CHM at the root, or canopy_threshold_m where the CHM is lower (default: a sapling
    /// in a gap dies at 3 m).
    ChmOrThreshold,
    /// Only under the canopy: the CHM where it is at least canopy_threshold_m (the paper's
    /// forest footprint); in gaps no limit below the species' own maximum height.
    CanopyOnly,
};

/// TOML spelling of the enums ("ideal", "literal", "resources", "deussen", ...).
const char* modelKindName(ModelKind k);
const char* growthRuleName(GrowthRule r);
const char* competitionModeName(CompetitionMode m);
const char* germinationCellsName(GerminationCells g);
const char* germinationVigourName(GerminationVigour g);
const char* canopyLimitName(CanopyLimit c);
/// Every ModelKind's spelling, in declaration order ("monthly", "ecomod"): the choices of --model.
std::vector<std::string> modelKindNames();
/// Parse those spellings; ValidationError naming `what` and the accepted values otherwise.
GrowthRule parseGrowthRule(const std::string& text, const std::string& what);
CompetitionMode parseCompetitionMode(const std::string& text, const std::string& what);
ModelKind parseModelKind(const std::string& text, const std::string& what);
GerminationCells parseGerminationCells(const std::string& text, const std::string& what);
GerminationVigour parseGerminationVigour(const std::string& text, const std::string& what);
CanopyLimit parseCanopyLimit(const std::string& text, const std::string& what);

/// Model constants of the simulation (units in the names). Defaults are the paper's values.
struct SimParams {
    /// The model (see ModelKind). Written into outputs and fingerprints only when not the
    /// default, so that monthly runs keep their bytes.
    ModelKind kind = ModelKind::Monthly;
    /// Edge of a square simulation cell, metres (paper: 20 cm).
    double cellSizeM = 0.2;
    /// Water each occupant (canopy tree first, then undergrowth by height) takes from a cell
    /// before the remainder is shared, mm per month per cell (reference implementation: 4).
    double minWaterDemandMm = 4.0;
    /// gamma: yearly germination probability added by a canopy tree inside the inner radius.
    double seedingProbability = 0.003;
    /// Seeding kernel: constant gamma within innerFactor * r of a canopy tree of crown radius r ...
    double seedInnerRadiusFactor = 4.0;
    /// ... falling linearly to zero at outerFactor * r.
    double seedOuterRadiusFactor = 12.0;
    /// beta of the germination roulette weight max(0, vbar_s / maxAge_s^beta).
    double rouletteAgeExponent = 1.2;
    /// P_s: expected fraction of a cohort surviving background mortality to its max age.
    double survivalAtMaxAge = 0.01;
    /// Carbon pool capacity in months of maximum stress: capacity_s = this * alpha_s * a, where
    /// -alpha_s * a is the most negative vigour of Eq. 1 (g's minimum is -a).
    double poolCapacityStressMonths = 3.0;
    /// Undergrowth dies on reaching the canopy height at its root: the CHM there, or this
    /// height where the CHM is lower (gaps, open ground). Metres.
    double canopyThresholdM = 3.0;
    /// Month (0 = January) at whose end the yearly germination happens; the leftover
    /// resources of the twelve months up to it form "the previous growing season".
    int seedingMonth = 7;
    /// Growth age of a new seedling, months: its height is h_s(this) (Eq. 3).
    double seedlingGrowthAgeMonths = 1.0;
    /// Months of growth age gained per unit of carbon-pool overflow (paper: dt * o with dt
    /// one month, so 1).
    double growthMonthsPerOverflow = 1.0;
    /// Overflow-to-growth rule (see GrowthRule).
    GrowthRule growthRule = GrowthRule::Ideal;
    /// Competition model (see CompetitionMode).
    CompetitionMode competition = CompetitionMode::Resources;
    /// Deussen mode: probability that a dominated plant survives one comparison round.
    double deussenDominatedSurvival = 0.5;
    /// Readings of the paper (see the enums): our defaults, or the paper's wording.
    GerminationCells germinationCells = GerminationCells::Uncovered;
    GerminationVigour germinationVigour = GerminationVigour::MeanResources;
    CanopyLimit canopyLimit = CanopyLimit::ChmOrThreshold;

    /// Throws ValidationError naming `source` and the key of the first bad value.
    void validate(const std::string& source = "SimParams") const;
    /// TOML text of a [model] table with every field (for records and configs).
    std::string toToml() const;
    /// (key, value) pairs in the order of toToml(), values as doubles (for HDF5 attributes).
    std::vector<std::pair<std::string, double>> namedValues() const;
    /// The same parameters typed for HDF5 attributes: reals as double, integer fields as
    /// int64, the choices (growth_rule, competition, ...) as enums of their names.
    std::vector<h5::NamedAttr> typedValues() const;
};

/// The one description of SimParams' numeric [model] keys (core/param_desc.h), in the order
/// of toToml(): reading the [model] table, writing it, the HDF5 attributes (namedValues),
/// validation and docs/simulator.md's table (tested) all go through it. growth_rule and
/// competition are enums, read and written beside it.
const std::vector<ParamDesc<SimParams>>& simParamFields();

/// Rectangle in world metres (x east, y north): [x0, x1) x [y0, y1).
struct SimArea {
    double x0 = 0, y0 = 0, x1 = 0, y1 = 0;
};

/// A run configuration file: everything `eco simulate` needs.
struct RunConfig {
    std::string sourcePath;     ///< file it was read from ("" when built in code)
    // [inputs]
    std::string terrainPath;    ///< optional: terrain (elevation) file; "" = elevation of the abiotics file
    std::string abioticsPath;   ///< abiotics.h5 (readAbiotics), without canopy shade
    std::string canopyPath;     ///< canopy.h5: /canopy plant group and /chm/height
    std::string biomePath;      ///< biome TOML; "" = the embedded Sonoma biome
    std::string initialPath;    ///< optional initial undergrowth: CSV, or HDF5 "file.h5[:/group]"
    // [run]
    int years = 10;
    std::uint64_t seed = 1;
    std::optional<SimArea> crop;        ///< sub-area to simulate; none = the whole abiotics extent
    std::vector<int> snapshotYears;     ///< years (0 = initial state) to snapshot; the last year is always added, years beyond it skipped
    int checkpointEveryYears = 0;       ///< 0 = no checkpoints
    // [outputs]
    std::string outputPath = "simulation.h5";
    std::string csvPath;        ///< "" = no CSV
    std::string pngDir;         ///< "" = no PNGs
    std::string checkpointPath; ///< "" = outputPath + ".checkpoint.h5"
    // [model]
    SimParams params;
    // [disturbance.fire], [disturbance.storm] (docs/disturbance.md; off without them)
    DisturbanceSettings disturbance;

    /// Checkpoint file actually used.
    std::string effectiveCheckpointPath() const;
    /// Throws ValidationError for inconsistent settings (years < 1, bad crop, ...).
    void validate() const;
};

/// Read a run configuration (strict). IoError when unreadable or not TOML; ValidationError
/// naming the file, the line and the key for an unknown key, a wrong type or a bad value.
/// The paths of [inputs] and [outputs] are relative to the directory of `path`
/// (pathRelativeToConfig; docs/simulator.md).
/// The configurations built into eco (embeddedRunConfigNames) are read without a file:
/// `path` "embedded:sim-default.toml" names one; a `path` that does not exist but whose file
/// name is that of an embedded one ("configs/sim-default.toml" copied away with demo.toml)
/// reads the embedded copy too, and `note` gets a line saying so. An embedded configuration's
/// own relative paths are relative to the working directory; its source is recorded as
/// "embedded:NAME".
RunConfig loadRunConfig(const std::string& path, const std::function<void(const std::string&)>& note = {});

/// The prefix that names a built-in configuration: "embedded:".
inline constexpr const char* kEmbeddedConfigPrefix = "embedded:";
/// The file names of the configurations built into eco: {"sim-default.toml"}.
const std::vector<std::string>& embeddedRunConfigNames();
/// True for "embedded:NAME" (any NAME: loadRunConfig refuses an unknown one, listing the names).
bool namesEmbeddedConfig(const std::string& path);
/// The text of the built-in configuration "embedded:NAME"; IoError listing the built-in
/// names for another NAME.
std::string embeddedRunConfigToml(const std::string& path);
/// Same from TOML text; `sourceName` is used in messages. `filePath`: the file the text came
/// from, whose directory relative paths are resolved against ("" = left as written).
RunConfig parseRunConfig(const std::string& tomlText, const std::string& sourceName, const std::string& filePath = "");

/// configs/sim-default.toml as built into this eco (the demo's simulation configuration).
const char* embeddedDefaultRunConfigToml();
/// Every key of a run configuration with its default, as TOML that loadRunConfig reads: the
/// built-in configs/sim-default.toml ([inputs], [run], [outputs] and their comments) with its
/// [model] table replaced by SimParams{}.toToml() (every model constant, from
/// simParamFields, and the enum choices). `eco config defaults simulate`.
std::string defaultRunConfigToml();

/// The path-valued keys of a run configuration file ({table, key}), for absolutizeConfigPaths.
const std::vector<std::pair<std::string, std::string>>& runConfigPathKeys();

/// Parse "x0,y0,x1,y1" (metres); ValidationError naming `what` otherwise.
SimArea parseArea(const std::string& text, const std::string& what);
/// Parse "10,20,50" into years; ValidationError naming `what` otherwise.
std::vector<int> parseYearList(const std::string& text, const std::string& what);

}  // namespace eco::sim
