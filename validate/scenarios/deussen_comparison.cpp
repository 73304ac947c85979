// Kind "deussen_comparison" (paper §7.2, Fig. 20), forest scene: the same scene simulated with
// our resource competition and with Deussen et al. 1998's; short-range pair correlation and
// the late species' change of share, ours against theirs. docs/validation.md defines them.
#include "scenario_context.h"

#include <algorithm>
#include <cmath>

#include "error.h"
#include "point_pattern.h"
#include "plots.h"
#include "sim_render.h"
#include "scenario_keys.h"
#include "strict_toml.h"

namespace eco::validate {

namespace {

struct DeussenComparisonSettings {
    double pcfRMaxM = 1.0;  ///< short range: g is pooled over [0, pcfRMaxM)
    int pcfBins = 5;
    std::string lateSpecies;
    int earlyYear = 25;
    int finalWindowYears = 25;
    double dominatedSurvival = 0.5;  ///< SimParams::deussenDominatedSurvival of the Deussen run
};

/// [comparison]'s numeric keys (late_species is read by hand).
const std::vector<ParamDesc<DeussenComparisonSettings>>& comparisonFields() {
    using P = DeussenComparisonSettings;
    using K = ParamDesc<P>::Kind;
    static const std::vector<ParamDesc<P>> fields = {
        {"pcf_r_max_m", "short range: the pair correlation g is pooled over [0, pcf_r_max_m) (below 0.45 x the scene's smallest plot)",
         "m", K::Real, &P::pcfRMaxM, nullptr, ParamRange::above(0), nullptr, "must be positive"},
        {"pcf_bins", "bins of g over that range listed in the report", "", K::Integer, nullptr, &P::pcfBins,
         ParamRange::closed(1, 1000)},
        {"early_year", "the late species' starting share is taken at this year", "years", K::Integer, nullptr, &P::earlyYear,
         ParamRange::closed(0, 100000)},
        {"final_window_years", "the final share is the mean over this many last censuses", "years", K::Integer, nullptr,
         &P::finalWindowYears, ParamRange::closed(1, 100000)},
        {"deussen_dominated_survival", "the Deussen run's deussen_dominated_survival (simulation parameter)", "", K::Real,
         &P::dominatedSurvival, nullptr, ParamRange::closed(0.0, 1.0)},
    };
    return fields;
}

class DeussenComparison final : public Scenario {
public:
    explicit DeussenComparison(const ScenarioParse& in);
    std::vector<std::string> checkIds() const override { return {"short_range_pcf_ratio", "late_share_change_difference"}; }
    std::vector<std::pair<std::string, std::string>> speciesNamed() const override {
        return {{"[comparison] late_species", settings_.lateSpecies}};
    }
    int windowYears() const override { return settings_.finalWindowYears; }
    std::vector<sim::CompetitionMode> forestModes() const override {
        return {sim::CompetitionMode::Resources, sim::CompetitionMode::Deussen};
    }
    void checkScene(const ForestSceneConfig& scene, const std::string& shown) const override {
        const double smallest = std::min(scene.quick.plotSizeM, scene.full.plotSizeM);
        if (settings_.pcfRMaxM > 0.45 * smallest)
            throw ValidationError(shown + ": [comparison] pcf_r_max_m = " + StrictTable::fmt(settings_.pcfRMaxM) +
                                  ": must stay below 0.45 x the smallest plot of the scene (" +
                                  StrictTable::fmt(smallest) + " m) for the edge correction");
    }
    void run(const ScenarioConfig& sc, ScenarioContext& ctx, ScenarioResult& r) const override;

private:
    DeussenComparisonSettings settings_;
};

DeussenComparison::DeussenComparison(const ScenarioParse& in) {
    DeussenComparisonSettings& d = settings_;
    StrictTable s(in.top.table("comparison"), in.path, "[comparison]");
    readScenarioParams(s, d, comparisonFields());
    d.lateSpecies = s.string("late_species");
    s.finish();
}

void DeussenComparison::run(const ScenarioConfig& sc, ScenarioContext& ctx, ScenarioResult& r) const {
    const Biome& biome = ctx.biome();
    const DeussenComparisonSettings& cfg = settings_;
    const ForestRun& ours = ctx.forest(sc.scenePath, sim::CompetitionMode::Resources, 0);
    const ForestRun& theirs = ctx.forest(sc.scenePath, sim::CompetitionMode::Deussen, cfg.dominatedSurvival);
    const int Y = ctx.measureYear(sc);
    ctx.describeRun(ours, Y, r, ctx.scene(sc));
    r.details.push_back("- Deussen run: same scene, seed and parameters with competition = \"deussen\" "
                        "(deussen_dominated_survival = " + num(cfg.dominatedSurvival) + "); simulated in " +
                        fixed(theirs.seconds, 1) + " s.");
    DistanceBins bins;
    bins.rMaxM = cfg.pcfRMaxM;
    bins.count = cfg.pcfBins;
    auto shortRange = [&](const ForestRun& run, std::vector<double>& perBin) {
        PointPattern pat;
        pat.typeNames = {"undergrowth"};
        for (const auto& p : run.plantsAt(Y)) {
            pat.x.push_back(p.xM);
            pat.y.push_back(p.yM);
            pat.type.push_back(0);
        }
        const RectWindow win{run.area.x0, run.area.y0, run.area.x1, run.area.y1};
        PcfOptions o;
        o.bins = bins;
        o.isotropic = false;
        const PairSums ps = countPairs(pat, win, o);
        double weighted = 0, annulus = 0;
        for (int k = 0; k < bins.count; ++k) {
            weighted += ps.translateSum[ps.index(0, 0, k)];
            annulus += bins.annulusAreaM2(k);
            perBin.push_back(ps.gTranslate(0, 0, k));
        }
        return annulusPcf(weighted, annulus, ps.normalisation(0, 0));
    };
    std::vector<double> gOursBins, gTheirsBins;
    const double gOurs = shortRange(ours, gOursBins), gTheirs = shortRange(theirs, gTheirsBins);
    r.checks.push_back(makeCheck(sc, "short_range_pcf_ratio",
                                 "pair correlation g of all undergrowth over [0, " + num(cfg.pcfRMaxM) +
                                     " m) at the last year: ours / Deussen's",
                                 gTheirs > 0 ? gOurs / gTheirs : kNaN,
                                 gTheirs > 0 ? "" : "Deussen run has g = 0 (too few plants)"));
    const int late = biome.speciesIndex(cfg.lateSpecies);
    auto change = [&](const ForestRun& run, double& early, double& fin) {
        early = shareOf(run.timeseries[static_cast<std::size_t>(std::min(cfg.earlyYear, Y))], late);
        std::vector<double> v;
        for (const auto* rec : censusWindow(run.timeseries, Y - cfg.finalWindowYears + 1, Y)) v.push_back(shareOf(*rec, late));
        fin = mean(v);
        return 100.0 * (fin - early);
    };
    double e1, f1, e2, f2;
    const double dOurs = change(ours, e1, f1), dTheirs = change(theirs, e2, f2);
    r.checks.push_back(makeCheck(sc, "late_share_change_difference",
                                 cfg.lateSpecies + ": change of its share of plants (percentage points, year " +
                                     std::to_string(cfg.earlyYear) + " to the last " + std::to_string(cfg.finalWindowYears) +
                                     " years), ours minus Deussen's",
                                 dOurs - dTheirs));
    std::string table = "\n| | ours (resources) | Deussen 1998 |\n|---|---|---|\n";
    table += "| plants at the end | " + std::to_string(ours.plantsAt(Y).size()) + " | " + std::to_string(theirs.plantsAt(Y).size()) + " |\n";
    table += "| g over [0, " + num(cfg.pcfRMaxM) + " m) | " + fixed(gOurs, 3) + " | " + fixed(gTheirs, 3) + " |\n";
    for (int k = 0; k < bins.count; ++k)
        table += "| g in [" + num(bins.loM(k)) + ", " + num(bins.hiM(k)) + ") m | " + fixed(gOursBins[static_cast<std::size_t>(k)], 3) +
                 " | " + fixed(gTheirsBins[static_cast<std::size_t>(k)], 3) + " |\n";
    table += "| " + cfg.lateSpecies + " share, year " + std::to_string(cfg.earlyYear) + " | " + fixed(100 * e1, 1) + " % | " +
             fixed(100 * e2, 1) + " % |\n";
    table += "| " + cfg.lateSpecies + " share, last " + std::to_string(cfg.finalWindowYears) + " years | " + fixed(100 * f1, 1) +
             " % | " + fixed(100 * f2, 1) + " % |\n";
    r.details.push_back("- Pair correlation: translation-corrected annulus estimator (core/point_pattern.h) of the "
                        "unmarked pattern of undergrowth roots in the plot at the last year; g > 1 means clustering, "
                        "g < 1 regularity (inhibition) at that range.");
    r.details.push_back(table);
    const std::string a = sc.name + "_deussen.png", b = sc.name + "_ours.png";
    sim::renderPlantsPng(ctx.file(a), theirs.plantsAt(Y), theirs.canopy, theirs.area, biome,
                         "Deussen 1998 competition, year " + std::to_string(Y), 900);
    sim::renderPlantsPng(ctx.file(b), ours.plantsAt(Y), ours.canopy, ours.area, biome,
                         "Ours (resource competition), year " + std::to_string(Y), 900);
    // report.html: each plot also from above, to pan and zoom (its picture folded away).
    r.figures.push_back({a, "Deussen et al. 1998 competition (left of the paper's Fig. 20).",
                         plotSceneView("Deussen 1998 competition, year " + std::to_string(Y) + ", from above", theirs.area, biome,
                                       theirs.canopy, theirs.plantsAt(Y))});
    r.figures.push_back({b, "Our resource competition (right of the paper's Fig. 20).",
                         plotSceneView("Ours (resource competition), year " + std::to_string(Y) + ", from above", ours.area,
                                       biome, ours.canopy, ours.plantsAt(Y))});
    const std::string counts = sc.name + "_deussen_population.png";
    sim::plotSpeciesCountsPng(ctx.file(counts), theirs.censusUpTo(Y), biome, "Deussen competition: plants per species");
    r.figures.push_back({counts, "Plants per species per year under Deussen's competition (compare with the succession scenario)."});
}

}  // namespace

std::unique_ptr<Scenario> createDeussenComparison(const ScenarioParse& in) { return std::make_unique<DeussenComparison>(in); }
std::vector<ScenarioKeyDoc> deussenComparisonKeys() { return scenarioKeyDocs("[comparison]", comparisonFields()); }

}  // namespace eco::validate
