// eco analyse, eco inspect: parsing only, the stages are in pipeline/analyse_stages. eco pcf:
// parsing, summary and plot; the statistics are in core/point_pattern.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include "analyse_stages.h"
#include "analysis.h"
#include "atomic_file.h"
#include "chart.h"
#include "cli_common.h"
#include "error.h"
#include "image_out.h"
#include "point_pattern.h"
#include "text_format.h"

namespace eco::cli {

namespace {

std::string num(double v, int precision = 4) { return formatNumber(v, precision); }


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
    // g needs pairs: with 0 or 1 point every bin would read 0 (issue 26).
    if (pattern.size() < 2)
        throw ValidationError(args.points + ": " + std::to_string(pattern.size()) + " point(s) inside the window " + args.window +
                              "; the pair correlation needs at least 2");
    PcfOptions opt;
    const double halfShorter = 0.5 * std::min(window.widthM(), window.heightM());
    opt.bins = DistanceBins{args.rMaxM > 0 ? args.rMaxM : 0.5 * halfShorter, args.bins};
    opt.isotropic = true;
    const PairSums sums = countPairs(pattern, window, opt);

    const std::string csv = args.out.empty()
                                ? replaceExtension(args.points, "") + "_pcf.csv"
                                : args.out;
    const std::string png = replaceExtension(csv, ".png");
    pipeline::requireOutputsNotInputs({{"--out", csv}, {"plot", png}}, {args.points});
    const std::filesystem::path parent = std::filesystem::path(csv).parent_path();
    if (!parent.empty()) ensureDirectory(parent.string());
    writePcfCsv(csv, sums, pattern.typeNames);

    // Plot: one panel per type pair (every pair; g_ij = g_ji with translation correction, so
    // each unordered pair once), each with the unmarked pattern's g for comparison.
    std::vector<double> mids;
    for (int k = 0; k < opt.bins.count; ++k) mids.push_back(opt.bins.midM(k));
    const auto curve = [&](const PairSums& s, int i, int j) {
        std::vector<double> g;
        for (int k = 0; k < opt.bins.count; ++k) g.push_back(s.gTranslate(i, j, k));
        return g;
    };
    const Rgb black{0.f, 0.f, 0.f}, grey{0.45f, 0.45f, 0.45f};
    const int nt = sums.nTypes;
    const std::vector<double> pooled = nt > 1 ? curve(sums.merged(), 0, 0) : std::vector<double>{};
    std::vector<ChartPanel> panels;
    int colour = 0;
    for (int i = 0; i < nt; ++i)
        for (int j = i; j < nt; ++j) {
            ChartPanel p;
            p.title = pattern.typeNames[static_cast<std::size_t>(i)] + (i == j ? " - " : " <-> ") +
                      pattern.typeNames[static_cast<std::size_t>(j)];
            p.subtitle = std::to_string(sums.typeCount[static_cast<std::size_t>(i)]) +
                         (i == j ? " points" : " and " + std::to_string(sums.typeCount[static_cast<std::size_t>(j)]) + " points");
            p.series.push_back(ChartSeries{p.title, mids, curve(sums, i, j), categoryColour(colour++)});
            if (!pooled.empty()) {
                ChartSeries all{"all points", mids, pooled, black};
                all.strokeOffsetsPx = {0, 1};
                p.series.insert(p.series.begin(), std::move(all));  // under the pair's curve
            }
            p.xmax = opt.bins.rMaxM;
            p.ymax = chartTop(p.series, 1.5);
            p.reference = ChartReference{1.0, grey, true};
            panels.push_back(std::move(p));
        }
    ChartPanelsLayout layout;
    layout.title = "Pair correlation, " + std::filesystem::path(args.points).filename().string() + " (" +
                   std::to_string(pattern.size()) + " points, " + std::to_string(nt) + " types, translation correction)";
    layout.notes.push_back("All " + std::to_string(panels.size()) + " type pairs, one panel each, every panel on its own g scale.");
    if (nt > 1) layout.key.push_back({"all points (types pooled)", black});
    layout.key.push_back({"the pair of the panel (a colour each)", categoryColour(0)});
    layout.key.push_back({"g = 1 (Poisson)", grey, true, 1});
    layout.xlabel = "r (m)";
    layout.ylabel = "g(r)";
    const int n = static_cast<int>(panels.size());
    layout.columns = n <= 3 ? n : (n <= 9 ? 3 : (n <= 24 ? 4 : 6));
    if (n > 9) layout.plotWidthPx = 240, layout.plotHeightPx = 140;
    chartPanels(panels, layout).writePng(png);

    // World coordinates in full (UTM northings have 7 digits before the point).
    resultStream() << "points: " << pattern.size() << " in window " << num(window.x0, 10) << "," << num(window.y0, 10)
                   << "," << num(window.x1, 10) << "," << num(window.y1, 10) << " (" << num(window.areaM2())
                   << " m2), types:";
    for (std::size_t t = 0; t < pattern.typeNames.size(); ++t)
        resultStream() << (t ? ", " : " ") << pattern.typeNames[t] << " (" << sums.typeCount[t] << ")";
    const ClarkEvans ce = clarkEvans(pattern.x, pattern.y, window);
    resultStream() << "\nClark-Evans index (Donnelly edge correction): " << num(ce.index) << " (mean nearest neighbour "
              << num(ce.meanNearestM) << " m, " << num(ce.expectedM)
              << " m expected under CSR; < 1 clustered, > 1 regular)";
    resultStream() << "\nwrote pair correlation: " << csv << " (" << opt.bins.count << " bins of " << num(opt.bins.widthM())
              << " m to " << num(opt.bins.rMaxM) << " m)\nwrote plot: " << png << "\n";
}

}  // namespace

void registerAnalyseCommand(CLI::App& app) {
    auto args = std::make_shared<pipeline::AnalyseOptions>();
    CLI::App* cmd = app.add_subcommand(
        "analyse",
        "Analyse simulations into a biome database (HDF5): regions (sub-biome combination x k-means cluster of the "
        "annual-mean abiotics), density, species proportions, size histograms, pair correlation and disk separation");
    cmd->add_option("simulations", args->simulations, "Simulation files (eco simulate output), analysed together")
        ->required()
        ->check(CLI::ExistingFile);
    cmd->add_option("--out", args->out, "Output biome database, e.g. biome-db.h5 (written atomically)")->required();
    // Flags of described parameters (analysis/analysis.cpp); not given (0, -1): the table's
    // default, or for the seeding radius the simulation's.
    const auto& fields = analysis::analysisParamFields();
    addParamOption(cmd, "--kmax", args->kMax, fields, "kmax");
    cmd->add_option("--year", args->year, "Snapshot year to analyse (default: the last)")->check(nonNegativeNumber());
    cmd->add_option("--abiotics", args->abiotics,
                    "Abiotics file(s) replacing those the simulations name: one for all, or one per simulation in order");
    addParamOption(cmd, "--seed", args->seed, fields, "seed")->check(nonNegativeNumber());
    cmd->add_option("--rmax", args->rMaxM, "Largest pair distance, m (default 10)")->check(positiveNumber());
    cmd->add_option("--bins", args->bins, "Distance bins of the pair correlation (default 40)")->check(CLI::Range(1, 100000));
    addParamOption(cmd, "--seeding-radius-factor", args->seedingRadiusFactor, fields, "seeding_radius_factor");
    cmd->add_flag("--species-sub-biomes", args->speciesSubBiomes,
                  "Label cells by the canopy species' own sub_biomes instead of the sub-biomes' canopy lists");
    cmd->callback([args] {
        CliReporter reporter;
        pipeline::analyseStage(*args, reporter);
    });
}

void registerInspectCommand(CLI::App& app) {
    auto args = std::make_shared<pipeline::InspectOptions>();
    CLI::App* cmd = app.add_subcommand(
        "inspect", "Readable summary of a biome database (regions, k per combination, densities, leading species)");
    cmd->add_option("database", args->database, "Biome database (eco analyse output)")->required();
    cmd->add_option("--png", args->pngDir, "Also plot g(r) of the main species pairs and height histograms per region");
    cmd->add_option("--max-pairs", args->maxPairs, "Species pairs per g(r) plot (default 8)")->check(CLI::Range(1, 64));
    cmd->add_option("--out", args->out, "Also write the summary to this text file");
    cmd->callback([args] {
        CliReporter reporter;
        pipeline::inspectStage(*args, reporter);
    });
}

void registerPcfCommand(CLI::App& app) {
    auto args = std::make_shared<PcfArgs>();
    CLI::App* cmd = app.add_subcommand(
        "pcf",
        "Pair correlation g(r) of a point pattern (e.g. a field stem map), cross-type g_ij with a species column; "
        "translation and isotropic edge correction; CSV and PNG");
    cmd->add_option("points", args->points, "CSV with a header x,y[,species] (x_m, y_m also accepted), metres")->required();
    cmd->add_option("--window", args->window, "Observation window x0,y0,x1,y1 in metres")
        ->required()
        ->check(parsedBy("--window", [](const std::string& t) { parseWindow(t, "--window"); }));
    cmd->add_option("--rmax", args->rMaxM, "Largest distance, m (default: a quarter of the shorter side; at most half)")
        ->check(positiveNumber());
    cmd->add_option("--bins", args->bins, "Number of distance bins")->check(CLI::Range(1, 100000))->capture_default_str();
    cmd->add_option("--out", args->out, "Output CSV (default POINTS_pcf.csv); the plot goes beside it as .png");
    cmd->callback([args] { runPcf(*args); });
}

}  // namespace eco::cli
