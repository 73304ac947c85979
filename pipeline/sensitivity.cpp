#include "sensitivity.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <numeric>
#include <sstream>

#include "atomic_file.h"
#include "chart.h"
#include "error.h"
#include "h5io.h"
#include "image_out.h"
#include "rng.h"
#include "sim_file.h"
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
    if (method != "morris") s.fail("method", "'" + method + "' is not supported (morris)");
    spec.trajectories = static_cast<int>(s.integerOr("trajectories", spec.trajectories));
    if (spec.trajectories < 2 || spec.trajectories > 1000) s.fail("trajectories", "must be in 2 .. 1000");
    spec.levels = static_cast<int>(s.integerOr("levels", spec.levels));
    if (spec.levels < 2 || spec.levels > 20 || spec.levels % 2 != 0) s.fail("levels", "must be even, in 2 .. 20");
    spec.replicates = static_cast<int>(s.integerOr("replicates", spec.replicates));
    if (spec.replicates < 1 || spec.replicates > 100) s.fail("replicates", "must be in 1 .. 100");
    const std::int64_t seed = s.integerOr("seed", 1);
    if (seed < 0) s.fail("seed", "must not be negative");
    spec.seed = static_cast<std::uint64_t>(seed);
    spec.membersAtOnce = static_cast<int>(s.integerOr("members_at_once", 1));
    if (spec.membersAtOnce < 1 || spec.membersAtOnce > 256) s.fail("members_at_once", "must be in 1 .. 256");
    {
        const toml::table& params = s.table("parameters");
        for (const auto& [k, v] : params) {
            const std::string key(k.str());
            const std::string where = path + ": [sensitivity.parameters] '" + key + "'";
            const auto* a = v.as_array();
            if (!a || a->size() != 2) throw ValidationError(where + ": expected [LOW, HIGH]");
            const auto num = [&](std::size_t i) {
                const toml::node* n = a->get(i);
                if (const auto* f = n->as_floating_point()) return f->get();
                if (const auto* in = n->as_integer()) return static_cast<double>(in->get());
                throw ValidationError(where + ": expected numbers [LOW, HIGH]");
            };
            const StudyParameter p = makeStudyParameter(key, num(0), num(1), where);
            spec.parameters.push_back(p);
        }
        if (spec.parameters.empty()) s.fail("parameters", "no parameter to vary");
        if (spec.parameters.size() > 200) s.fail("parameters", "more than 200 parameters");
    }
    for (const std::string& o : s.strings("outputs")) spec.outputs.push_back(parseSimulationOutput(o, path + ": [sensitivity] outputs"));
    if (spec.outputs.empty()) s.fail("outputs", "no output to measure");
    spec.base = studyBase(s.node("base"), path, path + ": [sensitivity] base");
    s.finish();
    top.finish();
    const std::size_t members = static_cast<std::size_t>(spec.trajectories) * (spec.parameters.size() + 1) *
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
            md << "| " << rank + 1 << " | `" << p.key << "` | " << formatNumber(p.low, 6) << " .. " << formatNumber(p.high, 6) << " | "
               << formatNumber(s.muStar, 4) << " | " << formatNumber(s.mu, 4) << " | " << formatNumber(s.sigma, 4) << " | " << ratio
               << (above == "no" ? " (noise)" : "") << " |\n";
            csv << csvField(out.text) << "," << csvField(out.units()) << "," << csvField(p.key) << "," << formatNumber(p.low, 12) << ","
                << formatNumber(p.high, 12) << "," << rank + 1 << "," << formatNumber(s.muStar, 10) << "," << formatNumber(s.mu, 10) << ","
                << formatNumber(s.sigma, 10) << "," << s.effects << "," << (measured ? formatNumber(noise.muStarNoise, 10) : std::string("")) << ","
                << (std::isfinite(noise.replicateSd) ? formatNumber(noise.replicateSd, 10) : std::string("")) << "," << above << "\n";
            summary << (rank == 0 ? " " : ", ") << p.key << " " << formatNumber(s.muStar, 3) << (above == "no" ? " (noise)" : "");
        }
        summary << "\n";
        const std::string png = (fs::path(spec.outDir) / "png" / ("morris_" + std::to_string(o + 1) + ".png")).string();
        ensureDirectory((fs::path(spec.outDir) / "png").string());
        writeMorrisPng(png, spec, out, stats, noise);
        md << "\n![mu* against sigma](png/morris_" << o + 1 << ".png)\n";
        rep.pngPaths.push_back(png);
    }
    rep.csvPath = (fs::path(spec.outDir) / "sensitivity.csv").string();
    rep.markdownPath = (fs::path(spec.outDir) / "sensitivity.md").string();
    writeTextFile(rep.csvPath, csv.str());
    writeTextFile(rep.markdownPath, md.str());
    outputs.commit();
    rep.summary = summary.str();
    return rep;
}

}  // namespace eco::pipeline
