#include "analyse_stages.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <numeric>
#include <ostream>
#include <sstream>

#include "analysis.h"
#include "atomic_file.h"
#include "chart.h"
#include "error.h"
#include "image_out.h"
#include "sim_input.h"
#include "stage_common.h"
#include "text_format.h"

namespace eco::pipeline {

namespace {

std::string num(double v, int precision = 4) { return formatNumber(v, precision); }

std::string fixed(double v, int decimals) {
    char buf[64];
    std::snprintf(buf, sizeof buf, "%.*f", decimals, v);
    return buf;
}

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

    // g(r) of the pairs with the most pairs counted, one panel each; g_ij = g_ji (translation
    // correction), so each unordered pair once. The picture says how many are left out.
    std::vector<const DbPairStats*> pairs;
    for (const auto& p : r.pairs)
        if (p.source <= p.target && std::accumulate(p.pairCount.begin(), p.pairCount.end(), 0.0) > 0) pairs.push_back(&p);
    std::stable_sort(pairs.begin(), pairs.end(), [](const DbPairStats* a, const DbPairStats* b) {
        return std::accumulate(a->pairCount.begin(), a->pairCount.end(), 0.0) >
               std::accumulate(b->pairCount.begin(), b->pairCount.end(), 0.0);
    });
    const std::size_t allPairs = pairs.size();
    if (pairs.size() > static_cast<std::size_t>(maxPairs)) pairs.resize(static_cast<std::size_t>(maxPairs));
    std::vector<double> mids;
    for (int k = 0; k < db.pcfBins.count; ++k) mids.push_back(db.pcfBins.midM(k));
    const Rgb grey{0.45f, 0.45f, 0.45f};
    std::vector<ChartPanel> pcfPanels;
    int colour = 0;
    for (const DbPairStats* p : pairs) {
        ChartPanel panel;
        panel.title = db.categoryName(p->source) + (p->source == p->target ? " - " : " <-> ") + db.categoryName(p->target);
        panel.subtitle = fixed(std::accumulate(p->pairCount.begin(), p->pairCount.end(), 0.0), 0) + " point pairs to " +
                         num(db.pcfBins.rMaxM) + " m";
        panel.series.push_back(ChartSeries{panel.title, mids, p->g, categoryColour(colour++)});
        panel.xmax = db.pcfBins.rMaxM;
        panel.ymax = chartTop(panel.series, 1.5);
        panel.reference = ChartReference{1.0, grey, true};
        pcfPanels.push_back(std::move(panel));
    }
    ChartPanelsLayout pcfLayout;
    pcfLayout.title = "Region " + std::to_string(ri) + " (" + where + "): pair correlation";
    pcfLayout.notes.push_back(
        allPairs > pairs.size()
            ? "The " + std::to_string(pairs.size()) + " of " + std::to_string(allPairs) +
                  " category pairs with the most point pairs, one panel each; " +
                  std::to_string(allPairs - pairs.size()) +
                  " pairs with fewer are left out (eco inspect --max-pairs N shows up to 64)."
            : "All " + std::to_string(allPairs) + " category pairs with point pairs, one panel each.");
    pcfLayout.key = {{"g(r) of the pair (a colour each)", categoryColour(0)}, {"g = 1 (Poisson)", grey, true, 1}};
    pcfLayout.xlabel = "r (m)";
    pcfLayout.ylabel = "g(r)";
    pcfLayout.columns = pcfPanels.size() <= 9 ? 4 : 6;
    pcfLayout.plotWidthPx = 240;
    pcfLayout.plotHeightPx = 140;
    chartPanels(pcfPanels, pcfLayout).writePng(dir + stem + "_pcf.png");

    // Height histograms of the leading species (plants per bin, not renormalised), one panel
    // each on its own height range: on one shared axis the short species' bins were hidden.
    const auto lead = leadingSpecies(r, 6);
    std::vector<ChartPanel> heightPanels;
    for (int s : lead) {
        const DbHistogram& h = r.height[static_cast<std::size_t>(s)];
        if (h.edges.size() < 2) continue;
        ChartPanel panel;
        panel.title = db.speciesNames[static_cast<std::size_t>(s)];
        panel.subtitle = fixed(r.speciesCount[static_cast<std::size_t>(s)], 0) + " plants" +
                         (h.overflow > 0 ? ", " + fixed(h.overflow, 0) + " above " + num(h.edges.back()) + " m not drawn" : "");
        panel.series.push_back(ChartSeries{panel.title, h.edges, h.counts, categoryColour(s), true});
        panel.xmin = h.edges.front();
        panel.xmax = h.edges.back();
        panel.ymax = chartTop(panel.series, 1.0);
        heightPanels.push_back(std::move(panel));
    }
    ChartPanelsLayout heightLayout;
    heightLayout.title = "Region " + std::to_string(ri) + " (" + where + "): undergrowth heights";
    heightLayout.notes.push_back("The " + std::to_string(lead.size()) +
                                 " most common species, each on its own height and count axes.");
    heightLayout.xlabel = "height (m)";
    heightLayout.ylabel = "plants per bin";
    heightLayout.columns = 3;
    chartPanels(heightPanels, heightLayout).writePng(dir + stem + "_heights.png");
}

}  // namespace

AnalyseResult analyseStage(const AnalyseOptions& args, Reporter& reporter) {
    std::vector<std::string> inputFiles = args.simulations;
    inputFiles.insert(inputFiles.end(), args.abiotics.begin(), args.abiotics.end());
    requireOutputsNotInputs({{"--out", args.out}}, inputFiles);
    cleanUpAfterDeadWriters(args.out);  // what killed runs left (the directory may not exist yet)
    if (!args.abiotics.empty() && args.abiotics.size() != 1 && args.abiotics.size() != args.simulations.size())
        throw ValidationError("--abiotics: give one file for all simulations or one per simulation (" +
                              std::to_string(args.simulations.size()) + "), got " + std::to_string(args.abiotics.size()));
    // One file named twice (two spellings of a path, a link) would count twice: the
    // database's area, plant count and replicates doubled, its statistics unchanged.
    for (std::size_t i = 0; i < args.simulations.size(); ++i)
        for (std::size_t j = 0; j < i; ++j) {
            std::error_code ec;
            if (std::filesystem::equivalent(args.simulations[j], args.simulations[i], ec) && !ec)
                throw ValidationError("simulation file '" + args.simulations[i] + "' is given twice (also as '" +
                                      args.simulations[j] + "'): it would count twice in the database's area, plants "
                                      "and replicates; give each simulation once");
        }
    std::vector<analysis::LoadedSimulation> loaded;
    double simFactor = 0;
    for (std::size_t i = 0; i < args.simulations.size(); ++i) {
        analysis::SimulationReadOptions opt;
        opt.year = args.year;
        if (!args.abiotics.empty()) opt.abioticsPath = args.abiotics.size() == 1 ? args.abiotics[0] : args.abiotics[i];
        loaded.push_back(analysis::readSimulation(args.simulations[i], opt));
        const auto& l = loaded.back();
        reporter.info("simulation " + args.simulations[i] + ": year " + std::to_string(l.input.provenance.year) + ", " +
                      std::to_string(l.input.undergrowth.size()) + " undergrowth plants, " +
                      std::to_string(l.input.canopy.size()) + " canopy trees, area " + num(l.input.window.widthM()) +
                      " x " + num(l.input.window.heightM()) + " m, abiotics " + l.input.provenance.abioticsPath);
        if (l.seedOuterRadiusFactor > 0) {
            if (simFactor > 0 && simFactor != l.seedOuterRadiusFactor)
                reporter.info("note: the simulations use different seeding disc factors; using " + num(simFactor));
            if (simFactor == 0) simFactor = l.seedOuterRadiusFactor;
        }
    }
    analysis::AnalysisParams params;
    if (args.kMax > 0) params.kMax = args.kMax;
    if (args.seed >= 0) params.seed = static_cast<std::uint64_t>(args.seed);
    if (args.rMaxM > 0) params.pcfBins.rMaxM = args.rMaxM;
    if (args.bins > 0) params.pcfBins.count = args.bins;
    // The combination labels must use the simulation's own seeding disc unless told otherwise.
    params.seedingRadiusFactor = args.seedingRadiusFactor > 0 ? args.seedingRadiusFactor : (simFactor > 0 ? simFactor : params.seedingRadiusFactor);
    if (args.speciesSubBiomes) params.membership = analysis::CanopyMembership::SpeciesSubBiomes;

    std::vector<analysis::AnalysisInput> inputs;
    for (auto& l : loaded) inputs.push_back(std::move(l.input));
    std::unique_ptr<ProgressBar> bar;
    std::string stage;
    const auto progress = [&](const std::string& s, double fraction) {
        if (s != stage) {
            if (bar) bar->finish();
            bar = reporter.progress("analyse " + s, 1000);
            stage = s;
        }
        bar->update(static_cast<long>(fraction * 1000.0 + 0.5));
    };
    AnalyseResult result;
    result.database = analysis::analyse(inputs, params, progress);
    if (bar) bar->finish();
    const BiomeDatabase& db = result.database;
    // A database without a region synthesizes nothing (eco synth refuses it); say why here
    // instead of writing it (issue 26: --seeding-radius-factor 1e-9 wrote one).
    if (db.regions.empty())
        throw ValidationError("analyse: no region: no analysed cell lies within the seeding disc of a canopy tree (seeding "
                              "radius factor " + formatNumber(params.seedingRadiusFactor, 6) + " x crown radius) or inside the "
                              "inputs' windows; nothing written to " + args.out);

    prepareOutput(args.out);
    writeBiomeDatabase(args.out, db);
    double area = 0, plants = 0;
    for (const auto& r : db.regions) {
        area += r.areaM2;
        plants += r.undergrowthCount;
    }
    reporter.out() << "wrote biome database: " << args.out << " (" << db.combinations.size() << " sub-biome combinations, "
                   << db.regions.size() << " regions, " << fixed(area, 0) << " m2, " << fixed(plants, 0)
                   << " undergrowth plants; schema " << kBiomeDbSchemaVersion << ")\n";
    return result;
}

std::vector<std::string> commandLine(const AnalyseOptions& a) {
    std::vector<std::string> args = {"analyse"};
    args.insert(args.end(), a.simulations.begin(), a.simulations.end());
    args.insert(args.end(), {"--out", a.out});
    if (a.seed >= 0) args.insert(args.end(), {"--seed", std::to_string(a.seed)});
    if (a.kMax > 0) args.insert(args.end(), {"--kmax", std::to_string(a.kMax)});
    if (a.year >= 0) args.insert(args.end(), {"--year", std::to_string(a.year)});
    for (const auto& f : a.abiotics) args.insert(args.end(), {"--abiotics", f});
    if (a.rMaxM > 0) args.insert(args.end(), {"--rmax", argNumber(a.rMaxM)});
    if (a.bins > 0) args.insert(args.end(), {"--bins", std::to_string(a.bins)});
    if (a.seedingRadiusFactor > 0) args.insert(args.end(), {"--seeding-radius-factor", argNumber(a.seedingRadiusFactor)});
    if (a.speciesSubBiomes) args.push_back("--species-sub-biomes");
    return args;
}

InspectResult inspectStage(const InspectOptions& args, Reporter& reporter) {
    requireOutputsNotInputs({{"--out", args.out}}, {args.database});
    const BiomeDatabase db = readBiomeDatabase(args.database);
    std::ostringstream o;
    o << "biome database " << args.database << "\n";
    o << "  format " << kBiomeDbFormat << ", schema " << db.schemaVersion << ", code " << db.codeVersion << ", created "
      << (db.createdUtc.empty() ? std::string("(not recorded: written with --no-provenance)") : db.createdUtc) << "\n";
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
    std::ostream& out = reporter.out();
    out << o.str();
    AtomicOutputSet outputs;  // the summary and the pictures together
    if (!args.out.empty()) {
        writeTextFile(args.out, o.str());
        out << "wrote summary: " << args.out << "\n";
    }
    if (!args.pngDir.empty()) {
        prepareOutputDirectory(args.pngDir);
        auto bar = reporter.progress("inspect pictures", static_cast<long>(db.regions.size()));
        for (std::size_t ri = 0; ri < db.regions.size(); ++ri) {
            writeRegionPlots(args.pngDir, db, ri, args.maxPairs);
            bar->update(static_cast<long>(ri + 1));
        }
        bar->finish();
        out << "wrote pictures: " << args.pngDir << "/ (region_NNNN_pcf.png, region_NNNN_heights.png for "
            << db.regions.size() << " regions)\n";
    }
    outputs.commit();
    return {o.str()};
}

std::vector<std::string> commandLine(const InspectOptions& a) {
    std::vector<std::string> args = {"inspect", a.database};
    if (!a.pngDir.empty()) args.insert(args.end(), {"--png", a.pngDir});
    if (!a.out.empty()) args.insert(args.end(), {"--out", a.out});
    if (a.maxPairs != 8) args.insert(args.end(), {"--max-pairs", std::to_string(a.maxPairs)});
    return args;
}

}  // namespace eco::pipeline
