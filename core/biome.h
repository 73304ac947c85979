// Biome definition: species parameters (paper Table 3), sub-biomes, climate, soil and the
// vigour shape. Read from TOML (biomes/*.toml) with strict validation.
#pragma once

#include <array>
#include <limits>
#include <string>
#include <vector>

#include "factors.h"
#include "param_desc.h"
#include "vigour.h"

namespace eco {

/// Crown radius from height, r = exp(a + b ln h) (Eq. 2), or r = factor * h (code E).
struct Allometry {
    std::string code;       ///< "A".."E" as in Table 3, or a user name
    bool linear = false;    ///< true: r = linearFactor * h
    double a = 0.0;
    double b = 1.0;
    double linearFactor = 0.0;
    /// Crown radius in metres for a plant of height heightM metres.
    double crownRadiusM(double heightM) const;
    /// The inverse: height in metres of a plant of crown radius crownRadiusM (0 for r <= 0;
    /// the allometry is increasing when b > 0 / linearFactor > 0, as every biome's is).
    double heightForCrownRadiusM(double crownRadiusM) const;
};

/// A species' parameters of the EcoMod model (Zamuda & Brest; sim/ecomod.h, docs/ecomod.md),
/// from the optional `ecomod = { ... }` table of a [[species]]. A field the table does not give
/// is NaN and gets its documented default, derived from the species' other parameters, when
/// the EcoMod simulator resolves it (sim::resolveEcoModSpecies).
struct EcoModSpecies {
    static constexpr double kUnset = std::numeric_limits<double>::quiet_NaN();
    double maturityAgeYears = kUnset;     ///< t_m: average age at maturity (first seeds), years
    double fullGrownAgeYears = kUnset;    ///< t_a: average age when fully grown, years
    double maxAgeYears = kUnset;          ///< t_f: maximum potential age, years
    double matureHeightM = kUnset;        ///< h_m: height at maturity, m
    double fullHeightM = kUnset;          ///< height when fully grown, m
    double persistence = kUnset;          ///< p_persist: persistent clinging to life, [0, 1]
    double seedsPerYear = kUnset;         ///< seeds a mature tree sheds per year
    double germination = kUnset;          ///< share of last year's seeds that try to establish
    double nearProbability = kUnset;      ///< p_s: share of new trees placed near a parent (under-dispersion)
    double dispersalRadiusM = kUnset;     ///< a near seed lands within this distance of its parent, m
    double immigrantsPerHaYear = kUnset;  ///< new trees arriving from outside per hectare and year
    double dominatedSurvival = kUnset;    ///< probability that a dominated tree survives one year
    double dominatedGrowth = kUnset;      ///< years of growth age a dominated tree gains per year
    double elevationOpt = kUnset;         ///< y_o: optimal normalised elevation, [0, 1]
    double elevationTol = kUnset;         ///< Delta y_o: tolerated deviation
    double elevationHarm = kUnset;        ///< f_y: harmfulness per unit of deviation
    double moistureOpt = kUnset, moistureTol = kUnset, moistureHarm = kUnset;  ///< m_o, Delta m_o (mm), f_m (1/mm)
    double sunOpt = kUnset, sunTol = kUnset, sunHarm = kUnset;                 ///< l_o, Delta l_o (hours/day), f_l (day/hour)
    double windOpt = kUnset, windTol = kUnset, windHarm = kUnset;              ///< w_o, Delta w_o (m/s), f_w (s/m)
    double slopeHarm = kUnset;            ///< f_s: s = 1 - (f_s (1 - cos slope))^2
};

/// The keys of a species' `ecomod` table (all optional), with their allowed values.
const std::vector<ParamDesc<EcoModSpecies>>& ecomodSpeciesFields();

struct Species {
    std::string name;
    int id = 0;                      ///< index in Biome::species
    double maxAgeYears = 1.0;        ///< l_s
    double maxHeightM = 1.0;         ///< h'_s
    double alpha = 0.5;              ///< light absorption / vigour scale, [0, 1]
    Responses responses = defaultResponses();  ///< per factor (factors.h order and units): optimum c, range r;
                                               ///< indifferent for an optional factor the biome does not give
    std::string growthPeriod;        ///< name of a Biome::growthPeriods entry
    std::vector<int> growthMonths;   ///< resolved months, 0 = January
    Allometry allometry;
    std::vector<int> subBiomes;      ///< 1-based sub-biome numbers (as in the paper)
    bool canopy = false;             ///< can be a canopy tree
    EcoModSpecies ecomod;            ///< the optional `ecomod` table (EcoMod model; unset fields NaN)
    /// Fire tolerance in [0, 1] (optional key fire_tolerance; NaN = not given: the run's
    /// [disturbance.fire] default_tolerance applies). docs/disturbance.md.
    double fireTolerance = std::numeric_limits<double>::quiet_NaN();
    /// The response to factor f.
    const Response& response(Factor f) const { return responses[factorIndex(f)]; }
    Response& response(Factor f) { return responses[factorIndex(f)]; }
};

/// One key of a biome file's [[species]] table: what it means (with units), which values it
/// allows and where it lands in Species. parseBiome reads and checks every key from this
/// description, biomeToToml prints it, and docs/biome.md's species table has its row
/// (speciesDocRow; tests/biome_test.cpp checks each row), so a new numeric species
/// parameter is its field in Species and one Real row in speciesFields() below.
struct SpeciesField {
    enum class Kind {
        Name,          ///< the species' name, unique in the biome
        SubBiomes,     ///< the 1-based sub-biomes it belongs to
        Real,          ///< a number within `range`, in member `real`
        Response,      ///< { c = optimum, r = range } for factor `factor`
        GrowthPeriod,  ///< a name from [growth_periods] (also sets growthMonths)
        Allometry,     ///< a code from [allometry]
        Flag,          ///< true or false, in member `flag`
        EcoMod,        ///< the optional `ecomod = { ... }` table (ecomodSpeciesFields)
        OptionalReal,  ///< like Real, but may be absent (NaN in `real` then, and not printed)
    };
    std::string key;   ///< the TOML key
    std::string doc;   ///< the meaning: docs/biome.md's row
    std::string unit;  ///< "years", "m", ...; "" for a pure number, a name or a table
    Kind kind;
    std::string allowed;               ///< the allowed values in words (Real: range.valuesText())
    double Species::*real = nullptr;
    ParamRange range{};
    const char* rule = nullptr;        ///< message text of the range when not range.text()
    bool Species::*flag = nullptr;
    Factor factor = Factor::Sun;

    /// The allowed values as docs/biome.md states them.
    std::string allowedText() const {
        if (kind == Kind::OptionalReal) return range.valuesText() + "; optional";
        return kind == Kind::Real ? range.valuesText() : allowed;
    }
    /// The message text of a Real value outside its range ("must be positive").
    std::string ruleText() const { return rule ? std::string(rule) : range.text(); }
};

/// Every key of a [[species]] table, in the order files list them: the one description of a
/// species' parameters. All keys are required but the responses to optional factors
/// (FactorInfo::responseRequired false: wind), whose absence makes the species indifferent.
inline const std::vector<SpeciesField>& speciesFields() {
    using K = SpeciesField::Kind;
    using R = ParamRange;
    static const std::vector<SpeciesField> fields = [] {
        std::vector<SpeciesField> v = {
            {"name", "the species' name in every output and in `--target`", "", K::Name, "text, unique in the biome"},
            {"sub_biomes", "the sub-biomes (`[[sub_biome]]` numbers) the species grows in", "", K::SubBiomes,
             "a non-empty list of existing sub-biome numbers"},
            // Upper bounds well above any living plant (the oldest about 5000 years, the
            // tallest about 116 m): a typo such as 1e300 is refused, not simulated.
            {"max_age_years", "l_s: maximum age", "years", K::Real, "", &Species::maxAgeYears, R::openClosed(0, 10000)},
            {"max_height_m", "h'_s: maximum height", "m", K::Real, "", &Species::maxHeightM, R::openClosed(0, 200)},
            {"alpha", "alpha_s: share of the light the crown absorbs, and the vigour scale (Eq. 1)", "", K::Real, "",
             &Species::alpha, R::closed(0, 1)},
        };
        // One response per abiotic factor, named by the factor table (core/factors.h).
        for (std::size_t f = 0; f < kFactorCount; ++f) {
            SpeciesField r{kFactors[f].key,
                           std::string("response to ") + kFactors[f].label + " (Eq. 1): `{ c = optimum, r = range }`",
                           kFactors[f].unit,
                           K::Response,
                           kFactors[f].responseRequired
                               ? "c any number, r > 0"
                               : "c any number, r > 0; optional: without it the species is indifferent (no effect on vigour)"};
            r.factor = static_cast<Factor>(f);
            v.push_back(r);
        }
        v.push_back({"growth_period", "the months in which carbon overflow drives growth", "", K::GrowthPeriod,
                     "a name from `[growth_periods]`"});
        v.push_back({"allometry", "crown radius from height", "", K::Allometry, "a code from `[allometry]`"});
        v.push_back({"canopy", "the species can be a canopy tree", "", K::Flag, "true or false", nullptr, {}, nullptr,
                     &Species::canopy});
        v.push_back({"ecomod",
                     "optional: the species' parameters of the EcoMod model (`[model] kind = \"ecomod\"`; docs/ecomod.md), "
                     "`{ maturity_age_years = ..., ... }`; a key not given gets its documented default",
                     "", K::EcoMod, "a table of the keys in docs/ecomod.md"});
        v.push_back({"fire_tolerance",
                     "share of the fire kill probability the species resists (docs/disturbance.md); absent: the run's "
                     "`default_tolerance`",
                     "", K::OptionalReal, "", &Species::fireTolerance, R::closed(0, 1)});
        return v;
    }();
    return fields;
}

/// docs/biome.md's row of a species key: "| `key` | doc | unit | allowed values |" ("-" for no unit).
std::string speciesDocRow(const SpeciesField& f);

struct SubBiome {
    int number = 1;  ///< 1-based, as in the paper
    std::string name;
    std::vector<std::string> canopySpecies;
};

struct Climate {
    double latitudeDeg = 38.58;
    std::array<double, 12> temperatureC{};     ///< sea-level monthly mean, Jan..Dec
    std::array<double, 12> rainfallMm{};       ///< monthly total
    std::array<double, 12> skyClarity{};       ///< fraction of direct sun reaching ground, [0, 1]
    double lapseRateCPerKm = 9.8;
};

/// The prevailing wind of the biome ([wind], optional; these defaults without it) and the
/// parameters of EcoMod's wind-shelter model (Zamuda & Brest; docs/abiotics.md "Wind").
struct Wind {
    double directionDeg = 270.0;  ///< where the wind comes from, degrees clockwise from north (270: westerly)
    double strengthMS = 5.0;      ///< yearly mean speed of the prevailing wind on exposed ground, m/s
    double thresholdDeg = 45.0;   ///< occlusion angle at which the wind is fully sheltered (Theta_0), degrees
    int samples = 10;             ///< upwind samples N_w, one cell apart
};

struct Soil {
    double runoffLimitMm = 100.0;      ///< most water a cell absorbs in one month
    double slopeThresholdDeg = 5.0;    ///< below: all water infiltrates
    double slopeMaxDeg = 55.0;         ///< above: all water runs off
    double evaporationFraction = 0.25; ///< fraction of soil water evaporated per month
    double saturationMm = 180.0;       ///< soil water capacity
};

/// The scalar keys of the biome's [climate] table (the monthly lists are read by hand),
/// [soil] and [vigour] (core/param_desc.h): read by loadBiome, written by biomeToToml,
/// documented in docs/biome.md. slope_max_deg must also exceed slope_threshold_deg.
const std::vector<ParamDesc<Climate>>& climateFields();
const std::vector<ParamDesc<Soil>>& soilFields();
const std::vector<ParamDesc<VigourShape>>& vigourFields();
/// The keys of the optional [wind] table (all optional, defaults of Wind).
const std::vector<ParamDesc<Wind>>& windFields();

struct Biome {
    std::string name;
    std::string sourcePath;
    std::vector<Species> species;
    std::vector<SubBiome> subBiomes;
    Climate climate;
    Soil soil;
    VigourShape vigour;
    Wind wind;               ///< [wind], or the defaults of Wind
    bool windGiven = false;  ///< the file had a [wind] table: biomeToToml prints it only then, so that
                             ///< a biome without one keeps its record (and every output) as before
    std::vector<std::pair<std::string, std::vector<int>>> growthPeriods;

    /// Index of a species by exact name; ValidationError listing the names if unknown.
    int speciesIndex(const std::string& name) const;
    /// Vigour v_s = alpha_s * min_f g(x_f - c_sf, r_sf) of species s (Eq. 1, the scalar form
    /// of vigour.h) for the abiotic values x (one per factor, factors.h units).
    double vigourOf(int s, const Features& x) const;
};

/// Parse and validate a biome TOML file. Throws IoError (unreadable, bad TOML) or
/// ValidationError naming the file, species and field.
Biome loadBiome(const std::string& path);
/// Same from TOML text; `sourceName` is used in messages.
Biome parseBiome(const std::string& tomlText, const std::string& sourceName);
/// The embedded Sonoma biome (paper Table 3), identical to biomes/sonoma.toml.
Biome defaultBiome();
/// TOML text of a biome, loadable by parseBiome (used to record it in outputs).
std::string biomeToToml(const Biome& b);

}  // namespace eco
