// What eco sensitivity and eco calibrate share (issue 28): parameters varied over a range
// (dotted keys of an ensemble's overrides), outputs measured from a simulation's time series,
// and the members of such a study written as an eco ensemble specification (so that they run
// in parallel, restartably, on MPI, and a finished simulation is never run twice).
#pragma once

#include <toml++/toml.h>

#include <memory>
#include <string>
#include <vector>

#include "point_pattern.h"

namespace eco::pipeline {

/// A parameter varied over [low, high]: a dotted key of the ensemble's overrides
/// ("biome.species.Toyon.alpha", "model.seeding_probability"). The designs and the
/// optimiser work in the unit interval; `at` maps it to the parameter's values: linearly, or
/// uniformly in log(value) (`logScale`: a probability over decades), and for an integer
/// parameter onto the whole numbers low .. high, each an equal share of the interval (of
/// its log with `logScale`: [n, n + 1) in log space).
struct StudyParameter {
    std::string key;
    double low = 0, high = 1;
    bool logScale = false;  ///< uniform in log(value); low > 0
    bool integer = false;   ///< whole numbers; written as TOML integers
    double at(double unit) const;      ///< unit in [0, 1]
    double unitOf(double value) const; ///< the inverse of `at` (an integer: the middle of its share)
    std::string describe() const;      ///< "0.001 .. 0.1 (log)", "1 .. 8 (integer)"
};

/// Checks a parameter's key and range (ValidationError naming `where`).
StudyParameter makeStudyParameter(const std::string& key, double low, double high, const std::string& where,
                                  bool logScale = false, bool integer = false);

/// Parses a parameter of [X.parameters]: "KEY" = [LOW, HIGH] or { low = , high = , scale =
/// "linear" | "log", integer = true | false } (and start = , when `start` is given: NaN
/// when absent). ValidationError naming the file, `table` and the key.
StudyParameter parseStudyParameter(const std::string& key, const toml::node& value, const std::string& path, const std::string& table,
                                   double* start = nullptr);

/// A field stem map's pair correlation g(r), as `eco pcf` estimates it (core/point_pattern.h:
/// translation edge correction, all the map's points or one species as one pattern), over the
/// distance bins from rMinM to the bins' rMaxM; the simulated plants' g(r) is compared with it.
struct PairCorrelationReference {
    std::string stemMap;   ///< the CSV (x, y and optionally species)
    RectWindow window;     ///< the map's window
    DistanceBins bins;
    double rMinM = 0;      ///< bins whose lower edge lies below this are left out
    double minHeightM = 0; ///< simulated plants lower than this are left out (a census's size limit)
    std::vector<double> observed;  ///< g of each bin
    std::size_t points = 0;        ///< of the map in the window (and species)
};

/// Reads the stem map and computes its g(r) (ValidationError naming the file when it has
/// fewer than 2 points of the species in the window, or r_max exceeds half the window's
/// shorter side).
PairCorrelationReference pairCorrelationReference(const std::string& stemMap, const RectWindow& window, const std::string& species,
                                                  double rMaxM, int bins, double rMinM, double minHeightM);

/// The root mean square over the used bins of g_simulated - g_observed.
double pairCorrelationDistance(const PairCorrelationReference& ref, const std::vector<double>& simulatedG);

/// g(r) of plants (x, y) in a window over the reference's bins (eco pcf's estimator); 0 in
/// every bin for fewer than 2 plants.
std::vector<double> pairCorrelation(const std::vector<double>& x, const std::vector<double>& y, const RectWindow& window, const DistanceBins& bins);

/// An output measured from a member's simulation file (its /timeseries, or a snapshot).
struct SimulationOutput {
    enum class Measure { Share, Density, MeanHeight, Cover, CountCv, HeightQuantile, PairCorrelation, CountRatio };
    std::string text;      ///< as written: "share:Toyon@30", "density@30", "cv@20-30"
    Measure measure = Measure::Density;
    std::string species;   ///< share (required), mean_height, cover and height_qNN (optional: all undergrowth)
    double quantile = 0.5; ///< height_qNN: NN / 100
    /// pcf[:SPECIES]@YEAR (eco calibrate's stem-map targets): the reference g(r); the
    /// output is the rms difference of the snapshot's g(r) from it.
    std::shared_ptr<const PairCorrelationReference> pcf;
    int year = 0;          ///< the year; for cv and a share's window the first year; for ratio the numerator's year
    int yearEnd = 0;       ///< cv, share: the last year of the window (share: = year for one year); ratio: the denominator's year
    std::string units() const;
};

/// Parses "MEASURE[:SPECIES]@YEAR" or "cv@FIRST-LAST"; share:SPECIES@FIRST-LAST is the mean of
/// the species' yearly shares over the window (eco validate's succession "final share"), and
/// ratio:SPECIES@YEAR/OTHER the species' plant count at YEAR over its count at OTHER (a count
/// of 0 at OTHER counts as 1). height_qNN[:SPECIES]@YEAR (NN in 1 ..
/// 99) is the NN % quantile of the undergrowth plants' heights in the snapshot of that year
/// (the simulation must keep one: its snapshot_years). ValidationError naming `where`.
SimulationOutput parseSimulationOutput(const std::string& text, const std::string& where);

/// The output measured from a simulation file. ValidationError naming the file when the
/// year is not in its time series or the species not in its biome.
double measureOutput(const std::string& simulationPath, const SimulationOutput& output);

/// The q quantile (0 .. 1) of the values, interpolated linearly between the sorted values
/// (Hyndman and Fan's type 7, R's default); 0 for none.
double heightQuantile(std::vector<double> values, double q);

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
