// eco analyse, eco inspect, eco pcf: parsing, progress, summaries and plots only; the
// statistics are in analysis/ and core/point_pattern, the database in core/biome_db.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <limits>
#include <memory>
#include <numeric>
#include <sstream>
#include <string>
#include <vector>

#include "analysis.h"
#include "atomic_file.h"
#include "biome_db.h"
#include "cli_common.h"
#include "error.h"
#include "image_out.h"
#include "point_pattern.h"
#include "sim_input.h"
#include "text_format.h"

namespace eco::cli {

namespace {

std::string num(double v, int precision = 4) { return formatNumber(v, precision); }

std::string fixed(double v, int decimals) {
    char buf[64];
    std::snprintf(buf, sizeof buf, "%.*f", decimals, v);
    return buf;
}

// ---------------------------------------------------------------------------------------
// A small line / bar plot on a Canvas: axes, ticks, labels.

struct Series {
    std::string name;
    std::vector<double> x, y;
    Rgb colour;
    bool bars = false;  ///< draw as bars between consecutive x (x has y.size() + 1 edges)
};

/// Tick positions: 1, 2 or 5 times a power of ten, about `target` of them.
std::vector<double> niceTicks(double lo, double hi, int target = 6) {
    std::vector<double> t;
    if (!(hi > lo)) return {lo};
    const double raw = (hi - lo) / target;
    const double mag = std::pow(10.0, std::floor(std::log10(raw)));
    double step = mag;
    for (double m : {1.0, 2.0, 5.0, 10.0})
        if (raw <= m * mag) {
            step = m * mag;
            break;
        }
    for (double v = std::ceil(lo / step - 1e-9) * step; v <= hi + 1e-9 * step; v += step) t.push_back(std::abs(v) < 1e-12 * step ? 0.0 : v);
    return t;
}

std::string tickLabel(double v) {
    std::ostringstream os;
    os << v;
    return os.str();
}

/// Plot area of w x h pixels with margins for tick labels; returns the whole canvas.
Canvas plot(const std::vector<Series>& series, double xmin, double xmax, double ymin, double ymax,
            const std::string& xlabel, const std::string& ylabel, double referenceY = std::numeric_limits<double>::quiet_NaN()) {
    const int w = 640, h = 400, left = 70, right = 20, top = 16, bottom = 56;
    Canvas c(left + w + right, top + h + bottom);
    const Rgb black{0.f, 0.f, 0.f}, grey{0.82f, 0.82f, 0.82f};
    auto px = [&](double x) { return left + (x - xmin) / (xmax - xmin) * w; };
    auto py = [&](double y) { return top + h - (y - ymin) / (ymax - ymin) * h; };
    for (double t : niceTicks(xmin, xmax)) {
        c.drawLine(px(t), top, px(t), top + h, grey);
        c.drawLine(px(t), top + h, px(t), top + h + 5, black);
        c.text(static_cast<int>(px(t)) - 4 * static_cast<int>(tickLabel(t).size()), top + h + 20, tickLabel(t), 13, black);
    }
    for (double t : niceTicks(ymin, ymax)) {
        c.drawLine(left, py(t), left + w, py(t), grey);
        c.drawLine(left - 5, py(t), left, py(t), black);
        c.text(left - 10 - 8 * static_cast<int>(tickLabel(t).size()), static_cast<int>(py(t)) + 5, tickLabel(t), 13, black);
    }
    if (std::isfinite(referenceY) && referenceY > ymin && referenceY < ymax)
        for (int x = left; x < left + w; x += 8) c.drawLine(x, py(referenceY), std::min(x + 4, left + w), py(referenceY), {0.4f, 0.4f, 0.4f});
    auto clampY = [&](double y) { return std::clamp(y, ymin, ymax); };
    for (const Series& s : series) {
        if (s.bars) {
            for (std::size_t i = 0; i + 1 < s.x.size() && i < s.y.size(); ++i) {
                if (!(s.y[i] > ymin)) continue;
                c.fillRect(static_cast<int>(px(s.x[i])) + 1, static_cast<int>(py(clampY(s.y[i]))), static_cast<int>(px(s.x[i + 1])) - 1,
                           static_cast<int>(py(ymin)), s.colour);
            }
            continue;
        }
        for (std::size_t i = 0; i + 1 < s.x.size(); ++i)
            for (int o = 0; o < 2; ++o)  // 2 px wide
                c.drawLine(px(s.x[i]), py(clampY(s.y[i])) + o, px(s.x[i + 1]), py(clampY(s.y[i + 1])) + o, s.colour);
    }
    c.drawLine(left, top + h, left + w, top + h, black);
    c.drawLine(left, top, left, top + h, black);
    c.text(left + w / 2 - 4 * static_cast<int>(xlabel.size()), top + h + 44, xlabel, 14, black);
    c.text(4, top + 12, ylabel, 14, black);
    return c;
}

/// Upper y limit for a set of series: the largest value, with headroom, at least `floor`.
double yTop(const std::vector<Series>& series, double floor) {
    double m = floor;
    for (const Series& s : series)
        for (double v : s.y)
            if (std::isfinite(v)) m = std::max(m, v);
    return m * 1.08;
}

// ---------------------------------------------------------------------------------------
// eco pcf

struct PcfArgs {
    std::string points;
    std::string window;
    double rMaxM = 0;
    int bins = 40;
    std::string out;
};

std::string replaceExtension(const std::string& path, const std::string& ext) {
    std::filesystem::path p(path);
    p.replace_extension(ext);
    return p.string();
}

void runPcf(const PcfArgs& args) {
    const RectWindow window = parseWindow(args.window, "--window");
    const PointPattern pattern = readPointPatternCsv(args.points, &window);
    PcfOptions opt;
    const double halfShorter = 0.5 * std::min(window.widthM(), window.heightM());
    opt.bins = DistanceBins{args.rMaxM > 0 ? args.rMaxM : 0.5 * halfShorter, args.bins};
    opt.isotropic = true;
    const PairSums sums = countPairs(pattern, window, opt);

    const std::string csv = args.out.empty()
                                ? replaceExtension(args.points, "") + "_pcf.csv"
                                : args.out;
    const std::string png = replaceExtension(csv, ".png");
    const std::filesystem::path parent = std::filesystem::path(csv).parent_path();
    if (!parent.empty()) ensureDirectory(parent.string());
    writePcfCsv(csv, sums, pattern.typeNames);

    // Plot: the type pairs (at most 12) and the unmarked pattern.
    std::vector<Series> series;
    std::vector<std::pair<std::string, Rgb>> legend;
    std::vector<double> mids;
    for (int k = 0; k < opt.bins.count; ++k) mids.push_back(opt.bins.midM(k));
    auto add = [&](const PairSums& s, int i, int j, const std::string& name, int colour) {
        Series se{name, mids, {}, categoryColour(colour)};
        for (int k = 0; k < opt.bins.count; ++k) se.y.push_back(s.gTranslate(i, j, k));
        legend.emplace_back(name, se.colour);
        series.push_back(std::move(se));
    };
    int colour = 0;
    const int nt = sums.nTypes;
    if (nt == 1) {
        add(sums, 0, 0, "g(r), " + pattern.typeNames[0], colour++);
    } else {
        // Translation-corrected g_ij equals g_ji: each unordered pair is drawn once.
        for (int i = 0; i < nt && colour < 12; ++i)
            for (int j = i; j < nt && colour < 12; ++j)
                add(sums, i, j,
                    pattern.typeNames[static_cast<std::size_t>(i)] + (i == j ? " - " : " <-> ") +
                        pattern.typeNames[static_cast<std::size_t>(j)],
                    colour++);
        add(sums.merged(), 0, 0, "all points", 7);
    }
    legend.emplace_back("g = 1 (Poisson)", Rgb{0.4f, 0.4f, 0.4f});
    const Canvas picture = plot(series, 0.0, opt.bins.rMaxM, 0.0, yTop(series, 1.5), "r (m)", "g(r)", 1.0);
    withLegend(picture,
               "Pair correlation, " + std::filesystem::path(args.points).filename().string() + " (" +
                   std::to_string(pattern.size()) + " points, translation correction)",
               legend)
        .writePng(png);

    std::cout << "points: " << pattern.size() << " in window " << num(window.x0) << "," << num(window.y0) << ","
              << num(window.x1) << "," << num(window.y1) << " (" << num(window.areaM2()) << " m2), types:";
    for (std::size_t t = 0; t < pattern.typeNames.size(); ++t)
        std::cout << (t ? ", " : " ") << pattern.typeNames[t] << " (" << sums.typeCount[t] << ")";
    const ClarkEvans ce = clarkEvans(pattern.x, pattern.y, window);
    std::cout << "\nClark-Evans index (Donnelly edge correction): " << num(ce.index) << " (mean nearest neighbour "
              << num(ce.meanNearestM) << " m, " << num(ce.expectedM)
              << " m expected under CSR; < 1 clustered, > 1 regular)";
    std::cout << "\nwrote pair correlation: " << csv << " (" << opt.bins.count << " bins of " << num(opt.bins.widthM())
              << " m to " << num(opt.bins.rMaxM) << " m)\nwrote plot: " << png << "\n";
}

// ---------------------------------------------------------------------------------------
// eco analyse

struct AnalyseArgs {
    std::vector<std::string> simulations;
    std::vector<std::string> abiotics;
    std::string out;
    int kMax = 0;
    int year = -1;
    long long seed = -1;
    double rMaxM = 0;
    int bins = 0;
    double seedingRadiusFactor = 0;
    bool speciesSubBiomes = false;
};

void runAnalyse(const AnalyseArgs& args) {
    if (!args.abiotics.empty() && args.abiotics.size() != 1 && args.abiotics.size() != args.simulations.size())
        throw ValidationError("--abiotics: give one file for all simulations or one per simulation (" +
                              std::to_string(args.simulations.size()) + "), got " + std::to_string(args.abiotics.size()));
    std::vector<LoadedSimulation> loaded;
    double simFactor = 0;
    for (std::size_t i = 0; i < args.simulations.size(); ++i) {
        SimulationReadOptions opt;
        opt.year = args.year;
        if (!args.abiotics.empty()) opt.abioticsPath = args.abiotics.size() == 1 ? args.abiotics[0] : args.abiotics[i];
        loaded.push_back(readSimulation(args.simulations[i], opt));
        const auto& l = loaded.back();
        info("simulation " + args.simulations[i] + ": year " + std::to_string(l.input.provenance.year) + ", " +
             std::to_string(l.input.undergrowth.size()) + " undergrowth plants, " + std::to_string(l.input.canopy.size()) +
             " canopy trees, area " + num(l.input.window.widthM()) + " x " + num(l.input.window.heightM()) + " m, abiotics " +
             l.input.provenance.abioticsPath);
        if (l.seedOuterRadiusFactor > 0) {
            if (simFactor > 0 && simFactor != l.seedOuterRadiusFactor)
                info("note: the simulations use different seeding disc factors; using " + num(simFactor));
            if (simFactor == 0) simFactor = l.seedOuterRadiusFactor;
        }
    }
    AnalysisParams params;
    if (args.kMax > 0) params.kMax = args.kMax;
    if (args.seed >= 0) params.seed = static_cast<std::uint64_t>(args.seed);
    if (args.rMaxM > 0) params.pcfBins.rMaxM = args.rMaxM;
    if (args.bins > 0) params.pcfBins.count = args.bins;
    // The combination labels must use the simulation's own seeding disc unless told otherwise.
    params.seedingRadiusFactor = args.seedingRadiusFactor > 0 ? args.seedingRadiusFactor : (simFactor > 0 ? simFactor : params.seedingRadiusFactor);
    if (args.speciesSubBiomes) params.membership = CanopyMembership::SpeciesSubBiomes;

    std::vector<AnalysisInput> inputs;
    for (auto& l : loaded) inputs.push_back(std::move(l.input));
    std::unique_ptr<Progress> bar;
    std::string stage;
    const auto progress = [&](const std::string& s, double fraction) {
        if (s != stage) {
            if (bar) bar->finish();
            bar = std::make_unique<Progress>("analyse " + s, 1000);
            stage = s;
        }
        bar->update(static_cast<long>(fraction * 1000.0 + 0.5));
    };
    const BiomeDatabase db = analyse(inputs, params, progress);
    if (bar) bar->finish();

    const std::filesystem::path parent = std::filesystem::path(args.out).parent_path();
    if (!parent.empty()) ensureDirectory(parent.string());
    writeBiomeDatabase(args.out, db);
    double area = 0, plants = 0;
    for (const auto& r : db.regions) {
        area += r.areaM2;
        plants += r.undergrowthCount;
    }
    std::cout << "wrote biome database: " << args.out << " (" << db.combinations.size() << " sub-biome combinations, "
              << db.regions.size() << " regions, " << fixed(area, 0) << " m2, " << fixed(plants, 0)
              << " undergrowth plants; schema " << kBiomeDbSchemaVersion << ")\n";
}

// ---------------------------------------------------------------------------------------
// eco inspect

struct InspectArgs {
    std::string database;
    std::string pngDir;
    std::string out;
    int maxPairs = 8;
};

std::vector<int> leadingSpecies(const DbRegion& r, std::size_t count) {
    std::vector<int> idx(r.speciesCount.size());
    std::iota(idx.begin(), idx.end(), 0);
    std::stable_sort(idx.begin(), idx.end(), [&](int a, int b) {
        return r.speciesCount[static_cast<std::size_t>(a)] > r.speciesCount[static_cast<std::size_t>(b)];
    });
    std::vector<int> out;
    for (int s : idx)
        if (r.speciesCount[static_cast<std::size_t>(s)] > 0 && out.size() < count) out.push_back(s);
    return out;
}

void writeRegionPlots(const std::string& dir, const BiomeDatabase& db, std::size_t ri, int maxPairs) {
    const DbRegion& r = db.regions[ri];
    char stem[64];
    std::snprintf(stem, sizeof stem, "/region_%04zu", ri);
    const std::string where = db.combinationName(r.combination) + ", cluster " + std::to_string(r.cluster);

    // g(r) of the pairs with the most pairs counted; g_ij = g_ji (translation correction),
    // so each unordered pair once.
    std::vector<const DbPairStats*> pairs;
    for (const auto& p : r.pairs)
        if (p.source <= p.target && std::accumulate(p.pairCount.begin(), p.pairCount.end(), 0.0) > 0) pairs.push_back(&p);
    std::stable_sort(pairs.begin(), pairs.end(), [](const DbPairStats* a, const DbPairStats* b) {
        return std::accumulate(a->pairCount.begin(), a->pairCount.end(), 0.0) >
               std::accumulate(b->pairCount.begin(), b->pairCount.end(), 0.0);
    });
    if (pairs.size() > static_cast<std::size_t>(maxPairs)) pairs.resize(static_cast<std::size_t>(maxPairs));
    std::vector<Series> series;
    std::vector<std::pair<std::string, Rgb>> legend;
    std::vector<double> mids;
    for (int k = 0; k < db.pcfBins.count; ++k) mids.push_back(db.pcfBins.midM(k));
    int colour = 0;
    for (const DbPairStats* p : pairs) {
        const std::string name =
            db.categoryName(p->source) + (p->source == p->target ? " - " : " <-> ") + db.categoryName(p->target);
        series.push_back(Series{name, mids, p->g, categoryColour(colour++)});
        legend.emplace_back(name, series.back().colour);
    }
    legend.emplace_back("g = 1 (Poisson)", Rgb{0.4f, 0.4f, 0.4f});
    withLegend(plot(series, 0.0, db.pcfBins.rMaxM, 0.0, yTop(series, 1.5), "r (m)", "g(r)", 1.0),
               "Region " + std::to_string(ri) + " (" + where + "): pair correlation", legend)
        .writePng(dir + stem + "_pcf.png");

    // Height histograms of the leading species (plants per bin, not renormalised).
    const auto lead = leadingSpecies(r, 6);
    std::vector<Series> bars;
    std::vector<std::pair<std::string, Rgb>> key;
    double hMax = 0.5;
    for (int s : lead) hMax = std::max(hMax, r.height[static_cast<std::size_t>(s)].edges.back());
    for (std::size_t i = 0; i < lead.size(); ++i) {
        const DbHistogram& h = r.height[static_cast<std::size_t>(lead[i])];
        Series se{db.speciesNames[static_cast<std::size_t>(lead[i])], h.edges, h.counts,
                  categoryColour(lead[i]), true};
        key.emplace_back(se.name + " (" + fixed(r.speciesCount[static_cast<std::size_t>(lead[i])], 0) + ")", se.colour);
        bars.push_back(std::move(se));
    }
    // Tallest first so that shorter species' bars stay visible on top.
    std::stable_sort(bars.begin(), bars.end(), [](const Series& a, const Series& b) { return a.x.back() > b.x.back(); });
    withLegend(plot(bars, 0.0, hMax, 0.0, yTop(bars, 1.0), "height (m)", "plants"),
               "Region " + std::to_string(ri) + " (" + where + "): undergrowth heights", key)
        .writePng(dir + stem + "_heights.png");
}

void runInspect(const InspectArgs& args) {
    const BiomeDatabase db = readBiomeDatabase(args.database);
    std::ostringstream o;
    o << "biome database " << args.database << "\n";
    o << "  format " << kBiomeDbFormat << ", schema " << db.schemaVersion << ", code " << db.codeVersion << ", created "
      << db.createdUtc << "\n";
    o << "  biome " << db.biomeName << ": " << db.speciesCount() << " species, " << db.subBiomeNames.size()
      << " sub-biomes; seeding disc " << num(db.seedingRadiusFactor) << " x crown radius\n";
    o << "  pair correlation: " << db.pcfBins.count << " bins of " << num(db.pcfBins.widthM()) << " m to "
      << num(db.pcfBins.rMaxM) << " m; disk separation: " << db.separationBins.count << " bins from "
      << num(db.separationBins.minM) << " to " << num(db.separationBins.maxM) << " m\n";
    o << "  inputs: " << db.inputs.size() << "\n";
    for (std::size_t i = 0; i < db.inputs.size(); ++i) {
        const DbInput& in = db.inputs[i];
        o << "    [" << i << "] " << in.path << ": seed " << in.seed << ", year " << in.year << ", window "
          << num(in.window.x0) << "," << num(in.window.y0) << "," << num(in.window.x1) << "," << num(in.window.y1) << ", "
          << in.undergrowthPlants << " undergrowth, " << in.canopyTrees << " canopy; " << in.unlabelledPlants
          << " plants in no region (cells seeded by no canopy tree, " << fixed(in.unlabelledAreaM2, 0)
          << " m2, or whose centre lies outside the window): not analysed\n";
    }
    o << "  combinations: " << db.combinations.size() << ", regions: " << db.regions.size() << "\n";
    for (const DbCombination& c : db.combinations) {
        o << "\n  combination " << db.combinationName(c.mask) << ": " << fixed(c.areaM2, 0) << " m2, k = " << c.k;
        std::string sil;
        for (std::size_t k = 1; k < c.silhouette.size(); ++k)
            if (std::isfinite(c.silhouette[k])) sil += (sil.empty() ? "" : ", ") + std::to_string(k + 1) + ": " + fixed(c.silhouette[k], 3);
        o << " (silhouette " << (sil.empty() ? "not computed" : sil) << ")\n";
        for (int ri = c.firstRegion; ri < c.firstRegion + c.k; ++ri) {
            const DbRegion& r = db.regions[static_cast<std::size_t>(ri)];
            o << "    region " << ri << " (cluster " << r.cluster << "): " << fixed(r.areaM2, 0) << " m2, "
              << fixed(r.undergrowthCount, 0) << " plants, " << fixed(r.densityPerM2, 4) << " plants/m2, "
              << fixed(r.canopyCount, 0) << " canopy trees; centroid";
            for (std::size_t f = 0; f < kFactorCount; ++f)
                o << (f ? ", " : " ") << kFactors[f].key << " " << num(r.centroidRaw[f]) << " " << kFactors[f].unit;
            o << "\n      leading species:";
            const auto lead = leadingSpecies(r, 4);
            if (lead.empty()) o << " none";
            for (std::size_t i = 0; i < lead.size(); ++i)
                o << (i ? ", " : " ") << db.speciesNames[static_cast<std::size_t>(lead[i])] << " "
                  << fixed(100.0 * r.speciesProportion[static_cast<std::size_t>(lead[i])], 1) << "%";
            o << "; " << r.pairs.size() << " species pairs\n";
        }
    }
    std::cout << o.str();
    if (!args.out.empty()) {
        writeTextFile(args.out, o.str());
        std::cout << "wrote summary: " << args.out << "\n";
    }
    if (!args.pngDir.empty()) {
        ensureDirectory(args.pngDir);
        Progress bar("inspect pictures", static_cast<long>(db.regions.size()));
        for (std::size_t ri = 0; ri < db.regions.size(); ++ri) {
            writeRegionPlots(args.pngDir, db, ri, args.maxPairs);
            bar.update(static_cast<long>(ri + 1));
        }
        bar.finish();
        std::cout << "wrote pictures: " << args.pngDir << "/ (region_NNNN_pcf.png, region_NNNN_heights.png for "
                  << db.regions.size() << " regions)\n";
    }
}

}  // namespace

void registerAnalyseCommand(CLI::App& app) {
    auto args = std::make_shared<AnalyseArgs>();
    CLI::App* cmd = app.add_subcommand(
        "analyse",
        "Analyse simulations into a biome database (HDF5): regions (sub-biome combination x k-means cluster of the "
        "annual-mean abiotics), density, species proportions, size histograms, pair correlation and disk separation");
    cmd->add_option("simulations", args->simulations, "Simulation files (eco simulate output), analysed together")
        ->required()
        ->check(CLI::ExistingFile);
    cmd->add_option("--out", args->out, "Output biome database, e.g. biome-db.h5 (written atomically)")->required();
    cmd->add_option("--kmax", args->kMax, "Largest number of k-means clusters tried per combination (default 6)")
        ->check(CLI::Range(1, 64));
    cmd->add_option("--year", args->year, "Snapshot year to analyse (default: the last)")->check(nonNegativeNumber());
    cmd->add_option("--abiotics", args->abiotics,
                    "Abiotics file(s) replacing those the simulations name: one for all, or one per simulation in order");
    cmd->add_option("--seed", args->seed, "Seed of k-means++ and sampling (default 1)")->check(nonNegativeNumber());
    cmd->add_option("--rmax", args->rMaxM, "Largest pair distance, m (default 10)")->check(positiveNumber());
    cmd->add_option("--bins", args->bins, "Distance bins of the pair correlation (default 40)")->check(CLI::Range(1, 100000));
    cmd->add_option("--seeding-radius-factor", args->seedingRadiusFactor,
                    "Canopy trees seed cells within this factor x crown radius (default: the simulation's, else 12)")
        ->check(positiveNumber());
    cmd->add_flag("--species-sub-biomes", args->speciesSubBiomes,
                  "Label cells by the canopy species' own sub_biomes instead of the sub-biomes' canopy lists");
    cmd->callback([args] { runAnalyse(*args); });
}

void registerInspectCommand(CLI::App& app) {
    auto args = std::make_shared<InspectArgs>();
    CLI::App* cmd = app.add_subcommand(
        "inspect", "Readable summary of a biome database (regions, k per combination, densities, leading species)");
    cmd->add_option("database", args->database, "Biome database (eco analyse output)")->required();
    cmd->add_option("--png", args->pngDir, "Also plot g(r) of the main species pairs and height histograms per region");
    cmd->add_option("--max-pairs", args->maxPairs, "Species pairs per g(r) plot (default 8)")->check(CLI::Range(1, 64));
    cmd->add_option("--out", args->out, "Also write the summary to this text file");
    cmd->callback([args] { runInspect(*args); });
}

void registerPcfCommand(CLI::App& app) {
    auto args = std::make_shared<PcfArgs>();
    CLI::App* cmd = app.add_subcommand(
        "pcf",
        "Pair correlation g(r) of a point pattern (e.g. a field stem map), cross-type g_ij with a species column; "
        "translation and isotropic edge correction; CSV and PNG");
    cmd->add_option("points", args->points, "CSV with a header x,y[,species] (x_m, y_m also accepted), metres")->required();
    cmd->add_option("--window", args->window, "Observation window x0,y0,x1,y1 in metres")->required();
    cmd->add_option("--rmax", args->rMaxM, "Largest distance, m (default: a quarter of the shorter side; at most half)")
        ->check(positiveNumber());
    cmd->add_option("--bins", args->bins, "Number of distance bins")->check(CLI::Range(1, 100000))->capture_default_str();
    cmd->add_option("--out", args->out, "Output CSV (default POINTS_pcf.csv); the plot goes beside it as .png");
    cmd->callback([args] { runPcf(*args); });
}

}  // namespace eco::cli
