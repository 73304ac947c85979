#include "sensitivity.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <numeric>
#include <sstream>
#include <utility>

#include "atomic_file.h"
#include "chart.h"
#include "error.h"
#include "h5io.h"
#include "image_out.h"
#include "rng.h"
#include "sim_file.h"
#include "sobol_sequence.h"
#include "strict_toml.h"
#include "text_format.h"

namespace eco::pipeline {

namespace fs = std::filesystem;

namespace {

constexpr double kPi = 3.14159265358979323846;

double mean(const std::vector<double>& v) { return v.empty() ? 0.0 : std::accumulate(v.begin(), v.end(), 0.0) / static_cast<double>(v.size()); }

}  // namespace

SensitivitySpec loadSensitivitySpec(const std::string& path, const std::string& outOverride) {
    const toml::table root = parseTomlFile(path);
    StrictTable top(root, path, "");
    SensitivitySpec spec;
    spec.path = path;
    StrictTable s(top.table("sensitivity"), path, "[sensitivity]");
    spec.outDir = outOverride.empty() ? pathRelativeToConfig(path, s.string("out_dir")) : outOverride;
    if (!outOverride.empty() && s.has("out_dir")) s.string("out_dir");
    const std::string method = s.stringOr("method", "morris");
    if (method != "morris" && method != "sobol") s.fail("method", "'" + method + "' is not supported (morris or sobol)");
    spec.method = method == "sobol" ? SensitivitySpec::Method::Sobol : SensitivitySpec::Method::Morris;
    if (spec.method == SensitivitySpec::Method::Morris) {
        for (const char* key : {"samples", "bootstrap", "sampling"})
            if (s.has(key)) s.fail(key, "is a key of method = \"sobol\"");
        spec.trajectories = static_cast<int>(s.integerOr("trajectories", spec.trajectories));
        if (spec.trajectories < 2 || spec.trajectories > 1000) s.fail("trajectories", "must be in 2 .. 1000");
        spec.levels = static_cast<int>(s.integerOr("levels", spec.levels));
        if (spec.levels < 2 || spec.levels > 20 || spec.levels % 2 != 0) s.fail("levels", "must be even, in 2 .. 20");
    } else {
        for (const char* key : {"trajectories", "levels"})
            if (s.has(key)) s.fail(key, "is a key of method = \"morris\"");
        spec.samples = static_cast<int>(s.integerOr("samples", spec.samples));
        if (spec.samples < 4 || spec.samples > 100000) s.fail("samples", "must be in 4 .. 100000");
        spec.bootstrap = static_cast<int>(s.integerOr("bootstrap", spec.bootstrap));
        if (spec.bootstrap < 0 || spec.bootstrap > 100000) s.fail("bootstrap", "must be in 0 .. 100000");
        const std::string sampling = s.stringOr("sampling", "random");
        if (sampling != "random" && sampling != "quasi-random") s.fail("sampling", "'" + sampling + "' is not supported (random or quasi-random)");
        spec.sampling = sampling == "quasi-random" ? SensitivitySpec::Sampling::QuasiRandom : SensitivitySpec::Sampling::Random;
    }
    spec.replicates = static_cast<int>(s.integerOr("replicates", spec.replicates));
    if (spec.replicates < 1 || spec.replicates > 100) s.fail("replicates", "must be in 1 .. 100");
    const std::int64_t seed = s.integerOr("seed", 1);
    if (seed < 0) s.fail("seed", "must not be negative");
    spec.seed = static_cast<std::uint64_t>(seed);
    spec.membersAtOnce = static_cast<int>(s.integerOr("members_at_once", 1));
    if (spec.membersAtOnce < 1 || spec.membersAtOnce > 256) s.fail("members_at_once", "must be in 1 .. 256");
    {
        const toml::table& params = s.table("parameters");
        for (const auto& [k, v] : params) spec.parameters.push_back(parseStudyParameter(std::string(k.str()), v, path, "[sensitivity.parameters]"));
        if (spec.parameters.empty()) s.fail("parameters", "no parameter to vary");
        if (spec.parameters.size() > 200) s.fail("parameters", "more than 200 parameters");
    }
    for (const std::string& o : s.strings("outputs")) {
        spec.outputs.push_back(parseSimulationOutput(o, path + ": [sensitivity] outputs"));
        if (spec.outputs.back().measure == SimulationOutput::Measure::PairCorrelation)
            s.fail("outputs", "'" + o + "': a pair correlation needs a stem map: a target of eco calibrate");
    }
    if (spec.outputs.empty()) s.fail("outputs", "no output to measure");
    if (spec.sampling == SensitivitySpec::Sampling::QuasiRandom && 2 * spec.parameters.size() > static_cast<std::size_t>(SobolSequence::kMaxDimensions))
        s.fail("sampling", "quasi-random sampling takes at most " + std::to_string(SobolSequence::kMaxDimensions / 2) + " parameters (" +
                               std::to_string(spec.parameters.size()) + " given)");
    spec.base = studyBase(s.node("base"), path, path + ": [sensitivity] base");
    s.finish();
    top.finish();
    const std::size_t members = (spec.method == SensitivitySpec::Method::Morris
                                     ? static_cast<std::size_t>(spec.trajectories) * (spec.parameters.size() + 1)
                                     : static_cast<std::size_t>(spec.samples) * (spec.parameters.size() + 2)) *
                                static_cast<std::size_t>(spec.replicates);
    if (members > 100000) throw ValidationError(path + ": [sensitivity]: " + std::to_string(members) + " members (more than 100000)");
    return spec;
}

MorrisDesign morrisDesign(int parameters, int trajectories, int levels, std::uint64_t seed) {
    if (parameters < 1 || trajectories < 1 || levels < 2 || levels % 2 != 0)
        throw ValidationError("Morris design: needs parameters >= 1, trajectories >= 1 and an even number of levels >= 2");
    MorrisDesign d;
    d.parameters = parameters;
    d.trajectories = trajectories;
    d.levels = levels;
    d.delta = static_cast<double>(levels) / (2.0 * static_cast<double>(levels - 1));
    const int half = levels / 2;
    const auto k = static_cast<std::size_t>(parameters);
    for (int t = 0; t < trajectories; ++t) {
        RandomStream rs(seed, 0x4d6f727269730000ull + static_cast<std::uint64_t>(t));
        // Each parameter's level (0 .. levels - 1) and direction: up from the lower half of
        // the grid, down from the upper half, so every point stays on the grid in [0, 1].
        std::vector<int> level(k), direction(k);
        for (std::size_t i = 0; i < k; ++i) {
            direction[i] = rs.below(2) == 0 ? 1 : -1;
            level[i] = static_cast<int>(rs.below(static_cast<std::uint32_t>(half))) + (direction[i] > 0 ? 0 : half);
        }
        std::vector<int> order(k);
        std::iota(order.begin(), order.end(), 0);
        for (std::size_t i = k; i > 1; --i) std::swap(order[i - 1], order[rs.below(static_cast<std::uint32_t>(i))]);
        const auto point = [&] {
            std::vector<double> x(k);
            for (std::size_t i = 0; i < k; ++i) x[i] = static_cast<double>(level[i]) / static_cast<double>(levels - 1);
            return x;
        };
        std::vector<std::vector<double>> pts{point()};
        for (std::size_t j = 0; j < k; ++j) {
            const auto i = static_cast<std::size_t>(order[j]);
            level[i] += direction[i] * half;
            pts.push_back(point());
        }
        d.points.push_back(std::move(pts));
        d.moved.push_back(order);
    }
    return d;
}

std::vector<MorrisStats> morrisStatistics(const MorrisDesign& design, const std::vector<std::vector<double>>& y) {
    const auto k = static_cast<std::size_t>(design.parameters);
    std::vector<std::vector<double>> effects(k);
    if (y.size() != design.points.size()) throw ValidationError("Morris statistics: outputs of " + std::to_string(y.size()) + " trajectories for a design of " + std::to_string(design.points.size()));
    for (std::size_t t = 0; t < y.size(); ++t) {
        if (y[t].size() != k + 1) throw ValidationError("Morris statistics: a trajectory needs k + 1 outputs");
        for (std::size_t j = 0; j < k; ++j) {
            const auto i = static_cast<std::size_t>(design.moved[t][j]);
            const double step = design.points[t][j + 1][i] - design.points[t][j][i];
            effects[i].push_back((y[t][j + 1] - y[t][j]) / step);
        }
    }
    std::vector<MorrisStats> out(k);
    for (std::size_t i = 0; i < k; ++i) {
        const std::vector<double>& e = effects[i];
        MorrisStats& s = out[i];
        s.effects = static_cast<int>(e.size());
        s.mu = mean(e);
        double absSum = 0, sq = 0;
        for (double v : e) {
            absSum += std::fabs(v);
            sq += (v - s.mu) * (v - s.mu);
        }
        s.muStar = e.empty() ? 0 : absSum / static_cast<double>(e.size());
        s.sigma = e.size() > 1 ? std::sqrt(sq / static_cast<double>(e.size() - 1)) : 0.0;
    }
    return out;
}

SeedNoise seedNoise(const MorrisDesign& design, const std::vector<std::vector<std::vector<double>>>& values) {
    SeedNoise n;
    n.replicateSd = n.muStarNoise = std::nan("");
    double pointVar = 0, stepVar = 0;
    std::size_t points = 0, steps = 0, replicates = 0;
    const auto variance = [](const std::vector<double>& v) {
        const double m = mean(v);
        double sq = 0;
        for (double x : v) sq += (x - m) * (x - m);
        return sq / static_cast<double>(v.size() - 1);
    };
    for (const auto& traj : values)
        for (std::size_t j = 0; j < traj.size(); ++j) {
            if (traj[j].size() < 2) continue;
            replicates = traj[j].size();
            pointVar += variance(traj[j]);
            ++points;
            if (j + 1 < traj.size() && traj[j + 1].size() == traj[j].size()) {
                // The step's differences replicate by replicate: the seeds are the same at both
                // points, so what they share cancels and only the noise of the step is left.
                std::vector<double> d(traj[j].size());
                for (std::size_t r = 0; r < d.size(); ++r) d[r] = traj[j + 1][r] - traj[j][r];
                stepVar += variance(d);
                ++steps;
            }
        }
    if (points == 0 || steps == 0) return n;
    n.replicateSd = std::sqrt(pointVar / static_cast<double>(points));
    // The mean of R replicate differences has sd sqrt(var(d) / R); a parameter without effect
    // gets a mean |EE| of sqrt(2 / pi) times that, divided by the step.
    n.muStarNoise = std::sqrt(2.0 / kPi) * std::sqrt(stepVar / static_cast<double>(steps) / static_cast<double>(replicates)) / design.delta;
    return n;
}

std::string sensitivityMemberName(int t, int j, int r) {
    char buf[48];
    std::snprintf(buf, sizeof buf, "t%03d-p%03d-r%02d", t + 1, j, r + 1);
    return buf;
}

std::string writeSensitivityEnsemble(const SensitivitySpec& spec, const MorrisDesign& design) {
    std::vector<StudyMember> members;
    std::ostringstream csv;
    csv << "trajectory,point,moved";
    for (const auto& p : spec.parameters) csv << "," << p.key;
    csv << "\n";
    for (int t = 0; t < design.trajectories; ++t)
        for (std::size_t j = 0; j < design.points[static_cast<std::size_t>(t)].size(); ++j) {
            const auto& x = design.points[static_cast<std::size_t>(t)][j];
            std::vector<double> values;
            for (std::size_t i = 0; i < x.size(); ++i) values.push_back(spec.parameters[i].at(x[i]));
            csv << t + 1 << "," << j << "," << (j == 0 ? std::string("") : spec.parameters[static_cast<std::size_t>(design.moved[static_cast<std::size_t>(t)][j - 1])].key);
            for (double v : values) csv << "," << formatNumber(v, 12);
            csv << "\n";
            for (int r = 0; r < spec.replicates; ++r) members.push_back({sensitivityMemberName(t, static_cast<int>(j), r), values, r + 1});
        }
    const std::string path = writeStudyEnsemble(spec.outDir, spec.base, spec.membersAtOnce, spec.parameters, members,
                                                "# The members of eco sensitivity " + spec.path + ": one per Morris design point and replicate\n"
                                                "# (written by eco sensitivity; run.seed is the replicate).\n");
    const std::string designPath = (fs::path(spec.outDir) / "design.csv").string();
    if (!fs::exists(designPath) || readTextFile(designPath) != csv.str()) writeTextFile(designPath, csv.str());
    return path;
}

namespace {

/// mu* against sigma, one marker per parameter with its name, and the seed-noise level of
/// mu* (twice it: the threshold of the report) as a dashed vertical line.
void writeMorrisPng(const std::string& path, const SensitivitySpec& spec, const SimulationOutput& out,
                    const std::vector<MorrisStats>& stats, const SeedNoise& noise) {
    Chart c;
    c.left = 90;
    c.top = 60;
    c.width = 640;
    c.height = 420;
    const double threshold = 2 * noise.muStarNoise;  // NaN with one replicate
    double xmax = std::isfinite(threshold) ? threshold : 0, ymax = 0;
    for (const auto& s : stats) {
        xmax = std::max(xmax, s.muStar);
        ymax = std::max(ymax, s.sigma);
    }
    xmax = xmax > 0 ? xmax * 1.12 : 1;
    ymax = ymax > 0 ? ymax * 1.12 : 1;
    const auto label = [](double v) { return formatNumber(v, 3); };
    c.x = {0, xmax, niceTicks(0, xmax, 6), label};
    c.y = {0, ymax, niceTicks(0, ymax, 6), label};
    if (std::isfinite(threshold) && threshold > 0) {
        for (int k = 0; k < 24; ++k) {
            ChartSeries dash;
            dash.colour = {0.45f, 0.45f, 0.45f};
            dash.strokeOffsetsPx = {0};
            dash.x = {threshold, threshold};
            dash.y = {ymax * k / 24.0, ymax * (k + 0.5) / 24.0};
            c.series.push_back(dash);
        }
    }
    for (std::size_t i = 0; i < stats.size(); ++i) {
        ChartSeries p;
        p.name = spec.parameters[i].key;
        p.x = {stats[i].muStar};
        p.y = {stats[i].sigma};
        p.colour = categoryColour(static_cast<int>(i));
        p.strokeOffsetsPx = {};
        p.pointRadiusPx = 6;
        c.series.push_back(p);
    }
    c.texts.push_back({c.left, 28, "Morris screening of " + out.text + " (" + out.units() + ")", 17, {0, 0, 0}});
    c.texts.push_back({c.left, 48, std::to_string(spec.trajectories) + " trajectories, " + std::to_string(spec.levels) + " levels, " +
                                       std::to_string(spec.replicates) + " replicates; dashed: twice the mu* of seed noise alone (left of it: not told from noise)", 13, {0.3f, 0.3f, 0.3f}});
    c.texts.push_back({c.left + c.width / 2 - 150, c.top + c.height + 48, "mu* (mean |elementary effect|, per whole range)", 14, {0, 0, 0}});
    c.texts.push_back({8, c.top - 10, "sigma", 14, {0, 0, 0}});
    // The key, right of the plot, and each marker's number beside it.
    const int keyX = c.left + c.width + 30;
    for (std::size_t i = 0; i < stats.size(); ++i) {
        const int y = c.top + 16 + static_cast<int>(i) * 20;
        c.texts.push_back({keyX + 14, y + 5, std::to_string(i + 1) + "  " + spec.parameters[i].key, 13, {0, 0, 0}});
        c.texts.push_back({static_cast<int>(c.px(stats[i].muStar)) + 8, static_cast<int>(c.py(stats[i].sigma)) - 6, std::to_string(i + 1), 12, {0, 0, 0}});
    }
    int keyWidth = 0;
    for (const auto& p : spec.parameters) keyWidth = std::max(keyWidth, static_cast<int>(p.key.size()) * 8 + 40);
    Canvas canvas(keyX + keyWidth + 20, std::max(c.top + c.height + 70, c.top + 40 + static_cast<int>(stats.size()) * 20));
    drawChart(canvas, c);
    for (std::size_t i = 0; i < stats.size(); ++i)
        canvas.fillDisc(keyX + 5, c.top + 16 + static_cast<int>(i) * 20, 5, categoryColour(static_cast<int>(i)));
    canvas.writePng(path);
}

// The picture of output o of a report (png/<stem>_<o + 1>.png in the study folder, the
// folder made): its path.
std::string reportPngPath(const SensitivitySpec& spec, const char* stem, std::size_t o) {
    ensureDirectory((fs::path(spec.outDir) / "png").string());
    return (fs::path(spec.outDir) / "png" / (stem + ("_" + std::to_string(o + 1)) + ".png")).string();
}

// The end of a report (Morris or Sobol): sensitivity.csv and sensitivity.md written, and
// with the pictures committed together.
SensitivityReport finishReport(SensitivityReport rep, const SensitivitySpec& spec, AtomicOutputSet& outputs,
                               const std::ostringstream& csv, const std::ostringstream& md, const std::ostringstream& summary) {
    rep.csvPath = (fs::path(spec.outDir) / "sensitivity.csv").string();
    rep.markdownPath = (fs::path(spec.outDir) / "sensitivity.md").string();
    writeTextFile(rep.csvPath, csv.str());
    writeTextFile(rep.markdownPath, md.str());
    outputs.commit();
    rep.summary = summary.str();
    return rep;
}

}  // namespace

SensitivityReport writeSensitivityReport(const SensitivitySpec& spec, const MorrisDesign& design) {
    const auto k = static_cast<std::size_t>(design.parameters);
    SensitivityReport rep;
    AtomicOutputSet outputs;  // the table, the report and its pictures together
    std::ostringstream csv, md, summary;
    csv << "output,units,parameter,low,high,rank,mu_star,mu,sigma,effects,mu_star_seed_noise,replicate_sd,above_noise\n";
    md << "# Sensitivity: Morris screening\n\n"
       << "Specification `" << spec.path << "`: " << k << " parameters, " << design.trajectories << " trajectories of "
       << k + 1 << " points on a grid of " << design.levels << " levels (step " << formatNumber(design.delta, 4)
       << " of each range), " << spec.replicates << " replicate" << (spec.replicates > 1 ? "s" : "") << " per point (run.seed 1 .. "
       << spec.replicates << ", the same at every point); " << design.trajectories * static_cast<int>(k + 1) * spec.replicates
       << " simulations. Design seed " << spec.seed << "; the points are in `design.csv`, the members in `ensemble/`.\n\n"
       << "An elementary effect is the change of the output when one parameter moves by the step, divided by the step "
       << "as a fraction of the parameter's range: the output's change over the whole range if the effect were linear. "
       << "mu* (mean |effect|) ranks the parameters; mu (mean effect) gives the direction; sigma (spread of the effects) "
       << "shows non-linearity or interaction. **Seed noise**: the same point with another seed changes the output too; "
       << "`noise` is the mu* that a parameter without any effect would get from that alone (from the spread, between "
       << "replicates, of each step's difference: the replicates' seeds are the same at every point). A parameter whose mu* is not above twice that cannot be told from seed noise with this design "
       << "(more replicates or trajectories would tell).\n";
    for (std::size_t o = 0; o < spec.outputs.size(); ++o) {
        const SimulationOutput& out = spec.outputs[o];
        std::vector<std::vector<double>> y(static_cast<std::size_t>(design.trajectories));
        std::vector<std::vector<std::vector<double>>> values(static_cast<std::size_t>(design.trajectories));
        for (int t = 0; t < design.trajectories; ++t)
            for (std::size_t j = 0; j <= k; ++j) {
                std::vector<double> reps;
                for (int r = 0; r < spec.replicates; ++r) {
                    const std::string sim = studySimulation(spec.outDir, sensitivityMemberName(t, static_cast<int>(j), r));
                    reps.push_back(measureOutput(sim, out));
                }
                y[static_cast<std::size_t>(t)].push_back(mean(reps));
                values[static_cast<std::size_t>(t)].push_back(reps);
            }
        const std::vector<MorrisStats> stats = morrisStatistics(design, y);
        const SeedNoise noise = seedNoise(design, values);
        std::vector<std::size_t> order(k);
        std::iota(order.begin(), order.end(), 0);
        std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) { return stats[a].muStar > stats[b].muStar; });
        md << "\n## " << out.text << " (" << out.units() << ")\n\n";
        md << "Seed noise: replicate sd " << (std::isfinite(noise.replicateSd) ? formatNumber(noise.replicateSd, 4) : std::string("not measured (one replicate)"))
           << ", mu* of noise alone " << (std::isfinite(noise.muStarNoise) ? formatNumber(noise.muStarNoise, 4) : std::string("-")) << ".\n\n";
        md << "| rank | parameter | range | mu* | mu | sigma | mu* / noise |\n|---:|---|---|---:|---:|---:|---:|\n";
        summary << out.text << ":";
        for (std::size_t rank = 0; rank < k; ++rank) {
            const std::size_t i = order[rank];
            const StudyParameter& p = spec.parameters[i];
            const MorrisStats& s = stats[i];
            const bool measured = std::isfinite(noise.muStarNoise) && noise.muStarNoise > 0;
            const std::string ratio = measured ? formatNumber(s.muStar / noise.muStarNoise, 3) : std::string("-");
            const std::string above = measured ? (s.muStar > 2 * noise.muStarNoise ? "yes" : "no") : "unknown";
            md << "| " << rank + 1 << " | `" << p.key << "` | " << p.describe() << " | "
               << formatNumber(s.muStar, 4) << " | " << formatNumber(s.mu, 4) << " | " << formatNumber(s.sigma, 4) << " | " << ratio
               << (above == "no" ? " (noise)" : "") << " |\n";
            csv << csvField(out.text) << "," << csvField(out.units()) << "," << csvField(p.key) << "," << formatNumber(p.low, 12) << ","
                << formatNumber(p.high, 12) << "," << rank + 1 << "," << formatNumber(s.muStar, 10) << "," << formatNumber(s.mu, 10) << ","
                << formatNumber(s.sigma, 10) << "," << s.effects << "," << (measured ? formatNumber(noise.muStarNoise, 10) : std::string("")) << ","
                << (std::isfinite(noise.replicateSd) ? formatNumber(noise.replicateSd, 10) : std::string("")) << "," << above << "\n";
            summary << (rank == 0 ? " " : ", ") << p.key << " " << formatNumber(s.muStar, 3) << (above == "no" ? " (noise)" : "");
        }
        summary << "\n";
        const std::string png = reportPngPath(spec, "morris", o);
        writeMorrisPng(png, spec, out, stats, noise);
        md << "\n![mu* against sigma](png/morris_" << o + 1 << ".png)\n";
        rep.pngPaths.push_back(png);
    }
    return finishReport(std::move(rep), spec, outputs, csv, md, summary);
}

// ---- Sobol indices ----

std::vector<double> SobolDesign::point(int matrix, int row) const {
    const auto n = static_cast<std::size_t>(row);
    if (matrix == 0) return a[n];
    if (matrix == 1) return b[n];
    std::vector<double> x = a[n];
    const auto i = static_cast<std::size_t>(matrix - 2);
    x[i] = b[n][i];
    return x;
}

SobolDesign sobolDesign(int parameters, int samples, std::uint64_t seed, SensitivitySpec::Sampling sampling) {
    if (parameters < 1 || samples < 2) throw ValidationError("Sobol design: needs parameters >= 1 and samples >= 2");
    SobolDesign d;
    d.parameters = parameters;
    d.samples = samples;
    d.sampling = sampling;
    const auto k = static_cast<std::size_t>(parameters);
    if (sampling == SensitivitySpec::Sampling::QuasiRandom) {
        if (2 * parameters > SobolSequence::kMaxDimensions)
            throw ValidationError("Sobol design: quasi-random sampling takes at most " + std::to_string(SobolSequence::kMaxDimensions / 2) + " parameters");
        const SobolSequence seq(2 * parameters);
        for (int n = 0; n < samples; ++n) {
            const std::vector<double> x = seq.point(static_cast<std::uint32_t>(n) + 1);
            d.a.emplace_back(x.begin(), x.begin() + static_cast<std::ptrdiff_t>(k));
            d.b.emplace_back(x.begin() + static_cast<std::ptrdiff_t>(k), x.end());
        }
        return d;
    }
    // One stream per row, so that a design with more samples begins with the same rows.
    for (int n = 0; n < samples; ++n) {
        RandomStream rs(seed, 0x536f626f6c000000ull + static_cast<std::uint64_t>(n));
        std::vector<double> a(k), b(k);
        for (double& v : a) v = rs.uniform();
        for (double& v : b) v = rs.uniform();
        d.a.push_back(std::move(a));
        d.b.push_back(std::move(b));
    }
    return d;
}

SobolDesign sobolDesign(const SensitivitySpec& spec) {
    return sobolDesign(static_cast<int>(spec.parameters.size()), spec.samples, spec.seed, spec.sampling);
}

namespace {

/// The estimates over the rows `rows` (indices into fA, fB, fAB[i]).
void sobolEstimate(const std::vector<double>& fA, const std::vector<double>& fB, const std::vector<std::vector<double>>& fAB,
                   const std::vector<std::size_t>& rows, std::vector<double>& first, std::vector<double>& total, double* meanOut,
                   double* varianceOut) {
    const auto n = static_cast<double>(rows.size());
    double m = 0;
    for (std::size_t r : rows) m += fA[r] + fB[r];
    m /= 2 * n;
    double v = 0;
    for (std::size_t r : rows) v += (fA[r] - m) * (fA[r] - m) + (fB[r] - m) * (fB[r] - m);
    v /= 2 * n - 1;
    if (meanOut) *meanOut = m;
    if (varianceOut) *varianceOut = v;
    first.assign(fAB.size(), 0.0);
    total.assign(fAB.size(), 0.0);
    for (std::size_t i = 0; i < fAB.size(); ++i) {
        double s = 0, t = 0;
        for (std::size_t r : rows) {
            // Centred on the mean (the same expectation, less round-off and variance).
            const double d = fAB[i][r] - fA[r];
            s += (fB[r] - m) * d;
            t += d * d;
        }
        first[i] = v > 0 ? s / n / v : 0.0;
        total[i] = v > 0 ? t / n / (2 * v) : 0.0;
    }
}

double percentile(std::vector<double> v, double q) {
    if (v.empty()) return std::nan("");
    std::sort(v.begin(), v.end());
    const double pos = q * static_cast<double>(v.size() - 1);
    const auto lo = static_cast<std::size_t>(std::floor(pos));
    const std::size_t hi = std::min(lo + 1, v.size() - 1);
    return v[lo] + (pos - static_cast<double>(lo)) * (v[hi] - v[lo]);
}

}  // namespace

SobolResult sobolIndices(const std::vector<double>& fA, const std::vector<double>& fB, const std::vector<std::vector<double>>& fAB,
                         int bootstrap, std::uint64_t seed) {
    const std::size_t n = fA.size();
    if (n < 2 || fB.size() != n) throw ValidationError("Sobol indices: A and B need the same number (>= 2) of outputs");
    for (const auto& f : fAB)
        if (f.size() != n) throw ValidationError("Sobol indices: every AB_i needs N outputs");
    std::vector<std::size_t> rows(n);
    std::iota(rows.begin(), rows.end(), 0);
    SobolResult res;
    std::vector<double> first, total;
    sobolEstimate(fA, fB, fAB, rows, first, total, &res.mean, &res.variance);
    const std::size_t k = fAB.size();
    res.indices.resize(k);
    for (std::size_t i = 0; i < k; ++i) {
        res.indices[i].first = res.indices[i].firstLow = res.indices[i].firstHigh = first[i];
        res.indices[i].total = res.indices[i].totalLow = res.indices[i].totalHigh = total[i];
    }
    if (bootstrap <= 0) return res;
    std::vector<std::vector<double>> bootFirst(k), bootTotal(k);
    RandomStream rs(seed, 0x426f6f7473747261ull);
    std::vector<double> f, t;
    for (int b = 0; b < bootstrap; ++b) {
        for (std::size_t& r : rows) r = rs.below(static_cast<std::uint32_t>(n));
        sobolEstimate(fA, fB, fAB, rows, f, t, nullptr, nullptr);
        for (std::size_t i = 0; i < k; ++i) {
            bootFirst[i].push_back(f[i]);
            bootTotal[i].push_back(t[i]);
        }
    }
    for (std::size_t i = 0; i < k; ++i) {
        res.indices[i].firstLow = percentile(bootFirst[i], 0.025);
        res.indices[i].firstHigh = percentile(bootFirst[i], 0.975);
        res.indices[i].totalLow = percentile(bootTotal[i], 0.025);
        res.indices[i].totalHigh = percentile(bootTotal[i], 0.975);
    }
    return res;
}

SobolNoise sobolNoise(const std::vector<std::vector<std::vector<double>>>& values) {
    SobolNoise out;
    out.replicateSd = out.varianceShare = std::nan("");
    if (values.size() < 3 || values[0].empty() || values[0][0].size() < 2) return out;
    const std::size_t rows = values[0].size(), reps = values[0][0].size();
    const auto variance = [](const std::vector<double>& v) {
        const double m = mean(v);
        double sq = 0;
        for (double x : v) sq += (x - m) * (x - m);
        return sq / static_cast<double>(v.size() - 1);
    };
    double pointVar = 0, diffVar = 0;
    std::size_t points = 0, diffs = 0;
    std::vector<double> means;  // of A and B: the V of the indices
    for (std::size_t m = 0; m < values.size(); ++m)
        for (std::size_t n = 0; n < rows; ++n) {
            pointVar += variance(values[m][n]);
            ++points;
            if (m < 2) means.push_back(mean(values[m][n]));
            if (m >= 2) {
                std::vector<double> d(reps);
                for (std::size_t r = 0; r < reps; ++r) d[r] = values[0][n][r] - values[m][n][r];
                diffVar += variance(d);
                ++diffs;
            }
        }
    const double v = variance(means);
    out.replicateSd = std::sqrt(pointVar / static_cast<double>(points));
    // The mean of R replicate differences varies by var(d) / R: twice the noise of one point's mean.
    if (v > 0) out.varianceShare = diffVar / static_cast<double>(diffs) / static_cast<double>(reps) / (2 * v);
    return out;
}

std::string sobolMemberName(int matrix, int row, int r) {
    char buf[48];
    if (matrix < 2) std::snprintf(buf, sizeof buf, "%s-%04d-r%02d", matrix == 0 ? "A" : "B", row + 1, r + 1);
    else std::snprintf(buf, sizeof buf, "AB%02d-%04d-r%02d", matrix - 1, row + 1, r + 1);
    return buf;
}

std::string writeSobolEnsemble(const SensitivitySpec& spec, const SobolDesign& design) {
    std::vector<StudyMember> members;
    std::ostringstream csv;
    csv << "matrix,row";
    for (const auto& p : spec.parameters) csv << "," << csvField(p.key);
    csv << "\n";
    for (int m = 0; m < design.matrices(); ++m)
        for (int n = 0; n < design.samples; ++n) {
            const std::vector<double> x = design.point(m, n);
            std::vector<double> values;
            for (std::size_t i = 0; i < x.size(); ++i) values.push_back(spec.parameters[i].at(x[i]));
            csv << (m == 0 ? std::string("A") : m == 1 ? std::string("B") : "AB" + std::to_string(m - 1)) << "," << n + 1;
            for (double v : values) csv << "," << formatNumber(v, 12);
            csv << "\n";
            for (int r = 0; r < spec.replicates; ++r) members.push_back({sobolMemberName(m, n, r), values, r + 1});
        }
    const std::string path = writeStudyEnsemble(spec.outDir, spec.base, spec.membersAtOnce, spec.parameters, members,
                                                "# The members of eco sensitivity " + spec.path + ": one per Sobol design point and replicate\n"
                                                "# (written by eco sensitivity; run.seed is the replicate).\n");
    const std::string designPath = (fs::path(spec.outDir) / "design.csv").string();
    if (!fs::exists(designPath) || readTextFile(designPath) != csv.str()) writeTextFile(designPath, csv.str());
    return path;
}

namespace {

/// Bars of S_i (light) and S_Ti (dark) per parameter with their 95 % intervals as whiskers,
/// and the S_Ti of seed noise alone dashed.
void writeSobolPng(const std::string& path, const SensitivitySpec& spec, const SimulationOutput& out, const SobolResult& res,
                   const SobolNoise& noise) {
    Chart c;
    c.left = 90;
    c.top = 80;
    c.width = std::max(360, 110 * static_cast<int>(res.indices.size()));
    c.height = 420;
    double ymax = 1, ymin = 0;
    for (const auto& s : res.indices) {
        ymax = std::max({ymax, s.totalHigh, s.firstHigh});
        ymin = std::min({ymin, s.firstLow, s.totalLow});
    }
    ymax = std::ceil(ymax * 10 + 0.5) / 10;
    ymin = ymin < 0 ? std::floor(ymin * 10 - 0.5) / 10 : 0;
    const double kCount = static_cast<double>(res.indices.size());
    c.x = {0, kCount, {}, {}};
    c.y = {ymin, ymax, niceTicks(ymin, ymax, 6), [](double v) { return formatNumber(v, 3); }};
    c.reference = ChartReference{0.0, {0.3f, 0.3f, 0.3f}, false};
    const bool noiseShown = std::isfinite(noise.varianceShare) && noise.varianceShare > 0 && 2 * noise.varianceShare < ymax;
    if (noiseShown) {
        for (int k = 0; k < 40; ++k) {
            ChartSeries dash;
            dash.colour = {0.84f, 0.15f, 0.16f};
            dash.x = {kCount * k / 40.0, kCount * (k + 0.5) / 40.0};
            dash.y = {2 * noise.varianceShare, 2 * noise.varianceShare};
            c.series.push_back(dash);
        }
    }
    c.texts.push_back({c.left, 26, "Sobol indices of " + out.text + " (" + out.units() + ")", 17, {0, 0, 0}});
    c.texts.push_back({c.left, 46, "N = " + std::to_string(spec.samples) + ", " + std::to_string(spec.replicates) +
                                       " replicates; light: first-order S, dark: total ST (from 0)", 13, {0.3f, 0.3f, 0.3f}});
    c.texts.push_back({c.left, 64, std::string("whiskers: 95 % bootstrap intervals") + (noiseShown ? "; red dashed: twice the seed-noise share (ST of noise alone)" : ""),
                       13, {0.3f, 0.3f, 0.3f}});
    c.texts.push_back({8, c.top - 10, "index", 14, {0, 0, 0}});
    for (std::size_t i = 0; i < res.indices.size(); ++i)
        c.texts.push_back({static_cast<int>(c.px(static_cast<double>(i) + 0.5)) - 4, c.top + c.height + 22, std::to_string(i + 1), 14, {0, 0, 0}});
    const int keyX = c.left + c.width + 30;
    int keyWidth = 0;
    for (std::size_t i = 0; i < spec.parameters.size(); ++i) {
        c.texts.push_back({keyX, c.top + 16 + static_cast<int>(i) * 20, std::to_string(i + 1) + "  " + spec.parameters[i].key, 13, {0, 0, 0}});
        keyWidth = std::max(keyWidth, static_cast<int>(spec.parameters[i].key.size()) * 8 + 40);
    }
    Canvas canvas(std::max(keyX + keyWidth + 20, c.left + 620), std::max(c.top + c.height + 50, c.top + 40 + static_cast<int>(spec.parameters.size()) * 20));
    drawChart(canvas, c);
    // The bars from 0 (up or down) and their whiskers, over the chart.
    const auto py = [&](double v) { return c.py(std::clamp(v, ymin, ymax)); };
    const Rgb light{0.62f, 0.79f, 0.88f}, dark{0.12f, 0.35f, 0.62f}, black{0, 0, 0};
    for (std::size_t i = 0; i < res.indices.size(); ++i) {
        const SobolIndex& s = res.indices[i];
        for (int which = 0; which < 2; ++which) {
            const double left = static_cast<double>(i) + (which == 0 ? 0.15 : 0.5), right = left + 0.35;
            const double v = which == 0 ? s.first : s.total;
            const double lo = which == 0 ? s.firstLow : s.totalLow, hi = which == 0 ? s.firstHigh : s.totalHigh;
            const int y0 = static_cast<int>(std::min(py(v), py(0))), y1 = static_cast<int>(std::max(py(v), py(0)));
            canvas.fillRect(static_cast<int>(c.px(left)) + 1, y0, static_cast<int>(c.px(right)) - 1, std::max(y1, y0 + 1), which == 0 ? light : dark);
            const double mid = c.px(0.5 * (left + right));
            for (int o : {0, 1}) canvas.drawLine(mid + o, py(lo), mid + o, py(hi), black);
            for (const double e : {lo, hi}) canvas.drawLine(mid - 7, py(e), mid + 8, py(e), black);
        }
    }
    canvas.writePng(path);
}

}  // namespace

SensitivityReport writeSobolReport(const SensitivitySpec& spec, const SobolDesign& design) {
    const auto k = static_cast<std::size_t>(design.parameters);
    const auto N = static_cast<std::size_t>(design.samples);
    SensitivityReport rep;
    AtomicOutputSet outputs;
    std::ostringstream csv, md, summary;
    csv << "output,units,parameter,low,high,scale,rank,first,first_low,first_high,total,total_low,total_high,"
           "seed_noise_share,variance,replicate_sd,above_noise\n";
    md << "# Sensitivity: Sobol indices\n\n"
       << "Specification `" << spec.path << "`: " << k << " parameters, base sample N = " << N << " (matrices A, B and one AB_i per parameter: "
       << N * (k + 2) << " points), " << spec.replicates << " replicate" << (spec.replicates > 1 ? "s" : "") << " per point (run.seed 1 .. "
       << spec.replicates << ", the same at every point); " << N * (k + 2) * static_cast<std::size_t>(spec.replicates)
       << " simulations. "
       << (design.sampling == SensitivitySpec::Sampling::QuasiRandom
               ? std::string("Quasi-random design: A and B from the ") + std::to_string(2 * k) + "-dimensional Sobol' sequence (Joe and Kuo 2008's direction numbers)"
               : "Pseudo-random design, seed " + std::to_string(spec.seed))
       << "; the points are in `design.csv`, the members in `ensemble/`.\n\n"
       << "**S** (first-order index, Saltelli 2010's estimator): the share of the output's variance that the parameter "
       << "explains alone. **ST** (total index, Jansen's estimator): its share with all its interactions; ST - S is the "
       << "interaction part, and a parameter with ST near 0 can be fixed anywhere in its range. Intervals: 95 % of "
       << spec.bootstrap << " bootstrap resamples of the N rows. **Seed noise**: the output is the mean over the replicates; "
       << "the seed-noise share is the part of its variance V that seed noise makes from one point to another (from the "
       << "replicates' spread of each A - AB_i difference: the seeds are the same at every point, so what they share "
       << "cancels); it is also the ST that a parameter without any effect would get. A parameter whose ST is not above "
       << "twice that is marked `(noise)`: this design cannot tell its effect from seed noise.\n";
    for (std::size_t o = 0; o < spec.outputs.size(); ++o) {
        const SimulationOutput& out = spec.outputs[o];
        std::vector<std::vector<std::vector<double>>> values(k + 2, std::vector<std::vector<double>>(N));
        std::vector<std::vector<double>> f(k + 2, std::vector<double>(N));
        for (std::size_t m = 0; m < k + 2; ++m)
            for (std::size_t n = 0; n < N; ++n) {
                for (int r = 0; r < spec.replicates; ++r)
                    values[m][n].push_back(measureOutput(studySimulation(spec.outDir, sobolMemberName(static_cast<int>(m), static_cast<int>(n), r)), out));
                f[m][n] = mean(values[m][n]);
            }
        const std::vector<std::vector<double>> fAB(f.begin() + 2, f.end());
        const SobolResult res = sobolIndices(f[0], f[1], fAB, spec.bootstrap, spec.seed + 7919 * (o + 1));
        const SobolNoise noise = sobolNoise(values);
        std::vector<std::size_t> order(k);
        std::iota(order.begin(), order.end(), 0);
        std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) { return res.indices[a].total > res.indices[b].total; });
        const bool measured = std::isfinite(noise.varianceShare);
        md << "\n## " << out.text << " (" << out.units() << ")\n\n"
           << "Mean " << formatNumber(res.mean, 4) << ", variance V " << formatNumber(res.variance, 4) << "; seed noise: replicate sd "
           << (std::isfinite(noise.replicateSd) ? formatNumber(noise.replicateSd, 4) : std::string("not measured (one replicate)"))
           << ", seed-noise share of V (= the ST of noise alone) " << (measured ? formatNumber(noise.varianceShare, 3) : std::string("-")) << ".\n\n"
           << "| rank | parameter | range | S [95 %] | ST [95 %] | ST - S |\n|---:|---|---|---|---|---:|\n";
        summary << out.text << ":";
        for (std::size_t rank = 0; rank < k; ++rank) {
            const std::size_t i = order[rank];
            const StudyParameter& p = spec.parameters[i];
            const SobolIndex& s = res.indices[i];
            const std::string above = measured ? (s.total > 2 * noise.varianceShare ? "yes" : "no") : "unknown";
            md << "| " << rank + 1 << " | `" << p.key << "` | " << p.describe() << " | " << formatNumber(s.first, 3) << " [" << formatNumber(s.firstLow, 3)
               << ", " << formatNumber(s.firstHigh, 3) << "] | " << formatNumber(s.total, 3) << " [" << formatNumber(s.totalLow, 3) << ", "
               << formatNumber(s.totalHigh, 3) << "]" << (above == "no" ? " (noise)" : "") << " | " << formatNumber(s.total - s.first, 3) << " |\n";
            csv << csvField(out.text) << "," << csvField(out.units()) << "," << csvField(p.key) << "," << formatNumber(p.low, 12) << ","
                << formatNumber(p.high, 12) << "," << (p.logScale ? "log" : "linear") << (p.integer ? " integer" : "") << "," << rank + 1;
            for (double v : {s.first, s.firstLow, s.firstHigh, s.total, s.totalLow, s.totalHigh}) csv << "," << formatNumber(v, 10);
            csv << "," << (measured ? formatNumber(noise.varianceShare, 10) : std::string("")) << "," << formatNumber(res.variance, 10)
                << "," << (std::isfinite(noise.replicateSd) ? formatNumber(noise.replicateSd, 10) : std::string("")) << "," << above << "\n";
            summary << (rank == 0 ? " " : ", ") << p.key << " S " << formatNumber(s.first, 2) << " ST " << formatNumber(s.total, 2)
                    << (above == "no" ? " (noise)" : "");
        }
        summary << "\n";
        const std::string png = reportPngPath(spec, "sobol", o);
        writeSobolPng(png, spec, out, res, noise);
        md << "\n![S and ST](png/sobol_" << o + 1 << ".png)\n";
        rep.pngPaths.push_back(png);
    }
    return finishReport(std::move(rep), spec, outputs, csv, md, summary);
}

}  // namespace eco::pipeline
