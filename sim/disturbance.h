// Disturbance events: fire and windthrow storms (issue 30 item 3; docs/disturbance.md).
//
// A unit of its own, acting on plain inputs only: grids of elevation, moisture and wind
// exposure (one geometry), and plants given as parallel arrays (id, species, position,
// height). The monthly simulator calls it in the event's month (sim/simulator.cpp), the
// yearly EcoMod model at the end of each year with its own tree arrays (sim/ecomod.cpp).
//
// Every random draw is a pure function of (run seed, a stream derived from the event, an
// entity: cell or plant id), core/rng.h: an event's outcome depends neither on the thread
// count nor on the order of evaluation, and there is no generator state to checkpoint.
//
// Units: metres, m/s, mm of water per month, years; probabilities in [0, 1].
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "abiotics.h"
#include "biome.h"
#include "grid.h"
#include "param_desc.h"
#include "sim_file.h"

namespace eco::sim {

enum class DisturbanceKind : std::uint8_t { Fire = 0, Storm = 1 };
/// "fire", "storm" (the `kind` column of the output table).
const char* disturbanceKindName(DisturbanceKind k);

/// When events of one kind happen: a yearly probability (a return interval T is 1 / T) and
/// forced years, in a fixed month.
struct EventTiming {
    double probabilityPerYear = 0;  ///< chance of an event in a year; 0 = only forced years
    std::vector<int> forcedYears;   ///< an event in each of these years (0 = the first simulated year)
    int month = 0;                  ///< 0 = January; the event strikes at the end of this month
};

/// `[disturbance.fire]` of a run configuration (defaults documented in docs/disturbance.md).
struct FireSettings {
    bool enabled = false;           ///< the table is present
    EventTiming timing{0, {}, 7};   ///< August: the end of the dry season in Sonoma
    /// Probability that fire passes from a burning cell to a neighbour (8 neighbours) on
    /// flat, calm, dry ground. The 8-neighbour bond-percolation threshold is about 0.25:
    /// well below it fires stay small, well above they run through the area.
    double spreadProbability = 0.35;
    /// Slope bias: the probability is multiplied by exp(slope_factor x rise / run) of the
    /// step (upslope faster, downslope slower).
    double slopeFactor = 2.0;
    /// Wind bias per m/s of the burning cell's exposure: x exp(wind_factor x U x cos phi), phi
    /// the angle between the step and the downwind direction.
    double windFactor = 0.2;
    /// Moisture (mm/month, the month's abiotics) at and above which a cell does not burn;
    /// below it the probability into the cell is multiplied by 1 - moisture / this.
    double extinctionMoistureMm = 150.0;
    /// Probability that a plant of tolerance 0 below the scorch height in a burnt cell dies.
    double severity = 0.9;
    /// Plants up to this height are scorched whole; a taller plant's kill probability is
    /// scaled by scorch_height / height.
    double scorchHeightM = 2.0;
    /// Tolerance of species whose biome entry has no fire_tolerance: the kill probability is
    /// multiplied by 1 - tolerance.
    double defaultTolerance = 0.0;
};

/// `[disturbance.storm]` of a run configuration.
struct StormSettings {
    bool enabled = false;
    EventTiming timing{0, {}, 11};  ///< December: winter storms
    /// Probability that a plant of reference height on fully exposed ground is thrown.
    double severity = 0.5;
    /// Height scale: the probability is multiplied by min(1, (height / this)^height_exponent).
    double referenceHeightM = 3.0;
    double heightExponent = 2.0;
    /// Wind exposure (m/s, the abiotics' wind map) counted as fully exposed; 0 = the biome's
    /// prevailing wind strength. The probability is multiplied by min(1, exposure / this).
    double referenceWindMS = 0.0;
};

struct DisturbanceSettings {
    FireSettings fire;
    StormSettings storm;
    bool enabled() const { return fire.enabled || storm.enabled; }
    /// ValidationError "<source>: [disturbance.KIND] key = value: rule" for the first value of
    /// an enabled kind outside its descriptor's range (fireFields(), stormFields()).
    void validate(const std::string& source) const;
    /// TOML text of the [disturbance.*] tables present (records, fingerprints; "" when off):
    /// the written keys of fireFields() / stormFields() in their order. The text enters
    /// checkpoint fingerprints: it must not change for the same settings.
    std::string toToml() const;
};

// ---------------------------------------------------------------- the keys' descriptors

/// The numbers of an event's timing, shared by both kinds: probability_per_year and month
/// (core/param_desc.h). The month's default is the kind's (FireSettings{}.timing: 7).
const std::vector<ParamDesc<EventTiming>>& eventTimingParamFields();
/// The numbers of `[disturbance.fire]` besides the timing.
const std::vector<ParamDesc<FireSettings>>& fireParamFields();
/// The numbers of `[disturbance.storm]` besides the timing.
const std::vector<ParamDesc<StormSettings>>& stormParamFields();

/// One key of `[disturbance.fire]` (S = FireSettings) or `[disturbance.storm]` (S =
/// StormSettings): the one description from which the table is read (parseRunConfig),
/// checked (DisturbanceSettings::validate), written (toToml, eco config defaults simulate)
/// and documented (eco config describe disturbance-fire / disturbance-storm, docs/
/// disturbance.md). The numbers are ParamDesc rows (of the timing or of S); three keys are
/// not one number and are described here.
template <typename S>
struct DisturbanceField {
    enum class Kind {
        Enabled,         ///< true / false in S::enabled; the table's presence alone means true. Not written.
        ReturnInterval,  ///< years >= 1, read as probability_per_year = 1 / this (not with it). Not written.
        ForcedYears,     ///< a list of integers, each in `range`, into S::timing.forcedYears
        Timing,          ///< a number of S::timing (`timing`)
        Setting,         ///< a number of S (`setting`)
    };
    Kind kind;
    const ParamDesc<EventTiming>* timing = nullptr;  ///< Kind::Timing
    const ParamDesc<S>* setting = nullptr;           ///< Kind::Setting
    // The text of the keys that are not one number (the numbers' is their ParamDesc's).
    const char* ownKey = "";
    const char* ownDoc = "";
    const char* ownUnit = "";
    const char* ownDefault = "";
    const char* ownAllowed = "";
    ParamRange range{};        ///< ReturnInterval: the value; ForcedYears: each year
    const char* rule = nullptr;

    static DisturbanceField timingField(const ParamDesc<EventTiming>& f) { return {Kind::Timing, &f, nullptr}; }
    static DisturbanceField settingField(const ParamDesc<S>& f) { return {Kind::Setting, nullptr, &f}; }

    const char* key() const { return timing ? timing->key : setting ? setting->key : ownKey; }
    const char* doc() const { return timing ? timing->doc : setting ? setting->doc : ownDoc; }
    const char* unit() const { return timing ? timing->unit : setting ? setting->unit : ownUnit; }
    /// In the TOML toToml writes (records, fingerprints, the defaults' template).
    bool written() const { return kind != Kind::Enabled && kind != Kind::ReturnInterval; }
    /// The range's message text ("must lie in [0, 1]").
    std::string ruleText() const {
        if (timing) return timing->ruleText();
        if (setting) return setting->ruleText();
        return rule ? std::string(rule) : range.text();
    }
    /// The allowed values as the docs show them.
    std::string allowedText() const {
        if (timing) return timing->range.valuesText();
        if (setting) return setting->range.valuesText();
        return ownAllowed;
    }
    /// The default (S{}'s value; the month the kind's own).
    std::string defaultText() const {
        static const S defaults{};
        if (timing) return paramText(*timing, defaults.timing, 6);
        if (setting) return paramText(*setting, defaults, 6);
        return ownDefault;
    }
    /// The value in s as TOML text (written keys only): reals with tomlReal, integers whole.
    std::string tomlValue(const S& s) const {
        if (kind == Kind::ForcedYears) {
            std::string out = "[";
            for (std::size_t i = 0; i < s.timing.forcedYears.size(); ++i)
                out += (i ? ", " : "") + std::to_string(s.timing.forcedYears[i]);
            return out + "]";
        }
        if (timing) return timing->kind == ParamDesc<EventTiming>::Kind::Real ? tomlReal(timing->value(s.timing)) : paramText(*timing, s.timing, 17);
        if (setting) return setting->kind == ParamDesc<S>::Kind::Real ? tomlReal(setting->value(s)) : paramText(*setting, s, 17);
        return {};
    }
    /// The docs' row "| `key` | default | unit | meaning |" (eco config describe adds the
    /// allowed values and the flag column).
    std::string docRow() const {
        return std::string("| `") + key() + "` | " + defaultText() + " | " + (*unit() ? unit() : "-") + " | " + doc() + " |";
    }
};

/// Every key of `[disturbance.fire]`, in the order toToml writes them.
const std::vector<DisturbanceField<FireSettings>>& fireFields();
/// Every key of `[disturbance.storm]`, in the order toToml writes them.
const std::vector<DisturbanceField<StormSettings>>& stormFields();
/// The written keys of s as TOML lines "key = value" (toToml's body of one table), each
/// followed by "  # doc, unit" when `withDocs` (the template of eco config defaults simulate).
template <typename S>
std::string disturbanceTomlLines(const S& s, const std::vector<DisturbanceField<S>>& fields, bool withDocs);
/// The first value of s outside its field's range: "key = value: rule" ("" when all are valid).
template <typename S>
std::string firstInvalidDisturbanceValue(const S& s, const std::vector<DisturbanceField<S>>& fields);

/// An event planned for a year: its kind, its month and the key of its random streams.
struct PlannedEvent {
    DisturbanceKind kind = DisturbanceKind::Fire;
    int year = 0;
    int month = 0;
    std::uint64_t key = 0;  ///< derives every draw of the event
};

/// The events of `year` (at most one per kind, in month order, fire before a storm of the
/// same month): a forced year, or a draw u < probability on the stream of the kind keyed by
/// the year.
std::vector<PlannedEvent> eventsOfYear(const DisturbanceSettings& s, std::uint64_t seed, int year);

/// The ground an event acts on: three grids of one geometry (any; the simulator uses the
/// abiotics cells covering its area) and the area (world metres) inside them that counts.
struct DisturbanceSite {
    Grid<float> elevationM;
    Grid<float> moistureMm;  ///< the event month's moisture
    Grid<float> windMS;      ///< wind exposure (abiotics /wind); all zero when unknown
    double windFromDeg = 270.0;  ///< where the prevailing wind comes from, clockwise from north
    double windStrengthMS = 5.0; ///< the biome's prevailing strength (storm reference)
    double x0 = 0, y0 = 0, x1 = 0, y1 = 0;  ///< area (ignitions fall inside; areas are clipped to it)
};

/// The site of an event on grids already of one geometry: the grids, the biome's prevailing
/// wind (direction and strength) and the area (x0, y0)-(x1, y1), world metres.
DisturbanceSite disturbanceSite(Grid<float> elevationM, Grid<float> moistureMm, Grid<float> windMS, const Wind& wind,
                                double x0, double y0, double x1, double y1);

/// The simulator's event ground: the abiotics cells covering the area (x0, y0)-(x1, y1) cut
/// from `abio` (elevation, the moisture of `month` (0 = January), wind exposure; a grid of
/// another geometry than the slope's gives zeros), with the biome's prevailing wind.
DisturbanceSite abioticsDisturbanceSite(const Abiotics& abio, const Wind& wind, int month, double x0, double y0, double x1,
                                        double y1);

/// Plants as parallel arrays (the simulator's own store, or any other model's).
struct PlantArrays {
    std::size_t n = 0;
    const std::uint64_t* id = nullptr;
    const std::int32_t* species = nullptr;
    const double* x = nullptr;
    const double* y = nullptr;
    const double* height = nullptr;
};

/// The spread rule: the probability that fire passes from cell a to its neighbour b (dx, dy
/// in -1..1, not both 0) of the site. 0 when b is at or above the extinction moisture.
double fireStepProbability(const DisturbanceSite& site, const FireSettings& f, int ax, int ay, int dx, int dy);

/// Cells burnt by a fire ignited in cell (ix, iy): 1 per burnt cell (site grid order).
/// Each directed step a -> b is open with fireStepProbability, drawn once per (event, cell
/// a, direction); the burnt cells are those reachable from the ignition through open steps
/// (the same set whatever the visiting order). Nothing burns when the ignition cell is wet.
std::vector<std::uint8_t> spreadFire(const DisturbanceSite& site, const FireSettings& f, int ix, int iy,
                                     std::uint64_t seed, std::uint64_t eventKey);

/// The cells a planned fire burns (its burn mask, site grid order; what runDisturbance
/// burns for the event): the ignition drawn uniformly in the site's area on the event's
/// stream, then spreadFire. The ignition point (world metres) goes to the pointers given.
std::vector<std::uint8_t> fireBurntCells(const PlannedEvent& e, const FireSettings& f, const DisturbanceSite& site,
                                         std::uint64_t seed, double* ignitionX = nullptr, double* ignitionY = nullptr);

/// Kill probabilities (documented in docs/disturbance.md).
double fireKillProbability(const FireSettings& f, double heightM, double tolerance);
double stormKillProbability(const StormSettings& s, double heightM, double exposureMS, double referenceWindMS);

/// What an event did: its record (killed per species, area) and which plants it killed.
struct DisturbanceOutcome {
    DisturbanceRecord record;
    std::vector<std::uint8_t> killed;  ///< per plant of the arrays: 1 = killed
    std::vector<std::uint8_t> burnt;   ///< fire: per site cell (spreadFire); empty for storms
};

/// Runs one planned event on the site and the plants. `tolerance`: per species fire
/// tolerance in [0, 1] (fire only). Plants outside the site's grids are untouched.
DisturbanceOutcome runDisturbance(const PlannedEvent& e, const DisturbanceSettings& s, const DisturbanceSite& site,
                                  const PlantArrays& plants, const std::vector<double>& tolerance,
                                  std::size_t speciesCount, std::uint64_t seed);

}  // namespace eco::sim
