#include "validate_config.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <regex>
#include <set>
#include <sstream>

#include "error.h"
#include "strict_toml.h"

namespace eco::validate {

namespace fs = std::filesystem;

const char* modeName(Mode m) { return m == Mode::Quick ? "quick" : "full"; }

const char* scenarioKindName(ScenarioKind k) {
    switch (k) {
        case ScenarioKind::SelfThinning: return "self_thinning";
        case ScenarioKind::Succession: return "succession";
        case ScenarioKind::Equilibrium: return "equilibrium";
        case ScenarioKind::GapDynamics: return "gap_dynamics";
        case ScenarioKind::AbioticGradients: return "abiotic_gradients";
        case ScenarioKind::DeussenComparison: return "deussen_comparison";
        case ScenarioKind::DeussenCircles: return "deussen_circles";
    }
    return "?";
}

std::vector<std::string> checkIdsOf(ScenarioKind k) {
    switch (k) {
        case ScenarioKind::SelfThinning: return {"slope", "r_squared"};
        case ScenarioKind::Succession:
            return {"late_share_gain", "late_cover_overtakes", "late_dominance", "early_peak_time", "early_decline"};
        case ScenarioKind::Equilibrium: return {"total_cv", "leading_species_cv"};
        case ScenarioKind::GapDynamics: return {"edge_vs_deep", "clearing_vs_deep"};
        case ScenarioKind::AbioticGradients: return {"sun_gap"};
        case ScenarioKind::DeussenComparison: return {"short_range_pcf_ratio", "late_share_change_difference"};
        case ScenarioKind::DeussenCircles: return {"slope", "r_squared"};
    }
    return {};
}

bool CheckSpec::passes(double v) const {
    if (!std::isfinite(v)) return false;
    switch (kind) {
        case Kind::Approx: return std::abs(v - target) <= tolerance;
        case Kind::AtLeast: return v >= target;
        case Kind::AtMost: return v <= target;
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

bool ScenarioConfig::usesForestScene() const {
    return kind == ScenarioKind::Succession || kind == ScenarioKind::Equilibrium || kind == ScenarioKind::GapDynamics ||
           kind == ScenarioKind::AbioticGradients || kind == ScenarioKind::DeussenComparison;
}

namespace {

toml::table parseText(const std::string& text, const std::string& path) { return parseTomlText(text, path); }

// The [model] table is read by the simulator's own strict parser (sim::parseRunConfig), so
// that the keys, ranges and messages are exactly those of a run configuration. Every line
// outside [model] is blanked, which keeps the line numbers of its messages right.
sim::SimParams parseModelTable(const std::string& text, const std::string& path) {
    static const std::regex header(R"(^\s*\[\s*([A-Za-z0-9_.\-"]+)\s*\]\s*(#.*)?$)");
    std::istringstream in(text);
    std::string line, kept;
    bool inModel = false;
    while (std::getline(in, line)) {
        std::smatch m;
        if (std::regex_match(line, m, header)) inModel = m[1].str() == "model";
        kept += (inModel ? line : std::string()) + "\n";
    }
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
    s.finish();
    return c;
}

int yearsIn(StrictTable& s, const std::string& key, int lo, int hi) {
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

}  // namespace

ForestSceneConfig parseForestSceneConfig(const std::string& text, const std::string& path) {
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
        c.snapshotEveryYears = yearsIn(s, "snapshot_every_years", 1, 1000);
        s.finish();
    }
    for (Mode m : {Mode::Quick, Mode::Full}) {
        StrictTable s(top.table(modeName(m)), path, std::string("[") + modeName(m) + "]");
        ForestSceneConfig::Size& z = m == Mode::Quick ? c.quick : c.full;
        z.plotSizeM = s.numberIn("plot_size_m", 5.0, 5000.0);
        z.years = yearsIn(s, "years", 1, 100000);
        z.seed = seedOf(s, "seed");
        s.finish();
    }
    top.optionalTable("model");
    top.finish();
    c.params = parseModelTable(text, path);
    if (c.params.competition != sim::CompetitionMode::Resources)
        throw ValidationError(path + ": [model] competition: the scene must use \"resources\"; the Deussen "
                                     "comparison selects the Deussen mode itself");
    return c;
}

ScenarioConfig parseScenarioConfig(const std::string& text, const std::string& path) {
    const toml::table root = parseText(text, path);
    StrictTable top(root, path, "");
    ScenarioConfig c;
    c.path = path;
    {
        StrictTable s(top.table("scenario"), path, "[scenario]");
        c.name = s.string("name");
        static const std::regex okName("^[a-z0-9_]+$");
        if (!std::regex_match(c.name, okName)) s.fail("name", "use lower-case letters, digits and '_' only");
        const std::string kind = s.string("kind");
        bool found = false;
        for (ScenarioKind k : {ScenarioKind::SelfThinning, ScenarioKind::Succession, ScenarioKind::Equilibrium,
                               ScenarioKind::GapDynamics, ScenarioKind::AbioticGradients, ScenarioKind::DeussenComparison,
                               ScenarioKind::DeussenCircles})
            if (kind == scenarioKindName(k)) {
                c.kind = k;
                found = true;
            }
        if (!found)
            s.fail("kind", "unknown kind '" + kind + "' (self_thinning, succession, equilibrium, gap_dynamics, "
                           "abiotic_gradients, deussen_comparison, deussen_circles)");
        c.title = s.string("title");
        c.description = s.string("description");
        c.order = static_cast<int>(s.integerOr("order", 100));
        if (c.usesForestScene()) c.scenePath = s.string("scene");
        s.finish();
    }
    auto modeTables = [&](auto&& readSize) {
        for (Mode m : {Mode::Quick, Mode::Full}) {
            StrictTable s(top.table(modeName(m)), path, std::string("[") + modeName(m) + "]");
            readSize(m, s);
            s.finish();
        }
    };
    if (c.usesForestScene()) {
        // Optional [quick] / [full] with only `years`: measure at another year than the scene's.
        for (Mode m : {Mode::Quick, Mode::Full}) {
            const toml::table* t = top.optionalTable(modeName(m));
            if (!t) continue;
            StrictTable s(*t, path, std::string("[") + modeName(m) + "]");
            (m == Mode::Quick ? c.yearsQuick : c.yearsFull) = yearsIn(s, "years", 1, 100000);
            s.finish();
        }
    }
    switch (c.kind) {
        case ScenarioKind::SelfThinning: {
            SelfThinningSettings& st = c.selfThinning;
            StrictTable s(top.table("stand"), path, "[stand]");
            st.species = s.string("species");
            st.densityPerM2 = s.numberIn("density_per_m2", 0.01, 25.0);
            st.initialHeightMinM = s.positive("initial_height_min_m");
            st.initialHeightMaxM = s.positive("initial_height_max_m");
            if (st.initialHeightMaxM < st.initialHeightMinM) s.fail("initial_height_max_m", "must not be below initial_height_min_m");
            s.finish();
            StrictTable t(top.table("thinning"), path, "[thinning]");
            st.onsetCoverFraction = t.numberIn("onset_cover_fraction", 0.0, 10.0);
            st.onsetMortalityFactor = t.numberIn("onset_mortality_factor", 1.0, 1000.0);
            st.minPlantsInFit = static_cast<int>(t.numberIn("min_plants_in_fit", 3, 1e9));
            t.finish();
            modeTables([&](Mode m, StrictTable& z) {
                auto& size = m == Mode::Quick ? st.quick : st.full;
                size.plotSizeM = z.numberIn("plot_size_m", 1.0, 1000.0);
                size.years = yearsIn(z, "years", 2, 100000);
                size.seed = seedOf(z, "seed");
            });
            top.optionalTable("model");
            st.params = parseModelTable(text, path);
            break;
        }
        case ScenarioKind::Succession: {
            StrictTable s(top.table("succession"), path, "[succession]");
            c.succession.lateSpecies = s.string("late_species");
            c.succession.earlySpecies = nonEmptyStrings(s, "early_species");
            c.succession.earlyYear = yearsIn(s, "early_year", 0, 100000);
            c.succession.finalWindowYears = yearsIn(s, "final_window_years", 1, 100000);
            c.succession.suitedMinFitness = s.numberIn("suited_min_fitness", -1.0, 1.0);
            s.finish();
            break;
        }
        case ScenarioKind::Equilibrium: {
            StrictTable s(top.table("equilibrium"), path, "[equilibrium]");
            c.equilibrium.windowYears = yearsIn(s, "window_years", 2, 100000);
            c.equilibrium.leadingMinShare = s.numberIn("leading_min_share", 0.0, 1.0);
            s.finish();
            break;
        }
        case ScenarioKind::GapDynamics: {
            StrictTable s(top.table("classes"), path, "[classes]");
            c.gap.edgeBandM = s.positive("edge_band_m");
            c.gap.deepMinDepthM = s.positive("deep_min_depth_m");
            if (c.gap.deepMinDepthM < c.gap.edgeBandM) s.fail("deep_min_depth_m", "must not be below edge_band_m");
            c.gap.windowYears = yearsIn(s, "window_years", 1, 100000);
            c.gap.minClassAreaM2 = s.positive("min_class_area_m2");
            s.finish();
            break;
        }
        case ScenarioKind::AbioticGradients: {
            StrictTable s(top.table("gradients"), path, "[gradients]");
            c.gradients.shadeSpecies = nonEmptyStrings(s, "shade_species");
            c.gradients.sunSpecies = nonEmptyStrings(s, "sun_species");
            c.gradients.windowYears = yearsIn(s, "window_years", 1, 100000);
            c.gradients.minPlants = yearsIn(s, "min_plants", 1, 1000000000);
            s.finish();
            break;
        }
        case ScenarioKind::DeussenComparison: {
            StrictTable s(top.table("comparison"), path, "[comparison]");
            c.deussen.pcfRMaxM = s.positive("pcf_r_max_m");
            c.deussen.pcfBins = yearsIn(s, "pcf_bins", 1, 1000);
            c.deussen.lateSpecies = s.string("late_species");
            c.deussen.earlyYear = yearsIn(s, "early_year", 0, 100000);
            c.deussen.finalWindowYears = yearsIn(s, "final_window_years", 1, 100000);
            c.deussen.dominatedSurvival = s.numberIn("deussen_dominated_survival", 0.0, 1.0);
            s.finish();
            break;
        }
        case ScenarioKind::DeussenCircles: {
            CirclesParams& p = c.circles.params;
            StrictTable s(top.table("circles"), path, "[circles]");
            p.initialRadiusMinM = s.number("initial_radius_min_m");
            p.initialRadiusMaxM = s.number("initial_radius_max_m");
            p.growthPerStepM = s.number("growth_per_step_m");
            p.limitRadiusM = s.number("limit_radius_m");
            p.maxSteps = static_cast<int>(s.numberIn("max_steps", 1, 1e7));
            p.onsetKilledFraction = s.number("onset_killed_fraction");
            p.minPlantsInFit = static_cast<int>(s.numberIn("min_plants_in_fit", 2, 1e9));
            s.finish();
            modeTables([&](Mode m, StrictTable& z) {
                auto& size = m == Mode::Quick ? c.circles.quick : c.circles.full;
                size.plantCount = static_cast<int>(z.numberIn("plant_count", 2, 5e7));
                size.fieldSideM = z.positive("field_side_m");
                size.seed = seedOf(z, "seed");
                CirclesParams q = p;
                q.plantCount = size.plantCount;
                q.fieldSideM = size.fieldSideM;
                try {
                    q.validate();
                } catch (const ValidationError& e) {
                    throw ValidationError(path + ": [circles] / [" + modeName(m) + "]: " + e.what());
                }
            });
            break;
        }
    }
    {
        StrictTable s(top.table("checks"), path, "[checks]");
        for (const std::string& id : checkIdsOf(c.kind)) {
            if (!s.has(id)) s.fail(id, std::string("missing: a scenario of kind ") + scenarioKindName(c.kind) + " needs a [checks." + id + "] table");
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
    return directory.empty() ? std::string("configs/validation (copy embedded at build time)") : directory;
}

std::string ConfigSource::displayPath(const std::string& name) const {
    return directory.empty() ? "configs/validation/" + name + " (embedded)" : (fs::path(directory) / name).string();
}

SuiteConfig loadSuiteConfig(const ConfigSource& source, const Biome& biome) {
    SuiteConfig suite;
    std::set<std::string> names;
    for (const std::string& file : source.scenarioFiles()) {
        const std::string shown = source.displayPath(file);
        ScenarioConfig c = parseScenarioConfig(source.read(file), shown);
        if (!names.insert(c.name).second) throw ValidationError(shown + ": [scenario] name '" + c.name + "' is used by another file");
        auto needSpecies = [&](const std::string& key, const std::string& species) {
            for (const Species& s : biome.species)
                if (s.name == species) return;
            throw ValidationError(shown + ": " + key + ": species '" + species + "' is not in biome '" + biome.name + "'");
        };
        if (c.kind == ScenarioKind::SelfThinning) needSpecies("[stand] species", c.selfThinning.species);
        if (c.kind == ScenarioKind::Succession) {
            needSpecies("[succession] late_species", c.succession.lateSpecies);
            for (const auto& s : c.succession.earlySpecies) needSpecies("[succession] early_species", s);
        }
        if (c.kind == ScenarioKind::AbioticGradients) {
            for (const auto& s : c.gradients.shadeSpecies) needSpecies("[gradients] shade_species", s);
            for (const auto& s : c.gradients.sunSpecies) needSpecies("[gradients] sun_species", s);
        }
        if (c.kind == ScenarioKind::DeussenComparison) needSpecies("[comparison] late_species", c.deussen.lateSpecies);
        if (c.usesForestScene()) {
            const std::string sceneFile = c.scenePath;
            if (!suite.scenes.count(sceneFile)) {
                std::string text;
                try {
                    text = source.read(sceneFile);
                } catch (const IoError& e) {
                    throw ValidationError(shown + ": [scenario] scene: " + e.what());
                }
                ForestSceneConfig scene = parseForestSceneConfig(text, source.displayPath(sceneFile));
                for (const auto& s : scene.canopySpecies) needSpecies(source.displayPath(sceneFile) + ": [scene] canopy_species", s);
                suite.scenes.emplace(sceneFile, std::move(scene));
            }
            const ForestSceneConfig& scene = suite.scenes.at(sceneFile);
            const double smallest = std::min(scene.quick.plotSizeM, scene.full.plotSizeM);
            if (c.kind == ScenarioKind::DeussenComparison && c.deussen.pcfRMaxM > 0.45 * smallest)
                throw ValidationError(shown + ": [comparison] pcf_r_max_m = " + StrictTable::fmt(c.deussen.pcfRMaxM) +
                                      ": must stay below 0.45 x the smallest plot of the scene (" +
                                      StrictTable::fmt(smallest) + " m) for the edge correction");
            for (int years : {c.measureYear(Mode::Quick, scene), c.measureYear(Mode::Full, scene)}) {
                const int window = c.kind == ScenarioKind::Succession      ? c.succession.finalWindowYears
                                   : c.kind == ScenarioKind::Equilibrium   ? c.equilibrium.windowYears
                                   : c.kind == ScenarioKind::GapDynamics   ? c.gap.windowYears
                                   : c.kind == ScenarioKind::AbioticGradients ? c.gradients.windowYears
                                                                           : c.deussen.finalWindowYears;
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
