#include "biome.h"

#include <toml++/toml.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <set>
#include <sstream>

#include "error.h"
#include "strict_toml.h"
#include "provenance.h"

namespace eco {

namespace detail {
extern const char* const kSonomaToml;
}

double Allometry::crownRadiusM(double heightM) const {
    if (heightM <= 0.0) return 0.0;
    return linear ? linearFactor * heightM : std::exp(a + b * std::log(heightM));
}

double Allometry::heightForCrownRadiusM(double crownRadiusM) const {
    if (crownRadiusM <= 0.0) return 0.0;
    if (linear) return linearFactor > 0 ? crownRadiusM / linearFactor : 0.0;
    return b != 0.0 ? std::exp((std::log(crownRadiusM) - a) / b) : 0.0;
}

const std::vector<ParamDesc<Climate>>& climateFields() {
    using K = ParamDesc<Climate>::Kind;
    using R = ParamRange;
    static const std::vector<ParamDesc<Climate>> f = {
        {"latitude_deg", "latitude of the biome (the sun's path)", "degrees north", K::Real, &Climate::latitudeDeg, nullptr,
         R::closed(-90, 90)},
        {"lapse_rate_c_per_km", "temperature fall with elevation", "C/km", K::Real, &Climate::lapseRateCPerKm, nullptr,
         R::closed(0, 50)},
    };
    return f;
}

const std::vector<ParamDesc<Soil>>& soilFields() {
    using K = ParamDesc<Soil>::Kind;
    using R = ParamRange;
    static const std::vector<ParamDesc<Soil>> f = {
        {"runoff_limit_mm", "most water a cell absorbs in a month", "mm/month", K::Real, &Soil::runoffLimitMm, nullptr, R::above(0)},
        {"slope_threshold_deg", "below this slope all water infiltrates", "degrees", K::Real, &Soil::slopeThresholdDeg, nullptr,
         R::closed(0, 90)},
        {"slope_max_deg", "above this slope all water runs off (> slope_threshold_deg)", "degrees", K::Real,
         &Soil::slopeMaxDeg, nullptr, R::closed(0, 90)},
        {"evaporation_fraction", "share of the soil water evaporated per month", "", K::Real, &Soil::evaporationFraction,
         nullptr, R::closed(0, 1)},
        {"saturation_mm", "soil water capacity", "mm", K::Real, &Soil::saturationMm, nullptr, R::above(0)},
    };
    return f;
}

const std::vector<ParamDesc<VigourShape>>& vigourFields() {
    using K = ParamDesc<VigourShape>::Kind;
    using R = ParamRange;
    static const std::vector<ParamDesc<VigourShape>> f = {
        {"a", "g(d) = (1 + a) exp((d / r)^p ln q) - a (Eq. 1): depth of the penalty beyond the range", "", K::Real,
         &VigourShape::a, nullptr, R::closed(0, 10)},
        {"q", "Eq. 1: (g + a) / (1 + a) at d = r", "", K::Real, &VigourShape::q, nullptr, R::open(0, 1)},
        {"p", "Eq. 1: sharpness of the fall towards the range", "", K::Real, &VigourShape::p, nullptr, R::above(0)},
    };
    return f;
}

const std::vector<ParamDesc<EcoModSpecies>>& ecomodSpeciesFields() {
    using R = ParamRange;
    using E = EcoModSpecies;
    // Every key is a real whose default is derived from the species' other keys
    // (sim/ecomod.cpp resolves them): the default in words (docs/ecomod.md's table).
    auto e = [](const char* key, const char* doc, const char* unit, double E::*member, ParamRange range, const char* dflt) {
        return ParamDesc<E>{key, doc, unit, ParamDesc<E>::Kind::Real, member, nullptr, range, nullptr, nullptr, dflt};
    };
    static const std::vector<ParamDesc<EcoModSpecies>> f = {
        e("maturity_age_years", "t_m: average age at maturity (first seeds; the polyline's first bend)", "years", &E::maturityAgeYears,
          R::openClosed(0, 10000), "0.1 x `max_age_years` of the species"),
        e("full_grown_age_years", "t_a: average age when fully grown", "years", &E::fullGrownAgeYears, R::openClosed(0, 10000),
          "0.5 x `max_age_years`"),
        e("max_age_years", "t_f: maximum potential age", "years", &E::maxAgeYears, R::openClosed(0, 10000), "the species' `max_age_years`"),
        e("mature_height_m", "h_m: height at maturity", "m", &E::matureHeightM, R::openClosed(0, 200), "0.6 x `full_height_m`"),
        e("full_height_m", "height when fully grown", "m", &E::fullHeightM, R::openClosed(0, 200), "the species' `max_height_m`"),
        e("persistence", "p_persist: persistent clinging to life", "", &E::persistence, R::closed(0, 1),
          "t_f / (t_f + 50): pioneers (short-lived) low, long-lived trees high"),
        e("seeds_per_year", "seeds a mature tree sheds per year", "1/year", &E::seedsPerYear, R::closed(0, 1e6), "2"),
        e("germination", "share of last year's seeds that try to establish", "", &E::germination, R::closed(0, 1), "0.5"),
        e("near_probability", "p_s: share of a parent's seeds that land near it", "", &E::nearProbability, R::closed(0, 1), "0.9"),
        e("dispersal_radius_m", "a near seed lands within this distance of its parent", "m", &E::dispersalRadiusM, R::openClosed(0, 10000),
          "2 x the crown radius at `full_height_m`, at least 1 m"),
        e("immigrants_per_ha_year", "new trees arriving from outside per hectare and year", "1/(ha year)", &E::immigrantsPerHaYear,
          R::closed(0, 1e6), "0.1"),
        e("dominated_survival", "probability that a dominated tree survives a year", "", &E::dominatedSurvival, R::closed(0, 1),
          "`persistence`"),
        e("dominated_growth", "growth age a dominated tree gains in a year", "years", &E::dominatedGrowth, R::closed(0, 1), "0"),
        e("elevation_opt", "y_o: optimal normalised elevation", "", &E::elevationOpt, R::closed(0, 1), "0.5"),
        e("elevation_tol", "Delta y_o: tolerated deviation of normalised elevation", "", &E::elevationTol, R::atLeast(0),
          "0.5 (indifferent: every normalised elevation is within it)"),
        e("elevation_harm", "f_y: harmfulness beyond the tolerance", "", &E::elevationHarm, R::atLeast(0), "1"),
        e("moisture_opt", "m_o: optimal moisture", "mm", &E::moistureOpt, R::any(), "c of the species' `moisture` response {c, r}"),
        e("moisture_tol", "Delta m_o: tolerated deviation", "mm", &E::moistureTol, R::atLeast(0),
          "r / 4 of the `moisture` response (full suitability within r/4 of the optimum)"),
        e("moisture_harm", "f_m: harmfulness beyond the tolerance", "1/mm", &E::moistureHarm, R::atLeast(0),
          "1 / r of the `moisture` response (none from r on, as Eq. 1's g reaches 0 near r)"),
        e("sun_opt", "l_o: optimal sunlight", "hours/day", &E::sunOpt, R::any(), "c of the `sun` response"),
        e("sun_tol", "Delta l_o: tolerated deviation", "hours/day", &E::sunTol, R::atLeast(0), "r / 4 of the `sun` response"),
        e("sun_harm", "f_l: harmfulness beyond the tolerance", "day/hour", &E::sunHarm, R::atLeast(0), "1 / r of the `sun` response"),
        e("wind_opt", "w_o: optimal wind exposure", "m/s", &E::windOpt, R::any(),
          "c of the `wind` response; 0 without one (the species is then indifferent)"),
        e("wind_tol", "Delta w_o: tolerated deviation", "m/s", &E::windTol, R::atLeast(0), "r / 4 of the `wind` response; infinite without one"),
        e("wind_harm", "f_w: harmfulness beyond the tolerance", "s/m", &E::windHarm, R::atLeast(0), "1 / r of the `wind` response; 0 without one"),
        e("slope_harm", "f_s: slope harmfulness, s = 1 - (f_s (1 - cos slope))^2", "", &E::slopeHarm, R::atLeast(0),
          "1 / (1 - cos(min(90, c + r))) from the `slope` response: s = 0 at the steepest slope the response tolerates"),
    };
    return f;
}

const std::vector<ParamDesc<Wind>>& windFields() {
    using K = ParamDesc<Wind>::Kind;
    using R = ParamRange;
    static const std::vector<ParamDesc<Wind>> f = {
        {"direction_deg", "where the prevailing wind comes from, clockwise from north (270: from the west)", "degrees",
         K::Real, &Wind::directionDeg, nullptr, R::closed(0, 360)},
        {"strength_m_s", "yearly mean speed of the prevailing wind on exposed ground", "m/s", K::Real, &Wind::strengthMS,
         nullptr, R::closed(0, 100)},
        {"threshold_deg", "occlusion angle at which the wind is fully sheltered (EcoMod's Theta_0)", "degrees", K::Real,
         &Wind::thresholdDeg, nullptr, R::openClosed(0, 90)},
        {"samples", "upwind samples N_w, one cell apart (EcoMod: 10)", "cells", K::Integer, nullptr, &Wind::samples,
         R::closed(1, 10000)},
    };
    return f;
}

double Biome::vigourOf(int s, const Features& x) const {
    const Species& sp = species[static_cast<std::size_t>(s)];
    return sp.alpha * minResponse(vigour, sp.responses, x);
}

int Biome::speciesIndex(const std::string& name) const {
    for (const auto& s : species)
        if (s.name == name) return s.id;
    std::string known;
    for (const auto& s : species) known += (known.empty() ? "" : ", ") + s.name;
    throw ValidationError("unknown species '" + name + "' in biome '" + this->name + "' (known: " + known + ")");
}

namespace {

Response readResponse(StrictTable& parent, const std::string& key, const std::string& file,
                      const std::string& context) {
    StrictTable t(parent.table(key), file, context + ": " + key);
    Response r;
    r.c = t.number("c");
    r.r = t.positive("r");
    t.finish();
    return r;
}

// Reads key f of a [[species]] table into s, checked against the biome read so far (its
// sub-biomes, growth periods and allometries); messages name the file, line, species and key.
void readSpeciesField(StrictTable& t, const SpeciesField& f, Species& s, const Biome& b,
                      const std::vector<Allometry>& allometries, const std::string& file, const std::string& ctx) {
    const std::string& key = f.key;
    switch (f.kind) {
        case SpeciesField::Kind::Name:
            s.name = t.string(key);
            for (const auto& other : b.species)
                if (other.name == s.name) t.fail(key, "duplicate species name '" + s.name + "'");
            break;
        case SpeciesField::Kind::SubBiomes:
            for (auto n : t.integers(key)) {
                if (n < 1 || n > static_cast<std::int64_t>(b.subBiomes.size()))
                    t.fail(key, "sub-biome " + std::to_string(n) + " does not exist (1.." +
                                    std::to_string(b.subBiomes.size()) + ")");
                s.subBiomes.push_back(static_cast<int>(n));
            }
            if (s.subBiomes.empty()) t.fail(key, "must name at least one sub-biome");
            break;
        case SpeciesField::Kind::Real: {
            const double v = t.number(key);
            if (!f.range.contains(v)) t.fail(key, "value " + StrictTable::fmt(v) + " " + f.ruleText());
            s.*(f.real) = v;
            break;
        }
        case SpeciesField::Kind::Response:
            if (!kFactors[factorIndex(f.factor)].responseRequired && !t.has(key)) s.response(f.factor) = Response::indifferent();
            else s.response(f.factor) = readResponse(t, key, file, ctx);
            break;
        case SpeciesField::Kind::GrowthPeriod: {
            s.growthPeriod = t.string(key);
            bool found = false;
            for (const auto& [name, months] : b.growthPeriods)
                if (name == s.growthPeriod) {
                    s.growthMonths = months;
                    found = true;
                }
            if (!found) t.fail(key, "unknown growth period '" + s.growthPeriod + "'");
            break;
        }
        case SpeciesField::Kind::Allometry: {
            const std::string code = t.string(key);
            bool found = false;
            for (const auto& al : allometries)
                if (al.code == code) {
                    s.allometry = al;
                    found = true;
                }
            if (!found) t.fail(key, "unknown allometry code '" + code + "'");
            break;
        }
        case SpeciesField::Kind::Flag: s.*(f.flag) = t.boolean(key); break;
        case SpeciesField::Kind::EcoMod: {
            if (!t.has(key)) break;
            StrictTable e(t.table(key), file, ctx + ": " + key);
            for (const auto& pf : ecomodSpeciesFields()) {
                if (!e.has(pf.key)) continue;
                const double v = e.number(pf.key);
                if (!pf.range.contains(v)) e.fail(pf.key, "value " + StrictTable::fmt(v) + " " + pf.ruleText());
                s.ecomod.*(pf.real) = v;
            }
            e.finish();
            break;
        }
        case SpeciesField::Kind::OptionalReal: {
            if (!t.has(key)) break;  // stays NaN: not given
            const double v = t.number(key);
            if (!f.range.contains(v)) t.fail(key, "value " + StrictTable::fmt(v) + " " + f.ruleText());
            s.*(f.real) = v;
            break;
        }
    }
}

// Key f of species s as a TOML value in a [[species]] table (the inverse of readSpeciesField).
void printSpeciesField(toml::table& st, const SpeciesField& f, const Species& s) {
    switch (f.kind) {
        case SpeciesField::Kind::Name: st.insert(f.key, s.name); break;
        case SpeciesField::Kind::SubBiomes: {
            toml::array subsOf;
            for (int n : s.subBiomes) subsOf.push_back(static_cast<std::int64_t>(n));
            st.insert(f.key, subsOf);
            break;
        }
        case SpeciesField::Kind::Real: st.insert(f.key, s.*(f.real)); break;
        case SpeciesField::Kind::Response:
            if (s.response(f.factor).isIndifferent()) break;  // an optional factor the species does not respond to
            st.insert(f.key, toml::table{{"c", s.response(f.factor).c}, {"r", s.response(f.factor).r}});
            break;
        case SpeciesField::Kind::GrowthPeriod: st.insert(f.key, s.growthPeriod); break;
        case SpeciesField::Kind::Allometry: st.insert(f.key, s.allometry.code); break;
        case SpeciesField::Kind::Flag: st.insert(f.key, s.*(f.flag)); break;
        case SpeciesField::Kind::EcoMod: {
            toml::table e;  // only the keys the file gave: a species without them prints as before
            for (const auto& pf : ecomodSpeciesFields())
                if (!std::isnan(s.ecomod.*(pf.real))) e.insert(pf.key, s.ecomod.*(pf.real));
            if (!e.empty()) st.insert(f.key, std::move(e));
            break;
        }
        case SpeciesField::Kind::OptionalReal:
            if (!std::isnan(s.*(f.real))) st.insert(f.key, s.*(f.real));
            break;
    }
}

}  // namespace

std::string speciesDocRow(const SpeciesField& f) {
    return "| `" + f.key + "` | " + f.doc + " | " + (f.unit.empty() ? std::string("-") : f.unit) + " | " + f.allowedText() + " |";
}

Biome parseBiome(const std::string& tomlText, const std::string& sourceName) {
    const toml::table root = parseTomlText(tomlText, sourceName);
    const std::string& file = sourceName;
    Biome b;
    b.sourcePath = sourceName;
    StrictTable top(root, file, "");

    {
        StrictTable t(top.table("biome"), file, "[biome]");
        b.name = t.string("name");
        t.finish();
    }
    {
        StrictTable t(top.table("climate"), file, "[climate]");
        readRequiredParams(t, b.climate, climateFields());
        const auto temp = t.numbers("temperature_c", 12);
        const auto rain = t.numbers("rainfall_mm", 12);
        const auto clar = t.numbers("sky_clarity", 12);
        for (int m = 0; m < 12; ++m) {
            b.climate.temperatureC[m] = temp[m];
            if (temp[m] < -90 || temp[m] > 60) t.fail("temperature_c", "month " + std::to_string(m) + " value " + StrictTable::fmt(temp[m]) + " outside [-90, 60]");
            b.climate.rainfallMm[m] = rain[m];
            if (rain[m] < 0) t.fail("rainfall_mm", "month " + std::to_string(m) + " value " + StrictTable::fmt(rain[m]) + " must not be negative");
            b.climate.skyClarity[m] = clar[m];
            if (clar[m] < 0 || clar[m] > 1) t.fail("sky_clarity", "month " + std::to_string(m) + " value " + StrictTable::fmt(clar[m]) + " outside [0, 1]");
        }
        t.finish();
    }
    {
        StrictTable t(top.table("soil"), file, "[soil]");
        readRequiredParams(t, b.soil, soilFields());
        if (b.soil.slopeMaxDeg <= b.soil.slopeThresholdDeg)
            t.fail("slope_max_deg", "must exceed slope_threshold_deg (" + StrictTable::fmt(b.soil.slopeThresholdDeg) + ")");
        t.finish();
    }
    {
        StrictTable t(top.table("vigour"), file, "[vigour]");
        readRequiredParams(t, b.vigour, vigourFields());
        t.finish();
    }
    if (top.has("wind")) {
        StrictTable t(top.table("wind"), file, "[wind]");
        readParams(t, b.wind, windFields());
        for (const auto& f : windFields())
            if (!f.range.contains(f.value(b.wind)))
                t.fail(f.key, "value " + StrictTable::fmt(f.value(b.wind)) + " " + f.ruleText());
        t.finish();
        b.windGiven = true;
    }
    {
        StrictTable t(top.table("growth_periods"), file, "[growth_periods]");
        for (const auto& [k, v] : top.table("growth_periods")) {
            const std::string key(k.str());
            std::vector<int> months;
            for (auto m : t.integers(key)) {
                if (m < 0 || m > 11) t.fail(key, "month " + std::to_string(m) + " outside 0-11 (0 = January)");
                if (std::find(months.begin(), months.end(), static_cast<int>(m)) != months.end())
                    t.fail(key, "month " + std::to_string(m) + " listed twice");
                months.push_back(static_cast<int>(m));
            }
            if (months.empty()) t.fail(key, "must list at least one month");
            b.growthPeriods.emplace_back(key, months);
        }
        t.finish();
    }
    std::vector<Allometry> allometries;
    {
        StrictTable t(top.table("allometry"), file, "[allometry]");
        for (const auto& [k, v] : top.table("allometry")) {
            const std::string code(k.str());
            StrictTable a(t.table(code), file, "[allometry." + code + "]");
            Allometry al;
            al.code = code;
            if (a.has("linear_factor")) {
                al.linear = true;
                al.linearFactor = a.positive("linear_factor");
            } else {
                al.a = a.number("a");
                al.b = a.positive("b");
            }
            a.finish();
            allometries.push_back(al);
        }
        t.finish();
    }
    {
        const toml::array& subs = top.array("sub_biome");
        for (std::size_t i = 0; i < subs.size(); ++i) {
            const toml::table* st = subs[i].as_table();
            if (!st) top.fail("sub_biome", "entry " + std::to_string(i) + " is not a table");
            StrictTable t(*st, file, "sub_biome #" + std::to_string(i + 1));
            SubBiome sb;
            sb.number = static_cast<int>(t.integer("number"));
            if (sb.number != static_cast<int>(i) + 1)
                t.fail("number", "sub-biomes must be numbered 1, 2, ... in order; got " + std::to_string(sb.number));
            sb.name = t.string("name");
            sb.canopySpecies = t.strings("canopy");
            t.finish();
            b.subBiomes.push_back(sb);
        }
        if (b.subBiomes.empty()) top.fail("sub_biome", "at least one sub-biome is required");
        if (b.subBiomes.size() > 16) top.fail("sub_biome", "at most 16 sub-biomes are supported");
    }
    {
        const toml::array& sps = top.array("species");
        if (sps.size() == 0) top.fail("species", "at least one species is required");
        for (std::size_t i = 0; i < sps.size(); ++i) {
            const toml::table* st = sps[i].as_table();
            if (!st) top.fail("species", "entry " + std::to_string(i) + " is not a table");
            std::string ctx = "species #" + std::to_string(i + 1);
            if (auto n = (*st)["name"].value<std::string>()) ctx = "species '" + *n + "'";
            StrictTable t(*st, file, ctx);
            Species s;
            s.id = static_cast<int>(i);
            for (const SpeciesField& f : speciesFields()) readSpeciesField(t, f, s, b, allometries, file, ctx);
            t.finish();
            b.species.push_back(s);
        }
    }
    // Cross-checks: sub-biome canopy lists name existing, canopy-capable member species.
    for (const auto& sb : b.subBiomes) {
        for (const auto& name : sb.canopySpecies) {
            auto it = std::find_if(b.species.begin(), b.species.end(), [&](const Species& s) { return s.name == name; });
            const std::string ctx = file + ": sub_biome " + std::to_string(sb.number) + " ('" + sb.name + "'): field 'canopy': ";
            if (it == b.species.end()) throw ValidationError(ctx + "unknown species '" + name + "'");
            if (!it->canopy) throw ValidationError(ctx + "species '" + name + "' has canopy = false");
            if (std::find(it->subBiomes.begin(), it->subBiomes.end(), sb.number) == it->subBiomes.end())
                throw ValidationError(ctx + "species '" + name + "' is not a member of this sub-biome");
        }
    }
    top.finish();
    return b;
}

Biome loadBiome(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    if (!in) throw IoError(path + ": cannot open biome file (missing or unreadable)");
    noteInputFile(path);  // recorded in /provenance with its hash
    std::ostringstream ss;
    ss << in.rdbuf();
    if (in.bad()) throw IoError(path + ": error while reading biome file");
    return parseBiome(ss.str(), path);
}

Biome defaultBiome() {
    Biome b = parseBiome(detail::kSonomaToml, "<embedded sonoma.toml>");
    return b;
}

std::string biomeToToml(const Biome& b) {
    toml::table root;
    root.insert("biome", toml::table{{"name", b.name}});
    auto arr = [](const auto& values) {
        toml::array a;
        for (auto v : values) a.push_back(v);
        return a;
    };
    auto paramTable = [](const auto& p, const auto& fields) {
        toml::table t;
        for (const auto& f : fields) t.insert(f.key, p.*(f.real));
        return t;
    };
    toml::table climate = paramTable(b.climate, climateFields());
    climate.insert("temperature_c", arr(b.climate.temperatureC));
    climate.insert("rainfall_mm", arr(b.climate.rainfallMm));
    climate.insert("sky_clarity", arr(b.climate.skyClarity));
    root.insert("climate", std::move(climate));
    root.insert("soil", paramTable(b.soil, soilFields()));
    root.insert("vigour", paramTable(b.vigour, vigourFields()));
    if (b.windGiven) {
        toml::table wind;
        for (const auto& f : windFields()) {
            if (f.kind == ParamDesc<Wind>::Kind::Integer) wind.insert(f.key, static_cast<std::int64_t>(b.wind.*(f.integer)));
            else wind.insert(f.key, b.wind.*(f.real));
        }
        root.insert("wind", std::move(wind));
    }
    toml::table periods;
    for (const auto& [name, months] : b.growthPeriods) {
        toml::array a;
        for (int m : months) a.push_back(static_cast<std::int64_t>(m));
        periods.insert(name, a);
    }
    root.insert("growth_periods", periods);
    toml::table allo;
    for (const auto& s : b.species) {
        if (allo.contains(s.allometry.code)) continue;
        if (s.allometry.linear) allo.insert(s.allometry.code, toml::table{{"linear_factor", s.allometry.linearFactor}});
        else allo.insert(s.allometry.code, toml::table{{"a", s.allometry.a}, {"b", s.allometry.b}});
    }
    root.insert("allometry", allo);
    toml::array subs;
    for (const auto& sb : b.subBiomes) {
        toml::array canopy;
        for (const auto& n : sb.canopySpecies) canopy.push_back(n);
        subs.push_back(toml::table{{"number", static_cast<std::int64_t>(sb.number)}, {"name", sb.name}, {"canopy", canopy}});
    }
    root.insert("sub_biome", subs);
    toml::array sps;
    for (const auto& s : b.species) {
        toml::table st;
        for (const SpeciesField& f : speciesFields()) printSpeciesField(st, f, s);
        sps.push_back(std::move(st));
    }
    root.insert("species", sps);
    std::ostringstream out;
    out << root;
    return out.str();
}

}  // namespace eco
