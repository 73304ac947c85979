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

int parseYear(const std::string& s, const std::string& where, const std::string& text) {
    if (s.empty() || s.size() > 6 || !std::all_of(s.begin(), s.end(), [](char c) { return c >= '0' && c <= '9'; }))
        throw ValidationError(where + ": output '" + text + "': '" + s + "' is not a year (a whole number)");
    return std::stoi(s);
}

double mean(const std::vector<double>& v) { return v.empty() ? 0.0 : std::accumulate(v.begin(), v.end(), 0.0) / static_cast<double>(v.size()); }

}  // namespace

std::string SensitivityOutput::units() const {
    switch (measure) {
        case Measure::Share: return "fraction of undergrowth plants";
        case Measure::Density: return "plants per m2";
        case Measure::MeanHeight: return "m";
        case Measure::Cover: return "crown area per m2";
        case Measure::CountCv: return "coefficient of variation";
    }
    return "";
}

SensitivityOutput parseSensitivityOutput(const std::string& text, const std::string& where) {
    SensitivityOutput o;
    o.text = text;
    const auto at = text.find('@');
    if (at == std::string::npos)
        throw ValidationError(where + ": output '" + text + "': expected MEASURE[:SPECIES]@YEAR (e.g. share:Toyon@30, density@30) or cv@FIRST-LAST");
    std::string head = text.substr(0, at);
    const std::string when = text.substr(at + 1);
    const auto colon = head.find(':');
    if (colon != std::string::npos) {
        o.species = head.substr(colon + 1);
        head = head.substr(0, colon);
        if (o.species.empty()) throw ValidationError(where + ": output '" + text + "': empty species name after ':'");
    }
    if (head == "share") o.measure = SensitivityOutput::Measure::Share;
    else if (head == "density") o.measure = SensitivityOutput::Measure::Density;
    else if (head == "mean_height") o.measure = SensitivityOutput::Measure::MeanHeight;
    else if (head == "cover") o.measure = SensitivityOutput::Measure::Cover;
    else if (head == "cv") o.measure = SensitivityOutput::Measure::CountCv;
    else
        throw ValidationError(where + ": output '" + text + "': unknown measure '" + head +
                              "' (share, density, mean_height, cover or cv)");
    if (o.measure == SensitivityOutput::Measure::Share && o.species.empty())
        throw ValidationError(where + ": output '" + text + "': share needs a species (share:SPECIES@YEAR)");
    if (o.measure == SensitivityOutput::Measure::Density && !o.species.empty())
        throw ValidationError(where + ": output '" + text + "': density is of all undergrowth (share:SPECIES gives a species' part)");
    if (o.measure == SensitivityOutput::Measure::CountCv) {
        if (!o.species.empty()) throw ValidationError(where + ": output '" + text + "': cv is of the total plant count (no species)");
        const auto dash = when.find('-');
        if (dash == std::string::npos) throw ValidationError(where + ": output '" + text + "': cv needs a window of years, cv@FIRST-LAST");
        o.year = parseYear(when.substr(0, dash), where, text);
        o.yearEnd = parseYear(when.substr(dash + 1), where, text);
        if (o.yearEnd <= o.year) throw ValidationError(where + ": output '" + text + "': the window's last year must follow its first");
    } else {
        o.year = o.yearEnd = parseYear(when, where, text);
    }
    return o;
}

SensitivitySpec loadSensitivitySpec(const std::string& path, const std::string& outOverride) {
    const toml::table root = parseTomlFile(path);
    StrictTable top(root, path, "");
    SensitivitySpec spec;
    spec.path = path;
    StrictTable s(top.table("sensitivity"), path, "[sensitivity]");
    spec.outDir = outOverride.empty() ? s.string("out_dir") : outOverride;
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
            SensitivityParameter p;
            p.key = key;
            const auto num = [&](std::size_t i) {
                const toml::node* n = a->get(i);
                if (const auto* f = n->as_floating_point()) return f->get();
                if (const auto* in = n->as_integer()) return static_cast<double>(in->get());
                throw ValidationError(where + ": expected numbers [LOW, HIGH]");
            };
            p.low = num(0);
            p.high = num(1);
            if (!std::isfinite(p.low) || !std::isfinite(p.high) || !(p.low < p.high))
                throw ValidationError(where + ": expected LOW < HIGH, got [" + formatNumber(p.low, 10) + ", " + formatNumber(p.high, 10) + "]");
            if (key == "run.seed") throw ValidationError(where + ": run.seed is the replicates' own key");
            if (key.find('.') == std::string::npos) throw ValidationError(where + ": expected TABLE.KEY (e.g. biome.species.Toyon.alpha)");
            spec.parameters.push_back(p);
        }
        if (spec.parameters.empty()) s.fail("parameters", "no parameter to vary");
        if (spec.parameters.size() > 200) s.fail("parameters", "more than 200 parameters");
    }
    for (const std::string& o : s.strings("outputs")) spec.outputs.push_back(parseSensitivityOutput(o, path + ": [sensitivity] outputs"));
    if (spec.outputs.empty()) s.fail("outputs", "no output to measure");
    if (const toml::node& b = s.node("base"); const auto* file = b.as_string()) {
        spec.base = parseTomlFile(file->get());
    } else if (const auto* t = b.as_table()) {
        spec.base = *t;
    } else {
        s.fail("base", "expected an eco run configuration file name or a table [sensitivity.base]");
    }
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

namespace {

double physical(const SensitivityParameter& p, double unit) { return p.low + unit * (p.high - p.low); }

std::string ensembleDir(const SensitivitySpec& spec) { return (fs::path(spec.outDir) / "ensemble").string(); }

}  // namespace

std::string writeSensitivityEnsemble(const SensitivitySpec& spec, const MorrisDesign& design) {
    toml::table ensemble;
    ensemble.insert("out_dir", ensembleDir(spec));
    ensemble.insert("database", false);
    ensemble.insert("members_at_once", static_cast<std::int64_t>(spec.membersAtOnce));
    ensemble.insert("base", spec.base);
    toml::array members;
    std::ostringstream csv;
    csv << "trajectory,point,moved";
    for (const auto& p : spec.parameters) csv << "," << p.key;
    csv << "\n";
    for (int t = 0; t < design.trajectories; ++t)
        for (std::size_t j = 0; j < design.points[static_cast<std::size_t>(t)].size(); ++j) {
            const auto& x = design.points[static_cast<std::size_t>(t)][j];
            csv << t + 1 << "," << j << "," << (j == 0 ? std::string("") : spec.parameters[static_cast<std::size_t>(design.moved[static_cast<std::size_t>(t)][j - 1])].key);
            for (std::size_t i = 0; i < x.size(); ++i) csv << "," << formatNumber(physical(spec.parameters[i], x[i]), 12);
            csv << "\n";
            for (int r = 0; r < spec.replicates; ++r) {
                toml::table m;
                m.insert("name", sensitivityMemberName(t, static_cast<int>(j), r));
                for (std::size_t i = 0; i < x.size(); ++i) m.insert(spec.parameters[i].key, physical(spec.parameters[i], x[i]));
                m.insert("run.seed", static_cast<std::int64_t>(r + 1));
                members.push_back(std::move(m));
            }
        }
    toml::table root;
    root.insert("ensemble", std::move(ensemble));
    root.insert("member", std::move(members));
    std::ostringstream text;
    text << "# The members of eco sensitivity " << spec.path << ": one per Morris design point and replicate\n"
         << "# (written by eco sensitivity; run.seed is the replicate).\n"
         << root << "\n";
    ensureDirectory(spec.outDir);
    const std::string path = (fs::path(spec.outDir) / "ensemble.toml").string();
    if (!fs::exists(path) || readTextFile(path) != text.str()) writeTextFile(path, text.str());
    const std::string designPath = (fs::path(spec.outDir) / "design.csv").string();
    if (!fs::exists(designPath) || readTextFile(designPath) != csv.str()) writeTextFile(designPath, csv.str());
    return path;
}

double measureOutput(const std::string& simulationPath, const SensitivityOutput& output) {
    const h5::File f = h5::File::openRead(simulationPath);
    if (!f.hasAttr("/", "format") || f.attrString("/", "format") != kSimulationFormat)
        throw IoError(simulationPath + ": not an eco-simulation file");
    const std::vector<std::string> names = f.readStrings("/species_names");
    const std::vector<YearRecord> series = readTimeseries(f, "/timeseries", names.size());
    const double area = (f.attrDouble("/", "x1") - f.attrDouble("/", "x0")) * (f.attrDouble("/", "y1") - f.attrDouble("/", "y0"));
    if (!(area > 0)) throw IoError(simulationPath + ": the simulated area (x0, y0, x1, y1) is empty");
    int species = -1;
    if (!output.species.empty()) {
        const auto it = std::find(names.begin(), names.end(), output.species);
        if (it == names.end()) throw ValidationError(simulationPath + ": output '" + output.text + "': no species '" + output.species + "' in the simulation's biome");
        species = static_cast<int>(it - names.begin());
    }
    const auto record = [&](int year) -> const YearRecord& {
        for (const YearRecord& r : series)
            if (r.year == year) return r;
        throw ValidationError(simulationPath + ": output '" + output.text + "': year " + std::to_string(year) + " is not in its time series (years " +
                              (series.empty() ? std::string("none") : std::to_string(series.front().year) + " .. " + std::to_string(series.back().year)) + ")");
    };
    const auto total = [](const YearRecord& r) {
        double n = 0;
        for (auto c : r.count) n += c;
        return n;
    };
    using M = SensitivityOutput::Measure;
    if (output.measure == M::CountCv) {
        std::vector<double> counts;
        for (int y = output.year; y <= output.yearEnd; ++y) counts.push_back(total(record(y)));
        const double m = mean(counts);
        double sq = 0;
        for (double c : counts) sq += (c - m) * (c - m);
        return m > 0 ? std::sqrt(sq / static_cast<double>(counts.size())) / m : 0.0;
    }
    const YearRecord& r = record(output.year);
    const auto s = static_cast<std::size_t>(species);
    switch (output.measure) {
        case M::Share: {
            const double n = total(r);
            return n > 0 ? r.count[s] / n : 0.0;
        }
        case M::Density: return total(r) / area;
        case M::MeanHeight: {
            if (species >= 0) return r.meanHeightM[s];
            double h = 0;
            for (std::size_t i = 0; i < r.count.size(); ++i) h += r.count[i] * r.meanHeightM[i];
            const double n = total(r);
            return n > 0 ? h / n : 0.0;
        }
        case M::Cover: {
            if (species >= 0) return r.crownAreaM2[s] / area;
            return std::accumulate(r.crownAreaM2.begin(), r.crownAreaM2.end(), 0.0) / area;
        }
        case M::CountCv: break;
    }
    return 0;
}

namespace {

/// mu* against sigma, one marker per parameter with its name, and the seed-noise level of
/// mu* (twice it: the threshold of the report) as a dashed vertical line.
void writeMorrisPng(const std::string& path, const SensitivitySpec& spec, const SensitivityOutput& out,
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
        const SensitivityOutput& out = spec.outputs[o];
        std::vector<std::vector<double>> y(static_cast<std::size_t>(design.trajectories));
        std::vector<std::vector<std::vector<double>>> values(static_cast<std::size_t>(design.trajectories));
        for (int t = 0; t < design.trajectories; ++t)
            for (std::size_t j = 0; j <= k; ++j) {
                std::vector<double> reps;
                for (int r = 0; r < spec.replicates; ++r) {
                    const std::string sim = (fs::path(ensembleDir(spec)) / "members" / sensitivityMemberName(t, static_cast<int>(j), r) / "simulation.h5").string();
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
            const SensitivityParameter& p = spec.parameters[i];
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
