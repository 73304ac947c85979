#include "sim_config.h"

#include <toml++/toml.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <set>
#include <sstream>

#include "error.h"

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

// Reads one TOML table and remembers the keys it used, so that finish() can reject the rest.
class Strict {
public:
    Strict(const toml::table& t, std::string file, std::string context)
        : t_(t), file_(std::move(file)), context_(std::move(context)) {}

    [[noreturn]] void fail(const std::string& key, const std::string& what) const {
        std::string loc = file_;
        const toml::node* n = t_.get(key);
        const auto line = n ? n->source().begin.line : t_.source().begin.line;
        if (line > 0) loc += ":" + std::to_string(line);
        throw ValidationError(loc + ": [" + context_ + "] key '" + key + "': " + what);
    }
    const toml::node* get(const std::string& key) {
        used_.insert(key);
        return t_.get(key);
    }
    bool has(const std::string& key) const { return t_.contains(key); }

    void number(const std::string& key, double& out) {
        const toml::node* n = get(key);
        if (!n) return;
        if (auto f = n->value_exact<double>()) out = *f;
        else if (auto i = n->value_exact<std::int64_t>()) out = static_cast<double>(*i);
        else fail(key, "expected a number");
        if (!std::isfinite(out)) fail(key, "value is not finite");
    }
    void integer(const std::string& key, int& out) {
        const toml::node* n = get(key);
        if (!n) return;
        auto i = n->value_exact<std::int64_t>();
        if (!i) fail(key, "expected an integer");
        if (*i < -2147483647 || *i > 2147483647) fail(key, "value out of range");
        out = static_cast<int>(*i);
    }
    void unsignedInt(const std::string& key, std::uint64_t& out) {
        const toml::node* n = get(key);
        if (!n) return;
        auto i = n->value_exact<std::int64_t>();
        if (!i) fail(key, "expected an integer");
        if (*i < 0) fail(key, "must not be negative");
        out = static_cast<std::uint64_t>(*i);
    }
    void string(const std::string& key, std::string& out) {
        const toml::node* n = get(key);
        if (!n) return;
        auto s = n->value_exact<std::string>();
        if (!s) fail(key, "expected a string");
        out = *s;
    }
    std::vector<double> numbers(const std::string& key) {
        const toml::node* n = get(key);
        std::vector<double> v;
        if (!n) return v;
        const toml::array* a = n->as_array();
        if (!a) fail(key, "expected an array of numbers");
        for (const auto& e : *a) {
            if (auto f = e.value_exact<double>()) v.push_back(*f);
            else if (auto i = e.value_exact<std::int64_t>()) v.push_back(static_cast<double>(*i));
            else fail(key, "expected an array of numbers");
        }
        return v;
    }
    const toml::table* table(const std::string& key) {
        const toml::node* n = get(key);
        if (!n) return nullptr;
        const toml::table* t = n->as_table();
        if (!t) fail(key, "expected a table");
        return t;
    }
    void finish() const {
        for (const auto& [k, v] : t_) {
            const std::string key(k.str());
            if (!used_.count(key)) {
                std::string loc = file_;
                if (v.source().begin.line > 0) loc += ":" + std::to_string(v.source().begin.line);
                throw ValidationError(loc + ": unknown key '" + key + "' in [" + context_ +
                                      "] (see docs/simulator.md for the accepted keys)");
            }
        }
    }

private:
    const toml::table& t_;
    std::string file_, context_;
    std::set<std::string> used_;
};

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
}

}  // namespace

void SimParams::validate(const std::string& source) const {
    auto bad = [&](const char* key, double v, const char* what) {
        throw ValidationError(source + ": model parameter '" + key + "' = " + fmt(v) + ": " + what);
    };
    if (!(cellSizeM > 0.001 && cellSizeM <= 10)) bad("cell_size_m", cellSizeM, "must lie in (0.001, 10] metres");
    if (!(minWaterDemandMm >= 0)) bad("min_water_demand_mm", minWaterDemandMm, "must not be negative");
    if (!(seedingProbability >= 0 && seedingProbability <= 1))
        bad("seeding_probability", seedingProbability, "must lie in [0, 1]");
    if (!(seedInnerRadiusFactor >= 0)) bad("seed_inner_radius_factor", seedInnerRadiusFactor, "must not be negative");
    if (!(seedOuterRadiusFactor > seedInnerRadiusFactor))
        bad("seed_outer_radius_factor", seedOuterRadiusFactor, "must exceed seed_inner_radius_factor");
    if (!(rouletteAgeExponent >= 0 && rouletteAgeExponent <= 10))
        bad("roulette_age_exponent", rouletteAgeExponent, "must lie in [0, 10]");
    if (!(survivalAtMaxAge > 0 && survivalAtMaxAge < 1))
        bad("survival_at_max_age", survivalAtMaxAge, "must lie in (0, 1)");
    if (!(poolCapacityStressMonths > 0)) bad("pool_capacity_stress_months", poolCapacityStressMonths, "must be positive");
    if (!(canopyThresholdM > 0)) bad("canopy_threshold_m", canopyThresholdM, "must be positive");
    if (seedingMonth < 0 || seedingMonth > 11) bad("seeding_month", seedingMonth, "must lie in 0..11 (0 = January)");
    if (!(seedlingGrowthAgeMonths > 0)) bad("seedling_growth_age_months", seedlingGrowthAgeMonths, "must be positive");
    if (!(growthMonthsPerOverflow >= 0)) bad("growth_months_per_overflow", growthMonthsPerOverflow, "must not be negative");
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
    return s;
}

std::vector<std::pair<std::string, double>> SimParams::namedValues() const {
    std::vector<std::pair<std::string, double>> out;
    forEachParam(*this, [&](const char* key, const auto& v) { out.emplace_back(key, static_cast<double>(v)); });
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
    toml::table root;
    try {
        root = toml::parse(tomlText, sourceName);
    } catch (const toml::parse_error& e) {
        throw IoError(sourceName + ":" + std::to_string(e.source().begin.line) + ": invalid TOML: " +
                      std::string(e.description()));
    }
    RunConfig c;
    c.sourcePath = sourceName;
    Strict top(root, sourceName, "top level");
    if (const toml::table* t = top.table("inputs")) {
        Strict s(*t, sourceName, "inputs");
        s.string("terrain", c.terrainPath);
        s.string("abiotics", c.abioticsPath);
        s.string("canopy", c.canopyPath);
        s.string("biome", c.biomePath);
        s.string("initial", c.initialPath);
        s.finish();
    }
    if (const toml::table* t = top.table("run")) {
        Strict s(*t, sourceName, "run");
        s.integer("years", c.years);
        s.unsignedInt("seed", c.seed);
        if (s.has("crop")) {
            const auto v = s.numbers("crop");
            if (v.size() != 4) s.fail("crop", "expected [x0, y0, x1, y1] in metres");
            c.crop = SimArea{v[0], v[1], v[2], v[3]};
            if (!(c.crop->x1 > c.crop->x0 && c.crop->y1 > c.crop->y0)) s.fail("crop", "need x0 < x1 and y0 < y1");
        }
        for (double y : s.numbers("snapshot_years")) {
            if (y != std::floor(y)) s.fail("snapshot_years", "years must be integers");
            c.snapshotYears.push_back(static_cast<int>(y));
        }
        s.integer("checkpoint_every_years", c.checkpointEveryYears);
        s.finish();
    }
    if (const toml::table* t = top.table("outputs")) {
        Strict s(*t, sourceName, "outputs");
        s.string("hdf5", c.outputPath);
        s.string("csv", c.csvPath);
        s.string("png_dir", c.pngDir);
        s.string("checkpoint", c.checkpointPath);
        s.finish();
    }
    if (const toml::table* t = top.table("model")) {
        Strict s(*t, sourceName, "model");
        forEachParam(c.params, [&](const char* key, auto& v) {
            using T = std::decay_t<decltype(v)>;
            if constexpr (std::is_same_v<T, int>) s.integer(key, v);
            else s.number(key, v);
        });
        s.finish();
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
