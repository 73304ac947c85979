// The EcoMod model of Zamuda & Brest (afforestation by yearly agents; docs/ecomod.md), the
// second simulator model, selected by `[model] kind = "ecomod"` in a run configuration.
//
// Every year: new trees per species (last year's seeds of mature trees times a germination
// share, plus immigrants from outside), placed near a parent of their species with
// probability p_s (under-dispersion) or anywhere, and established with probability v, the
// suitability of their place; growth of every tree along its species' height polyline
// through (0, 0), (t_m, h_m), (t_a, h_full), (t_f, h_full), unless a neighbour whose
// ecological neighbourhood (crown circle) overlaps its own has a higher competitive ability
// a = (h / h_max of the biome) x p_persist x v (Eq. 1); then it is dominated: it gains
// dominated_growth years of growth age and dies with probability 1 - dominated_survival
// (each tree draws at birth how many dominated years it survives, geometric with that
// survival: the same law as a draw per dominated year); natural deaths at an age drawn
// uniformly in [t_a, t_f] at birth. v = k_y m l w s (Eq. 2): the
// suitabilities of normalised elevation, moisture, sun, wind (Eqs. 4-7) and slope (Eq. 3),
// from the annual maps of the abiotics file.
//
// The plant state is a structure of arrays of positions, heights, species and ages; the
// Simulation front (simulator.h) delegates to EcoModel when the model kind is "ecomod", so
// the run loop, outputs, checkpoints and resume are those of the monthly model. Suppressed
// seedlings are set aside from the yearly passes with their event year planned (sleepers;
// merged back by id wherever the trees are listed: the same results). Results are
// bit-identical for any thread count: every random draw comes from a stream keyed by (seed,
// year, species or plant id), and parallel loops only write per-plant results.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "biome.h"
#include "disturbance.h"
#include "h5io.h"
#include "sim_config.h"
#include "sim_file.h"

namespace eco::sim {

struct SimInputs;
struct SimCounters;

/// A species' EcoMod parameters with every default resolved (units in docs/ecomod.md).
struct EcoModSpeciesParams {
    double maturityAgeYears = 0, fullGrownAgeYears = 0, maxAgeYears = 0;
    double matureHeightM = 0, fullHeightM = 0;
    double persistence = 0, seedsPerYear = 0, germination = 0, nearProbability = 0, dispersalRadiusM = 0;
    double immigrantsPerHaYear = 0, dominatedSurvival = 0, dominatedGrowth = 0;
    double elevationOpt = 0, elevationTol = 0, elevationHarm = 0;
    double moistureOpt = 0, moistureTol = 0, moistureHarm = 0;
    double sunOpt = 0, sunTol = 0, sunHarm = 0;
    double windOpt = 0, windTol = 0, windHarm = 0;
    double slopeHarm = 0;
};

/// The species' `ecomod` table with the documented defaults for the keys it does not give
/// (docs/ecomod.md "Species parameters"). ValidationError naming `source`, the species, the
/// key and the value when the polyline is not increasing in age (t_m < t_a <= t_f) or in
/// height (h_m <= h_full).
EcoModSpeciesParams resolveEcoModSpecies(const Species& s, const std::string& source);

/// The height polyline (Fig. 1): metres at growth age `ageYears` >= 0, linear between
/// (0, 0), (t_m, h_m), (t_a, h_full) and constant h_full from t_a on.
double ecomodPolylineHeightM(const EcoModSpeciesParams& p, double ageYears);
/// Its inverse on [0, t_a]: the growth age at which the polyline reaches `heightM`
/// (t_a for heights at or above h_full). Initial plants get their growth age from it.
double ecomodPolylineAgeYears(const EcoModSpeciesParams& p, double heightM);
/// Eqs. 4-7: 1 within the tolerated deviation `tol` of the optimum `opt`, else
/// 1 - min(1, |x - opt| harm) (the paper prints max, which would make it <= 0 everywhere).
double ecomodDeviationSuitability(double x, double opt, double tol, double harm);
/// Eq. 3 with the paper's slope 1 - n_y = 1 - cos(slope): 1 - (harm (1 - cos slope))^2, >= 0.
double ecomodSlopeSuitability(double slopeDeg, double harm);

/// The EcoMod engine behind Simulation (see the file comment). Coordinates in world metres;
/// ages in years; heights and radii in metres.
class EcoModel {
public:
    /// ValidationError for bad parameters, an area outside the abiotics, a species id
    /// outside the biome. `initial` plants outside the area are dropped (counted).
    EcoModel(SimInputs inputs, const SimParams& params, std::uint64_t seed, const std::vector<UndergrowthPlant>& initial);
    ~EcoModel();
    EcoModel(const EcoModel&) = delete;
    EcoModel& operator=(const EcoModel&) = delete;

    /// One year: seeding, growth with domination, elimination (Algorithm 1).
    void stepYear();
    int yearsDone() const;
    std::size_t plantCount() const;
    /// How many of them are set aside (suppressed seedlings out of the yearly passes until an
    /// event of theirs; docs/ecomod.md "Speed"). Diagnostic: no result depends on it.
    std::size_t setAsideCount() const;
    /// How often the step's caches served since construction (diagnostic; docs/ecomod.md
    /// "Speed"): a tree of ability 0 found dominated by the cover cache's guess, a set-aside
    /// tree rejoining the store in growStore's pass, an able tree's grid place kept, a
    /// set-aside tree under a canopy tree met by the events' calendar in its event year, and
    /// (checkSleeperCalendar on) a year whose calendar entry differed from a scan.
    struct CacheCounts {
        std::size_t coverHits = 0, wokenInPass = 0, keysKept = 0, calendarEvents = 0, calendarMismatches = 0;
    };
    CacheCounts cacheCounts() const;
    /// Test mode: each year the set-aside trees that the events' calendar gives are compared
    /// with a scan of every set-aside tree's event year (cacheCounts().calendarMismatches).
    void checkSleeperCalendar(bool on);
    /// How many dominated trees of height > 0 doze (set aside from the store's yearly passes,
    /// among the dominators; docs/ecomod-speed.md "Dozing dominated trees").
    std::size_t dozingCount() const;
    /// Test mode: with dozing off no tree dozes (the trees are the same; tests).
    void setDozing(bool on);
    /// Drops every cache of the step (witnesses, the set-aside, grid places, cover guesses), so
    /// that the next year tests every tree by the plain search; no result changes (tests).
    void forgetCaches();
    /// The living trees, in creation order. vigour = suitability v, pool = competitive ability a.
    std::vector<UndergrowthPlant> plants() const;
    YearRecord census() const;
    const SimCounters& counters() const;
    std::size_t droppedInitialPlants() const;
    const SimParams& params() const;
    const Biome& biome() const;
    std::uint64_t seed() const;
    SimArea area() const;
    const Grid<float>& gridGeometry() const;
    const std::vector<Plant>& relevantCanopy() const;
    const std::vector<EcoModSpeciesParams>& speciesParams() const;
    /// Suitability v of species s at world point (x, y) (0 outside the area).
    double suitability(int s, double xM, double yM) const;
    /// Fire and windthrow events (sim/disturbance.h, docs/disturbance.md); off by default.
    /// The year's events strike at its end, after growth and the year's deaths, in the
    /// order of their months, on the abiotics cells covering the area (the event month's
    /// moisture). Changes the fingerprint when on. ValidationError for bad settings.
    void setDisturbance(const DisturbanceSettings& settings);
    const DisturbanceSettings& disturbance() const;
    /// The events so far, in order (restored from a checkpoint).
    const std::vector<DisturbanceRecord>& disturbances() const;
    /// Disturbance hook (fire, windthrow; issue 30 item 3): removes the trees whose entry in
    /// `dead` (indexed as plants(), same length) is non-zero, keeping the others' order; returns
    /// how many were removed. ValidationError when the length differs.
    std::size_t removeTrees(const std::vector<std::uint8_t>& dead);
    std::uint64_t fingerprint() const;
    void saveState(h5::File& file, const std::string& group) const;
    void loadState(const h5::File& file, const std::string& group);
    std::size_t bytesPerPlant() const;

private:
    struct Impl;
    std::unique_ptr<Impl> impl_;
};

}  // namespace eco::sim
