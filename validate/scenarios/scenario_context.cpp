#include "scenario_context.h"

#include "plots.h"
#include "calibration_scene.h"

#include <algorithm>

#include "demo_scene.h"
#include "error.h"
#include "processes.h"
#include "rng.h"
#include "sim_render.h"

namespace eco::validate {

CheckResult makeCheck(const ScenarioConfig& sc, const std::string& id, const std::string& title, double value,
                      const std::string& note) {
    // A quick bound must not be ignored silently: the kind has to pass the mode.
    if (sc.check(id).hasQuickBound)
        throw Error("validate: check " + sc.name + "/" + id + " has a quick bound; its kind must call makeCheck with the mode");
    return makeCheck(sc, Mode::Full, id, title, value, note);
}

CheckResult makeCheck(const ScenarioConfig& sc, Mode m, const std::string& id, const std::string& title, double value,
                      const std::string& note) {
    CheckResult r;
    r.scenario = sc.name;
    r.spec = sc.check(id).forMode(m);
    r.title = title;
    r.value = value;
    r.pass = r.spec.passes(value);
    r.note = note;
    return r;
}

std::vector<const Snapshot*> ForestRun::window(int first, int last) const {
    std::vector<const Snapshot*> out;
    for (const Snapshot& s : snapshots)
        if (s.year >= first && s.year <= last) out.push_back(&s);
    return out;
}

const Snapshot* ForestRun::at(int year) const {
    for (const Snapshot& s : snapshots)
        if (s.year == year) return &s;
    return nullptr;
}

const std::vector<sim::UndergrowthPlant>& ForestRun::plantsAt(int year) const {
    auto it = plantsAtYear.find(year);
    if (it == plantsAtYear.end()) throw Error("validate: no plant list kept for year " + std::to_string(year));
    return it->second;
}

std::vector<sim::YearRecord> ForestRun::censusUpTo(int year) const {
    return {timeseries.begin(), timeseries.begin() + std::min<std::ptrdiff_t>(year + 1, static_cast<std::ptrdiff_t>(timeseries.size()))};
}

std::vector<sim::UndergrowthPlant> toUndergrowth(const Snapshot& s) {
    std::vector<sim::UndergrowthPlant> out(s.plants.size());
    for (std::size_t i = 0; i < s.plants.size(); ++i) {
        out[i].speciesId = s.plants[i].species;
        out[i].xM = s.plants[i].x;
        out[i].yM = s.plants[i].y;
        out[i].heightM = s.plants[i].heightM;
        out[i].crownRadiusM = s.plants[i].crownRadiusM;
    }
    return out;
}

double shareOf(const sim::YearRecord& r, int s) {
    const double total = std::accumulate(r.count.begin(), r.count.end(), 0.0);
    return total > 0 ? r.count[static_cast<std::size_t>(s)] / total : 0.0;
}

std::vector<const sim::YearRecord*> censusWindow(const std::vector<sim::YearRecord>& ts, int first, int last) {
    std::vector<const sim::YearRecord*> out;
    for (const auto& r : ts)
        if (r.year >= first && r.year <= last) out.push_back(&r);
    return out;
}

// ---------------------------------------------------------------------------------------

void ScenarioContext::planForestRuns(const std::vector<const ScenarioConfig*>& selected) {
    for (const ScenarioConfig* sc : selected) {
        if (!sc->usesForestScene()) continue;
        const int y = sc->measureYear(opt_.mode, suite_.scenes.at(sc->scenePath));
        for (sim::CompetitionMode mode : sc->scenario->forestModes()) {
            const std::string k = sc->scenePath + "|" + sim::competitionModeName(mode);
            runYears_[k] = std::max(runYears_[k], y);
            keepPlantsAt_[k].insert(y);
        }
    }
}

sim::SimInputs ScenarioContext::forestInputs(const ForestSceneConfig& scene, const ForestSceneConfig::Size& size) const {
    return forestSceneInputs(scene, size.plotSizeM, seed(size.seed), biome_);
}

const ForestRun& ScenarioContext::forest(const std::string& sceneFile, sim::CompetitionMode mode, double dominatedSurvival) {
    const ForestSceneConfig& scene = suite_.scenes.at(sceneFile);
    const std::string planKey = sceneFile + "|" + sim::competitionModeName(mode);
    const std::string key = sceneFile + "|" + sim::competitionModeName(mode) +
                            (mode == sim::CompetitionMode::Deussen ? "|" + num(dominatedSurvival, 17) : "");
    auto it = cache_.find(key);
    if (it != cache_.end()) return *it->second;

    ForestSceneConfig::Size size = scene.size(opt_.mode);
    if (runYears_.count(planKey)) size.years = runYears_.at(planKey);
    std::set<int> keepAt = keepPlantsAt_.count(planKey) ? keepPlantsAt_.at(planKey) : std::set<int>{};
    keepAt.insert(size.years);
    auto run = std::make_unique<ForestRun>();
    run->label = sceneFile + " (" + sim::competitionModeName(mode) + " competition)";
    const auto t0 = Clock::now();
    log("validate: building scene " + sceneFile + ": " + fixed(size.plotSizeM, 0) + " m plot, " +
        std::to_string(size.years) + " years, seed " + std::to_string(seed(size.seed)));
    sim::SimInputs in = forestInputs(scene, size);
    const FactorGrids annual = annualFactors(in.abiotics);
    run->canopy = in.canopy;
    sim::SimParams params = scene.params;
    params.competition = mode;
    if (mode == sim::CompetitionMode::Deussen) params.deussenDominatedSurvival = dominatedSurvival;
    sim::Simulation s(std::move(in), params, seed(size.seed));
    run->area = s.area();
    run->plotSideM = run->area.x1 - run->area.x0;
    run->canopy = s.relevantCanopy();
    run->transmission = s.canopyTransmission();
    run->seedProb = s.seedProbability();
    run->seedPackages = s.seedPackages();
    for (Grid<float>& m : run->site.maps) m = Grid<float>::like(run->transmission, 0.f);
    const Grid<float>& g = run->site.geometry();
    const Grid<float>& ag = annual.geometry();
    for (int iy = 0; iy < g.height(); ++iy)
        for (int ix = 0; ix < g.width(); ++ix) {
            const int ax = ag.cellX(g.cellCentreX(ix)), ay = ag.cellY(g.cellCentreY(iy));
            for (std::size_t f = 0; f < kFactorCount; ++f) run->site.maps[f](ix, iy) = annual.maps[f].clamped(ax, ay);
            // The sun under the canopy: the only factor the canopy changes.
            run->site[Factor::Sun](ix, iy) = annual[Factor::Sun].clamped(ax, ay) * run->transmission(ix, iy);
        }
    const ForestSceneConfig& sc = scene;
    run->timeseries.push_back(s.census());
    auto lastPrint = Clock::now();
    const auto simStart = Clock::now();
    for (int y = 1; y <= size.years; ++y) {
        s.stepYear();
        run->timeseries.push_back(s.census());
        if (keepAt.count(y)) run->plantsAtYear[y] = s.plants();
        if (y % sc.snapshotEveryYears == 0 || keepAt.count(y)) {
            Snapshot snap;
            snap.year = y;
            for (const sim::UndergrowthPlant& p : s.plants())
                snap.plants.push_back(LitePlant{p.speciesId, static_cast<float>(p.xM), static_cast<float>(p.yM),
                                                static_cast<float>(p.heightM), static_cast<float>(p.crownRadiusM),
                                                static_cast<float>(p.sunShare)});
            run->snapshots.push_back(std::move(snap));
        }
        if (secondsSince(lastPrint) >= 5.0 || y == size.years || y == 1) {
            lastPrint = Clock::now();
            const double el = secondsSince(simStart);
            log("validate:   " + run->label + ": year " + std::to_string(y) + "/" + std::to_string(size.years) + ", " +
                std::to_string(s.plantCount()) + " plants, " + fixed(el, 1) + " s, ~" +
                fixed(el / y * (size.years - y), 0) + " s left");
        }
    }
    run->years = size.years;
    run->plantMonths = s.counters().plantMonths;
    run->seconds = secondsSince(t0);
    log("validate:   " + run->label + ": done in " + fixed(run->seconds, 1) + " s (" + num(run->plantMonths / 1e6, 3) +
        " M plant-months)");
    const ForestRun& ref = *run;
    cache_.emplace(key, std::move(run));
    return ref;
}

void ScenarioContext::describeRun(const ForestRun& run, int year, ScenarioResult& r, const ForestSceneConfig& scene) const {
    r.details.push_back("- Scene: " + scene.title + " (`" + scene.path + "`): " + fixed(run.plotSideM, 1) + " m x " +
                        fixed(run.area.y1 - run.area.y0, 1) + " m, " + std::to_string(run.canopy.size()) +
                        " canopy trees; measured at year " + std::to_string(year) + " of a " + std::to_string(run.years) +
                        "-year run, simulated in " + fixed(run.seconds, 1) +
                        " s (" + num(run.plantMonths / 1e6, 3) + " M plant-months).");
}

void ScenarioContext::forestFigures(const ForestRun& run, int lastYear, const std::string& stem, const std::string& what,
                                    ScenarioResult& r, bool renders) const {
    const std::string counts = stem + "_population.png";
    const std::vector<sim::YearRecord> census = run.censusUpTo(lastYear);
    sim::plotSpeciesCountsPng(file(counts), census, biome_, what + ": plants per species");
    r.figures.push_back({counts, what + ": plants per species per year (as the paper's Fig. 15).",
                         populationLinePlot(census, biome_, what + ": plants per species per year")});
    if (!renders) return;
    std::vector<int> years;
    for (int y = 25; y < lastYear; y += 50) years.push_back(y);
    years.push_back(lastYear);
    for (int y : years) {
        const Snapshot* s = run.at(y);
        if (!s) continue;
        char name[64];
        std::snprintf(name, sizeof name, "%s_year_%04d.png", stem.c_str(), y);
        const std::vector<sim::UndergrowthPlant> plants = toUndergrowth(*s);
        sim::renderPlantsPng(file(name), plants, run.canopy, run.area, biome_, what + ", year " + std::to_string(y), 900);
        const std::string caption = what + ", top-down at year " + std::to_string(y) + " (as the paper's Fig. 14).";
        if (y == lastYear)  // report.html: the plot at the end also from above, to pan and zoom
            r.figures.push_back({name, caption,
                                 plotSceneView(what + ", year " + std::to_string(y) + ", from above", run.area, biome_, run.canopy,
                                               plants)});
        else
            r.figures.push_back({name, caption});
    }
}

}  // namespace eco::validate
