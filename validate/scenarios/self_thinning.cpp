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
#include "strict_toml.h"

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

/// The stand's census of one year.
struct YearStats {
    int year;
    double alive, densityPerM2, meanMass, meanAreaM2, meanHeightM, coverFraction, deaths, mortality;
};

/// A simulated stand: its census of every year (0 = the initial stand).
struct Stand {
    std::vector<YearStats> stats;
    std::size_t plants = 0;       ///< initial plants
    Clock::time_point started{};  ///< when the simulation started
};

/// Simulates the even-aged stand of settings st in `size` and records every year.
Stand simulateStand(const SelfThinningSettings& st, const SelfThinningSettings::Size& size, int species,
                    const ScenarioContext& ctx) {
    const Biome& biome = ctx.biome();
    const Species& sp = biome.species[static_cast<std::size_t>(species)];
    Stand out;
    // Flat, uniform plot without canopy: no shade but the stand's own, no seedbank.
    sim::DemoSceneParams dp;
    dp.cells = static_cast<int>(std::ceil(size.plotSizeM / dp.cellSizeM)) + 1;
    dp.seed = size.seed;
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
        RandomStream rs(size.seed, mixStream(i, kStandStreamTag));
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
    sim::Simulation s(std::move(in), st.params, size.seed, initial);

    std::vector<YearStats>& stats = out.stats;
    auto record = [&](int year, double deaths, double before) {
        const auto plants = s.plants();
        double mass = 0, area = 0, height = 0;
        for (const auto& p : plants) {
            const double a = M_PI * p.crownRadiusM * p.crownRadiusM;
            area += a;
            mass += std::pow(a, 1.5);
            height += p.heightM;
        }
        const double k = static_cast<double>(plants.size());
        stats.push_back({year, k, k / areaM2, k > 0 ? mass / k : kNaN, k > 0 ? area / k : kNaN, k > 0 ? height / k : kNaN,
                         area / areaM2, deaths, before > 0 ? deaths / before : kNaN});
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

/// The thinning phase [first, last] (-1 when none) for crown cover `coverNeeded`;
/// `background` is the yearly background mortality.
/// It starts in the first year in which the crowns have closed and mortality exceeds the
/// background by the configured factor, while enough plants remain for a meaningful mean.
/// (Without the closure condition the phase would include the first years, in which
/// randomly placed neighbours already kill each other while the stand is still open and mean
/// size grows faster than the thinning line; the report gives that fit too.) It lasts while
/// the canopy stays closed (cover at least the onset cover) and enough plants remain: Yoda's
/// line describes fully stocked stands, and once the plants near their maximum size,
/// background deaths open gaps that nothing refills.
void thinningPhase(const std::vector<YearStats>& stats, const SelfThinningSettings& st, double background,
                   double coverNeeded, int& first, int& last) {
    first = last = -1;
    for (const YearStats& y : stats) {
        if (y.year == 0) continue;
        if (first < 0 && y.coverFraction >= coverNeeded && y.mortality > st.onsetMortalityFactor * background)
            first = y.year;
        if (first < 0) continue;
        if (y.alive < st.minPlantsInFit || y.coverFraction < coverNeeded) break;
        last = y.year;
    }
}

/// Fits log10 mean mass on log10 density over the phase [first, last]: false with a note
/// when there is no phase, fewer than 3 years or a degenerate fit. lx, ly get the points.
bool fitThinningPhase(const std::vector<YearStats>& stats, const SelfThinningSettings& st, double background, int first,
                      int last, std::vector<double>& lx, std::vector<double>& ly, LineFit& fit, std::string& note) {
    if (first >= 0)
        for (const YearStats& y : stats)
            if (y.year >= first && y.year <= last && y.alive > 0) {
                lx.push_back(std::log10(y.densityPerM2));
                ly.push_back(std::log10(y.meanMass));
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
    note = first < 0 ? "no thinning phase: crown cover never reached " + num(st.onsetCoverFraction) +
                           " with yearly mortality above " + num(st.onsetMortalityFactor) + " x background (" +
                           fixed(100 * background, 2) + " %/year)"
                     : "thinning phase has fewer than 3 years";
    return false;
}

/// Log-log plot: every year, the fitted years, the fit and a -3/2 reference line.
void plotLogLog(const std::string& path, const std::string& speciesName, const std::vector<YearStats>& stats,
                const std::vector<double>& lx, const std::vector<double>& ly, bool fitted, const LineFit& fit) {
    PlotSeries all{"every year", {}, {}, {0.6f, 0.6f, 0.6f}, true, 2.5};
    PlotSeries used{"thinning phase (fitted)", {}, {}, {0.85f, 0.3f, 0.1f}, false, 4.0};
    for (const YearStats& y : stats)
        if (y.alive > 0 && y.meanMass > 0) {
            all.x.push_back(std::log10(y.densityPerM2));
            all.y.push_back(std::log10(y.meanMass));
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
                   "log10 mean mass, (crown area)^1.5 (m^3)", series);
}

class SelfThinning final : public Scenario {
public:
    explicit SelfThinning(const ScenarioParse& in);
    std::vector<std::string> checkIds() const override { return {"slope", "r_squared"}; }
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
    st.densityPerM2 = s.numberIn("density_per_m2", 0.01, 25.0);
    st.initialHeightMinM = s.positive("initial_height_min_m");
    st.initialHeightMaxM = s.positive("initial_height_max_m");
    if (st.initialHeightMaxM < st.initialHeightMinM) s.fail("initial_height_max_m", "must not be below initial_height_min_m");
    s.finish();
    StrictTable t(in.top.table("thinning"), in.path, "[thinning]");
    st.onsetCoverFraction = t.numberIn("onset_cover_fraction", 0.0, 10.0);
    st.onsetMortalityFactor = t.numberIn("onset_mortality_factor", 1.0, 1000.0);
    st.minPlantsInFit = static_cast<int>(t.numberIn("min_plants_in_fit", 3, 1e9));
    t.finish();
    in.sizes([&](Mode m, StrictTable& z) {
        auto& size = m == Mode::Quick ? st.quick : st.full;
        size.plotSizeM = z.numberIn("plot_size_m", 1.0, 1000.0);
        size.years = yearsIn(z, "years", 2, 100000);
        size.seed = seedOf(z, "seed");
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
    const std::vector<YearStats>& stats = stand.stats;
    const std::size_t n = stand.plants;
    const auto t0 = stand.started;
    const double background = 1.0 - std::pow(st.params.survivalAtMaxAge, 1.0 / sp.maxAgeYears);
    int first, last, firstAny, lastAny;
    thinningPhase(stats, st, background, st.onsetCoverFraction, first, last);
    thinningPhase(stats, st, background, 0.0, firstAny, lastAny);
    std::vector<double> lx, ly, ax, ay;
    LineFit fit, fitAny;
    std::string note, noteAny;
    const bool fitted = fitThinningPhase(stats, st, background, first, last, lx, ly, fit, note);
    const bool fittedAny = fitThinningPhase(stats, st, background, firstAny, lastAny, ax, ay, fitAny, noteAny);
    r.checks.push_back(makeCheck(sc, "slope",
                                 "slope of log10 mean mass against log10 density over the thinning phase (Yoda: -3/2)",
                                 fitted ? fit.slope : kNaN, note));
    r.checks.push_back(makeCheck(sc, "r_squared", "R^2 of that fit", fitted ? fit.rSquared : kNaN, note));

    r.details.push_back("- Stand: " + std::to_string(n) + " " + sp.name + " (max height " + num(sp.maxHeightM) +
                        " m, max age " + num(sp.maxAgeYears) + " years, allometry " + sp.allometry.code + ") at " +
                        num(st.densityPerM2) + " plants/m^2 on a flat " + fixed(size.plotSizeM, 0) + " m x " +
                        fixed(size.plotSizeM, 0) + " m plot with uniform abiotics, no canopy, germination off "
                        "(seeding_probability = " + num(st.params.seedingProbability) + "), initial heights uniform in [" +
                        num(st.initialHeightMinM) + ", " + num(st.initialHeightMaxM) + "] m; growth rule " +
                        sim::growthRuleName(st.params.growthRule) + "; " + std::to_string(size.years) + " years in " +
                        fixed(secondsSince(t0), 1) + " s.");
    r.details.push_back("- Mass proxy: m = (crown area)^(3/2) per plant (m^3), mean over the living plants; density = "
                        "living plants per m^2. Fit: ordinary least squares (Eigen QR) of log10 mean mass on log10 density.");
    r.details.push_back("- Thinning phase: from the first year in which the crown cover (sum of crown areas / plot area) "
                        "is at least " + num(st.onsetCoverFraction) + " and the mortality exceeds " + num(st.onsetMortalityFactor) +
                        " x the background rate (1 - P_s^(1/l) = " + fixed(100 * background, 2) +
                        " %/year), for as long as the cover stays at least " + num(st.onsetCoverFraction) +
                        " (a closed stand) and at least " + std::to_string(st.minPlantsInFit) +
                        " plants live: " + (first < 0 ? std::string("none") : "years " + std::to_string(first) + "-" + std::to_string(last)) +
                        (fitted ? ", " + std::to_string(fit.points) + " points, slope " + fixed(fit.slope, 3) + " ± " +
                                      fixed(fit.slopeStdError, 3) + " (standard error), R^2 " + fixed(fit.rSquared, 3)
                                : std::string()) + ".");
    r.details.push_back("- For comparison, without the crown-closure conditions (from the first year with mortality above " +
                        num(st.onsetMortalityFactor) + " x background while at least " + std::to_string(st.minPlantsInFit) +
                        " plants live: " +
                        (firstAny < 0 ? std::string("none") : "years " + std::to_string(firstAny) + "-" + std::to_string(lastAny)) +
                        "): " + (fittedAny ? "slope " + fixed(fitAny.slope, 3) + ", R^2 " + fixed(fitAny.rSquared, 3) : noteAny) +
                        ". Not a check; it shows how much the definition of the phase matters.");
    std::string table = "\n| year | plants | density (1/m^2) | mean height (m) | mean crown area (m^2) | cover | mortality |\n|---|---|---|---|---|---|---|\n";
    for (const YearStats& y : stats)
        if (y.year % 5 == 0 || y.year == first || y.year == last)
            table += "| " + std::to_string(y.year) + " | " + num(y.alive, 6) + " | " + num(y.densityPerM2) + " | " +
                     num(y.meanHeightM) + " | " + num(y.meanAreaM2) + " | " + fixed(y.coverFraction, 2) + " | " +
                     (std::isnan(y.mortality) ? std::string("") : fixed(100 * y.mortality, 1) + " %") + " |\n";
    r.details.push_back(table);

    const std::string png = sc.name + "_loglog.png";
    plotLogLog(ctx.file(png), sp.name, stats, lx, ly, fitted, fit);
    r.figures.push_back({png, "Log mean mass against log density, every year; the fitted thinning phase and a -3/2 reference."});
}

}  // namespace

std::unique_ptr<Scenario> createSelfThinning(const ScenarioParse& in) { return std::make_unique<SelfThinning>(in); }

}  // namespace eco::validate
