// What eco sensitivity and eco calibrate share (issue 28): parameters varied over a range
// (dotted keys of an ensemble's overrides), outputs measured from a simulation's time series,
// and the members of such a study written as an eco ensemble specification (so that they run
// in parallel, restartably, on MPI, and a finished simulation is never run twice).
#pragma once

#include <toml++/toml.h>

#include <string>
#include <vector>

namespace eco::pipeline {

/// A parameter varied over [low, high]: a dotted key of the ensemble's overrides
/// ("biome.species.Toyon.alpha", "model.seeding_probability").
struct StudyParameter {
    std::string key;
    double low = 0, high = 1;
    double at(double unit) const { return low + unit * (high - low); }  ///< unit in [0, 1]
};

/// Checks a parameter's key and range (ValidationError naming `where`).
StudyParameter makeStudyParameter(const std::string& key, double low, double high, const std::string& where);

/// An output measured from a member's simulation file (its /timeseries).
struct SimulationOutput {
    enum class Measure { Share, Density, MeanHeight, Cover, CountCv };
    std::string text;      ///< as written: "share:Toyon@30", "density@30", "cv@20-30"
    Measure measure = Measure::Density;
    std::string species;   ///< share (required), mean_height and cover (optional: all undergrowth)
    int year = 0;          ///< the year; for cv the first year of the window
    int yearEnd = 0;       ///< cv: the last year of the window
    std::string units() const;
};

/// Parses "MEASURE[:SPECIES]@YEAR" or "cv@FIRST-LAST". ValidationError naming `where`.
SimulationOutput parseSimulationOutput(const std::string& text, const std::string& where);

/// The output measured from a simulation file. ValidationError naming the file when the
/// year is not in its time series or the species not in its biome.
double measureOutput(const std::string& simulationPath, const SimulationOutput& output);

/// One simulation of a study: its name (a folder name), the parameters' values (in the
/// order of the study's parameters) and its run.seed.
struct StudyMember {
    std::string name;
    std::vector<double> values;
    int seed = 1;
};

/// Writes OUT/ensemble.toml (atomically, unless it already holds the same text): the
/// members with their parameter values and run.seed over the eco run configuration `base`,
/// in OUT/ensemble, without a database. `comment` heads the file. Returns its path.
std::string writeStudyEnsemble(const std::string& outDir, const toml::table& base, int membersAtOnce,
                               const std::vector<StudyParameter>& parameters, const std::vector<StudyMember>& members,
                               const std::string& comment);

/// OUT/ensemble/members/NAME/simulation.h5.
std::string studySimulation(const std::string& outDir, const std::string& member);

/// [X.base]: an eco run configuration as a table, or the name of its file.
toml::table studyBase(const toml::node& node, const std::string& specPath, const std::string& where);

}  // namespace eco::pipeline
