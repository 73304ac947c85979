#include "method_comparison.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <limits>
#include <set>
#include <sstream>

#include "atomic_file.h"
#include "biome_db.h"
#include "eco_version.h"
#include "error.h"
#include "h5io.h"
#include "provenance.h"
#include "scene.h"
#include "sim_input.h"
#include "stage_common.h"
#include "text_format.h"
#include "undergrowth.h"

namespace eco::validate {

namespace {

constexpr const char* kAllMethods[] = {"structured", "darts", "deussen", "xu2015"};

std::string num(double v, int digits = 3) {
    if (!std::isfinite(v)) return "n/a";
    std::ostringstream s;
    s.setf(std::ios::fixed);
    s.precision(digits);
    s << v;
    return s.str();
}

std::vector<double> xs(const std::vector<Plant>& p) {
    std::vector<double> v;
    v.reserve(p.size());
    for (const Plant& q : p) v.push_back(q.xM);
    return v;
}
std::vector<double> ys(const std::vector<Plant>& p) {
    std::vector<double> v;
    v.reserve(p.size());
    for (const Plant& q : p) v.push_back(q.yM);
    return v;
}

/// The overall figure named `name` of a report; nullptr when absent.
const FidelityFigure* overallFigure(const FidelityReport& r, const std::string& name) {
    for (const FidelityFigure& f : r.figures)
        if (f.scope == "overall" && f.figure == name) return &f;
    return nullptr;
}

/// The protocol's reporter for one method: its lines go on to `parent`, its report (each
/// method's fidelity.md, also written to a file) is not printed.
class MethodReporter : public pipeline::Reporter {
public:
    explicit MethodReporter(pipeline::Reporter& parent) : parent_(parent) {}
    std::ostream& out() override { return sink_; }
    void info(const std::string& line) override { parent_.info(line); }
    std::unique_ptr<pipeline::ProgressBar> progress(const std::string& label, long total) override {
        return parent_.progress(label, total);
    }
    bool stopRequested() override { return parent_.stopRequested(); }

private:
    pipeline::Reporter& parent_;
    std::ostringstream sink_;
};

}  // namespace

std::vector<std::string> parseMethodList(const std::string& text) {
    if (text == "all") return {std::begin(kAllMethods), std::end(kAllMethods)};
    std::vector<std::string> out;
    std::set<std::string> seen;
    std::string item;
    std::istringstream in(text);
    while (std::getline(in, item, ',')) {
        synth::parseSynthMethod(item);  // ValidationError naming an unknown method
        if (!seen.insert(item).second) throw ValidationError("--synth-method " + text + ": '" + item + "' is listed twice");
        out.push_back(item);
    }
    if (out.empty() || text.back() == ',')
        throw ValidationError("--synth-method '" + text + "': expected a method, a comma list of methods, or all");
    return out;
}

RectWindow xuExemplarWindow(const RectWindow& plot) {
    const double side = std::min(plot.widthM(), plot.heightM()) / 3.0;
    const double cx = 0.5 * (plot.x0 + plot.x1), cy = 0.5 * (plot.y0 + plot.y1);
    return RectWindow{cx - 0.5 * side, cy - 0.5 * side, cx + 0.5 * side, cy + 0.5 * side};
}

XuEvaluation evaluateXuEnlargements(const std::vector<Plant>& exemplar, const RectWindow& exemplarWindow,
                                    const std::vector<Plant>& scene, const RectWindow& sceneWindow,
                                    const DistanceBins& fidelityBins, std::uint64_t seed, std::vector<int>& skipped) {
    skipped.clear();
    std::vector<int> factors;
    for (const int k : {3, 6, 10}) {
        if (k * exemplarWindow.widthM() <= sceneWindow.widthM() && k * exemplarWindow.heightM() <= sceneWindow.heightM())
            factors.push_back(k);
        else
            skipped.push_back(k);
    }
    // The fidelity bins, cut at half the exemplar's side (the pair counts' limit).
    const double half = 0.5 * std::min(exemplarWindow.widthM(), exemplarWindow.heightM());
    int nb = fidelityBins.count;
    while (nb > 1 && fidelityBins.hiM(nb - 1) > half + 1e-9) --nb;
    const DistanceBins bins{std::min(fidelityBins.hiM(nb - 1), half), nb};
    if (factors.empty()) {
        XuEvaluation e;
        e.exemplar = xuIndices(xs(exemplar), ys(exemplar), exemplarWindow, bins);
        e.meanPctDevDensity = e.meanPctDevRipley = std::numeric_limits<double>::quiet_NaN();
        return e;
    }
    return evaluateXu(xs(exemplar), ys(exemplar), exemplarWindow, xs(scene), ys(scene), sceneWindow, bins, factors, 10, seed);
}

std::string methodComparisonMarkdown(const MethodComparison& c, const std::string& heading) {
    std::ostringstream md;
    md << heading << "\n\n";
    if (c.methods.empty()) return md.str();
    const FidelityReport& first = c.methods.front().fidelity;
    const auto& w = first.params.window;
    md << "Every method synthesizes the same terrain, canopy and abiotics from the same database (made from simulation "
          "A); each scene is compared with the held-out simulation B inside the plot "
       << num(w.x0, 0) << "," << num(w.y0, 0) << "," << num(w.x1, 0) << "," << num(w.y1, 0)
       << " (docs/fidelity.md). Per figure: d(scene, B), and the score (0 = as good as a second simulation, 1 = as a "
          "pattern without structure). The replicate and CSR levels are the same for every method, so the smallest "
          "distance is the best; it is marked **bold**.\n\n";
    md << "| figure | replicate | CSR |";
    for (const MethodResult& m : c.methods) md << " " << m.method << " |";
    md << "\n|---|---:|---:|";
    for (std::size_t i = 0; i < c.methods.size(); ++i) md << "---:|";
    md << "\n";
    for (const FidelityFigure& f : first.figures) {
        if (f.scope != "overall") continue;
        md << "| " << markdownCell(f.figure) << " | " << num(f.replicate) << " | " << num(f.csr) << " |";
        double best = std::numeric_limits<double>::infinity();
        for (const MethodResult& m : c.methods)
            if (const FidelityFigure* g = overallFigure(m.fidelity, f.figure); g && std::isfinite(g->scene))
                best = std::min(best, g->scene);
        for (const MethodResult& m : c.methods) {
            const FidelityFigure* g = overallFigure(m.fidelity, f.figure);
            if (!g) {
                md << " n/a |";
                continue;
            }
            const bool isBest = std::isfinite(g->scene) && g->scene <= best + 1e-12 && c.methods.size() > 1;
            md << " " << (isBest ? "**" : "") << num(g->scene) << (isBest ? "**" : "")
               << (g->scored ? " (" + num(g->score, 2) + ")" : std::string()) << " |";
        }
        md << "\n";
    }

    md << "\n### Under-crown share per species (whole plot)\n\n| species | A | B |";
    for (const MethodResult& m : c.methods) md << " " << m.method << " |";
    md << "\n|---|---:|---:|";
    for (std::size_t i = 0; i < c.methods.size(); ++i) md << "---:|";
    md << "\n";
    for (std::size_t i = 0; i < first.species.size(); ++i) {
        const SpeciesRow& s = first.species[i];
        if (s.quantity != "under-crown share") continue;
        md << "| " << s.species << " | " << num(s.reference) << " | " << num(s.replicate) << " |";
        for (const MethodResult& m : c.methods)
            md << " " << (i < m.fidelity.species.size() ? num(m.fidelity.species[i].scene) : std::string("n/a")) << " |";
        md << "\n";
    }

    const RectWindow& e = c.exemplarWindow;
    md << "\n### Xu et al. 2015's evaluation: PCT.DEV against the exemplar\n\n"
       << "Exemplar: simulation A's undergrowth (all species, unmarked) in the square " << num(e.x0, 1) << "," << num(e.y0, 1)
       << "," << num(e.x1, 1) << "," << num(e.y1, 1) << " (" << num(e.widthM(), 1) << " m, a third of the plot; density "
       << num(c.methods.front().xu.exemplar.densityPerM2) << " /m2, Ripley index "
       << num(c.methods.front().xu.exemplar.ripleyIndexM) << " m). Each scene: 10 random k x k patches of the exemplar's "
          "area anywhere on its terrain, density and Ripley's aggregation index (mean of L(r) - r) averaged and compared "
          "as |I - I_exemplar| / |I_exemplar| x 100 (docs/synth.md 2d). The patches cover the whole landscape, so a "
          "method that follows the abiotics and the canopy away from the plot departs from the exemplar by design; "
          "Xu et al. claim under 5 % for a stationary exemplar.\n\n";
    md << "| method | k | density /m2 | density PCT.DEV % | Ripley index, m | Ripley PCT.DEV % |\n|---|---:|---:|---:|---:|---:|\n";
    for (const MethodResult& m : c.methods) {
        for (const XuEnlargement& x : m.xu.enlargements)
            md << "| " << m.method << " | " << x.factor << " | " << num(x.mean.densityPerM2) << " | " << num(x.pctDevDensity, 1)
               << " | " << num(x.mean.ripleyIndexM) << " | " << num(x.pctDevRipley, 1) << " |\n";
        for (const int k : m.xuFactorsSkipped)
            md << "| " << m.method << " | " << k << " | patch larger than the scene | | | |\n";
    }

    md << "\n### Speed of the undergrowth sampler\n\n"
       << "The sampler's wall time as its scene file records it (/provenance sampling_seconds; the machine's load at "
          "that time is not recorded), per million undergrowth plants of the whole scene.\n\n"
       << "| method | undergrowth plants | sampling, s | s per million plants |\n|---|---:|---:|---:|\n";
    for (const MethodResult& m : c.methods) {
        const double perM = m.scenePlants > 0 ? m.samplingSeconds / (static_cast<double>(m.scenePlants) * 1e-6)
                                              : std::numeric_limits<double>::quiet_NaN();
        md << "| " << m.method << " | " << m.scenePlants << " | " << num(m.samplingSeconds) << " | " << num(perM, 2) << " |\n";
    }
    return md.str();
}

void writeMethodComparisonCsv(const std::string& path, const MethodComparison& c) {
    std::ostringstream s;
    s << "method,kind,quantity,value\n";
    const auto row = [&](const std::string& method, const std::string& kind, const std::string& quantity, double v) {
        s << csvField(method) << ',' << kind << ',' << csvField(quantity) << ',' << formatNumber(v, 10) << '\n';
    };
    for (const MethodResult& m : c.methods) {
        for (const FidelityFigure& f : m.fidelity.figures) {
            if (f.scope != "overall") continue;
            row(m.method, "distance", f.figure, f.scene);
            row(m.method, "score", f.figure, f.scored ? f.score : std::numeric_limits<double>::quiet_NaN());
        }
        for (const SpeciesRow& sp : m.fidelity.species)
            if (sp.quantity == "under-crown share") row(m.method, "under_crown_share", sp.species, sp.scene);
        for (const XuEnlargement& x : m.xu.enlargements) {
            const std::string k = std::to_string(x.factor);
            row(m.method, "xu_density_per_m2", "k=" + k, x.mean.densityPerM2);
            row(m.method, "xu_density_pct_dev", "k=" + k, x.pctDevDensity);
            row(m.method, "xu_ripley_index_m", "k=" + k, x.mean.ripleyIndexM);
            row(m.method, "xu_ripley_pct_dev", "k=" + k, x.pctDevRipley);
        }
        row(m.method, "speed", "undergrowth plants", static_cast<double>(m.scenePlants));
        row(m.method, "speed", "sampling seconds", m.samplingSeconds);
    }
    if (!c.methods.empty()) {
        const FidelityReport& first = c.methods.front().fidelity;
        for (const FidelityFigure& f : first.figures) {
            if (f.scope != "overall") continue;
            row("replicate", "distance", f.figure, f.replicate);
            row("csr", "distance", f.figure, f.csr);
        }
        row("exemplar", "xu_density_per_m2", "exemplar", c.methods.front().xu.exemplar.densityPerM2);
        row("exemplar", "xu_ripley_index_m", "exemplar", c.methods.front().xu.exemplar.ripleyIndexM);
    }
    writeTextFile(path, s.str());
}

MethodComparison runMethodComparison(const FidelityRunOptions& options, const std::vector<std::string>& methods,
                                     pipeline::Reporter& reporter,
                                     const std::function<std::unique_ptr<pipeline::Reporter>()>& stageReporter) {
    if (methods.empty()) throw ValidationError("--synth-method: no method to compare");
    if (!options.scene.empty())
        throw ValidationError("--scene " + options.scene + ": a comparison of methods synthesizes one scene per method; "
                              "give one method to measure an existing scene");
    MethodComparison c;
    const std::string outDir = options.outDir.empty() ? std::string("out/fidelity") : options.outDir;
    for (const std::string& method : methods) {
        FidelityRunOptions o = options;
        o.synthMethod = method;
        o.outMd.clear();
        o.outCsv.clear();
        reporter.info("methods: " + method);
        MethodReporter methodReporter(reporter);
        const FidelityRunResult r = runFidelityProtocol(o, methodReporter, stageReporter);
        if (r.databasePath.empty()) throw ValidationError("methods: no database to synthesize from");
        MethodResult m;
        m.method = method;
        m.scenePath = r.scenePath;
        m.fidelity = r.report;
        // Xu's evaluation: A's plants in the exemplar square against the whole scene.
        const Biome biome = synth::databaseBiome(readBiomeDatabase(r.databasePath));
        const synth::SceneData scene = synth::readSceneFile(r.scenePath, biome);
        const analysis::LoadedSimulation A = analysis::readSimulation(r.referencePath, analysis::SimulationReadOptions{});
        c.exemplarWindow = xuExemplarWindow(r.report.params.window);
        const Grid<float>& t = scene.terrainM;
        const RectWindow sceneWindow{t.originX(), t.originY(), t.originX() + t.width() * t.cellSizeM(),
                                     t.originY() + t.height() * t.cellSizeM()};
        m.xu = evaluateXuEnlargements(A.input.undergrowth, c.exemplarWindow, scene.undergrowth, sceneWindow,
                                      r.report.params.bins, static_cast<std::uint64_t>(options.synthSeed), m.xuFactorsSkipped);
        m.scenePlants = static_cast<std::int64_t>(scene.undergrowth.size());
        const h5::File f = h5::File::openRead(r.scenePath);
        m.samplingSeconds = readProvenanceDouble(f, "sampling_seconds").value_or(std::numeric_limits<double>::quiet_NaN());
        c.methods.push_back(std::move(m));
    }
    std::ostringstream heading;
    heading << "## The placement methods compared by the fidelity protocol\n\n"
            << "eco " << ECO_VERSION_STRING << ", " << utcTimestamp() << ". Output folder: " << outDir << ".";
    c.markdown = methodComparisonMarkdown(c, heading.str());
    c.markdownPath = options.outMd.empty() ? (std::filesystem::path(outDir) / "methods.md").string() : options.outMd;
    c.csvPath = options.outCsv.empty() ? (std::filesystem::path(outDir) / "methods.csv").string() : options.outCsv;
    AtomicOutputSet outputs;
    writeTextFile(c.markdownPath, c.markdown);
    writeMethodComparisonCsv(c.csvPath, c);
    outputs.commit();
    reporter.out() << c.markdown;
    reporter.info("methods: wrote " + c.markdownPath + " and " + c.csvPath);
    return c;
}

}  // namespace eco::validate
