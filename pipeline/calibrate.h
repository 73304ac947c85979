// eco calibrate SPEC.toml (issue 28 item 4): fits chosen parameters (species parameters of
// the biome, model constants) within bounds to target observations (species shares, density,
// mean heights, cover at a year; the cv of the plant count over a window), each with its
// uncertainty: minimises chi2 = sum over targets of ((simulated - observed) / sd)^2, the
// simulated value the mean over replicate seeds (the same seeds at every evaluation), with a
// derivative-free optimiser of NLopt (Debian's libnlopt). Every evaluation's simulations are
// members of one ensemble (pipeline/ensemble.h): run in parallel, never twice, and a killed
// calibration run again replays the optimiser over the finished simulations to where it
// stopped. Writes the best biome and simulation configuration, the history of evaluations,
// the fit against each target and a linearised estimate of the parameters' uncertainty.
// docs/calibration.md describes the file and the outputs.
#pragma once

#include <toml++/toml.h>

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "parameter_study.h"
#include "reporter.h"

namespace eco::pipeline {

struct CalibrationTarget {
    SimulationOutput output;
    double value = 0;  ///< observed (or the bound of a one-sided target)
    double sd = 1;     ///< its uncertainty: the residual's scale
    /// Two-sided (`value`), or one-sided (`min` / `max`): no residual on the bound's good side.
    enum class Side { Both, AtLeast, AtMost };
    Side side = Side::Both;
    /// (simulated - value) / sd; 0 for a one-sided target on its good side.
    double residual(double simulated) const;
};

/// [calibrate.scene]: the members simulate eco validate's forest scene (a scene file of
/// configs/validation) instead of running eco run pipelines. Each replicate has its own
/// scene seed (the scene's terrain, canopy and simulation seed, as `eco validate` uses it).
struct CalibrationScene {
    std::string file;                 ///< the forest scene file (scene_*.toml)
    std::string biome;                ///< the base biome file ("" = the embedded Sonoma biome)
    double plotSizeM = 0;             ///< the plot's side
    int years = 0;
    std::vector<std::uint64_t> seeds; ///< one per replicate
    std::vector<std::string> model;   ///< "KEY = VALUE" lines over the scene's [model] (as eco validate --model)
};

/// One simulation of the scene: write `dir`/simulation.h5 with the biome file `biomePath`,
/// the scene's [model] with `model` lines over it, the scene seed `seed`.
struct SceneMember {
    std::string dir;
    std::string biomePath;
    std::vector<std::string> model;
    std::uint64_t seed = 1;
};
/// Runs scene members (apps: the forest scene lives in validate, above the pipeline).
using SceneRunner = std::function<void(const CalibrationScene& scene, const std::vector<SceneMember>& members)>;

struct CalibrationSpec {
    std::string path;
    std::string outDir;
    std::string algorithm = "sbplx";  ///< sbplx, neldermead, bobyqa, cobyla (NLopt's LN_ local methods)
    int maxEvaluations = 40;
    int replicates = 2;
    double tolerance = 1e-3;     ///< relative change of the parameters (in their ranges) that stops
    double initialStep = 0.25;   ///< first step of the optimiser, as a fraction of each range
    bool uncertainty = true;     ///< k more evaluations at the optimum (finite differences)
    /// Global search (docs/calibration.md): "none" (the local `algorithm` from `start`),
    /// "multistart" (the local algorithm from `starts` points: `start`, then quasi-random
    /// points shifted by `seed`), "crs2" or "isres" (NLopt's GN_CRS2_LM or GN_ISRES, seeded
    /// with `seed`, for `global_evaluations`, then the local algorithm from their best).
    std::string global = "none";
    int starts = 4;              ///< multistart: local searches
    /// multistart: the starts search side by side, in rounds: one evaluation of every start
    /// still searching per round, the round's simulations run together (members_at_once
    /// children or MPI ranks share them); each start gets max_evaluations / starts.
    bool parallelStarts = false;
    int globalEvaluations = 0;   ///< crs, crs2, isres: evaluations of the global phase (0: half of max_evaluations)
    /// crs (our controlled random search in rounds, docs/calibration.md): the population's
    /// size (0: 10 (k + 1)) and the trial points of a round (0: k + 1), each round's points
    /// evaluated together (members_at_once children or MPI ranks share their simulations).
    int population = 0;
    int batchSize = 0;
    std::uint64_t seed = 1;      ///< multistart, crs, crs2, isres
    int membersAtOnce = 1;
    std::vector<StudyParameter> parameters;  ///< sorted by key, or as written (parameters_as_written = true)
    std::vector<double> start;   ///< starting values (default: the middle of each range)
    std::vector<CalibrationTarget> targets;
    toml::table base;            ///< [calibrate.base] (not with a scene)
    CalibrationScene scene;      ///< [calibrate.scene]: scene.file empty without one
    /// [calibrate.truth]: known values of every parameter. When given, the targets' values
    /// are replaced by the outputs of simulations at these values with other seeds (1001 ..
    /// 1000 + replicates), so that the calibration shows whether it recovers them.
    std::vector<double> truth;
};

/// Reads and checks a specification (ValidationError naming the file and key).
CalibrationSpec loadCalibrationSpec(const std::string& path, const std::string& outOverride = "");

struct Evaluation {
    int index = 0;                 ///< 1-based
    std::string purpose;           ///< "search" or "uncertainty"
    std::vector<double> values;    ///< the parameters
    std::vector<double> simulated; ///< per target: mean over the replicates
    std::vector<double> spread;    ///< per target: standard deviation over the replicates (0 for one)
    double chi2 = 0;
};

/// One run of an optimiser: a local search from one start, or a global phase.
struct SearchRun {
    std::string method;          ///< e.g. "sbplx", "crs2"
    std::vector<double> start;   ///< in the unit cube
    std::vector<double> best;    ///< in the unit cube
    double value = 0;
    int evaluations = 0;         ///< calls of the objective (a repeated point counts again)
    std::string stopReason;
    bool converged = false;      ///< stopped by the tolerance (not the budget)
};
struct SearchResult {
    std::vector<double> best;    ///< in the unit cube
    double value = 0;
    std::vector<SearchRun> runs;
    std::size_t bestRun = 0;
    int evaluations = 0;
    std::string stopReason;      ///< of the run that found the best (with its index when several)
    bool converged = false;      ///< the run that found the best stopped by the tolerance
};

struct CalibrationResult {
    std::vector<Evaluation> history;
    std::size_t best = 0;               ///< index into history
    std::string stopReason;
    bool converged = false;             ///< the best's search stopped by the tolerance
    std::vector<SearchRun> runs;        ///< the search's runs (one without a global search)
    /// Linearised standard deviation of each parameter at the optimum (NaN when not
    /// estimated or not identifiable from the targets).
    std::vector<double> parameterSd;
    std::string bestBiome, bestSimulation;  ///< written files ("" when no key of that kind)
    std::string reportPath, historyPath;
    std::vector<double> targetValues;  ///< the values fitted (from the truth when given)
    bool writer = true;                ///< this process wrote the outputs (false on MPI ranks other than 0)
};

/// Runs a set of members: writes nothing itself; given the ensemble specification's path it
/// runs the members not yet done (eco ensemble's runner: this process, its children or MPI
/// ranks) and returns when all are done (throws when one failed). Returns whether this
/// process writes the calibration's outputs: under MPI every rank runs the same (determin-
/// istic) search and shares each run's members, and rank 0 alone writes the report and
/// the history; true in a single process.
using MemberRunner = std::function<bool(const std::string& ensembleSpecPath)>;

/// How the optimiser searches the unit cube of the ranges (the search part of a
/// CalibrationSpec).
struct SearchSettings {
    std::string algorithm = "sbplx";
    std::string global = "none";
    int starts = 4;
    bool parallelStarts = false;  ///< multistart: the starts in rounds (minimiseInUnitCube's batch objective), max_evaluations / starts each
    int globalEvaluations = 0;
    int population = 0;        ///< crs: points of the population (0: 10 (k + 1))
    int batchSize = 0;         ///< crs: trial points per round (0: k + 1)
    std::uint64_t seed = 1;
    int maxEvaluations = 40;   ///< of the whole search (every start, both phases; multistart: an equal share of what is left per start)
    double tolerance = 1e-3;
    double initialStep = 0.25;
};
SearchSettings searchSettingsOf(const CalibrationSpec& spec);

/// The starts of a multistart in the unit cube: `first`, then points 1, 2, ... of the k-
/// dimensional Sobol' sequence (pipeline/sobol_sequence.h) shifted modulo 1 by a uniform
/// vector drawn with `seed` (a Cranley-Patterson rotation: another seed, other starts spread
/// as evenly). k <= SobolSequence::kMaxDimensions.
std::vector<std::vector<double>> multistartPoints(int k, int starts, const std::vector<double>& first, std::uint64_t seed);

/// Values of the objective at several points at once (in the order given).
using BatchObjective = std::function<std::vector<double>(const std::vector<std::vector<double>>&)>;

/// The population sizes of global = "crs" for k parameters: settings.population and
/// settings.batchSize, or their defaults 10 (k + 1) and k + 1.
int crsPopulation(const SearchSettings& settings, int k);
int crsBatchSize(const SearchSettings& settings, int k);

/// Minimises f over the unit cube [0, 1]^k from `start` as `settings` say. Deterministic: the
/// same points in the same order for the same settings (NLopt's generator seeded with
/// settings.seed before each global phase). An exception thrown by f stops the search and is
/// rethrown.
///
/// With a multistart whose settings.parallelStarts is set, the starts' local searches run
/// side by side in rounds through `batch` (f when it is empty, one point after the other):
/// round n holds the n-th point of every start still searching, in the order of the starts,
/// so the rounds depend on the settings alone; each start gets maxEvaluations / starts, and
/// its points are those of the same local search run alone.
///
/// With global = "crs" (a controlled random search of our own, in rounds: Price 1983's CRS2
/// reflection, alternating with Kaelo and Ali 2006's local mutation around the best) the
/// population's first points (the start, then multistartPoints) form the first round, then
/// every round holds settings.batchSize trial points drawn from the population as it stood
/// at the round's start; each trial that beats the population's worst replaces it, in the
/// order of the round. The rounds go to `batch` and depend on the settings alone (not on how
/// `batch` runs them); the global phase stops when every coordinate of the population lies
/// within settings.tolerance of the best's, or after globalEvaluations, and the local
/// `algorithm` polishes the best with the rest of maxEvaluations.
SearchResult minimiseInUnitCube(const std::function<double(const std::vector<double>&)>& f, const std::vector<double>& start,
                                const SearchSettings& settings, const BatchObjective& batch = {});

/// The member name of replicate r (0-based) of evaluation e (1-based).
std::string calibrationMemberName(int evaluation, int replicate);

/// chi2 of simulated values against the targets.
double chiSquare(const std::vector<CalibrationTarget>& targets, const std::vector<double>& simulated);

/// Linearised parameter covariance from the Jacobian of the normalised residuals (rows:
/// targets, columns: parameters, d residual / d parameter in the parameters' units):
/// (J^T J)^-1; NaN for the parameters the targets cannot tell apart (rank-deficient J).
std::vector<double> linearisedSd(const std::vector<std::vector<double>>& jacobian);

/// The whole calibration (the truth's simulations when given, search, uncertainty, outputs),
/// running members through `run`, one line per evaluation through `reporter`.
/// With spec.scene, the members run through `scene` (required then) instead of `run`.
CalibrationResult calibrate(const CalibrationSpec& spec, const MemberRunner& run, Reporter& reporter, const SceneRunner& scene = {});

}  // namespace eco::pipeline
