// eco sensitivity SPEC.toml (issue 28 item 3): global sensitivity of simulation outputs
// (species shares, density, mean height and cover at a year, the coefficient of variation of
// the plant count over a window) to the species' parameters and the model constants, by
// Morris elementary effects. The design's points run as members of an ensemble
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
    std::string path;
    std::string outDir;
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

}  // namespace eco::pipeline
