#include "sim_config.h"

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <stdexcept>

#include "error.h"
#include "param_desc.h"
#include "strict_toml.h"

namespace eco::sim {

namespace {

// Shortest text that reads back as the same double (and always looks like a float in TOML).
std::string fmt(double v) { return tomlReal(v); }

template <typename E>
struct EnumName {
    E value;
    const char* name;
};
constexpr EnumName<ModelKind> kModelKinds[] = {{ModelKind::Monthly, "monthly"}, {ModelKind::EcoMod, "ecomod"}};
constexpr EnumName<GrowthRule> kGrowthRules[] = {{GrowthRule::Ideal, "ideal"}, {GrowthRule::Literal, "literal"}};
constexpr EnumName<CompetitionMode> kCompetitionModes[] = {{CompetitionMode::Resources, "resources"},
                                                           {CompetitionMode::Deussen, "deussen"}};
constexpr EnumName<GerminationCells> kGerminationCells[] = {{GerminationCells::Uncovered, "uncovered"},
                                                            {GerminationCells::Every, "every"}};
constexpr EnumName<GerminationVigour> kGerminationVigours[] = {{GerminationVigour::MeanResources, "mean_resources"},
                                                               {GerminationVigour::MeanVigour, "mean_vigour"}};
constexpr EnumName<CanopyLimit> kCanopyLimits[] = {{CanopyLimit::ChmOrThreshold, "chm_or_threshold"},
                                                   {CanopyLimit::CanopyOnly, "canopy_only"}};

template <typename E, std::size_t N>
const char* enumName(E v, const EnumName<E> (&names)[N]) {
    for (const auto& n : names)
        if (n.value == v) return n.name;
    return "?";
}

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
const char* modelKindName(ModelKind k) { return enumName(k, kModelKinds); }
const char* germinationCellsName(GerminationCells g) { return enumName(g, kGerminationCells); }
const char* germinationVigourName(GerminationVigour g) { return enumName(g, kGerminationVigours); }
const char* canopyLimitName(CanopyLimit c) { return enumName(c, kCanopyLimits); }
std::vector<std::string> modelKindNames() {
    std::vector<std::string> names;
    for (const auto& n : kModelKinds) names.emplace_back(n.name);
    return names;
}

const std::vector<ParamDesc<SimParams>>& simParamFields() {
    using K = ParamDesc<SimParams>::Kind;
    using R = ParamRange;
    using P = SimParams;
    static const std::vector<ParamDesc<SimParams>> fields = {
        {"cell_size_m", "side of a simulation cell", "m", K::Real, &P::cellSizeM, nullptr, R::openClosed(0.001, 10), nullptr,
         "must lie in (0.001, 10] metres"},
        {"min_water_demand_mm", "minimum water demand of each plant over a cell (canopy trees take this first)", "mm/month", K::Real, &P::minWaterDemandMm, nullptr, R::atLeast(0),
         nullptr, "must not be negative"},
        {"seeding_probability", "gamma: germination probability a canopy tree adds to the cells of its inner seeding disc (yearly draw)", "", K::Real, &P::seedingProbability, nullptr, R::closed(0, 1)},
        {"seed_inner_radius_factor", "inner kernel radius", "crown radii", K::Real, &P::seedInnerRadiusFactor, nullptr,
         R::atLeast(0), nullptr, "must not be negative"},
        // Also more than seed_inner_radius_factor (firstInvalid).
        {"seed_outer_radius_factor", "outer kernel radius", "crown radii", K::Real, &P::seedOuterRadiusFactor, nullptr,
         R::any()},
        {"roulette_age_exponent", "beta: the species roulette weighs vbar_s / max_age_s^beta", "", K::Real, &P::rouletteAgeExponent, nullptr, R::closed(0, 10)},
        {"survival_at_max_age", "P_s: probability of surviving background mortality up to the maximum age", "", K::Real, &P::survivalAtMaxAge, nullptr,
         R{R::Bound::Open, 0, R::Bound::Open, 1}},
        {"pool_capacity_stress_months", "carbon pool capacity = this x alpha_s x a: months of the worst vigour a full pool survives", "months", K::Real, &P::poolCapacityStressMonths, nullptr,
         R::above(0), nullptr, "must be positive"},
        {"canopy_threshold_m", "undergrowth dies at this height where the CHM at its root is lower", "m", K::Real, &P::canopyThresholdM, nullptr, R::above(0),
         nullptr, "must be positive"},
        {"seeding_month", "germination at the end of this month (0 = January)", "month", K::Integer, nullptr, &P::seedingMonth,
         R::closed(0, 11), nullptr, "must lie in 0..11 (0 = January)"},
        {"seedling_growth_age_months", "growth age of a new seedling (its size via Eq. 3)", "months", K::Real, &P::seedlingGrowthAgeMonths, nullptr,
         R::above(0), nullptr, "must be positive"},
        {"growth_months_per_overflow",
         "months of growth age per unit overflow (a multiplier under both growth rules)", "months", K::Real,
         &P::growthMonthsPerOverflow, nullptr, R::atLeast(0), nullptr, "must not be negative"},
        {"deussen_dominated_survival",
         "Deussen mode: probability of surviving one year of domination by one plant", "", K::Real,
         &P::deussenDominatedSurvival, nullptr, R::closed(0, 1)},
    };
    return fields;
}

namespace {
// The first invalid parameter of `p`: its key and what is wrong ("" when all are valid), in
// the order of simParamFields. Shared by SimParams::validate and the config reader (which
// adds the key's line).
std::pair<std::string, std::string> firstInvalid(const SimParams& p) {
    auto bad = [](const std::string& key, double v, const std::string& what) {
        return std::pair<std::string, std::string>(key, "value " + fmt(v) + ": " + what);
    };
    for (const auto& f : simParamFields()) {
        const double v = f.value(p);
        if (!f.range.contains(v)) return bad(f.key, v, f.ruleText());
        if (f.real == &SimParams::seedOuterRadiusFactor && !(p.seedOuterRadiusFactor > p.seedInnerRadiusFactor))
            return bad(f.key, v, "must exceed seed_inner_radius_factor");
    }
    if (p.growthRule != GrowthRule::Ideal && p.growthRule != GrowthRule::Literal)
        return bad("growth_rule", static_cast<double>(p.growthRule), "unknown growth rule");
    if (p.competition != CompetitionMode::Resources && p.competition != CompetitionMode::Deussen)
        return bad("competition", static_cast<double>(p.competition), "unknown competition mode");
    if (std::string(germinationCellsName(p.germinationCells)) == "?")
        return bad("germination_cells", static_cast<double>(p.germinationCells), "unknown germination cells");
    if (std::string(germinationVigourName(p.germinationVigour)) == "?")
        return bad("germination_vigour", static_cast<double>(p.germinationVigour), "unknown germination vigour");
    if (std::string(modelKindName(p.kind)) == "?") return bad("kind", static_cast<double>(p.kind), "unknown model kind");
    if (std::string(canopyLimitName(p.canopyLimit)) == "?")
        return bad("canopy_limit", static_cast<double>(p.canopyLimit), "unknown canopy limit");
    return {};
}
}  // namespace

GrowthRule parseGrowthRule(const std::string& text, const std::string& what) {
    return parseEnum(text, kGrowthRules, what);
}
CompetitionMode parseCompetitionMode(const std::string& text, const std::string& what) {
    return parseEnum(text, kCompetitionModes, what);
}
ModelKind parseModelKind(const std::string& text, const std::string& what) { return parseEnum(text, kModelKinds, what); }
GerminationCells parseGerminationCells(const std::string& text, const std::string& what) {
    return parseEnum(text, kGerminationCells, what);
}
GerminationVigour parseGerminationVigour(const std::string& text, const std::string& what) {
    return parseEnum(text, kGerminationVigours, what);
}
CanopyLimit parseCanopyLimit(const std::string& text, const std::string& what) { return parseEnum(text, kCanopyLimits, what); }

void SimParams::validate(const std::string& source) const {
    const auto [key, what] = firstInvalid(*this);
    if (!key.empty()) throw ValidationError(source + ": model parameter '" + key + "': " + what);
}

std::string SimParams::toToml() const {
    std::ostringstream os;
    os << "[model]\n";
    for (const auto& f : simParamFields())  // integers stay integers in TOML
        os << f.key << " = " << (f.kind == ParamDesc<SimParams>::Kind::Integer ? std::to_string(this->*(f.integer)) : fmt(f.value(*this)))
           << "\n";
    std::string s = os.str();
    s += std::string("growth_rule = \"") + growthRuleName(growthRule) + "\"\n";
    s += std::string("competition = \"") + competitionModeName(competition) + "\"\n";
    s += std::string("germination_cells = \"") + germinationCellsName(germinationCells) + "\"\n";
    s += std::string("germination_vigour = \"") + germinationVigourName(germinationVigour) + "\"\n";
    s += std::string("canopy_limit = \"") + canopyLimitName(canopyLimit) + "\"\n";
    if (kind != ModelKind::Monthly) s += std::string("kind = \"") + modelKindName(kind) + "\"\n";
    return s;
}

std::vector<std::pair<std::string, double>> SimParams::namedValues() const {
    std::vector<std::pair<std::string, double>> out;
    for (const auto& f : simParamFields()) out.emplace_back(f.key, f.value(*this));
    out.emplace_back("growth_rule", static_cast<double>(growthRule));   // 0 = ideal, 1 = literal
    out.emplace_back("competition", static_cast<double>(competition));  // 0 = resources, 1 = deussen
    out.emplace_back("germination_cells", static_cast<double>(germinationCells));    // 0 = uncovered, 1 = every
    out.emplace_back("germination_vigour", static_cast<double>(germinationVigour));  // 0 = mean_resources, 1 = mean_vigour
    out.emplace_back("canopy_limit", static_cast<double>(canopyLimit));              // 0 = chm_or_threshold, 1 = canopy_only
    if (kind != ModelKind::Monthly) out.emplace_back("kind", static_cast<double>(kind));  // 1 = ecomod
    return out;
}

namespace {
// An enum's value and its names indexed by value (the EnumName tables list every value 0..N-1).
template <typename E, std::size_t N>
h5::EnumChoice choice(E value, const EnumName<E> (&names)[N]) {
    h5::EnumChoice c;
    c.value = static_cast<int>(value);
    c.names.resize(N);
    for (const auto& n : names) c.names.at(static_cast<std::size_t>(n.value)) = n.name;
    return c;
}
}  // namespace

std::vector<h5::NamedAttr> SimParams::typedValues() const {
    std::vector<h5::NamedAttr> out;
    for (const auto& f : simParamFields()) {
        if (f.kind == ParamDesc<SimParams>::Kind::Integer) out.push_back({f.key, static_cast<std::int64_t>(this->*(f.integer))});
        else out.push_back({f.key, f.value(*this)});
    }
    out.push_back({"growth_rule", choice(growthRule, kGrowthRules)});
    out.push_back({"competition", choice(competition, kCompetitionModes)});
    out.push_back({"germination_cells", choice(germinationCells, kGerminationCells)});
    out.push_back({"germination_vigour", choice(germinationVigour, kGerminationVigours)});
    out.push_back({"canopy_limit", choice(canopyLimit, kCanopyLimits)});
    if (kind != ModelKind::Monthly) out.push_back({"kind", choice(kind, kModelKinds)});
    return out;
}

std::string RunConfig::effectiveCheckpointPath() const {
    return checkpointPath.empty() ? outputPath + ".checkpoint.h5" : checkpointPath;
}

void RunConfig::validate() const {
    const std::string src = sourcePath.empty() ? std::string("run configuration") : sourcePath;
    params.validate(src);
    disturbance.validate(src);
    if (years < 1 || years > 100000)
        throw ValidationError(src + ": [run] years = " + std::to_string(years) + ": must lie in 1..100000");
    if (checkpointEveryYears < 0)
        throw ValidationError(src + ": [run] checkpoint_every_years must not be negative");
    if (abioticsPath.empty()) throw ValidationError(src + ": [inputs] abiotics: no abiotics file given");
    if (canopyPath.empty() && params.kind != ModelKind::EcoMod)  // EcoMod may start from empty ground
        throw ValidationError(src + ": [inputs] canopy: no canopy file given");
    if (outputPath.empty()) throw ValidationError(src + ": [outputs] hdf5: no output file given");
    if (crop && !(crop->x1 > crop->x0 && crop->y1 > crop->y0))
        throw ValidationError(src + ": [run] crop: need x0 < x1 and y0 < y1");
    for (int y : snapshotYears)  // years beyond the run's length are skipped (a shorter run of the same config)
        if (y < 0) throw ValidationError(src + ": [run] snapshot_years: year " + std::to_string(y) + " is negative");
}

namespace {
/// The path-valued keys of a run configuration and the members they set: read by
/// parseRunConfig (relative to the file) and listed by runConfigPathKeys (one list).
struct PathKey {
    const char* table;
    const char* key;
    std::string RunConfig::*member;
};
const std::vector<PathKey>& pathKeys() {
    static const std::vector<PathKey> keys = {
        {"inputs", "terrain", &RunConfig::terrainPath},   {"inputs", "abiotics", &RunConfig::abioticsPath},
        {"inputs", "canopy", &RunConfig::canopyPath},     {"inputs", "biome", &RunConfig::biomePath},
        {"inputs", "initial", &RunConfig::initialPath},   {"outputs", "hdf5", &RunConfig::outputPath},
        {"outputs", "csv", &RunConfig::csvPath},          {"outputs", "png_dir", &RunConfig::pngDir},
        {"outputs", "checkpoint", &RunConfig::checkpointPath}};
    return keys;
}
}  // namespace

namespace {
// Reads a [disturbance.KIND] table into s by its descriptors (fireFields(), stormFields()):
// the table's presence switches the kind on; each key given is read with its type and
// checked against its range at once, so that a message names the file, the key's line, the
// table, the key and the value; unknown keys are errors.
template <typename S>
void readDisturbanceConfigTable(StrictTable& t, S& s, const std::vector<DisturbanceField<S>>& fields) {
    using K = typename DisturbanceField<S>::Kind;
    s.enabled = true;
    for (const auto& f : fields) {
        const std::string key = f.key();
        switch (f.kind) {
            case K::Enabled:
                if (t.has(key)) s.enabled = t.boolean(key);
                break;
            case K::ReturnInterval:
                if (!t.has(key)) break;
                for (const auto& other : fields)  // the interval is another spelling of the probability
                    if (other.kind == K::Timing && other.timing->real == &EventTiming::probabilityPerYear && t.has(other.key()))
                        t.fail(key, std::string("give ") + other.key() + " or " + key + ", not both");
                {
                    const double years = t.number(key);
                    if (!f.range.contains(years)) t.fail(key, "value " + fmt(years) + ": " + f.ruleText());
                    s.timing.probabilityPerYear = 1.0 / years;
                }
                break;
            case K::ForcedYears:
                if (!t.has(key)) break;
                for (const std::int64_t y : t.integers(key)) {
                    if (!f.range.contains(static_cast<double>(y))) t.fail(key, "value " + std::to_string(y) + ": " + f.ruleText());
                    s.timing.forcedYears.push_back(static_cast<int>(y));
                }
                break;
            case K::Timing:
                if (readParam(t, s.timing, *f.timing) && !f.timing->range.contains(f.timing->value(s.timing)))
                    t.fail(key, "value " + f.tomlValue(s) + ": " + f.ruleText());
                break;
            case K::Setting:
                if (readParam(t, s, *f.setting) && !f.setting->range.contains(f.setting->value(s)))
                    t.fail(key, "value " + f.tomlValue(s) + ": " + f.ruleText());
                break;
        }
    }
    t.finish();
}
}  // namespace

RunConfig parseRunConfig(const std::string& tomlText, const std::string& sourceName, const std::string& filePath) {
    const toml::table root = parseTomlText(tomlText, sourceName);
    // A path the file sets is relative to the file's directory; defaults stay as they are.
    RunConfig c;
    const auto readPaths = [&](StrictTable& s, const std::string& table) {
        for (const PathKey& p : pathKeys())
            if (table == p.table && s.has(p.key))
                c.*(p.member) = pathRelativeToConfig(filePath, s.possiblyEmptyStringOr(p.key, c.*(p.member)));
    };
    c.sourcePath = sourceName;
    StrictTable top(root, sourceName, "");
    if (const toml::table* t = top.optionalTable("inputs")) {
        StrictTable s(*t, sourceName, "[inputs]");
        readPaths(s, "inputs");
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
        readPaths(s, "outputs");
        s.finish();
    }
    if (const toml::table* t = top.optionalTable("model")) {
        StrictTable s(*t, sourceName, "[model]");
        readParams(s, c.params, simParamFields());
        readEnum(s, "growth_rule", kGrowthRules, c.params.growthRule);
        readEnum(s, "competition", kCompetitionModes, c.params.competition);
        readEnum(s, "germination_cells", kGerminationCells, c.params.germinationCells);
        readEnum(s, "germination_vigour", kGerminationVigours, c.params.germinationVigour);
        readEnum(s, "canopy_limit", kCanopyLimits, c.params.canopyLimit);
        readEnum(s, "kind", kModelKinds, c.params.kind);
        s.finish();
        const auto [key, what] = firstInvalid(c.params);
        if (!key.empty()) s.fail(key, what);  // names the key's line when the file set it
    }
    if (const toml::table* t = top.optionalTable("disturbance")) {
        StrictTable d(*t, sourceName, "[disturbance]");
        if (const toml::table* ft = d.optionalTable("fire")) {
            StrictTable s(*ft, sourceName, "[disturbance.fire]");
            readDisturbanceConfigTable(s, c.disturbance.fire, fireFields());
        }
        if (const toml::table* st = d.optionalTable("storm")) {
            StrictTable s(*st, sourceName, "[disturbance.storm]");
            readDisturbanceConfigTable(s, c.disturbance.storm, stormFields());
        }
        d.finish();
    }
    top.finish();
    c.params.validate(sourceName);
    c.disturbance.validate(sourceName);
    return c;
}

namespace detail {
extern const char* const kSimDefaultToml;
}

const char* embeddedDefaultRunConfigToml() { return detail::kSimDefaultToml; }

namespace {
// The [disturbance.*] tables at their defaults, commented out: a table's presence switches
// its events on, so the defaults print them as a template (the written keys of fireFields()
// and stormFields(), each with its doc line).
std::string disturbanceDefaultsToml() {
    std::string text =
        "\n# Fire and windthrow storms (docs/disturbance.md), in either model: off unless their table is\n"
        "# present (uncomment one to switch it on). Every key at its default; probability_per_year = 0\n"
        "# and no forced years strike nothing (return_interval_years = T instead: probability 1 / T).\n";
    const std::string tables = "[disturbance.fire]\n" + disturbanceTomlLines(FireSettings{}, fireFields(), true) +
                               "[disturbance.storm]\n" + disturbanceTomlLines(StormSettings{}, stormFields(), true);
    for (std::size_t begin = 0; begin < tables.size();) {
        const std::size_t end = tables.find('\n', begin);
        const std::size_t stop = end == std::string::npos ? tables.size() : end;
        text += "# " + tables.substr(begin, stop - begin) + "\n";
        begin = stop + 1;
    }
    return text;
}
}  // namespace

std::string defaultRunConfigToml() {
    std::string text = detail::kSimDefaultToml;
    // The file's [model] table (and the comment block just above it) is replaced by the one
    // description of the model constants, so that a key added to SimParams shows here even
    // when configs/sim-default.toml does not list it.
    std::size_t cut = text.find("\n[model]");
    if (cut == std::string::npos) throw std::logic_error("configs/sim-default.toml as built in has no [model] table");
    while (cut > 0) {  // back over the comment lines right above [model]
        const std::size_t lineStart = text.rfind('\n', cut - 1);
        const std::size_t begin = lineStart == std::string::npos ? 0 : lineStart + 1;
        if (text.compare(begin, 1, "#") != 0) break;
        cut = begin == 0 ? 0 : begin - 1;
    }
    text.resize(cut);
    return text + "\n# Model constants (paper §6.1 and SPEC §5), every one at its default (docs/simulator.md).\n" +
           SimParams{}.toToml() +
           "# The model: \"monthly\" (the paper's, above) or \"ecomod\" (Zamuda & Brest, yearly; docs/ecomod.md)\n"
           "kind = \"monthly\"\n" +
           disturbanceDefaultsToml();
}

const std::vector<std::pair<std::string, std::string>>& runConfigPathKeys() {
    static const std::vector<std::pair<std::string, std::string>> keys = [] {
        std::vector<std::pair<std::string, std::string>> out;
        for (const PathKey& p : pathKeys()) out.emplace_back(p.table, p.key);
        return out;
    }();
    return keys;
}

const std::vector<std::string>& embeddedRunConfigNames() {
    static const std::vector<std::string> names = {"sim-default.toml"};
    return names;
}

bool namesEmbeddedConfig(const std::string& path) { return path.rfind(kEmbeddedConfigPrefix, 0) == 0; }

namespace {
const char* embeddedText(const std::string& name) {
    if (name == "sim-default.toml") return detail::kSimDefaultToml;
    return nullptr;
}
std::string embeddedNamesText() {
    std::string names;
    for (const auto& n : embeddedRunConfigNames()) names += (names.empty() ? "" : ", ") + std::string(kEmbeddedConfigPrefix) + n;
    return names;
}
}  // namespace

std::string embeddedRunConfigToml(const std::string& path) {
    const char* text = namesEmbeddedConfig(path) ? embeddedText(path.substr(std::string(kEmbeddedConfigPrefix).size())) : nullptr;
    if (!text) throw IoError(path + ": no such configuration built into eco (built in: " + embeddedNamesText() + ")");
    return text;
}

RunConfig loadRunConfig(const std::string& path, const std::function<void(const std::string&)>& note) {
    namespace fs = std::filesystem;
    const std::string names = embeddedNamesText();
    if (namesEmbeddedConfig(path)) return parseRunConfig(embeddedRunConfigToml(path), path, "");
    std::error_code ec;
    // The fallback covers a configuration copied alone into a folder (its sim-default.toml is
    // not beside it); a path through a directory that does not exist is a typo: an error.
    const fs::path parent = fs::path(path).parent_path();
    if (!fs::exists(path, ec) && fs::is_directory(parent.empty() ? fs::path(".") : parent, ec)) {
        const std::string name = fs::path(path).filename().string();
        if (const char* text = embeddedText(name)) {
            if (note)
                note(path + " not found: using the copy of configs/" + name + " built into eco (" + kEmbeddedConfigPrefix +
                     name + "; 'eco config defaults simulate' prints it)");
            return parseRunConfig(text, kEmbeddedConfigPrefix + name, "");
        }
    }
    std::ifstream in(path);
    if (!in) throw IoError(path + ": cannot open run configuration (missing or unreadable; built in: " + names + ")");
    std::stringstream ss;
    ss << in.rdbuf();
    return parseRunConfig(ss.str(), path, path);
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
