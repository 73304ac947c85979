// Abiotic maps (SPEC §2, paper §5.1): slope, monthly temperature, monthly sunlight with
// terrain self-shadowing and a diffuse sky term, and monthly soil moisture from rainfall
// routed over the terrain. docs/abiotics.md gives the models, formulas and file layout.
//
// Conventions: grids follow grid.h (row iy = 0 is the southern row, x east, y north,
// elevations in metres); monthly maps are 12 planes, plane 0 = January.
// Every function here is deterministic: results are bit-identical whatever the number of
// OpenMP threads.
#pragma once

#include <array>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "biome.h"
#include "factors.h"
#include "grid.h"
#include "param_desc.h"
#include "plants.h"

namespace eco {

// ---------------------------------------------------------------------------------------
// Slope and temperature

/// Slope in degrees (0 = horizontal, 90 = vertical): the angle between the surface normal
/// and the vertical, from central differences of the elevation (one-sided differences on
/// the edge rows and columns). Exact on a plane. Needs at least 2 cells along each axis
/// that has a gradient; a single row or column gets a zero gradient along it.
Grid<float> slopeDegrees(const Grid<float>& elevationM);

/// Monthly air temperature in degrees Celsius: sea-level monthly temperature minus
/// lapseRateCPerKm * elevationM / 1000. 12 planes, 0 = January.
MonthlyGrids<float> temperatureC(const Grid<float>& elevationM, const Climate& climate);

// ---------------------------------------------------------------------------------------
// Wind (Zamuda & Brest's EcoMod wind shelter; docs/abiotics.md "Wind")

/// Wind occlusion angle in degrees per cell, >= 0: from the cell's centre, N_w = wind.samples
/// points upwind (towards wind.directionDeg, where the wind comes from) one cell size apart,
/// elevation interpolated bilinearly; the largest elevation angle atan((z_w - z) / (w K)) of
/// those points, 0 when none is higher than the cell. Points beyond the grid are not sampled
/// (terrain outside the grid shelters nothing).
Grid<float> windOcclusionDeg(const Grid<float>& elevationM, const Wind& wind);

/// Wind exposure in m/s: wind.strengthMS * max(0, 1 - occlusion / wind.thresholdDeg), so
/// open ground gets the full strength and a cell whose upwind horizon reaches the threshold
/// angle none. ValidationError for wind parameters outside windFields()' ranges.
Grid<float> windSpeedMS(const Grid<float>& elevationM, const Wind& wind);

// ---------------------------------------------------------------------------------------
// Sun

/// Parameters of the sunlight model (all written into every abiotics file; described once
/// in sunParamFields()).
struct SunParams {
    double stepMinutes = 10;  ///< sampling interval of the sun path, minutes (about)
    int skyAzimuths = 16;     ///< azimuths of the sky-view sweeps
    int skyElevations = 6;    ///< elevation bands of the sky-view sweeps (0..90 degrees)
    int dayOfMonth = 15;      ///< representative day of each month, 1..28
};

/// The fields of SunParams (core/param_desc.h), keyed as the abiotics file's attributes
/// (sun_step_minutes ...) and docs/abiotics.md's table: the one description of them, from
/// which validation and the attributes come.
const std::vector<ParamDesc<SunParams>>& sunParamFields();

/// Solar declination in radians for day of year 1..366 (1 = 1 January), from the sun's
/// ecliptic longitude with the first-order orbital eccentricity correction.
double solarDeclinationRad(int dayOfYear);

/// Astronomical day length in hours (sun centre above the geometric horizon, no
/// refraction) at latitudeDeg (north positive) on day of year 1..366. 0 in polar night,
/// 24 in polar day.
double dayLengthHours(double latitudeDeg, int dayOfYear);

/// Day of year (1..365, non-leap year) of day `dayOfMonth` of month `month0` (0 = January).
int dayOfYearFor(int month0, int dayOfMonth);

/// Everything the sunlight model computes, for inspection and tests.
struct SunDetail {
    MonthlyGrids<float> directHours;   ///< hours/day of direct sun (unshadowed, facing the sun)
    Grid<float> skyView;               ///< fraction of the (cosine-weighted) sky seen, [0, 1]
    std::array<double, 12> dayLengthHours{};  ///< astronomical day length of each month's day
    MonthlyGrids<float> sunHours;      ///< total: clarity*direct + (1-clarity)*skyView*dayLength
};

/// Sky-view factor in [0, 1] per cell: the fraction of the diffuse light of a uniform sky
/// that reaches the surface, relative to open flat ground (which gets exactly 1). Uses
/// params.skyAzimuths x params.skyElevations horizon sweeps.
Grid<float> skyViewFactor(const Grid<float>& elevationM, const SunParams& params);

/// The full sunlight model; `progress(fraction)` is called from the calling thread.
SunDetail sunDetail(const Grid<float>& elevationM, const Climate& climate, const SunParams& params,
                    const std::function<void(double fraction)>& progress = {});

/// Monthly sunlight in hours/day (12 planes, 0 = January):
///   clarity_m * directHours_m + (1 - clarity_m) * skyView * dayLength_m,
/// so open flat ground gets exactly the astronomical day length.
MonthlyGrids<float> sunHours(const Grid<float>& elevationM, const Climate& climate,
                             const SunParams& params,
                             const std::function<void(double fraction)>& progress = {});

/// A canopy tree that shades the ground under its crown disc.
struct ShadingTree {
    double x = 0, y = 0;        ///< crown centre, world metres
    double crownRadiusM = 0;    ///< crown radius, metres
    double alpha = 0;           ///< fraction of light the crown absorbs, [0, 1]
};

/// Canopy attenuation: every cell whose centre lies inside (or on) a crown disc is
/// multiplied by (1 - alpha) once per covering tree. Cells under no crown are unchanged.
/// ValidationError for a negative or non-finite radius or an alpha outside [0, 1].
MonthlyGrids<float> applyCanopyShade(const MonthlyGrids<float>& sun,
                                     const std::vector<ShadingTree>& trees);
/// Shading trees of a canopy: crown at the trunk, alpha of the tree's species in `biome`.
/// ValidationError for a species id outside the biome.
std::vector<ShadingTree> shadingTrees(const std::vector<Plant>& canopy, const Biome& biome);

// ---------------------------------------------------------------------------------------
// Moisture

/// Water budget of the recorded year of moistureMm(), in cubic metres of water over the
/// whole grid (1 mm on 1 m^2 = 0.001 m^3). Month 0 = January.
struct MoistureBalance {
    std::array<double, 12> rainM3{};           ///< rain falling on the grid
    std::array<double, 12> absorbedM3{};       ///< infiltrated into the soil store
    std::array<double, 12> evaporatedM3{};     ///< removed from the soil store by evaporation
    std::array<double, 12> storageChangeM3{};  ///< store at month end minus store at month start
    std::array<double, 12> outflowM3{};        ///< runoff leaving the grid edge
    double initialStorageM3 = 0;  ///< soil store at the start of the recorded January
    double finalStorageM3 = 0;    ///< soil store at the end of the recorded December

    static double sum(const std::array<double, 12>& a);
    double rainYearM3() const { return sum(rainM3); }
    double absorbedYearM3() const { return sum(absorbedM3); }
    double evaporatedYearM3() const { return sum(evaporatedM3); }
    double storageChangeYearM3() const { return sum(storageChangeM3); }
    double outflowYearM3() const { return sum(outflowM3); }
    /// |rain - (storage change + evaporated + outflow)| / rain over the year (0 if no rain).
    double relativeError() const;
};

/// Monthly soil water in mm (the store W after each month; 12 planes, 0 = January).
/// Runoff is routed from high to low over the depression-filled terrain with
/// multiple-flow-direction (slope-weighted) partitioning; see docs/abiotics.md.
/// The 12-month cycle is run spinUpYears times (>= 0) from a dry soil before the recorded
/// year. When `balance` is given it receives the water budget of the recorded year.
/// `progress(fraction)` is called from the calling thread after each simulated month.
MonthlyGrids<float> moistureMm(const Grid<float>& elevationM, const Climate& climate, const Soil& soil,
                               MoistureBalance* balance = nullptr, int spinUpYears = 1,
                               const std::function<void(double fraction)>& progress = {});

// ---------------------------------------------------------------------------------------
// All maps together, and their file

struct AbioticParams {
    SunParams sun;
    int moistureSpinUpYears = 1;  ///< years of moisture routing run before the recorded one
};

/// The fields of AbioticParams besides `sun` (sunParamFields), keyed as the abiotics file's
/// attributes and docs/abiotics.md's table.
const std::vector<ParamDesc<AbioticParams>>& abioticParamFields();

struct Abiotics {
    MonthlyGrids<float> sunHours;      ///< hours/day
    MonthlyGrids<float> moistureMm;    ///< mm (soil water after each month)
    MonthlyGrids<float> temperatureC;  ///< degrees Celsius
    Grid<float> slopeDeg;              ///< degrees
    Grid<float> windMS;                ///< m/s: wind exposure of the biome's prevailing wind (static)
    Grid<float> elevationM;            ///< metres
    /// Where the sun planes were shaded by a canopy ("eco abiotics --canopy FILE"): that
    /// file; empty for the terrain's own sun. The simulator and the analyser apply their
    /// canopy themselves and refuse shaded input (the shade would count twice).
    std::string canopyShadeSource;
    /// The biome's [wind] that the /wind map was computed for (the file's wind_* attributes);
    /// runs whose disturbance uses the wind check their biome against it.
    std::optional<Wind> mapWind;
};

/// One map of Abiotics (besides the elevation, which is the terrain and the geometry of the
/// others): the one description that the abiotics file's writer and reader, the CRS
/// setting, annualFactors, the simulator's input checks and its checkpoint fingerprint loop
/// over (issue 23; docs/factors.md). A map is monthly (12 planes, `monthly`) or static (one
/// plane, `single`); exactly one of the two member pointers is set.
struct AbioticMapInfo {
    const char* name;     ///< "sun": the map's name in messages
    const char* dataset;  ///< "/sun": its dataset in the abiotics file
    const char* unit;     ///< "hours/day": the dataset's unit attribute (of one plane)
    Factor factor;        ///< the factor whose annual map it gives (factors.h)
    MonthlyGrids<float> Abiotics::*monthly;  ///< the member holding a monthly map, else nullptr
    Grid<float> Abiotics::*single;           ///< the member holding a static map, else nullptr
    double lo, hi;            ///< the values a file may hold (readAbiotics refuses others)
    const char* description;  ///< one line, what the map is (docs/abiotics.md)

    constexpr bool isMonthly() const { return monthly != nullptr; }
};

/// The maps of Abiotics, in the order of the abiotics file's datasets. A new abiotic factor
/// adds its member to Abiotics and its row here (docs/factors.md "Adding a factor").
inline constexpr std::array<AbioticMapInfo, kFactorCount> kAbioticMaps = {{
    {"slope", "/slope", "degrees", Factor::Slope, nullptr, &Abiotics::slopeDeg, 0, 90,
     "terrain slope from central differences of the elevation"},
    {"sun", "/sun", "hours/day", Factor::Sun, &Abiotics::sunHours, nullptr, 0, 24,
     "sunlight: direct sun with terrain self-shadowing plus diffuse sky light"},
    {"moisture", "/moisture", "mm/month", Factor::Moisture, &Abiotics::moistureMm, nullptr, 0, 1e6,
     "soil water: the store after each month's rain, run-on, runoff and evaporation"},
    {"temperature", "/temperature", "degC", Factor::Temperature, &Abiotics::temperatureC, nullptr, -100, 100,
     "air temperature: the climate's sea-level temperature minus the lapse rate"},
    {"wind", "/wind", "m/s", Factor::Wind, nullptr, &Abiotics::windMS, 0, 100,
     "exposure to the biome's prevailing wind after the terrain upwind shelters it"},
}};

namespace detail {
constexpr bool everyFactorHasOneMap() {
    for (std::size_t f = 0; f < kFactorCount; ++f) {
        int n = 0;
        for (const AbioticMapInfo& m : kAbioticMaps) n += factorIndex(m.factor) == f ? 1 : 0;
        if (n != 1) return false;
    }
    for (const AbioticMapInfo& m : kAbioticMaps)
        if ((m.monthly == nullptr) == (m.single == nullptr)) return false;
    return true;
}
}  // namespace detail
static_assert(detail::everyFactorHasOneMap(),
              "kAbioticMaps: every factor needs exactly one map, monthly or static (docs/factors.md)");

namespace detail {
constexpr std::size_t countStaticMaps() {
    std::size_t n = 0;
    for (const AbioticMapInfo& m : kAbioticMaps) n += m.isMonthly() ? 0 : 1;
    return n;
}
constexpr bool isMonthlyFactor(Factor f) {
    for (const AbioticMapInfo& m : kAbioticMaps)
        if (m.factor == f) return m.isMonthly();
    return false;
}
}  // namespace detail

/// The number of static maps of kAbioticMaps (one plane each: slope, wind).
inline constexpr std::size_t kStaticMapCount = detail::countStaticMaps();

/// The static maps of kAbioticMaps, in table order: the simulator reads a plant's static
/// factors from them (sim/simulator_impl.h SitePlanes), so a new static factor needs no line
/// there.
inline constexpr std::array<AbioticMapInfo, kStaticMapCount> kStaticMaps = [] {
    std::array<AbioticMapInfo, kStaticMapCount> out{};
    std::size_t n = 0;
    for (const AbioticMapInfo& m : kAbioticMaps)
        if (!m.isMonthly()) out[n++] = m;
    return out;
}();

/// Calls fn(plane) for each plane of map m of a (12 for a monthly map, 1 for a static one),
/// in order. A is Abiotics or const Abiotics.
template <typename A, typename Fn>
void forEachPlane(A& a, const AbioticMapInfo& m, Fn&& fn) {
    if (m.isMonthly())
        for (auto& plane : (a.*(m.monthly)).months) fn(plane);
    else
        fn(a.*(m.single));
}

/// The annual map of m: the mean of its planes for a monthly map, the map itself for a static one.
Grid<float> annualMap(const Abiotics& a, const AbioticMapInfo& m);

/// The annual maps of the factors (factors.h): the annual means of the monthly maps (sun,
/// moisture, temperature), the slope and the wind, in factor order, as kAbioticMaps says
/// which map feeds which factor. `sunHoursAnnual`, when given, replaces the sun's
/// annual mean (a canopy-shaded sun, as the analyser and synthesizer use).
FactorGrids annualFactors(const Abiotics& a, const Grid<float>* sunHoursAnnual = nullptr);

/// Throws ValidationError unless the elevation grid is at least 3 x 3 with finite values.
void validateElevation(const Grid<float>& elevationM, const std::string& what = "elevation");

/// Peak memory of computeAbiotics per terrain cell, bytes (the maps and the buffers of the
/// sun and moisture computations; measured 2026-11-28).
inline constexpr double kAbioticsBytesPerCell = 280.0;

/// All abiotic maps for a terrain and biome. `progress(stage, fraction)` is called from
/// the calling thread with stage "slope", "temperature", "sun", "moisture" or "wind" and the
/// fraction of that stage done (each stage ends with 1.0). A terrain whose maps would not fit
/// in the available memory (core/memory.h) is refused first (ValidationError: what it needs,
/// what the machine has).
Abiotics computeAbiotics(const Grid<float>& elevationM, const Biome& biome, const AbioticParams& params,
                         const std::function<void(const std::string& stage, double fraction)>& progress = {});

/// Write an abiotics file atomically (temporary file, then rename). Layout in
/// docs/abiotics.md: /elevation, /slope, /sun, /moisture, /temperature, /wind and root
/// attributes recording the biome, the climate, the soil and every model parameter.
void writeAbiotics(const std::string& path, const Abiotics& maps, const Biome& biome,
                   const AbioticParams& params);

/// Read the maps of an abiotics file. IoError naming the file and the dataset when one is
/// missing, has the wrong shape or a different geometry than /elevation, or when the file
/// is not an eco-abiotics file.
Abiotics readAbiotics(const std::string& path);

}  // namespace eco
