#include "sim_config.h"

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <sstream>

#include "error.h"
#include "strict_toml.h"

namespace eco::sim {

namespace {

// Shortest text that reads back as the same double (and always looks like a float in TOML).
std::string fmt(double v) {
    char buf[64];
    for (int precision = 6; precision <= 17; ++precision) {
        std::snprintf(buf, sizeof buf, "%.*g", precision, v);
        if (std::strtod(buf, nullptr) == v) break;
    }
    std::string s = buf;
    if (std::isfinite(v) && s.find_first_of(".eE") == std::string::npos) s += ".0";
    return s;
}

// The [model] keys, in one place for reading, writing and recording.
template <typename P, typename F>
void forEachParam(P& p, F&& f) {
    f("cell_size_m", p.cellSizeM);
    f("min_water_demand_mm", p.minWaterDemandMm);
    f("seeding_probability", p.seedingProbability);
    f("seed_inner_radius_factor", p.seedInnerRadiusFactor);
    f("seed_outer_radius_factor", p.seedOuterRadiusFactor);
    f("roulette_age_exponent", p.rouletteAgeExponent);
    f("survival_at_max_age", p.survivalAtMaxAge);
    f("pool_capacity_stress_months", p.poolCapacityStressMonths);
    f("canopy_threshold_m", p.canopyThresholdM);
    f("seeding_month", p.seedingMonth);
    f("seedling_growth_age_months", p.seedlingGrowthAgeMonths);
    f("growth_months_per_overflow", p.growthMonthsPerOverflow);
    f("deussen_dominated_survival", p.deussenDominatedSurvival);
}

template <typename E>
struct EnumName {
    E value;
    const char* name;
};
constexpr EnumName<GrowthRule> kGrowthRules[] = {{GrowthRule::Ideal, "ideal"}, {GrowthRule::Literal, "literal"}};
constexpr EnumName<CompetitionMode> kCompetitionModes[] = {{CompetitionMode::Resources, "resources"},
                                                           {CompetitionMode::Deussen, "deussen"}};

template <typename E, std::size_t N>
const EnumName<E>* findEnum(const std::string& text, const EnumName<E> (&names)[N]) {
    for (const auto& n : names)
        if (text == n.name) return &n;
    return nullptr;
}
// "'text' is not one of "a", "b"" for error messages.
template <typename E, std::size_t N>
std::string notOneOf(const std::string& text, const EnumName<E> (&names)[N]) {
    std::string accepted;
    for (const auto& n : names) accepted += std::string(accepted.empty() ? "" : ", ") + "\"" + n.name + "\"";
    return "'" + text + "' is not one of " + accepted;
}
// Reads an enum key spelled as one of `names` (absent: `out` unchanged).
template <typename E, std::size_t N>
void readEnum(StrictTable& t, const char* key, const EnumName<E> (&names)[N], E& out) {
    if (!t.has(key)) return;
    const std::string v = t.string(key);
    const EnumName<E>* e = findEnum(v, names);
    if (!e) t.fail(key, notOneOf(v, names));
    out = e->value;
}
template <typename E, std::size_t N>
E parseEnum(const std::string& text, const EnumName<E> (&names)[N], const std::string& what) {
    const EnumName<E>* e = findEnum(text, names);
    if (!e) throw ValidationError(what + ": " + notOneOf(text, names));
    return e->value;
}

}  // namespace

const char* growthRuleName(GrowthRule r) {
    for (const auto& n : kGrowthRules)
        if (n.value == r) return n.name;
    return "?";
}
const char* competitionModeName(CompetitionMode m) {
    for (const auto& n : kCompetitionModes)
        if (n.value == m) return n.name;
    return "?";
}

namespace {
// The first invalid parameter of `p`: its key and what is wrong ("" when all are valid).
// Shared by SimParams::validate and the config reader (which adds the key's line).
std::pair<std::string, std::string> firstInvalid(const SimParams& p) {
    auto bad = [](const char* key, double v, const char* what) {
        return std::pair<std::string, std::string>(key, "value " + fmt(v) + ": " + what);
    };
    if (!(p.cellSizeM > 0.001 && p.cellSizeM <= 10)) return bad("cell_size_m", p.cellSizeM, "must lie in (0.001, 10] metres");
    if (!(p.minWaterDemandMm >= 0)) return bad("min_water_demand_mm", p.minWaterDemandMm, "must not be negative");
    if (!(p.seedingProbability >= 0 && p.seedingProbability <= 1))
        return bad("seeding_probability", p.seedingProbability, "must lie in [0, 1]");
    if (!(p.seedInnerRadiusFactor >= 0)) return bad("seed_inner_radius_factor", p.seedInnerRadiusFactor, "must not be negative");
    if (!(p.seedOuterRadiusFactor > p.seedInnerRadiusFactor))
        return bad("seed_outer_radius_factor", p.seedOuterRadiusFactor, "must exceed seed_inner_radius_factor");
    if (!(p.rouletteAgeExponent >= 0 && p.rouletteAgeExponent <= 10))
        return bad("roulette_age_exponent", p.rouletteAgeExponent, "must lie in [0, 10]");
    if (!(p.survivalAtMaxAge > 0 && p.survivalAtMaxAge < 1))
        return bad("survival_at_max_age", p.survivalAtMaxAge, "must lie in (0, 1)");
    if (!(p.poolCapacityStressMonths > 0)) return bad("pool_capacity_stress_months", p.poolCapacityStressMonths, "must be positive");
    if (!(p.canopyThresholdM > 0)) return bad("canopy_threshold_m", p.canopyThresholdM, "must be positive");
    if (p.seedingMonth < 0 || p.seedingMonth > 11) return bad("seeding_month", p.seedingMonth, "must lie in 0..11 (0 = January)");
    if (!(p.seedlingGrowthAgeMonths > 0)) return bad("seedling_growth_age_months", p.seedlingGrowthAgeMonths, "must be positive");
    if (!(p.growthMonthsPerOverflow >= 0)) return bad("growth_months_per_overflow", p.growthMonthsPerOverflow, "must not be negative");
    if (!(p.deussenDominatedSurvival >= 0 && p.deussenDominatedSurvival <= 1))
        return bad("deussen_dominated_survival", p.deussenDominatedSurvival, "must lie in [0, 1]");
    if (p.growthRule != GrowthRule::Ideal && p.growthRule != GrowthRule::Literal)
        return bad("growth_rule", static_cast<double>(p.growthRule), "unknown growth rule");
    if (p.competition != CompetitionMode::Resources && p.competition != CompetitionMode::Deussen)
        return bad("competition", static_cast<double>(p.competition), "unknown competition mode");
    return {};
}
}  // namespace

GrowthRule parseGrowthRule(const std::string& text, const std::string& what) {
    return parseEnum(text, kGrowthRules, what);
}
CompetitionMode parseCompetitionMode(const std::string& text, const std::string& what) {
    return parseEnum(text, kCompetitionModes, what);
}

void SimParams::validate(const std::string& source) const {
    const auto [key, what] = firstInvalid(*this);
    if (!key.empty()) throw ValidationError(source + ": model parameter '" + key + "': " + what);
}

std::string SimParams::toToml() const {
    std::ostringstream os;
    os << "[model]\n";
    forEachParam(*this, [&](const char* key, const auto& v) { os << key << " = " << fmt(static_cast<double>(v)) << "\n"; });
    std::string s = os.str();
    // Integers must stay integers in TOML.
    const std::string key = "seeding_month = ";
    const auto pos = s.find(key);
    const auto end = s.find('\n', pos);
    s.replace(pos, end - pos, key + std::to_string(seedingMonth));
    s += std::string("growth_rule = \"") + growthRuleName(growthRule) + "\"\n";
    s += std::string("competition = \"") + competitionModeName(competition) + "\"\n";
    return s;
}

std::vector<std::pair<std::string, double>> SimParams::namedValues() const {
    std::vector<std::pair<std::string, double>> out;
    forEachParam(*this, [&](const char* key, const auto& v) { out.emplace_back(key, static_cast<double>(v)); });
    out.emplace_back("growth_rule", static_cast<double>(growthRule));   // 0 = ideal, 1 = literal
    out.emplace_back("competition", static_cast<double>(competition));  // 0 = resources, 1 = deussen
    return out;
}

std::string RunConfig::effectiveCheckpointPath() const {
    return checkpointPath.empty() ? outputPath + ".checkpoint.h5" : checkpointPath;
}

void RunConfig::validate() const {
    const std::string src = sourcePath.empty() ? std::string("run configuration") : sourcePath;
    params.validate(src);
    if (years < 1 || years > 100000)
        throw ValidationError(src + ": [run] years = " + std::to_string(years) + ": must lie in 1..100000");
    if (checkpointEveryYears < 0)
        throw ValidationError(src + ": [run] checkpoint_every_years must not be negative");
    if (abioticsPath.empty()) throw ValidationError(src + ": [inputs] abiotics: no abiotics file given");
    if (canopyPath.empty()) throw ValidationError(src + ": [inputs] canopy: no canopy file given");
    if (outputPath.empty()) throw ValidationError(src + ": [outputs] hdf5: no output file given");
    if (crop && !(crop->x1 > crop->x0 && crop->y1 > crop->y0))
        throw ValidationError(src + ": [run] crop: need x0 < x1 and y0 < y1");
    for (int y : snapshotYears)  // years beyond the run's length are skipped (a shorter run of the same config)
        if (y < 0) throw ValidationError(src + ": [run] snapshot_years: year " + std::to_string(y) + " is negative");
}

RunConfig parseRunConfig(const std::string& tomlText, const std::string& sourceName) {
    const toml::table root = parseTomlText(tomlText, sourceName);
    RunConfig c;
    c.sourcePath = sourceName;
    StrictTable top(root, sourceName, "");
    if (const toml::table* t = top.optionalTable("inputs")) {
        StrictTable s(*t, sourceName, "[inputs]");
        c.terrainPath = s.possiblyEmptyStringOr("terrain", c.terrainPath);
        c.abioticsPath = s.possiblyEmptyStringOr("abiotics", c.abioticsPath);
        c.canopyPath = s.possiblyEmptyStringOr("canopy", c.canopyPath);
        c.biomePath = s.possiblyEmptyStringOr("biome", c.biomePath);
        c.initialPath = s.possiblyEmptyStringOr("initial", c.initialPath);
        s.finish();
    }
    if (const toml::table* t = top.optionalTable("run")) {
        StrictTable s(*t, sourceName, "[run]");
        auto intIn = [&](const char* key, std::int64_t lo, std::int64_t hi, std::int64_t fallback) {
            const std::int64_t v = s.integerOr(key, fallback);
            if (v < lo || v > hi) s.fail(key, "value " + std::to_string(v) + " out of range");
            return v;
        };
        c.years = static_cast<int>(intIn("years", -2147483647, 2147483647, c.years));
        if (s.has("seed")) {
            const std::int64_t seed = s.integer("seed");
            if (seed < 0) s.fail("seed", "must not be negative");
            c.seed = static_cast<std::uint64_t>(seed);
        }
        if (s.has("crop")) {
            const auto v = s.numbers("crop", 4);
            c.crop = SimArea{v[0], v[1], v[2], v[3]};
            if (!(c.crop->x1 > c.crop->x0 && c.crop->y1 > c.crop->y0)) s.fail("crop", "need x0 < x1 and y0 < y1");
        }
        if (s.has("snapshot_years")) {
            const toml::array& a = s.array("snapshot_years");
            for (const double y : s.numbers("snapshot_years", a.size())) {
                if (y != std::floor(y) || std::fabs(y) > 2147483647.0) s.fail("snapshot_years", "years must be integers");
                c.snapshotYears.push_back(static_cast<int>(y));
            }
        }
        c.checkpointEveryYears =
            static_cast<int>(intIn("checkpoint_every_years", -2147483647, 2147483647, c.checkpointEveryYears));
        s.finish();
    }
    if (const toml::table* t = top.optionalTable("outputs")) {
        StrictTable s(*t, sourceName, "[outputs]");
        c.outputPath = s.possiblyEmptyStringOr("hdf5", c.outputPath);
        c.csvPath = s.possiblyEmptyStringOr("csv", c.csvPath);
        c.pngDir = s.possiblyEmptyStringOr("png_dir", c.pngDir);
        c.checkpointPath = s.possiblyEmptyStringOr("checkpoint", c.checkpointPath);
        s.finish();
    }
    if (const toml::table* t = top.optionalTable("model")) {
        StrictTable s(*t, sourceName, "[model]");
        forEachParam(c.params, [&](const char* key, auto& v) {
            using T = std::decay_t<decltype(v)>;
            if constexpr (std::is_same_v<T, int>) {
                const std::int64_t i = s.integerOr(key, v);
                if (i < -2147483647 || i > 2147483647) s.fail(key, "value out of range");
                v = static_cast<int>(i);
            } else {
                v = s.numberOr(key, v);
            }
        });
        readEnum(s, "growth_rule", kGrowthRules, c.params.growthRule);
        readEnum(s, "competition", kCompetitionModes, c.params.competition);
        s.finish();
        const auto [key, what] = firstInvalid(c.params);
        if (!key.empty()) s.fail(key, what);  // names the key's line when the file set it
    }
    top.finish();
    c.params.validate(sourceName);
    return c;
}

RunConfig loadRunConfig(const std::string& path) {
    std::ifstream in(path);
    if (!in) throw IoError(path + ": cannot open run configuration");
    std::stringstream ss;
    ss << in.rdbuf();
    return parseRunConfig(ss.str(), path);
}

namespace {
std::vector<double> parseNumberList(const std::string& text, const std::string& what) {
    std::vector<double> out;
    std::stringstream ss(text);
    std::string item;
    while (std::getline(ss, item, ',')) {
        try {
            std::size_t used = 0;
            const double v = std::stod(item, &used);
            while (used < item.size() && item[used] == ' ') ++used;
            if (used != item.size() || !std::isfinite(v)) throw std::invalid_argument(item);
            out.push_back(v);
        } catch (const std::exception&) {
            throw ValidationError(what + ": '" + text + "' is not a comma-separated list of numbers");
        }
    }
    return out;
}
}  // namespace

SimArea parseArea(const std::string& text, const std::string& what) {
    const auto v = parseNumberList(text, what);
    if (v.size() != 4 || !(v[2] > v[0] && v[3] > v[1]))
        throw ValidationError(what + ": '" + text + "': expected x0,y0,x1,y1 in metres with x0 < x1 and y0 < y1");
    return SimArea{v[0], v[1], v[2], v[3]};
}

std::vector<int> parseYearList(const std::string& text, const std::string& what) {
    std::vector<int> out;
    for (double v : parseNumberList(text, what)) {
        if (v != std::floor(v) || v < 0) throw ValidationError(what + ": '" + text + "': years must be non-negative integers");
        out.push_back(static_cast<int>(v));
    }
    return out;
}

}  // namespace eco::sim
