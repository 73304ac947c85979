// Private to validate/: what the scenario kinds share. The context of a suite run (options,
// biome, the forest scene's runs, shared between scenarios and simulated once each), and the
// small measures and number formats the kinds use. Not installed; include only from
// validate/*.cpp and validate/scenarios/*.cpp.
#pragma once

#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <limits>
#include <map>
#include <memory>
#include <numeric>
#include <set>
#include <string>
#include <vector>

#include "biome.h"
#include "grid.h"
#include "plants.h"
#include "scenario.h"
#include "simulator.h"
#include "text_format.h"
#include "validate.h"

namespace eco::validate {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kPi = 3.14159265358979323846;

using Clock = std::chrono::steady_clock;
inline double secondsSince(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

/// A number for the report: `precision` significant digits, "n/a" for NaN.
inline std::string num(double v, int precision = 4) { return std::isnan(v) ? "n/a" : formatNumber(v, precision); }

/// A number with `decimals` decimals, "n/a" for NaN.
inline std::string fixed(double v, int decimals) {
    if (std::isnan(v)) return "n/a";
    char buf[64];
    std::snprintf(buf, sizeof buf, "%.*f", decimals, v);
    return buf;
}

/// Arithmetic mean; NaN when empty.
inline double mean(const std::vector<double>& v) {
    if (v.empty()) return kNaN;
    return std::accumulate(v.begin(), v.end(), 0.0) / static_cast<double>(v.size());
}

/// Coefficient of variation (population standard deviation over the mean).
inline double coefficientOfVariation(const std::vector<double>& v) {
    const double m = mean(v);
    if (!(m > 0)) return kNaN;
    double ss = 0;
    for (double x : v) ss += (x - m) * (x - m);
    return std::sqrt(ss / static_cast<double>(v.size())) / m;
}

/// The result of check `id` of scenario sc (its [checks.ID] bound applied to value). For a
/// check with a quick bound (CheckSpec::hasQuickBound) use the overload with the mode.
CheckResult makeCheck(const ScenarioConfig& sc, const std::string& id, const std::string& title, double value,
                      const std::string& note = "");
/// The same in mode m: the check's quick bound applies in a quick run when it has one.
CheckResult makeCheck(const ScenarioConfig& sc, Mode m, const std::string& id, const std::string& title, double value,
                      const std::string& note = "");

// ---------------------------------------------------------------------------------------
// Runs of the forest scene, shared by the scenarios that use it.

/// What the scenarios need of a plant in a snapshot.
struct LitePlant {
    std::int32_t species = 0;
    float x = 0, y = 0, heightM = 0, crownRadiusM = 0, sunShare = 0;
};

struct Snapshot {
    int year = 0;
    std::vector<LitePlant> plants;
};

struct ForestRun {
    std::string label;
    sim::SimArea area;
    std::vector<Plant> canopy;
    Grid<float> transmission;  ///< simulation grid: canopy transmission (1 = open)
    Grid<float> seedProb;      ///< simulation grid: yearly germination probability
    /// Simulation grid: the annual means per factor at the nearest abiotic cell (factors.h),
    /// the sun after canopy shade.
    FactorGrids site;
    Grid<std::int32_t> seedPackages;  ///< simulation grid: bit b = sub-biome b + 1 seeds the cell
    std::vector<sim::YearRecord> timeseries;
    std::vector<Snapshot> snapshots;
    /// Every plant (full records) at the years some scenario measures at, and the last year.
    std::map<int, std::vector<sim::UndergrowthPlant>> plantsAtYear;
    int years = 0;  ///< simulated years (the longest any of its scenarios needs)
    double seconds = 0;
    std::int64_t plantMonths = 0;
    double plotSideM = 0;

    /// Snapshots of years in [first, last].
    std::vector<const Snapshot*> window(int first, int last) const;
    /// The snapshot of year `year`, or nullptr.
    const Snapshot* at(int year) const;
    /// The plants at year `year`, one of the measured years (internal error otherwise).
    const std::vector<sim::UndergrowthPlant>& plantsAt(int year) const;
    /// The yearly census of years 0..year.
    std::vector<sim::YearRecord> censusUpTo(int year) const;
};

/// A snapshot's plants as simulator records (for the renders).
std::vector<sim::UndergrowthPlant> toUndergrowth(const Snapshot& s);

/// Share of species s among all plants of census r (0 when empty).
double shareOf(const sim::YearRecord& r, int s);

/// Census records of years in [first, last].
std::vector<const sim::YearRecord*> censusWindow(const std::vector<sim::YearRecord>& ts, int first, int last);

/// The context of one suite run, given to every Scenario::run: the mode, the biome, the
/// output directory, the log, and the forest scene's runs (each (scene, competition mode)
/// simulated once, as long as the longest of the selected scenarios needs).
class ScenarioContext {
public:
    /// Replicate `replicate` (0-based) of the suite; its figures go to `figureDir` (the
    /// output directory for replicate 0, a scratch directory for the others).
    ScenarioContext(const SuiteOptions& o, Biome biome, SuiteConfig suite, int replicate = 0, std::string figureDir = "")
        : opt_(o), biome_(std::move(biome)), suite_(std::move(suite)), replicate_(replicate),
          figureDir_(figureDir.empty() ? o.outDir : std::move(figureDir)) {}

    Mode mode() const { return opt_.mode; }
    /// Which replicate this is (0 = the seeds exactly as configured).
    int replicate() const { return replicate_; }
    /// The seed a configuration's `configured` seed stands for in this replicate: every seed
    /// a scenario uses passes through here (SuiteOptions::replicates).
    std::uint64_t seed(std::uint64_t configured) const {
        return configured + static_cast<std::uint64_t>(replicate_) * kReplicateSeedStep;
    }
    const Biome& biome() const { return biome_; }
    /// A progress line (stderr in the CLI).
    void log(const std::string& s) const {
        if (opt_.log) opt_.log(s);
    }
    /// Path of output file `name` (relative to the output directory, as Figure::file).
    std::string file(const std::string& name) const { return figureDir_ + "/" + name; }

    /// Before the scenarios run: every (scene, competition mode) is simulated as long as the
    /// longest of the selected scenarios that use it needs, and keeps the plants at each
    /// year one of them measures at.
    void planForestRuns(const std::vector<const ScenarioConfig*>& selected);

    /// The forest scene of a forest-based scenario.
    const ForestSceneConfig& scene(const ScenarioConfig& sc) const { return suite_.scenes.at(sc.scenePath); }
    /// The year scenario sc measures at.
    int measureYear(const ScenarioConfig& sc) const { return sc.measureYear(opt_.mode, scene(sc)); }
    /// The run of scene file `sceneFile` under competition `mode` (simulated on first use).
    /// `dominatedSurvival` is SimParams::deussenDominatedSurvival of a Deussen run.
    const ForestRun& forest(const std::string& sceneFile, sim::CompetitionMode mode, double dominatedSurvival);

    /// A report line describing the run (scene, size, years, time).
    void describeRun(const ForestRun& run, int year, ScenarioResult& r, const ForestSceneConfig& scene) const;
    /// Fig. 15-style plot and (when `renders`) Fig. 14-style renders of a forest run.
    void forestFigures(const ForestRun& run, int lastYear, const std::string& stem, const std::string& what,
                       ScenarioResult& r, bool renders = true) const;

private:
    sim::SimInputs forestInputs(const ForestSceneConfig& scene, const ForestSceneConfig::Size& size) const;

    SuiteOptions opt_;
    Biome biome_;
    SuiteConfig suite_;
    int replicate_ = 0;
    std::string figureDir_;
    std::map<std::string, std::unique_ptr<ForestRun>> cache_;
    std::map<std::string, int> runYears_;                // "scene|mode": years to simulate
    std::map<std::string, std::set<int>> keepPlantsAt_;  // "scene|mode": years whose plants are kept
};

}  // namespace eco::validate
