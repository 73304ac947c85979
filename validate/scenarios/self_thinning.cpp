// Kind "self_thinning" (paper §7.2, Fig. 13; Yoda's -3/2 law): a dense even-aged stand of one
// species on a flat open plot; the slope of log mean mass against log density over the
// thinning phase. docs/validation.md defines the measures.
#include "scenario_context.h"

#include <algorithm>
#include <cmath>

#include "demo_scene.h"
#include "error.h"
#include "fit.h"
#include "plots.h"
#include "rng.h"
#include "scenario_keys.h"
#include "strict_toml.h"
#include "thinning.h"

namespace eco::validate {

namespace {

constexpr std::uint64_t kStandStreamTag = 0x5354414E44504C41ull;  // self-thinning stand

struct SelfThinningSettings {
    std::string species;
    double densityPerM2 = 16;
    double initialHeightMinM = 0.05, initialHeightMaxM = 0.15;
    /// The thinning phase starts in the first year in which the crowns have closed (crown
    /// cover, sum of crown areas over the plot area, at least onsetCoverFraction) and the
    /// yearly mortality exceeds onsetMortalityFactor x the background rate.
    double onsetCoverFraction = 0.5;
    double onsetMortalityFactor = 3;
    int minPlantsInFit = 30;
    struct Size {
        double plotSizeM = 20;
        int years = 60;
        std::uint64_t seed = 1;
    };
    Size quick, full;
    sim::SimParams params;
};

using StK = ParamDesc<SelfThinningSettings>::Kind;
using StP = SelfThinningSettings;

/// [stand]'s numeric keys (species is read by hand; max >= min is checked after them).
const std::vector<ParamDesc<StP>>& standFields() {
    static const std::vector<ParamDesc<StP>> fields = {
        {"density_per_m2", "initial plants per m^2", "1/m^2", StK::Real, &StP::densityPerM2, nullptr,
         ParamRange::closed(0.01, 25.0)},
        {"initial_height_min_m", "initial heights uniform in [min, max]: the smallest", "m", StK::Real,
         &StP::initialHeightMinM, nullptr, ParamRange::above(0), nullptr, "must be positive"},
        {"initial_height_max_m", "initial heights uniform in [min, max]: the largest", "m", StK::Real,
         &StP::initialHeightMaxM, nullptr, ParamRange::above(0), nullptr, "must be positive"},
    };
    return fields;
}

/// [thinning].
const std::vector<ParamDesc<StP>>& thinningFields() {
    static const std::vector<ParamDesc<StP>> fields = {
        {"onset_cover_fraction", "the thinning phase starts once crown cover (crown areas over plot area) reaches this", "",
         StK::Real, &StP::onsetCoverFraction, nullptr, ParamRange::closed(0.0, 10.0)},
        {"onset_mortality_factor", "... and the yearly mortality exceeds this x the background rate", "", StK::Real,
         &StP::onsetMortalityFactor, nullptr, ParamRange::closed(1.0, 1000.0)},
        {"min_plants_in_fit", "the fitted phase ends while at least this many plants live", "", StK::Integer, nullptr,
         &StP::minPlantsInFit, ParamRange::closed(3, 1e9)},
    };
    return fields;
}

/// [quick] and [full]: the plot and run of each size.
const std::vector<ParamDesc<StP::Size>>& standSizeFields() {
    using K = ParamDesc<StP::Size>::Kind;
    using P = StP::Size;
    static const std::vector<ParamDesc<P>> fields = {
        {"plot_size_m", "side of the square plot", "m", K::Real, &P::plotSizeM, nullptr, ParamRange::closed(1.0, 1000.0)},
        {"years", "years simulated", "years", K::Integer, nullptr, &P::years, ParamRange::closed(2, 100000)},
        {"seed", "seed of the stand and the run (replicate k adds k x 1000)", "", K::Seed, nullptr, nullptr,
         ParamRange::any(), &P::seed},
    };
    return fields;
}

/// A simulated stand: its census of every year (0 = the initial stand) and every plant's
/// (id, height) in every year, for the ranks of the dying.
struct Stand {
    std::vector<StandYear> stats;
    std::vector<std::vector<std::pair<std::uint64_t, double>>> heights;  ///< [year]: (id, height), by id
    std::size_t plants = 0;       ///< initial plants
    Clock::time_point started{};  ///< when the simulation started
};

/// Simulates the even-aged stand of settings st in `size` and records every year.
Stand simulateStand(const SelfThinningSettings& st, const SelfThinningSettings::Size& size, int species,
                    const ScenarioContext& ctx) {
    const Biome& biome = ctx.biome();
    const Species& sp = biome.species[static_cast<std::size_t>(species)];
    Stand out;
    const std::uint64_t seed = ctx.seed(size.seed);
    // Flat, uniform plot without canopy: no shade but the stand's own, no seedbank.
    sim::DemoSceneParams dp;
    dp.cells = static_cast<int>(std::ceil(size.plotSizeM / dp.cellSizeM)) + 1;
    dp.seed = seed;
    dp.uniformAbiotics = true;
    sim::SimInputs in = sim::makeDemoScene(dp, biome);
    in.canopy.clear();
    in.chmM = Grid<float>();
    const double ox = in.abiotics.elevationM.originX(), oy = in.abiotics.elevationM.originY();
    in.area = sim::SimArea{ox, oy, ox + size.plotSizeM, oy + size.plotSizeM};
    const double areaM2 = size.plotSizeM * size.plotSizeM;
    const auto n = static_cast<std::size_t>(std::llround(st.densityPerM2 * areaM2));
    std::vector<sim::UndergrowthPlant> initial(n);
    for (std::size_t i = 0; i < n; ++i) {
        RandomStream rs(seed, mixStream(i, kStandStreamTag));
        sim::UndergrowthPlant& p = initial[i];
        p.id = i + 1;
        p.speciesId = species;
        p.xM = rs.uniform(ox, ox + size.plotSizeM);
        p.yM = rs.uniform(oy, oy + size.plotSizeM);
        p.heightM = rs.uniform(st.initialHeightMinM, st.initialHeightMaxM);
        p.groundZM = in.abiotics.elevationM.sampleBilinear(p.xM, p.yM);
    }
    ctx.log("validate: self-thinning stand: " + std::to_string(n) + " " + sp.name + " on " + fixed(size.plotSizeM, 0) +
            " m x " + fixed(size.plotSizeM, 0) + " m, " + std::to_string(size.years) + " years");
    out.plants = n;
    out.started = Clock::now();
    const auto t0 = out.started;
    sim::Simulation s(std::move(in), st.params, seed, initial);

    std::vector<StandYear>& stats = out.stats;
    auto record = [&](int year, double deaths, double before) {
        const auto plants = s.plants();
        double volume = 0, area = 0, height = 0;
        std::vector<std::pair<std::uint64_t, double>> hs;
        hs.reserve(plants.size());
        for (const auto& p : plants) {
            const double a = M_PI * p.crownRadiusM * p.crownRadiusM;
            area += a;
            volume += a * p.heightM;
            height += p.heightM;
            hs.emplace_back(p.id, p.heightM);
        }
        std::sort(hs.begin(), hs.end());
        out.heights.push_back(std::move(hs));
        const double k = static_cast<double>(plants.size());
        StandYear y;
        y.year = year;
        y.alive = k;
        y.densityPerM2 = k / areaM2;
        y.meanVolumeM3 = k > 0 ? volume / k : kNaN;
        y.meanAreaM2 = k > 0 ? area / k : kNaN;
        y.meanHeightM = k > 0 ? height / k : kNaN;
        y.coverFraction = area / areaM2;
        y.mortality = before > 0 ? deaths / before : kNaN;
        stats.push_back(y);
    };
    record(0, 0, 0);
    auto deathsSoFar = [&] {
        return static_cast<double>(s.counters().diedBackgroundOrStress + s.counters().diedAtCanopy);
    };
    double lastDeaths = deathsSoFar();
    for (int y = 1; y <= size.years; ++y) {
        const double before = static_cast<double>(s.plantCount());
        s.stepYear();
        const double d = deathsSoFar();
        record(y, d - lastDeaths, before);
        lastDeaths = d;
        if (y % 10 == 0 || y == size.years)
            ctx.log("validate:   self-thinning: year " + std::to_string(y) + "/" + std::to_string(size.years) + ", " +
                    std::to_string(s.plantCount()) + " plants, " + fixed(secondsSince(t0), 1) + " s");
    }
    return out;
}

/// Fits log10 of `measure` (a mean per plant) on log10 density over the phase: false with a
/// note when there is no phase, fewer than 3 years or a degenerate fit. lx, ly get the points.
bool fitPhase(const std::vector<StandYear>& stats, const SelfThinningSettings& st, const ThinningRule& rule,
              std::pair<int, int> phase, double StandYear::*measure, std::vector<double>& lx, std::vector<double>& ly,
              LineFit& fit, std::string& note) {
    if (phase.first >= 0)
        for (const StandYear& y : stats)
            if (y.year >= phase.first && y.year <= phase.second && y.alive > 0) {
                lx.push_back(std::log10(y.densityPerM2));
                ly.push_back(std::log10(y.*measure));
            }
    if (lx.size() >= 3) {
        try {
            fit = fitLine(lx, ly);
            return true;
        } catch (const ValidationError& e) {
            note = e.what();
            return false;
        }
    }
    note = phase.first < 0 ? "no thinning phase: crown cover never reached " + num(st.onsetCoverFraction) +
                                 " with yearly mortality above " + num(st.onsetMortalityFactor) + " x background (" +
                                 fixed(100 * rule.backgroundMortality, 2) + " %/year)"
                           : "thinning phase has fewer than 3 years";
    return false;
}

/// Log-log plot: every year, the fitted years, the fit and a -3/2 reference line.
void plotLogLog(const std::string& path, const std::string& speciesName, const std::vector<StandYear>& stats,
                const std::vector<double>& lx, const std::vector<double>& ly, bool fitted, const LineFit& fit) {
    PlotSeries all{"every year", {}, {}, {0.6f, 0.6f, 0.6f}, true, 2.5};
    PlotSeries used{"thinning phase (fitted)", {}, {}, {0.85f, 0.3f, 0.1f}, false, 4.0};
    for (const StandYear& y : stats)
        if (y.alive > 0 && y.meanVolumeM3 > 0) {
            all.x.push_back(std::log10(y.densityPerM2));
            all.y.push_back(std::log10(y.meanVolumeM3));
        }
    used.x = lx;
    used.y = ly;
    std::vector<PlotSeries> series{all, used};
    if (fitted) {
        const auto [mn, mx] = std::minmax_element(lx.begin(), lx.end());
        PlotSeries line{"fit, slope " + fixed(fit.slope, 2), {*mn, *mx},
                        {fit.intercept + fit.slope * *mn, fit.intercept + fit.slope * *mx}, {0.1f, 0.3f, 0.8f}, true, 0};
        const double cx = mean(lx), cy = mean(ly);
        PlotSeries ref{"slope -3/2 (Yoda)", {*mn, *mx}, {cy - 1.5 * (*mn - cx), cy - 1.5 * (*mx - cx)}, {0.2f, 0.65f, 0.2f}, true, 0};
        series.push_back(line);
        series.push_back(ref);
    }
    writeXYPlotPng(path, "Self-thinning: " + speciesName, "log10 density (plants per m^2)",
                   "log10 mean plant volume, crown area x height (m^3)", series);
}

class SelfThinning final : public Scenario {
public:
    explicit SelfThinning(const ScenarioParse& in);
    std::vector<std::string> checkIds() const override {
        return {"slope", "r_squared", "closure_exponent", "density_drop", "death_size_rank"};
    }
    std::vector<std::pair<std::string, std::string>> speciesNamed() const override {
        return {{"[stand] species", settings_.species}};
    }
    void run(const ScenarioConfig& sc, ScenarioContext& ctx, ScenarioResult& r) const override;

private:
    SelfThinningSettings settings_;
};

SelfThinning::SelfThinning(const ScenarioParse& in) {
    SelfThinningSettings& st = settings_;
    StrictTable s(in.top.table("stand"), in.path, "[stand]");
    st.species = s.string("species");
    readScenarioParams(s, st, standFields());
    if (st.initialHeightMaxM < st.initialHeightMinM) s.fail("initial_height_max_m", "must not be below initial_height_min_m");
    s.finish();
    StrictTable t(in.top.table("thinning"), in.path, "[thinning]");
    readScenarioParams(t, st, thinningFields());
    t.finish();
    in.sizes([&](Mode m, StrictTable& z) {
        auto& size = m == Mode::Quick ? st.quick : st.full;
        readScenarioParams(z, size, standSizeFields());
    });
    st.params = in.model();
}

void SelfThinning::run(const ScenarioConfig& sc, ScenarioContext& ctx, ScenarioResult& r) const {
    const Biome& biome = ctx.biome();
    const SelfThinningSettings& st = settings_;
    const auto& size = ctx.mode() == Mode::Quick ? st.quick : st.full;
    const int species = biome.speciesIndex(st.species);
    const Species& sp = biome.species[static_cast<std::size_t>(species)];
    const Stand stand = simulateStand(st, size, species, ctx);
    const std::vector<StandYear>& stats = stand.stats;
    const std::size_t n = stand.plants;
    const auto t0 = stand.started;
    ThinningRule rule;
    rule.onsetCoverFraction = st.onsetCoverFraction;
    rule.onsetMortalityFactor = st.onsetMortalityFactor;
    rule.backgroundMortality = 1.0 - std::pow(st.params.survivalAtMaxAge, 1.0 / sp.maxAgeYears);
    rule.minPlants = st.minPlantsInFit;
    ThinningRule open = rule;
    open.onsetCoverFraction = 0.0;
    const auto phase = thinningPhase(stats, rule), phaseAny = thinningPhase(stats, open);
    std::vector<double> lx, ly, ax, ay, cx, cy;
    LineFit fit, fitAny, closure;
    std::string note, noteAny, noteClosure;
    const bool fitted = fitPhase(stats, st, rule, phase, &StandYear::meanVolumeM3, lx, ly, fit, note);
    const bool fittedAny = fitPhase(stats, st, open, phaseAny, &StandYear::meanVolumeM3, ax, ay, fitAny, noteAny);
    const bool closed = fitPhase(stats, st, rule, phase, &StandYear::meanAreaM2, cx, cy, closure, noteClosure);
    const double drop = densityDropLog10(stats, phase);
    double rank = kNaN;
    std::string rankNote = note;
    if (phase.first >= 0) {
        // Year by year: who dies in year y among those alive at its start, weighted by the deaths
        // (over the whole phase most plants die, and the dead of many years average to 1/2).
        double sum = 0, deaths = 0;
        for (int y = std::max(1, phase.first); y <= phase.second; ++y) {
            const auto& before = stand.heights[static_cast<std::size_t>(y - 1)];
            const auto& after = stand.heights[static_cast<std::size_t>(y)];
            std::vector<std::uint64_t> alive;
            for (const auto& [id, h] : after) alive.push_back(id);
            const double rk = deathSizeRank(before, alive);
            const double died = static_cast<double>(before.size()) - static_cast<double>(after.size());
            if (!std::isnan(rk) && died > 0) {
                sum += rk * died;
                deaths += died;
            }
        }
        rank = deaths > 0 ? sum / deaths : kNaN;
        rankNote = deaths > 0 ? "" : "nobody died in the thinning phase";
    }
    r.checks.push_back(makeCheck(sc, "slope",
                                 "slope of log10 mean plant volume (crown area x height) against log10 density over the "
                                 "thinning phase (Yoda: -3/2)",
                                 fitted ? fit.slope : kNaN, note));
    r.checks.push_back(makeCheck(sc, "r_squared", "R^2 of that fit", fitted ? fit.rSquared : kNaN, note));
    r.checks.push_back(makeCheck(sc, "closure_exponent",
                                 "slope of log10 mean crown area against log10 density over the phase (-1: the stand "
                                 "stays closed as it thins)",
                                 closed ? closure.slope : kNaN, noteClosure));
    r.checks.push_back(makeCheck(sc, "density_drop", "log10 of the density at the phase's start over that at its end",
                                 drop, phase.first < 0 ? note : ""));
    r.checks.push_back(makeCheck(sc, "death_size_rank",
                                 "mean height rank (0 = shortest, 1 = tallest), among the plants alive at the start of a "
                                 "year of the phase, of those that die in it (1/2 when deaths ignore size)",
                                 rank, rankNote));

    r.details.push_back("- Stand: " + std::to_string(n) + " " + sp.name + " (max height " + num(sp.maxHeightM) +
                        " m, max age " + num(sp.maxAgeYears) + " years, allometry " + sp.allometry.code + ") at " +
                        num(st.densityPerM2) + " plants/m^2 on a flat " + fixed(size.plotSizeM, 0) + " m x " +
                        fixed(size.plotSizeM, 0) + " m plot with uniform abiotics, no canopy, germination off "
                        "(seeding_probability = " + num(st.params.seedingProbability) + "), initial heights uniform in [" +
                        num(st.initialHeightMinM) + ", " + num(st.initialHeightMaxM) + "] m; growth rule " +
                        sim::growthRuleName(st.params.growthRule) + "; " + std::to_string(size.years) + " years in " +
                        fixed(secondsSince(t0), 1) + " s.");
    r.details.push_back("- Mass proxy: plant volume v = crown area x height (m^3), mean over the living plants; density = "
                        "living plants per m^2. Fits: ordinary least squares (Eigen QR) of log10 mean volume, and of log10 "
                        "mean crown area, on log10 density. A mass made of crown area alone, e.g. (crown area)^(3/2), "
                        "gives -3/2 by geometry in any stand that stays closed; the volume's slope also depends on how "
                        "height scales with crown size, and the closure exponent and the death ranks test the thinning "
                        "itself.");
    const std::string phaseText =
        phase.first < 0 ? std::string("none") : "years " + std::to_string(phase.first) + "-" + std::to_string(phase.second);
    r.details.push_back("- Thinning phase: from the first year in which the crown cover (sum of crown areas / plot area) "
                        "is at least " + num(st.onsetCoverFraction) + " and the mortality exceeds " + num(st.onsetMortalityFactor) +
                        " x the background rate (1 - P_s^(1/l) = " + fixed(100 * rule.backgroundMortality, 2) +
                        " %/year), for as long as the cover stays at least " + num(st.onsetCoverFraction) +
                        " (a closed stand) and at least " + std::to_string(st.minPlantsInFit) + " plants live: " + phaseText +
                        (fitted ? ", " + std::to_string(fit.points) + " points, volume slope " + fixed(fit.slope, 3) + " ± " +
                                      fixed(fit.slopeStdError, 3) + " (standard error), R^2 " + fixed(fit.rSquared, 3)
                                : std::string()) +
                        (closed ? "; crown-area slope " + fixed(closure.slope, 3) + " ± " + fixed(closure.slopeStdError, 3)
                                : std::string()) + ".");
    r.details.push_back("- For comparison, without the crown-closure conditions (from the first year with mortality above " +
                        num(st.onsetMortalityFactor) + " x background while at least " + std::to_string(st.minPlantsInFit) +
                        " plants live: " +
                        (phaseAny.first < 0 ? std::string("none")
                                            : "years " + std::to_string(phaseAny.first) + "-" + std::to_string(phaseAny.second)) +
                        "): " + (fittedAny ? "volume slope " + fixed(fitAny.slope, 3) + ", R^2 " + fixed(fitAny.rSquared, 3) : noteAny) +
                        ". Not a check; it shows how much the definition of the phase matters.");
    std::string table = "\n| year | plants | density (1/m^2) | mean height (m) | mean crown area (m^2) | mean volume (m^3) | cover | mortality |\n|---|---|---|---|---|---|---|---|\n";
    for (const StandYear& y : stats)
        if (y.year % 5 == 0 || y.year == phase.first || y.year == phase.second)
            table += "| " + std::to_string(y.year) + " | " + num(y.alive, 6) + " | " + num(y.densityPerM2) + " | " +
                     num(y.meanHeightM) + " | " + num(y.meanAreaM2) + " | " + num(y.meanVolumeM3) + " | " +
                     fixed(y.coverFraction, 2) + " | " +
                     (std::isnan(y.mortality) ? std::string("") : fixed(100 * y.mortality, 1) + " %") + " |\n";
    r.details.push_back(table);

    const std::string png = sc.name + "_loglog.png";
    plotLogLog(ctx.file(png), sp.name, stats, lx, ly, fitted, fit);
    r.figures.push_back({png, "Log mean plant volume against log density, every year; the fitted thinning phase and a -3/2 reference."});
}

}  // namespace

std::unique_ptr<Scenario> createSelfThinning(const ScenarioParse& in) { return std::make_unique<SelfThinning>(in); }
std::vector<ScenarioKeyDoc> selfThinningKeys() {
    return joinKeyDocs({scenarioKeyDocs("[stand]", standFields()), scenarioKeyDocs("[thinning]", thinningFields()),
                        scenarioKeyDocs("[quick], [full]", standSizeFields())});
}

}  // namespace eco::validate
