// Kind "ecomod" (issue 30 item 2; Zamuda & Brest's Fig. 8): the EcoMod model's afforestation
// of an empty terrain over centuries (tree counts per species per year: CSV and PNG, checked
// for the exponential start, the pioneers' retreat, the late species' gain and the
// stabilisation), and the succession of both simulator models on the same small forest scene
// side by side (counts per species per year: CSV and PNG, not checked: the models differ by
// design). docs/ecomod.md describes the measures.
#include "scenario_context.h"

#include <algorithm>
#include <cmath>
#include <fstream>

#include "atomic_file.h"
#include "chart.h"
#include "demo_scene.h"
#include "error.h"
#include "fit.h"
#include "sim_render.h"
#include "scenario_keys.h"
#include "strict_toml.h"

namespace eco::validate {

namespace {

struct EcoModSettings {
    double pioneerMaxAgeYears = 100;  ///< pioneers: species whose max age is at most this
    double lateMinAgeYears = 250;     ///< late species: max age at least this
    double stableFraction = 0.25;     ///< stabilisation measured over the last this share of the years
    struct Size {
        int terrainCells = 96;
        double terrainCellM = 2.0;
        int years = 300;
        double comparisonPlotM = 20;
        int comparisonYears = 30;
        std::uint64_t seed = 1;
    };
    Size quick, full;
    sim::SimParams ecomod;  ///< [model] of the file, with kind = "ecomod"
};

/// [groups].
const std::vector<ParamDesc<EcoModSettings>>& groupFields() {
    using P = EcoModSettings;
    using K = ParamDesc<P>::Kind;
    static const std::vector<ParamDesc<P>> fields = {
        {"pioneer_max_age_years", "pioneers: the species whose max age is at most this", "years", K::Real,
         &P::pioneerMaxAgeYears, nullptr, ParamRange::closed(0.0, 10000.0)},
        {"late_min_age_years", "late species: the species whose max age is at least this", "years", K::Real,
         &P::lateMinAgeYears, nullptr, ParamRange::closed(0.0, 10000.0)},
        {"stable_fraction", "stabilisation is measured over this last share of the years", "", K::Real, &P::stableFraction,
         nullptr, ParamRange::closed(0.01, 1.0)},
    };
    return fields;
}

/// [quick] and [full]: the terrain, the run and the comparison plot of each size.
const std::vector<ParamDesc<EcoModSettings::Size>>& ecomodSizeFields() {
    using P = EcoModSettings::Size;
    using K = ParamDesc<P>::Kind;
    static const std::vector<ParamDesc<P>> fields = {
        {"terrain_cells", "square terrain of this many cells a side", "", K::Integer, nullptr, &P::terrainCells,
         ParamRange::closed(8, 4096)},
        {"terrain_cell_m", "cell size of the terrain", "m", K::Real, &P::terrainCellM, nullptr, ParamRange::closed(0.1, 100.0)},
        {"years", "years simulated", "years", K::Integer, nullptr, &P::years, ParamRange::closed(10, 100000)},
        {"comparison_plot_m", "side of the plot run with both models for the comparison", "m", K::Real, &P::comparisonPlotM,
         nullptr, ParamRange::closed(1.0, 1000.0)},
        {"comparison_years", "years of the comparison runs", "years", K::Integer, nullptr, &P::comparisonYears, ParamRange::closed(1, 100000)},
        {"seed", "seed of the terrain and the runs (replicate k adds k x 1000)", "", K::Seed, nullptr, nullptr,
         ParamRange::any(), &P::seed},
    };
    return fields;
}

struct Run {
    std::vector<sim::YearRecord> timeseries;
    double seconds = 0;
    std::int64_t plantMonths = 0;
};

Run simulate(sim::SimInputs in, const sim::SimParams& params, std::uint64_t seed, int years, const std::string& label,
             const ScenarioContext& ctx) {
    Run r;
    const auto t0 = Clock::now();
    sim::Simulation s(std::move(in), params, seed);
    r.timeseries.push_back(s.census());
    for (int y = 1; y <= years; ++y) {
        s.stepYear();
        r.timeseries.push_back(s.census());
        if (y % 50 == 0 || y == years)
            ctx.log("validate:   " + label + ": year " + std::to_string(y) + "/" + std::to_string(years) + ", " +
                    std::to_string(s.plantCount()) + " trees, " + fixed(secondsSince(t0), 1) + " s");
    }
    r.seconds = secondsSince(t0);
    r.plantMonths = s.counters().plantMonths;
    return r;
}

double total(const sim::YearRecord& r) {
    double n = 0;
    for (auto c : r.count) n += c;
    return n;
}
double groupCount(const sim::YearRecord& r, const std::vector<int>& group) {
    double n = 0;
    for (int s : group) n += r.count[static_cast<std::size_t>(s)];
    return n;
}

/// CSV: year, model, then one column per species (counts).
void writeCountsCsv(const std::string& path, const Biome& biome,
                    const std::vector<std::pair<std::string, const std::vector<sim::YearRecord>*>>& runs) {
    AtomicOutput out(path);
    {
        std::ofstream f(out.tempPath());
        f << "year,model";
        for (const Species& s : biome.species) f << ",\"" << s.name << "\"";
        f << ",total\n";
        for (const auto& [model, ts] : runs)
            for (const sim::YearRecord& r : *ts) {
                f << r.year << "," << model;
                for (auto c : r.count) f << "," << c;
                f << "," << static_cast<long long>(total(r)) << "\n";
            }
        if (!f) throw IoError(path + ": write failed");
    }
    out.commit();
}

/// Two panels side by side: counts per species per year of each model.
void plotComparison(const std::string& path, const Biome& biome, const Run& monthly, const Run& eco, double plotM) {
    std::vector<ChartPanel> panels;
    std::vector<bool> used(biome.species.size(), false);
    for (const auto* run : {&monthly, &eco}) {
        ChartPanel p;
        p.title = run == &monthly ? "monthly model (Kapp et al. 2020, section 6.1)" : "EcoMod (Zamuda & Brest)";
        double ymax = 1;
        for (std::size_t s = 0; s < biome.species.size(); ++s) {
            ChartSeries line{biome.species[s].name, {}, {}, categoryColour(static_cast<int>(s))};
            bool any = false;
            for (const sim::YearRecord& r : run->timeseries) {
                line.x.push_back(r.year);
                line.y.push_back(r.count[s]);
                ymax = std::max(ymax, static_cast<double>(r.count[s]));
                any = any || r.count[s] > 0;
            }
            if (any) {
                used[s] = true;
                p.series.push_back(std::move(line));
            }
        }
        p.xmin = 0;
        p.xmax = std::max(1, run->timeseries.back().year);
        p.ymin = 0;
        p.ymax = ymax * 1.05;
        panels.push_back(std::move(p));
    }
    ChartPanelsLayout layout;
    layout.title = "Succession of the two simulator models on the same " + fixed(plotM, 0) + " m x " + fixed(plotM, 0) +
                   " m forest plot (same canopy, abiotics and seed)";
    layout.notes = {"Plants per species per year. The monthly model grows undergrowth under a static canopy; EcoMod grows "
                    "every species (canopy species too) as yearly agents, with the canopy trees as static dominators and parents."};
    for (std::size_t s = 0; s < used.size(); ++s)
        if (used[s]) layout.key.push_back({biome.species[s].name, categoryColour(static_cast<int>(s))});
    layout.xlabel = "year";
    layout.ylabel = "plants";
    layout.columns = 2;
    layout.plotWidthPx = 420;
    layout.plotHeightPx = 260;
    chartPanels(panels, layout).writePng(path);
}

class EcoModScenario final : public Scenario {
public:
    explicit EcoModScenario(const ScenarioParse& in);
    std::vector<std::string> checkIds() const override {
        return {"exponential_start", "pioneer_retreat", "late_share_gain", "stabilisation"};
    }
    void run(const ScenarioConfig& sc, ScenarioContext& ctx, ScenarioResult& r) const override;

private:
    EcoModSettings settings_;
};

EcoModScenario::EcoModScenario(const ScenarioParse& in) {
    EcoModSettings& st = settings_;
    StrictTable g(in.top.table("groups"), in.path, "[groups]");
    readScenarioParams(g, st, groupFields());
    g.finish();
    in.sizes([&](Mode m, StrictTable& z) {
        auto& size = m == Mode::Quick ? st.quick : st.full;
        readScenarioParams(z, size, ecomodSizeFields());
    });
    st.ecomod = in.model();
    st.ecomod.kind = sim::ModelKind::EcoMod;
}

void EcoModScenario::run(const ScenarioConfig& sc, ScenarioContext& ctx, ScenarioResult& r) const {
    const Biome& biome = ctx.biome();
    const EcoModSettings& st = settings_;
    const auto& size = ctx.mode() == Mode::Quick ? st.quick : st.full;
    const std::uint64_t seed = ctx.seed(size.seed);

    // 1. Afforestation: the procedural terrain (hills and valleys, its sun, moisture and wind),
    // without its canopy: empty ground, as the paper's abandoned grassland.
    sim::DemoSceneParams dp;
    dp.cells = size.terrainCells;
    dp.cellSizeM = size.terrainCellM;
    dp.seed = seed;
    sim::SimInputs terrain = sim::makeDemoScene(dp, biome);
    sim::SimInputs empty = terrain;
    empty.canopy.clear();
    empty.chmM = Grid<float>();
    const double sideM = size.terrainCells * size.terrainCellM;
    ctx.log("validate: ecomod afforestation of " + fixed(sideM, 0) + " m x " + fixed(sideM, 0) + " m, " +
            std::to_string(size.years) + " years");
    const Run aff = simulate(std::move(empty), st.ecomod, seed, size.years, "afforestation", ctx);
    const auto& ts = aff.timeseries;

    std::vector<int> pioneers, late;
    std::string pioneerNames, lateNames;
    for (const Species& s : biome.species) {
        if (s.maxAgeYears <= st.pioneerMaxAgeYears) {
            pioneers.push_back(s.id);
            pioneerNames += (pioneerNames.empty() ? "" : ", ") + s.name;
        }
        if (s.maxAgeYears >= st.lateMinAgeYears) {
            late.push_back(s.id);
            lateNames += (lateNames.empty() ? "" : ", ") + s.name;
        }
    }
    // Exponential start: from the first year with trees to the first year the total reaches half
    // its maximum, the count's yearly gain over the second half of that window against the first
    // half (an exponential rise accelerates, a linear one does not); the exponential rate, from
    // log(total) against year, is reported beside it.
    double peakTotal = 0;
    for (const auto& y : ts) peakTotal = std::max(peakTotal, total(y));
    std::vector<double> wx, wn, wlog;
    int halfYear = -1;
    for (const auto& y : ts) {
        const double n = total(y);
        if (n > 0) {
            wx.push_back(y.year);
            wn.push_back(n);
            wlog.push_back(std::log(n));
        }
        if (n >= 0.5 * peakTotal) {
            halfYear = y.year;
            break;
        }
    }
    double acceleration = kNaN, rate = kNaN, firstGain = kNaN, secondGain = kNaN;
    std::string expNote;
    try {
        const GrowthAcceleration g = growthAcceleration(wx, wn);
        acceleration = g.ratio;
        firstGain = g.firstSlope;
        secondGain = g.secondSlope;
        rate = fitLine(wx, wlog).slope;
    } catch (const ValidationError& e) {
        expNote = e.what();
    }
    // Pioneers: final count over their peak; late species: share at the end minus share at the
    // pioneers' peak.
    double pioneerPeak = 0;
    int pioneerPeakYear = 0;
    for (const auto& y : ts)
        if (groupCount(y, pioneers) > pioneerPeak) {
            pioneerPeak = groupCount(y, pioneers);
            pioneerPeakYear = y.year;
        }
    const sim::YearRecord& last = ts.back();
    const double retreat = pioneerPeak > 0 ? groupCount(last, pioneers) / pioneerPeak : kNaN;
    const sim::YearRecord& atPeak = ts[static_cast<std::size_t>(pioneerPeakYear)];
    auto share = [&](const sim::YearRecord& y) { return total(y) > 0 ? groupCount(y, late) / total(y) : 0.0; };
    const double gain = share(last) - share(atPeak);
    // Stabilisation: (max - min) / mean of the total over the last stable_fraction of the years.
    const int firstStable = static_cast<int>(std::floor(size.years * (1.0 - st.stableFraction)));
    double lo = 1e300, hi = 0, sum = 0, k = 0;
    for (const auto& y : ts)
        if (y.year >= firstStable) {
            lo = std::min(lo, total(y));
            hi = std::max(hi, total(y));
            sum += total(y);
            ++k;
        }
    const double swing = sum > 0 ? (hi - lo) / (sum / k) : kNaN;

    r.checks.push_back(makeCheck(sc, "exponential_start",
                                 "from the first trees to the year the total reaches half its maximum, the total's yearly "
                                 "gain over the second half of those years over its gain over the first half (least-squares "
                                 "slopes; an exponential rise gives e^(rate x years / 2), a linear one 1; the paper: the "
                                 "number of trees increases exponentially)",
                                 acceleration, expNote));
    r.checks.push_back(makeCheck(sc, ctx.mode(), "pioneer_retreat",
                                 "pioneers' (max age <= " + num(st.pioneerMaxAgeYears) +
                                     " years) count in the last year over their peak count (the paper: shrubs propagate "
                                     "fastest, then retreat before the stronger trees)",
                                 retreat, pioneerPeak > 0 ? "" : "no pioneer ever established"));
    r.checks.push_back(makeCheck(sc, "late_share_gain",
                                 "share of the late species (max age >= " + num(st.lateMinAgeYears) +
                                     " years) among all trees in the last year minus their share in the pioneers' peak year",
                                 gain));
    r.checks.push_back(makeCheck(sc, "stabilisation",
                                 "(max - min) / mean of the total count over the last " + fixed(100 * st.stableFraction, 0) +
                                     " % of the years (the paper: populations fairly stabilised once the terrain is saturated)",
                                 swing));

    const std::string csv = sc.name + "_afforestation.csv", png = sc.name + "_afforestation.png";
    writeCountsCsv(ctx.file(csv), biome, {{"ecomod", &ts}});
    sim::plotSpeciesCountsPng(ctx.file(png), ts, biome,
                              "EcoMod afforestation of empty ground, " + fixed(sideM, 0) + " m x " + fixed(sideM, 0) +
                                  " m: trees per species per year");
    r.figures.push_back({png, "Trees per species per year of the EcoMod afforestation (as the paper's Fig. 8, without its catastrophes)."});
    r.details.push_back("- Afforestation: the procedural terrain of " + std::to_string(size.terrainCells) + " x " +
                        std::to_string(size.terrainCells) + " cells of " + num(size.terrainCellM) + " m (" + fixed(sideM, 0) +
                        " m square; its sun, moisture and wind maps), empty at year 0, " + std::to_string(size.years) +
                        " years of EcoMod with the biome's species and their default EcoMod parameters (docs/ecomod.md), in " +
                        fixed(aff.seconds, 1) + " s (" + num(aff.plantMonths / 12.0 / std::max(1e-9, aff.seconds) / 1e6, 3) +
                        "M tree-years/s). Counts in `" + csv + "`.");
    r.details.push_back("- Total trees: peak " + num(peakTotal, 6) + ", last year " + num(total(last), 6) +
                        "; up to year " + std::to_string(halfYear) + " (half the peak) the total gains " + num(firstGain, 3) +
                        " trees a year over the first half of those years and " + num(secondGain, 3) +
                        " over the second; a log-linear fit gives " + num(rate, 3) + " per year (doubling every " +
                        num(std::log(2.0) / rate, 3) + " years). Pioneers (" + pioneerNames +
                        ") peak at " + num(pioneerPeak, 6) + " in year " + std::to_string(pioneerPeakYear) + " and end at " +
                        num(groupCount(last, pioneers), 6) + "; late species (" + lateNames + ") hold " +
                        fixed(100 * share(atPeak), 1) + " % then and " + fixed(100 * share(last), 1) + " % at the end.");
    {
        std::string table = "\n| year |";
        std::string rule = "|---|";
        for (const Species& s : biome.species) {
            table += " " + s.name + " |";
            rule += "---|";
        }
        table += " total |\n" + rule + "---|\n";
        const int step = std::max(1, size.years / 10);
        for (const auto& y : ts)
            if (y.year % step == 0 || y.year == size.years) {
                table += "| " + std::to_string(y.year) + " |";
                for (auto c : y.count) table += " " + std::to_string(c) + " |";
                table += " " + num(total(y), 8) + " |\n";
            }
        r.details.push_back(table);
    }

    // 2. The two models on the same small forest plot (the terrain's canopy kept).
    sim::SimInputs plot = std::move(terrain);
    const Grid<float>& g = plot.abiotics.slopeDeg;
    const double cx = g.originX() + 0.5 * g.extentX(), cy = g.originY() + 0.5 * g.extentY(), h = 0.5 * size.comparisonPlotM;
    plot.area = sim::SimArea{cx - h, cy - h, cx + h, cy + h};
    ctx.log("validate: ecomod vs monthly on a " + fixed(size.comparisonPlotM, 0) + " m plot, " +
            std::to_string(size.comparisonYears) + " years");
    sim::SimParams monthlyParams = st.ecomod;
    monthlyParams.kind = sim::ModelKind::Monthly;
    const Run monthly = simulate(plot, monthlyParams, seed, size.comparisonYears, "monthly", ctx);
    const Run eco = simulate(std::move(plot), st.ecomod, seed, size.comparisonYears, "ecomod", ctx);
    const std::string ccsv = sc.name + "_comparison.csv", cpng = sc.name + "_comparison.png";
    writeCountsCsv(ctx.file(ccsv), biome, {{"monthly", &monthly.timeseries}, {"ecomod", &eco.timeseries}});
    plotComparison(ctx.file(cpng), biome, monthly, eco, size.comparisonPlotM);
    r.figures.push_back({cpng, "Plants per species per year of both models on the same plot, side by side."});
    auto perStep = [](const Run& run, double months) {
        return run.plantMonths > 0 ? run.seconds / (static_cast<double>(run.plantMonths) / months) : kNaN;
    };
    r.details.push_back("- Comparison on the " + fixed(size.comparisonPlotM, 0) + " m plot at the terrain's centre, " +
                        std::to_string(size.comparisonYears) + " years (counts in `" + ccsv + "`): monthly model " +
                        num(total(monthly.timeseries.back()), 6) + " plants at the end (" + fixed(monthly.seconds, 1) +
                        " s, " + num(1e6 * perStep(monthly, 1), 3) + " µs per plant-month), EcoMod " +
                        num(total(eco.timeseries.back()), 6) + " trees (" + fixed(eco.seconds, 2) + " s, " +
                        num(1e6 * perStep(eco, 12), 3) + " µs per tree-year). Not a check: the models differ by design "
                        "(docs/ecomod.md, \"The two models side by side\").");
}

}  // namespace

std::unique_ptr<Scenario> createEcoMod(const ScenarioParse& in) { return std::make_unique<EcoModScenario>(in); }
std::vector<ScenarioKeyDoc> ecomodKeys() {
    return joinKeyDocs({scenarioKeyDocs("[groups]", groupFields()), scenarioKeyDocs("[quick], [full]", ecomodSizeFields())});
}

}  // namespace eco::validate
