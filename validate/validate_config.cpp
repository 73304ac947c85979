#include "validate_config.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <regex>
#include <set>
#include <sstream>

#include "error.h"
#include "scenario.h"
#include "strict_toml.h"

namespace eco::validate {

namespace fs = std::filesystem;

const char* modeName(Mode m) { return m == Mode::Quick ? "quick" : "full"; }

bool CheckSpec::passes(double v) const {
    if (!std::isfinite(v)) return false;
    switch (kind) {
        case Kind::Approx: return std::abs(v - target) <= tolerance;
        case Kind::AtLeast: return v >= target;
        case Kind::AtMost: return v <= target;
    }
    return false;
}

bool CheckSpec::intervalPasses(double lo, double hi) const {
    if (!std::isfinite(lo) || !std::isfinite(hi) || lo > hi) return false;
    switch (kind) {
        case Kind::Approx: return lo >= target - tolerance && hi <= target + tolerance;
        case Kind::AtLeast: return lo >= target;
        case Kind::AtMost: return hi <= target;
    }
    return false;
}

static std::string shortNum(double v) {
    std::ostringstream os;
    os.precision(4);
    os << v;
    return os.str();
}

std::string CheckSpec::expectedText() const {
    switch (kind) {
        case Kind::Approx: return shortNum(target) + " ± " + shortNum(tolerance);
        case Kind::AtLeast: return ">= " + shortNum(target);
        case Kind::AtMost: return "<= " + shortNum(target);
    }
    return "";
}

CheckSpec CheckSpec::forMode(Mode m) const {
    if (m != Mode::Quick || !hasQuickBound) return *this;
    CheckSpec q = *this;
    q.target = quickTarget;
    q.tolerance = quickTolerance;
    q.why = quickWhy + " (quick run; the full run's bound is " + expectedText() + (why.empty() ? "" : ": " + why) + ")";
    q.hasQuickBound = false;
    return q;
}

const char* CheckSpec::comparator() const {
    switch (kind) {
        case Kind::Approx: return "approx";
        case Kind::AtLeast: return "min";
        case Kind::AtMost: return "max";
    }
    return "";
}

const CheckSpec& ScenarioConfig::check(const std::string& id) const {
    for (const CheckSpec& c : checks)
        if (c.id == id) return c;
    throw ValidationError(path + ": no check '" + id + "'");
}

namespace {

toml::table parseText(const std::string& text, const std::string& path) { return parseTomlText(text, path); }

// The [model] table is read by the simulator's own strict parser (sim::parseRunConfig), so
// that the keys, ranges and messages are exactly those of a run configuration. Every line
// outside [model] is blanked, which keeps the line numbers of its messages right.
// `overrides` ("key = value" lines, ConfigSource::modelOverrides) replace the file's keys of
// the same name: they are inserted after its [model] header (or in a [model] table appended
// when it has none), and its own lines of those keys are blanked.
sim::SimParams parseModelTable(const std::string& text, const std::string& path, const std::vector<std::string>& overrides) {
    static const std::regex header(R"(^\s*\[\s*([A-Za-z0-9_.\-"]+)\s*\]\s*(#.*)?$)");
    static const std::regex keyLine(R"(^\s*([A-Za-z0-9_\-]+)\s*=.*$)");
    std::set<std::string> overridden;
    for (const std::string& o : overrides) {
        std::smatch m;
        if (std::regex_match(o, m, keyLine)) overridden.insert(m[1].str());
    }
    std::string block;
    for (const std::string& o : overrides) block += o + "\n";
    std::istringstream in(text);
    std::string line, kept;
    bool inModel = false, sawModel = false;
    while (std::getline(in, line)) {
        std::smatch m;
        if (std::regex_match(line, m, header)) {
            inModel = m[1].str() == "model";
            if (inModel && !overrides.empty()) {
                sawModel = true;
                kept += line + "\n" + block;  // the overrides' lines shift the rest of [model] down
                continue;
            }
        }
        if (inModel && std::regex_match(line, m, keyLine) && overridden.count(m[1].str())) line.clear();
        kept += (inModel ? line : std::string()) + "\n";
    }
    if (!overrides.empty() && !sawModel) kept += "[model]\n" + block;
    return sim::parseRunConfig(kept, path).params;
}

CheckSpec parseCheck(const toml::table& t, const std::string& path, const std::string& id) {
    StrictTable s(t, path, "[checks." + id + "]");
    CheckSpec c;
    c.id = id;
    const bool hasExpected = s.has("expected"), hasMin = s.has("min"), hasMax = s.has("max");
    const int kinds = (hasExpected ? 1 : 0) + (hasMin ? 1 : 0) + (hasMax ? 1 : 0);
    if (kinds != 1) s.fail(hasExpected ? "expected" : (hasMin ? "min" : "max"),
                           "give exactly one of 'expected' (with 'tolerance'), 'min' or 'max'");
    if (hasExpected) {
        c.kind = CheckSpec::Kind::Approx;
        c.target = s.number("expected");
        c.tolerance = s.number("tolerance");
        if (!(c.tolerance >= 0)) s.fail("tolerance", "must not be negative");
    } else if (hasMin) {
        c.kind = CheckSpec::Kind::AtLeast;
        c.target = s.number("min");
    } else {
        c.kind = CheckSpec::Kind::AtMost;
        c.target = s.number("max");
    }
    if (!hasExpected && s.has("tolerance")) s.fail("tolerance", "only with 'expected'");
    c.units = s.has("units") ? s.string("units") : std::string();
    c.why = s.has("why") ? s.string("why") : std::string();
    c.knownDeviation = s.has("known_deviation") ? s.string("known_deviation") : std::string();
    // An optional looser bound for --quick, of the same kind and not stricter.
    const bool qExpected = s.has("quick_expected"), qMin = s.has("quick_min"), qMax = s.has("quick_max");
    if (qExpected || qMin || qMax) {
        const char* own = hasExpected ? "quick_expected" : (hasMin ? "quick_min" : "quick_max");
        const char* given = qExpected ? "quick_expected" : (qMin ? "quick_min" : "quick_max");
        if ((qExpected ? 1 : 0) + (qMin ? 1 : 0) + (qMax ? 1 : 0) != 1 || std::string(own) != given)
            s.fail(given, std::string("the quick bound must be of the same kind as the bound: give only '") + own + "'");
        c.hasQuickBound = true;
        c.quickTarget = s.number(own);
        if (hasExpected) {
            c.quickTolerance = s.number("quick_tolerance");
            if (!(c.quickTolerance >= c.tolerance))
                s.fail("quick_tolerance", "must not be below 'tolerance' (" + shortNum(c.tolerance) + "): a quick bound may only be looser");
        } else if (hasMin ? c.quickTarget > c.target : c.quickTarget < c.target) {
            s.fail(own, "value " + shortNum(c.quickTarget) + " is stricter than the bound " + c.expectedText() +
                            ": a quick bound may only be looser");
        }
        if (!s.has("quick_why")) s.fail("quick_why", "missing: say why the quick run's bound is looser");
        c.quickWhy = s.string("quick_why");
    } else {
        for (const char* k : {"quick_tolerance", "quick_why"})
            if (s.has(k)) s.fail(k, "only with quick_min, quick_max or quick_expected");
    }
    if (!hasExpected && s.has("quick_tolerance")) s.fail("quick_tolerance", "only with 'quick_expected'");
    s.finish();
    return c;
}

}  // namespace

int integerIn(StrictTable& s, const std::string& key, int lo, int hi) {
    const std::int64_t v = s.integer(key);
    if (v < lo || v > hi) s.fail(key, "value " + std::to_string(v) + " outside [" + std::to_string(lo) + ", " + std::to_string(hi) + "]");
    return static_cast<int>(v);
}

std::uint64_t seedOf(StrictTable& s, const std::string& key) {
    const std::int64_t v = s.integer(key);
    if (v < 0) s.fail(key, "must not be negative");
    return static_cast<std::uint64_t>(v);
}

std::vector<std::string> nonEmptyStrings(StrictTable& s, const std::string& key) {
    std::vector<std::string> v = s.strings(key);
    if (v.empty()) s.fail(key, "must name at least one species");
    return v;
}

ForestSceneConfig parseForestSceneConfig(const std::string& text, const std::string& path,
                                         const std::vector<std::string>& modelOverrides) {
    const toml::table root = parseText(text, path);
    StrictTable top(root, path, "");
    ForestSceneConfig c;
    c.path = path;
    {
        StrictTable s(top.table("scene"), path, "[scene]");
        c.title = s.string("title");
        c.terrainCellSizeM = s.numberIn("terrain_cell_size_m", 0.1, 10.0);
        c.emptyFraction = s.numberIn("empty_fraction", 0.0, 0.95);
        c.denseFraction = s.numberIn("dense_fraction", 0.0, 1.0);
        if (c.emptyFraction + c.denseFraction > 1.0) s.fail("dense_fraction", "empty_fraction + dense_fraction must not exceed 1");
        c.uniformAbiotics = s.boolean("uniform_abiotics");
        c.canopySpecies = nonEmptyStrings(s, "canopy_species");
        c.canopyWeights = s.numbers("canopy_species_weights", c.canopySpecies.size());
        double total = 0;
        for (double w : c.canopyWeights) {
            if (!(w >= 0)) s.fail("canopy_species_weights", "weights must not be negative");
            total += w;
        }
        if (!(total > 0)) s.fail("canopy_species_weights", "at least one weight must be positive");
        c.snapshotEveryYears = integerIn(s, "snapshot_every_years", 1, 1000);
        s.finish();
    }
    for (Mode m : {Mode::Quick, Mode::Full}) {
        StrictTable s(top.table(modeName(m)), path, std::string("[") + modeName(m) + "]");
        ForestSceneConfig::Size& z = m == Mode::Quick ? c.quick : c.full;
        z.plotSizeM = s.numberIn("plot_size_m", 5.0, 5000.0);
        z.years = integerIn(s, "years", 1, 100000);
        z.seed = seedOf(s, "seed");
        s.finish();
    }
    top.optionalTable("model");
    top.finish();
    c.params = parseModelTable(text, path, modelOverrides);
    if (c.params.competition != sim::CompetitionMode::Resources)
        throw ValidationError(path + ": [model] competition: the scene must use \"resources\"; the Deussen "
                                     "comparison selects the Deussen mode itself");
    return c;
}

sim::SimParams ScenarioParse::model() const {
    top.optionalTable("model");
    return parseModelTable(text, path, modelOverrides ? *modelOverrides : std::vector<std::string>{});
}

void ScenarioParse::sizes(const std::function<void(Mode, StrictTable&)>& read) const {
    for (Mode m : {Mode::Quick, Mode::Full}) {
        StrictTable s(top.table(modeName(m)), path, std::string("[") + modeName(m) + "]");
        read(m, s);
        s.finish();
    }
}

ScenarioConfig parseScenarioConfig(const std::string& text, const std::string& path,
                                   const std::vector<std::string>& modelOverrides) {
    const toml::table root = parseText(text, path);
    StrictTable top(root, path, "");
    ScenarioConfig c;
    c.path = path;
    const ScenarioKind* kind = nullptr;
    {
        StrictTable s(top.table("scenario"), path, "[scenario]");
        c.name = s.string("name");
        static const std::regex okName("^[a-z0-9_]+$");
        if (!std::regex_match(c.name, okName)) s.fail("name", "use lower-case letters, digits and '_' only");
        c.kind = s.string("kind");
        kind = findScenarioKind(c.kind);
        if (!kind) {
            std::string names;
            for (const ScenarioKind& k : scenarioKinds()) names += (names.empty() ? "" : ", ") + std::string(k.name);
            s.fail("kind", "unknown kind '" + c.kind + "' (" + names + ")");
        }
        c.forestScene = kind->usesForestScene;
        c.title = s.string("title");
        c.description = s.string("description");
        c.order = static_cast<int>(s.integerOr("order", 100));
        // Replicate counts, as a check's bound and its quick_ variant: quick_replicates for
        // --quick only (e.g. a quick plot too small for the default count to judge steadily).
        if (s.has("replicates")) c.replicates = integerIn(s, "replicates", 1, kMaxReplicates);
        if (s.has("quick_replicates")) c.quickReplicates = integerIn(s, "quick_replicates", 1, kMaxReplicates);
        if (c.usesForestScene()) c.scenePath = s.string("scene");
        s.finish();
    }
    if (c.usesForestScene()) {
        // Optional [quick] / [full] with only `years`: measure at another year than the scene's.
        for (Mode m : {Mode::Quick, Mode::Full}) {
            const toml::table* t = top.optionalTable(modeName(m));
            if (!t) continue;
            StrictTable s(*t, path, std::string("[") + modeName(m) + "]");
            (m == Mode::Quick ? c.yearsQuick : c.yearsFull) = integerIn(s, "years", 1, 100000);
            s.finish();
        }
    }
    c.scenario = kind->create(ScenarioParse{top, text, path, &modelOverrides});
    {
        StrictTable s(top.table("checks"), path, "[checks]");
        for (const std::string& id : c.scenario->checkIds()) {
            if (!s.has(id)) s.fail(id, "missing: a scenario of kind " + c.kind + " needs a [checks." + id + "] table");
            c.checks.push_back(parseCheck(s.table(id), path, id));
        }
        s.finish();
    }
    top.finish();
    return c;
}

// ---------------------------------------------------------------------------------------

std::string ConfigSource::read(const std::string& name) const {
    if (directory.empty()) {
        for (const auto& [n, text] : embeddedConfigs())
            if (n == name) return text;
        throw IoError("embedded configs/validation/" + name + ": no such configuration");
    }
    const std::string p = (fs::path(directory) / name).string();
    std::ifstream in(p, std::ios::binary);
    if (!in) throw IoError(p + ": cannot open validation configuration");
    std::stringstream ss;
    ss << in.rdbuf();
    return ss.str();
}

std::vector<std::string> ConfigSource::scenarioFiles() const {
    std::vector<std::string> out;
    auto take = [&](const std::string& n) {
        if (n.size() > 5 && n.substr(n.size() - 5) == ".toml" && n.rfind("scene_", 0) != 0) out.push_back(n);
    };
    if (directory.empty()) {
        for (const auto& e : embeddedConfigs()) take(e.first);
    } else {
        std::error_code ec;
        if (!fs::is_directory(directory, ec)) throw IoError(directory + ": not a directory of validation configurations");
        for (const auto& e : fs::directory_iterator(directory))
            if (e.is_regular_file()) take(e.path().filename().string());
    }
    std::sort(out.begin(), out.end());
    if (out.empty()) throw IoError(describe() + ": no scenario configurations (*.toml)");
    return out;
}

std::string ConfigSource::describe() const {
    std::string d = directory.empty() ? std::string("configs/validation (copy embedded at build time)") : directory;
    if (!modelOverrides.empty()) {
        d += ", every [model] with";
        for (std::size_t i = 0; i < modelOverrides.size(); ++i) d += (i ? ", " : " ") + modelOverrides[i];
    }
    return d;
}

std::string ConfigSource::displayPath(const std::string& name) const {
    return directory.empty() ? "configs/validation/" + name + " (embedded)" : (fs::path(directory) / name).string();
}

SuiteConfig loadSuiteConfig(const ConfigSource& source, const Biome& biome) {
    SuiteConfig suite;
    std::set<std::string> names;
    for (const std::string& file : source.scenarioFiles()) {
        const std::string shown = source.displayPath(file);
        ScenarioConfig c = parseScenarioConfig(source.read(file), shown, source.modelOverrides);
        if (!names.insert(c.name).second) throw ValidationError(shown + ": [scenario] name '" + c.name + "' is used by another file");
        auto needSpecies = [&](const std::string& key, const std::string& species) {
            for (const Species& s : biome.species)
                if (s.name == species) return;
            throw ValidationError(shown + ": " + key + ": species '" + species + "' is not in biome '" + biome.name + "'");
        };
        for (const auto& [key, species] : c.scenario->speciesNamed()) needSpecies(key, species);
        if (c.usesForestScene()) {
            const std::string sceneFile = c.scenePath;
            if (!suite.scenes.count(sceneFile)) {
                std::string text;
                try {
                    text = source.read(sceneFile);
                } catch (const IoError& e) {
                    throw ValidationError(shown + ": [scenario] scene: " + e.what());
                }
                ForestSceneConfig scene = parseForestSceneConfig(text, source.displayPath(sceneFile), source.modelOverrides);
                for (const auto& s : scene.canopySpecies) needSpecies(source.displayPath(sceneFile) + ": [scene] canopy_species", s);
                suite.scenes.emplace(sceneFile, std::move(scene));
            }
            const ForestSceneConfig& scene = suite.scenes.at(sceneFile);
            c.scenario->checkScene(scene, shown);
            for (int years : {c.measureYear(Mode::Quick, scene), c.measureYear(Mode::Full, scene)}) {
                const int window = c.scenario->windowYears();
                if (window > years)
                    throw ValidationError(shown + ": the window of " + std::to_string(window) + " years is longer than the " +
                                          std::to_string(years) + " years measured of the scene " + sceneFile);
            }
        }
        suite.scenarios.push_back(std::move(c));
    }
    std::stable_sort(suite.scenarios.begin(), suite.scenarios.end(), [](const ScenarioConfig& a, const ScenarioConfig& b) {
        return a.order != b.order ? a.order < b.order : a.name < b.name;
    });
    return suite;
}

}  // namespace eco::validate
