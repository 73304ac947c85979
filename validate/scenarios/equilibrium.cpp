// Kind "equilibrium" (paper §7.2: dynamic equilibrium at about 125 years), forest scene:
// the coefficients of variation of the total and the leading species' counts over the last
// years. docs/validation.md defines the measures.
#include "scenario_context.h"

#include <cmath>
#include <numeric>

#include "scenario_keys.h"
#include "strict_toml.h"

namespace eco::validate {

namespace {

struct EquilibriumSettings {
    int windowYears = 25;
    double leadingMinShare = 0.1;  ///< species with at least this share of the plants are "leading"
};

/// [equilibrium].
const std::vector<ParamDesc<EquilibriumSettings>>& equilibriumFields() {
    using P = EquilibriumSettings;
    using K = ParamDesc<P>::Kind;
    static const std::vector<ParamDesc<P>> fields = {
        {"window_years", "the census is measured over this many years ending at the measured year", "years", K::Integer,
         nullptr, &P::windowYears, ParamRange::closed(2, 100000)},
        {"leading_min_share", "species with at least this share of the plants over the window are leading", "", K::Real,
         &P::leadingMinShare, nullptr, ParamRange::closed(0.0, 1.0)},
    };
    return fields;
}

/// Coefficients of variation of the yearly census over the `windowYears` ending at year Y.
struct EquilibriumCvs {
    std::vector<double> total;  ///< total plants per year of the window
    double totalCv = kNaN, worstCv = kNaN;
    std::string worstName;
    std::vector<std::string> leading;  ///< report lines, one per leading species
};
EquilibriumCvs equilibriumCvs(const ForestRun& run, int Y, const EquilibriumSettings& cfg, const Biome& biome) {
    EquilibriumCvs out;
    const auto window = censusWindow(run.timeseries, Y - cfg.windowYears + 1, Y);
    for (const auto* rec : window) out.total.push_back(std::accumulate(rec->count.begin(), rec->count.end(), 0.0));
    out.totalCv = coefficientOfVariation(out.total);
    for (std::size_t s = 0; s < biome.species.size(); ++s) {
        std::vector<double> c, share;
        for (const auto* rec : window) {
            c.push_back(rec->count[s]);
            share.push_back(shareOf(*rec, static_cast<int>(s)));
        }
        if (mean(share) < cfg.leadingMinShare) continue;
        const double cv = coefficientOfVariation(c);
        out.leading.push_back("- Leading species " + biome.species[s].name + ": mean " + num(mean(c), 6) + " plants (" +
                              fixed(100 * mean(share), 1) + " %), CV " + fixed(cv, 3) + ".");
        if (std::isnan(out.worstCv) || cv > out.worstCv) {
            out.worstCv = cv;
            out.worstName = biome.species[s].name;
        }
    }
    return out;
}

class Equilibrium final : public Scenario {
public:
    explicit Equilibrium(const ScenarioParse& in);
    std::vector<std::string> checkIds() const override { return {"total_cv", "leading_species_cv"}; }
    int windowYears() const override { return settings_.windowYears; }
    void run(const ScenarioConfig& sc, ScenarioContext& ctx, ScenarioResult& r) const override;

private:
    EquilibriumSettings settings_;
};

Equilibrium::Equilibrium(const ScenarioParse& in) {
    StrictTable s(in.top.table("equilibrium"), in.path, "[equilibrium]");
    readScenarioParams(s, settings_, equilibriumFields());
    s.finish();
}

void Equilibrium::run(const ScenarioConfig& sc, ScenarioContext& ctx, ScenarioResult& r) const {
    const Biome& biome = ctx.biome();
    const EquilibriumSettings& cfg = settings_;
    const ForestRun& run = ctx.forest(sc.scenePath, sim::CompetitionMode::Resources, 0);
    const int Y = ctx.measureYear(sc);
    ctx.describeRun(run, Y, r, ctx.scene(sc));
    const EquilibriumCvs cvs = equilibriumCvs(run, Y, cfg, biome);
    const std::vector<double>& total = cvs.total;
    r.checks.push_back(makeCheck(sc, "total_cv",
                                 "coefficient of variation of the total plant count over the last " +
                                     std::to_string(cfg.windowYears) + " years",
                                 cvs.totalCv));
    const double worst = cvs.worstCv;
    const std::string& worstName = cvs.worstName;
    for (const std::string& line : cvs.leading) r.details.push_back(line);
    const std::string note = std::isnan(worst) ? "no species reached the leading share" : "";
    r.checks.push_back(makeCheck(sc, "leading_species_cv",
                                 "largest coefficient of variation of a leading species' count (share >= " +
                                     fixed(100 * cfg.leadingMinShare, 0) + " %) over the last " +
                                     std::to_string(cfg.windowYears) + " years" + (worstName.empty() ? "" : " (" + worstName + ")"),
                                 worst, note));
    r.details.push_back("- Total: mean " + num(mean(total), 6) + " plants over years " + std::to_string(Y - cfg.windowYears + 1) +
                        "-" + std::to_string(Y) + ". CV = population standard deviation / mean of the yearly census.");
    if (Y < 2 * cfg.windowYears)
        r.details.push_back("- Note: the run (" + std::to_string(Y) + " years) is short compared with the window; the "
                            "paper reaches equilibrium at about 125 years.");
    // The same measures at the end of the scene's own run (the succession span), for comparison.
    const int sceneYears = ctx.scene(sc).size(ctx.mode()).years;
    if (sceneYears != Y && sceneYears >= cfg.windowYears && sceneYears <= run.years) {
        const EquilibriumCvs at = equilibriumCvs(run, sceneYears, cfg, biome);
        r.details.push_back("- For comparison, over years " + std::to_string(sceneYears - cfg.windowYears + 1) + "-" +
                            std::to_string(sceneYears) + " (the end of the " + std::to_string(sceneYears) +
                            "-year succession span): total CV " + fixed(at.totalCv, 3) + ", largest leading-species CV " +
                            fixed(at.worstCv, 3) + (at.worstName.empty() ? "" : " (" + at.worstName + ")") +
                            ". The paper reports equilibrium at about 125 years; docs/validation.md explains why ours "
                            "settles later.");
    }
    ctx.forestFigures(run, Y, sc.name, "Undergrowth under Douglas-Fir and Redwood, " + std::to_string(Y) + " years", r, false);
}

}  // namespace

std::unique_ptr<Scenario> createEquilibrium(const ScenarioParse& in) { return std::make_unique<Equilibrium>(in); }
std::vector<ScenarioKeyDoc> equilibriumKeys() { return scenarioKeyDocs("[equilibrium]", equilibriumFields()); }

}  // namespace eco::validate
