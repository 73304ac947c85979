// eco sensitivity SPEC.toml (issue 28 item 3): global sensitivity of simulation outputs
// (species shares, density, mean height and cover at a year, the coefficient of variation of
// the plant count over a window, height quantiles of a snapshot) to the species' parameters
// and the model constants, by Morris elementary effects (a screening of many parameters) or
// Sobol indices (first-order and total, for a chosen few). The design's points run as members of an ensemble
// (pipeline/ensemble.h: in parallel, restartable, on MPI), each point with the same
// replicate seeds (common random numbers), so that the effects can be told from seed noise.
// docs/sensitivity.md describes the file, the method and the report.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "parameter_study.h"

namespace eco::pipeline {

struct SensitivitySpec {
    enum class Method { Morris, Sobol };
    /// Sobol: how the A and B samples are drawn (docs/sensitivity.md).
    enum class Sampling { Random, QuasiRandom };
    std::string path;
    std::string outDir;
    Method method = Method::Morris;
    int samples = 32;       ///< Sobol: N, the base sample size (N (k + 2) design points)
    int bootstrap = 1000;   ///< Sobol: bootstrap resamples of the 95 % intervals
    Sampling sampling = Sampling::Random;  ///< Sobol: `sampling`, "random" or "quasi-random"
    int trajectories = 10;  ///< r
    int levels = 4;         ///< p (even), the grid of each parameter's range
    int replicates = 2;     ///< seeds per design point (run.seed = 1 .. replicates)
    std::uint64_t seed = 1; ///< of the design
    int membersAtOnce = 1;
    std::vector<StudyParameter> parameters;
    std::vector<SimulationOutput> outputs;
    toml::table base;       ///< [sensitivity.base]: the members' eco run configuration
};

/// Reads and checks a specification (ValidationError naming the file and key).
SensitivitySpec loadSensitivitySpec(const std::string& path, const std::string& outOverride = "");

/// A Morris design in the unit cube: `trajectories` trajectories of k + 1 points on a grid of
/// `levels` levels; from each point to the next one parameter moves by delta = levels /
/// (2 (levels - 1)), up or down, each parameter once per trajectory, in a random order.
struct MorrisDesign {
    int parameters = 0, trajectories = 0, levels = 0;
    double delta = 0;
    /// points[t][j][i]: parameter i at point j of trajectory t, in [0, 1].
    std::vector<std::vector<std::vector<double>>> points;
    /// moved[t][j]: the parameter moved from point j to point j + 1 (j < k).
    std::vector<std::vector<int>> moved;
};
MorrisDesign morrisDesign(int parameters, int trajectories, int levels, std::uint64_t seed);

/// Morris statistics of one output for each parameter, the elementary effects EE = (y(x +
/// step e_i) - y(x)) / step in units of the output per whole range of the parameter.
struct MorrisStats {
    double mu = 0;      ///< mean EE
    double muStar = 0;  ///< mean |EE| (the ranking measure)
    double sigma = 0;   ///< standard deviation of EE (interaction or non-linearity)
    int effects = 0;
};
/// y[t][j]: the output at design point j of trajectory t.
std::vector<MorrisStats> morrisStatistics(const MorrisDesign& design, const std::vector<std::vector<double>>& y);

/// Seed noise of one output: the pooled standard deviation between replicates of a design
/// point, and the mu* that seed noise alone would give a parameter without effect: sqrt(2 /
/// pi) times the standard error of a step's mean difference (the differences taken replicate
/// by replicate, whose seeds are the same at both points), divided by the step.
struct SeedNoise {
    double replicateSd = 0;  ///< NaN with one replicate
    double muStarNoise = 0;  ///< NaN with one replicate
};
/// values[t][j][r]: the output of replicate r at point j of trajectory t.
SeedNoise seedNoise(const MorrisDesign& design, const std::vector<std::vector<std::vector<double>>>& values);

/// The member name of design point j of trajectory t, replicate r (1-based in the name).
std::string sensitivityMemberName(int t, int j, int r);

/// Writes OUT/ensemble.toml: one member per design point and replicate (the parameters'
/// values and run.seed), no database; returns its path. The design is written as
/// OUT/design.csv.
std::string writeSensitivityEnsemble(const SensitivitySpec& spec, const MorrisDesign& design);

struct SensitivityReport {
    std::string csvPath, markdownPath;
    std::vector<std::string> pngPaths;
    std::string summary;  ///< the ranking of each output, printed
};
/// Measures every member (OUT/ensemble/members/<name>/simulation.h5), computes the
/// statistics and writes OUT/sensitivity.csv, OUT/sensitivity.md and one picture per output
/// (OUT/png/morris_<n>.png: mu* against sigma, with the seed-noise level).
SensitivityReport writeSensitivityReport(const SensitivitySpec& spec, const MorrisDesign& design);

/// A Sobol design (Saltelli 2002, 2010): two samples A and B of N points in the unit cube,
/// and for each parameter i the matrix AB_i: A with column i taken from B. N (k + 2) points;
/// matrix 0 is A, 1 is B, 2 + i is AB_i.
///
/// Sampling::Random: A and B independent pseudo-random uniform, one stream per row (seeded).
/// Sampling::QuasiRandom (Saltelli 2002, 2010): row n of A is the first k coordinates and
/// row n of B the last k of point n + 1 of the 2k-dimensional Sobol' sequence
/// (pipeline/sobol_sequence.h; point 0, the origin, would give A = B); no seed, at most
/// SobolSequence::kMaxDimensions / 2 = 25 parameters. Both: a larger N begins with the same rows.
struct SobolDesign {
    int parameters = 0, samples = 0;
    SensitivitySpec::Sampling sampling = SensitivitySpec::Sampling::Random;
    std::vector<std::vector<double>> a, b;  ///< [n][i] in [0, 1)
    int matrices() const { return parameters + 2; }
    std::vector<double> point(int matrix, int row) const;
};
SobolDesign sobolDesign(int parameters, int samples, std::uint64_t seed,
                        SensitivitySpec::Sampling sampling = SensitivitySpec::Sampling::Random);
/// The design of a specification (its parameters, samples, seed and sampling).
SobolDesign sobolDesign(const SensitivitySpec& spec);

/// One parameter's indices with bootstrap 95 % intervals (percentiles of the resampled rows).
struct SobolIndex {
    double first = 0, firstLow = 0, firstHigh = 0;  ///< S_i (Saltelli 2010's estimator)
    double total = 0, totalLow = 0, totalHigh = 0;  ///< S_Ti (Jansen 1999's estimator)
};
struct SobolResult {
    std::vector<SobolIndex> indices;
    double mean = 0, variance = 0;  ///< of the output over A and B
};
/// fA[n], fB[n], fAB[i][n]: the output at the design's points. V = the variance of fA and fB
/// together; S_i = mean(fB (fAB_i - fA)) / V; S_Ti = mean((fA - fAB_i)^2) / (2 V). The
/// intervals from `bootstrap` resamples of the N rows (0: intervals = the estimates), drawn
/// with `seed`.
SobolResult sobolIndices(const std::vector<double>& fA, const std::vector<double>& fB, const std::vector<std::vector<double>>& fAB,
                         int bootstrap, std::uint64_t seed);

/// Seed noise of a Sobol design's output: values[m][n][r] (matrix, row, replicate).
struct SobolNoise {
    double replicateSd = 0;  ///< pooled sd between replicates of a point; NaN with one replicate
    /// The variance that seed noise adds to the replicates' mean from one point to another,
    /// as a share of the output's variance V (of those means): half the mean over rows and
    /// parameters of var_r(y_A - y_ABi) / R, over V (the replicates' seeds are the same at
    /// every point, so what the seeds share cancels). It is also the S_Ti that a parameter
    /// without effect would get from seed noise alone. NaN with one replicate.
    double varianceShare = 0;
};
SobolNoise sobolNoise(const std::vector<std::vector<std::vector<double>>>& values);

/// The member name of row n (0-based) of matrix m, replicate r: A-0001-r01, B-..., AB03-... .
std::string sobolMemberName(int matrix, int row, int r);

/// Writes OUT/ensemble.toml with one member per design point and replicate, and
/// OUT/design.csv; returns the ensemble's path.
std::string writeSobolEnsemble(const SensitivitySpec& spec, const SobolDesign& design);

/// Measures every member, computes the indices and writes OUT/sensitivity.csv,
/// OUT/sensitivity.md and OUT/png/sobol_<n>.png (bars of S_i and S_Ti with their intervals).
SensitivityReport writeSobolReport(const SensitivitySpec& spec, const SobolDesign& design);

}  // namespace eco::pipeline
