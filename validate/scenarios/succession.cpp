// Kind "succession" (paper §7.2, Figs. 14-15), forest scene: a late, shade-tolerant species
// gains on the fast-growing early species where the site suits it, and the early species
// peak and decline. docs/validation.md defines the measures.
#include "scenario_context.h"

#include <algorithm>
#include <cmath>
#include <numeric>

#include "scenario_keys.h"
#include "strict_toml.h"

namespace eco::validate {

namespace {

struct SuccessionSettings {
    std::string lateSpecies;                ///< e.g. California Laurel
    std::vector<std::string> earlySpecies;  ///< e.g. Western Swordfern (the fast-growing competitors)
    int earlyYear = 25;                     ///< the late species' starting share is taken here
    int finalWindowYears = 25;
    /// "Where suited": cells where the late species' Eq. 1 fitness (vigour / alpha) is at least this.
    double suitedMinFitness = 0.9;
};

/// [succession]'s numeric keys (the species are read by hand).
const std::vector<ParamDesc<SuccessionSettings>>& successionFields() {
    using P = SuccessionSettings;
    using K = ParamDesc<P>::Kind;
    static const std::vector<ParamDesc<P>> fields = {
        {"early_year", "the late species' starting share is taken at this year", "years", K::Integer, nullptr, &P::earlyYear,
         ParamRange::closed(0, 100000)},
        {"final_window_years", "the final share is the mean over this many last censuses", "years", K::Integer, nullptr,
         &P::finalWindowYears, ParamRange::closed(1, 100000)},
        {"suited_min_fitness", "cells where the late species' Eq. 1 fitness (vigour / alpha) is at least this are suited", "",
         K::Real, &P::suitedMinFitness, nullptr, ParamRange::closed(-1.0, 1.0)},
    };
    return fields;
}

/// "Where it is suited": cells in which the late species' Eq. 1 fitness min(f_t, f_m, f_e,
/// f_g) (its vigour without the alpha scale) on the annual-mean site conditions is at least
/// minFitness, among the cells its seeds can reach (simulation grid).
struct SuitedCells {
    Grid<std::uint8_t> mask;
    double areaM2 = 0, seededAreaM2 = 0;
};
SuitedCells suitedCells(const ForestRun& run, const Biome& biome, int late, double minFitness) {
    const Grid<float>& g = run.site[Factor::Sun];
    const Species& lateSp = biome.species[static_cast<std::size_t>(late)];
    SuitedCells out;
    out.mask = Grid<std::uint8_t>::like(g, 0);
    for (int iy = 0; iy < g.height(); ++iy)
        for (int ix = 0; ix < g.width(); ++ix) {
            const std::int32_t package = run.seedPackages(ix, iy);
            bool reach = false;
            for (int b : lateSp.subBiomes) reach = reach || (package & (1 << (b - 1))) != 0;
            if (!reach) continue;
            out.seededAreaM2 += g.cellSizeM() * g.cellSizeM();
            const double fitness = biome.vigourOf(late, run.site.at(ix, iy)) / lateSp.alpha;
            if (fitness >= minFitness) {
                out.mask(ix, iy) = 1;
                out.areaM2 += g.cellSizeM() * g.cellSizeM();
            }
        }
    return out;
}

/// Crown cover (m^2) per species in the suited cells, mean over the snapshots (NaN if none).
std::vector<double> suitedCover(const std::vector<const Snapshot*>& snaps, const Grid<float>& g,
                                const Grid<std::uint8_t>& suited, std::size_t ns) {
    std::vector<double> cover(ns, 0.0);
    for (const Snapshot* snap : snaps)
        for (const LitePlant& p : snap->plants) {
            const int ix = g.cellX(p.x), iy = g.cellY(p.y);
            if (!g.inside(ix, iy) || !suited(ix, iy)) continue;
            cover[static_cast<std::size_t>(p.species)] += kPi * static_cast<double>(p.crownRadiusM) * p.crownRadiusM;
        }
    for (double& c : cover) c = snaps.empty() ? kNaN : c / static_cast<double>(snaps.size());
    return cover;
}

/// The early species' count peaks: the largest final-window mean / peak over the early species
/// (NaN with a note when one never occurred); a detail line each.
struct EarlyPeaks {
    double decline = -1;
    std::string note;
};
EarlyPeaks earlyPeaks(const ForestRun& run, const std::vector<const sim::YearRecord*>& window, int Y,
                      const SuccessionSettings& cfg, const Biome& biome, ScenarioResult& r) {
    EarlyPeaks out;
    double& decline = out.decline;
    std::string& peakNote = out.note;
    for (const std::string& name : cfg.earlySpecies) {
        const int e = biome.speciesIndex(name);
        double peak = 0;
        int peakYear = -1;
        for (const auto& rec : run.timeseries)
            if (rec.count[static_cast<std::size_t>(e)] > peak) {
                peak = rec.count[static_cast<std::size_t>(e)];
                peakYear = rec.year;
            }
        if (peakYear < 0) {
            decline = kNaN;
            peakNote = name + " never occurred";
            break;
        }
        std::vector<double> fin;
        for (const auto* rec : window) fin.push_back(rec->count[static_cast<std::size_t>(e)]);
        const double d = mean(fin) / peak;
        decline = std::max(decline, d);
        r.details.push_back("- " + name + ": peak of " + num(peak, 6) + " plants in year " + std::to_string(peakYear) +
                            ", mean of the last " + std::to_string(cfg.finalWindowYears) + " years " + num(mean(fin), 6) +
                            " (" + fixed(100 * d, 0) + " % of the peak).");
    }
    return out;
}

/// The early species' crown-cover peak against the late species' rise, in the suited cells:
/// the latest year at which an early species' cover peaks, divided by the first year at which
/// the late species' cover reaches half its mean over the final window (NaN with a note when
/// either never happens). Below 1 the early species peak before the late species has risen.
struct PeakBeforeRise {
    double ratio = kNaN;
    std::string note;
};
PeakBeforeRise peakBeforeRise(const ForestRun& run, int Y, const SuccessionSettings& cfg, const Biome& biome,
                              const Grid<float>& g, const Grid<std::uint8_t>& suited, double lateCoverEnd,
                              ScenarioResult& r) {
    PeakBeforeRise out;
    const std::size_t ns = biome.species.size();
    const auto late = static_cast<std::size_t>(biome.speciesIndex(cfg.lateSpecies));
    int peakYear = -1, riseYear = -1;
    std::string peakName;
    std::vector<double> peak(cfg.earlySpecies.size(), 0.0);
    std::vector<int> peakAt(cfg.earlySpecies.size(), -1);
    for (const Snapshot* snap : run.window(1, Y)) {
        const std::vector<double> cover = suitedCover({snap}, g, suited, ns);
        for (std::size_t k = 0; k < cfg.earlySpecies.size(); ++k) {
            const double c = cover[static_cast<std::size_t>(biome.speciesIndex(cfg.earlySpecies[k]))];
            if (c > peak[k]) {
                peak[k] = c;
                peakAt[k] = snap->year;
            }
        }
        if (riseYear < 0 && lateCoverEnd > 0 && cover[late] >= 0.5 * lateCoverEnd) riseYear = snap->year;
    }
    for (std::size_t k = 0; k < cfg.earlySpecies.size(); ++k)
        if (peakAt[k] > peakYear) {
            peakYear = peakAt[k];
            peakName = cfg.earlySpecies[k];
        }
    if (peakYear < 0) out.note = "no early species ever covers the suited cells";
    else if (riseYear <= 0) out.note = cfg.lateSpecies + " never covers half its final cover in the suited cells";
    else out.ratio = static_cast<double>(peakYear) / riseYear;
    r.details.push_back("- Crown cover in the suited cells over time: " + (peakName.empty() ? std::string("no early species") : peakName) +
                        " peaks in year " + std::to_string(peakYear) + "; " + cfg.lateSpecies +
                        " first reaches half its final cover (" + fixed(0.5 * lateCoverEnd, 1) + " m^2) in year " +
                        (riseYear > 0 ? std::to_string(riseYear) : std::string("never")) + ".");
    return out;
}

/// Plants per species every 25 years up to Y (species that ever occurred), a Markdown table.
std::string countsTable(const ForestRun& run, const Biome& biome, int Y) {
    const std::size_t ns = biome.species.size();
    std::string head = "\n| species |", sep = "|---|", body;
    std::vector<int> years;
    for (int y = 0; y <= Y; y += 25) years.push_back(y);
    if (years.back() != Y) years.push_back(Y);
    for (int y : years) {
        head += " " + std::to_string(y) + " |";
        sep += "---|";
    }
    for (std::size_t s = 0; s < ns; ++s) {
        bool any = false;
        for (const auto& rec : run.timeseries) any = any || rec.count[s] > 0;
        if (!any) continue;
        body += "| " + biome.species[s].name + " |";
        for (int y : years) body += " " + std::to_string(run.timeseries[static_cast<std::size_t>(y)].count[s]) + " |";
        body += "\n";
    }
    return head + "\n" + sep + "\n" + body;
}

class Succession final : public Scenario {
public:
    explicit Succession(const ScenarioParse& in);
    std::vector<std::string> checkIds() const override {
        return {"late_share_gain", "late_cover_overtakes", "late_dominance", "early_peak_time", "early_decline"};
    }
    std::vector<std::pair<std::string, std::string>> speciesNamed() const override {
        std::vector<std::pair<std::string, std::string>> out{{"[succession] late_species", settings_.lateSpecies}};
        for (const auto& s : settings_.earlySpecies) out.emplace_back("[succession] early_species", s);
        return out;
    }
    int windowYears() const override { return settings_.finalWindowYears; }
    void run(const ScenarioConfig& sc, ScenarioContext& ctx, ScenarioResult& r) const override;

private:
    SuccessionSettings settings_;
};

Succession::Succession(const ScenarioParse& in) {
    SuccessionSettings& st = settings_;
    StrictTable s(in.top.table("succession"), in.path, "[succession]");
    st.lateSpecies = s.string("late_species");
    st.earlySpecies = nonEmptyStrings(s, "early_species");
    readScenarioParams(s, st, successionFields());
    s.finish();
}

void Succession::run(const ScenarioConfig& sc, ScenarioContext& ctx, ScenarioResult& r) const {
    const Biome& biome = ctx.biome();
    const SuccessionSettings& cfg = settings_;
    const ForestRun& run = ctx.forest(sc.scenePath, sim::CompetitionMode::Resources, 0);
    const int Y = ctx.measureYear(sc);
    ctx.describeRun(run, Y, r, ctx.scene(sc));
    const int late = biome.speciesIndex(cfg.lateSpecies);
    const int early = std::min(cfg.earlyYear, Y);
    const auto window = censusWindow(run.timeseries, Y - cfg.finalWindowYears + 1, Y);
    const std::size_t ns = biome.species.size();
    std::vector<double> finalShare(ns, 0.0);
    for (std::size_t s = 0; s < ns; ++s) {
        std::vector<double> v;
        for (const auto* rec : window) v.push_back(shareOf(*rec, static_cast<int>(s)));
        finalShare[s] = mean(v);
    }
    const double earlyShare = shareOf(run.timeseries[static_cast<std::size_t>(early)], late);
    const double gain = earlyShare > 0 ? finalShare[static_cast<std::size_t>(late)] / earlyShare : kNaN;
    r.checks.push_back(makeCheck(sc, "late_share_gain",
                                 cfg.lateSpecies + ": share of plants in the last " + std::to_string(cfg.finalWindowYears) +
                                     " years / share at year " + std::to_string(early),
                                 gain, earlyShare > 0 ? "" : cfg.lateSpecies + " absent at year " + std::to_string(early)));
    const Grid<float>& g = run.site[Factor::Sun];
    const SuitedCells cells = suitedCells(run, biome, late, cfg.suitedMinFitness);
    const Grid<std::uint8_t>& suited = cells.mask;
    const double suitedAreaM2 = cells.areaM2, seededAreaM2 = cells.seededAreaM2;
    std::vector<double> suitedCount(ns, 0.0);
    double suitedTotal = 0;
    for (const Snapshot* snap : run.window(Y - cfg.finalWindowYears + 1, Y))
        for (const LitePlant& p : snap->plants) {
            const int ix = g.cellX(p.x), iy = g.cellY(p.y);
            if (!g.inside(ix, iy) || !suited(ix, iy)) continue;
            suitedCount[static_cast<std::size_t>(p.species)] += 1;
            suitedTotal += 1;
        }
    double otherMax = 0;
    std::string otherName = "none";
    for (std::size_t s = 0; s < ns; ++s)
        if (static_cast<int>(s) != late && suitedCount[s] > otherMax) {
            otherMax = suitedCount[s];
            otherName = biome.species[s].name;
        }
    // Dominance as vegetation science measures it: crown cover (the discs of Fig. 14, in
    // which "Western Swordferns are overtaken by California Laurel"), of the late species
    // against each fast-growing early species, in the suited cells; mean over snapshots.
    const std::vector<double> coverEnd = suitedCover(run.window(Y - cfg.finalWindowYears + 1, Y), g, suited, ns);
    const std::vector<double> coverEarly = suitedCover(run.window(early, early), g, suited, ns);
    double earlyCoverMax = 0, earlyCoverAtStart = 0;
    std::string earlyCoverName = cfg.earlySpecies.front();
    for (const std::string& name : cfg.earlySpecies) {
        const auto e = static_cast<std::size_t>(biome.speciesIndex(name));
        if (coverEnd[e] > earlyCoverMax) {
            earlyCoverMax = coverEnd[e];
            earlyCoverName = name;
        }
        earlyCoverAtStart = std::max(earlyCoverAtStart, coverEarly[e]);
    }
    const double lateCoverEnd = coverEnd[static_cast<std::size_t>(late)];
    std::string coverNote;
    if (suitedAreaM2 <= 0) coverNote = "no cell suits " + cfg.lateSpecies;
    else if (!(lateCoverEnd > 0)) coverNote = cfg.lateSpecies + " has no cover in the suited cells";
    r.checks.push_back(makeCheck(sc, "late_cover_overtakes",
                                 "where the site suits " + cfg.lateSpecies + ": its crown cover / that of the early species "
                                 "with the most (" + earlyCoverName + "), mean of the snapshots of the last " +
                                 std::to_string(cfg.finalWindowYears) + " years",
                                 coverNote.empty() ? (earlyCoverMax > 0 ? lateCoverEnd / earlyCoverMax : 1e9) : kNaN, coverNote));
    {
        std::vector<std::size_t> order(ns);
        std::iota(order.begin(), order.end(), std::size_t{0});
        std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) { return coverEnd[a] > coverEnd[b]; });
        std::string table = "\n| species (suited cells) | crown cover, year " + std::to_string(early) +
                            " (m^2) | crown cover, last " + std::to_string(cfg.finalWindowYears) +
                            " years (m^2, mean of snapshots) | plants, last " + std::to_string(cfg.finalWindowYears) +
                            " years (sum over snapshots) |\n|---|---|---|---|\n";
        for (std::size_t s : order)
            if (coverEnd[s] > 0 || coverEarly[s] > 0)
                table += "| " + biome.species[s].name + " | " + fixed(coverEarly[s], 1) + " | " + fixed(coverEnd[s], 1) +
                         " | " + num(suitedCount[s], 7) + " |\n";
        r.details.push_back("- Crown cover in the suited cells: " + cfg.lateSpecies + " " + fixed(coverEarly[static_cast<std::size_t>(late)], 1) +
                            " m^2 at year " + std::to_string(early) + " against " + fixed(earlyCoverAtStart, 1) +
                            " m^2 of the early species; " + fixed(lateCoverEnd, 1) + " m^2 against " + fixed(earlyCoverMax, 1) +
                            " m^2 at the end. Every species by cover:");
        r.details.push_back(table);
    }
    std::string domNote;
    if (suitedAreaM2 <= 0) domNote = "no cell suits " + cfg.lateSpecies + " (fitness >= " + num(cfg.suitedMinFitness) + ")";
    else if (suitedTotal <= 0) domNote = "no plants in the suited cells";
    r.checks.push_back(makeCheck(sc, "late_dominance",
                                 "where the site suits " + cfg.lateSpecies + ": its plants / the plants of the most "
                                 "numerous other species (" + otherName + "), last " + std::to_string(cfg.finalWindowYears) +
                                 " years",
                                 domNote.empty() && otherMax > 0 ? suitedCount[static_cast<std::size_t>(late)] / otherMax
                                                                 : (domNote.empty() && suitedCount[static_cast<std::size_t>(late)] > 0 ? 1e9 : kNaN),
                                 domNote));
    r.details.push_back("- Where suited: the cells its seeds reach in which " + cfg.lateSpecies + "'s fitness min(f_t, f_m, "
                        "f_e, f_g) of Eq. 1 (vigour without the alpha scale) on the annual means of site sun after canopy "
                        "shade, moisture, temperature and slope is at least " + num(cfg.suitedMinFitness) +
                        " (undergrowth shade and water sharing not included): " +
                        fixed(suitedAreaM2, 0) + " m^2 of " + fixed(seededAreaM2, 0) + " m^2 seeded. Plants there (snapshots of the last " +
                        std::to_string(cfg.finalWindowYears) + " years): " + num(suitedTotal, 7) + ", of which " +
                        cfg.lateSpecies + " " + (suitedTotal > 0 ? fixed(100 * suitedCount[static_cast<std::size_t>(late)] / suitedTotal, 1) : std::string("n/a")) +
                        " %, " + otherName + " " + (suitedTotal > 0 ? fixed(100 * otherMax / suitedTotal, 1) : std::string("n/a")) + " %.");
    {
        double wholeOther = 0;
        std::string wholeName = "none";
        for (std::size_t s = 0; s < ns; ++s)
            if (static_cast<int>(s) != late && finalShare[s] > wholeOther) {
                wholeOther = finalShare[s];
                wholeName = biome.species[s].name;
            }
        r.details.push_back("- Whole plot, last " + std::to_string(cfg.finalWindowYears) + " years: " + cfg.lateSpecies + " " +
                            fixed(100 * finalShare[static_cast<std::size_t>(late)], 1) + " % of the plants, the most numerous "
                            "other species " + wholeName + " " + fixed(100 * wholeOther, 1) + " %.");
    }
    const EarlyPeaks peaks = earlyPeaks(run, window, Y, cfg, biome, r);
    const double decline = peaks.decline;
    const std::string& peakNote = peaks.note;
    std::string earlyNames;
    for (const auto& n : cfg.earlySpecies) earlyNames += (earlyNames.empty() ? "" : ", ") + n;
    const PeakBeforeRise order = peakBeforeRise(run, Y, cfg, biome, g, suited, lateCoverEnd, r);
    r.checks.push_back(makeCheck(sc, "early_peak_time",
                                 "where the site suits " + cfg.lateSpecies + ": year in which the early species' crown cover "
                                 "peaks (latest of " + earlyNames + ") / year in which " + cfg.lateSpecies +
                                 "'s cover first reaches half its final level",
                                 order.ratio, order.note));
    r.checks.push_back(makeCheck(sc, "early_decline",
                                 "early species: mean count of the last " + std::to_string(cfg.finalWindowYears) +
                                     " years / peak count (largest of them)",
                                 decline, peakNote));
    r.details.push_back("- " + cfg.lateSpecies + ": " + fixed(100 * earlyShare, 1) + " % of the plants at year " +
                        std::to_string(early) + ", " + fixed(100 * finalShare[static_cast<std::size_t>(late)], 1) +
                        " % over the last " + std::to_string(cfg.finalWindowYears) + " years.");
    r.details.push_back(countsTable(run, biome, Y));
    ctx.forestFigures(run, Y, sc.name, "Undergrowth under Douglas-Fir and Redwood", r);
}

}  // namespace

std::unique_ptr<Scenario> createSuccession(const ScenarioParse& in) { return std::make_unique<Succession>(in); }
std::vector<ScenarioKeyDoc> successionKeys() { return scenarioKeyDocs("[succession]", successionFields()); }

}  // namespace eco::validate
