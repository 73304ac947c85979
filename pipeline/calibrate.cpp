#include "calibrate.h"

#include <nlopt.h>

#include <Eigen/Dense>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <condition_variable>
#include <exception>
#include <filesystem>
#include <map>
#include <mutex>
#include <numeric>
#include <sstream>
#include <thread>

#include "atomic_file.h"
#include "biome.h"
#include "ensemble.h"
#include "chart.h"
#include "error.h"
#include "image_out.h"
#include "rng.h"
#include "sobol_sequence.h"
#include "strict_toml.h"
#include "text_format.h"

namespace eco::pipeline {

namespace fs = std::filesystem;

namespace {

/// The replicates' seeds as the report states them.
std::string sceneOrSeeds(const CalibrationSpec& spec) {
    if (spec.scene.file.empty()) return "run.seed 1 .. " + std::to_string(spec.replicates);
    std::string seeds;
    for (std::uint64_t s : spec.scene.seeds) seeds += (seeds.empty() ? "" : ", ") + std::to_string(s);
    return "the forest scene `" + spec.scene.file + "`, " + formatNumber(spec.scene.plotSizeM, 6) + " m, " + std::to_string(spec.scene.years) +
           " years, scene seeds " + seeds;
}


/// The shortest text of a double that reads back as the same number, with a decimal point.
std::string shortestNumber(double v) {
    char buf[64];
    std::string number(buf, std::to_chars(buf, buf + sizeof buf, v).ptr);
    if (number.find_first_of(".eEn") == std::string::npos) number += ".0";
    return number;
}


nlopt_algorithm algorithmOf(const std::string& name) {
    if (name == "sbplx") return NLOPT_LN_SBPLX;
    if (name == "neldermead") return NLOPT_LN_NELDERMEAD;
    if (name == "bobyqa") return NLOPT_LN_BOBYQA;
    if (name == "cobyla") return NLOPT_LN_COBYLA;
    throw ValidationError("unknown algorithm '" + name + "'");
}

bool convergedBy(nlopt_result r) { return r == NLOPT_SUCCESS || r == NLOPT_XTOL_REACHED || r == NLOPT_FTOL_REACHED || r == NLOPT_STOPVAL_REACHED; }

std::string stopText(nlopt_result r) {
    switch (r) {
        case NLOPT_SUCCESS: return "converged";
        case NLOPT_STOPVAL_REACHED: return "chi2 reached its stop value";
        case NLOPT_FTOL_REACHED: return "chi2 changed less than the tolerance";
        case NLOPT_XTOL_REACHED: return "the parameters changed less than the tolerance";
        case NLOPT_MAXEVAL_REACHED: return "max_evaluations reached";
        case NLOPT_MAXTIME_REACHED: return "time limit reached";
        case NLOPT_ROUNDOFF_LIMITED: return "stopped by round-off";
        case NLOPT_FORCED_STOP: return "stopped";
        default: return "the optimiser failed (NLopt code " + std::to_string(static_cast<int>(r)) + ")";
    }
}

std::string joinValues(const std::vector<StudyParameter>& params, const std::vector<double>& v) {
    std::string s;
    for (std::size_t i = 0; i < params.size(); ++i) s += (i ? ", " : "") + params[i].key + " = " + formatNumber(v[i], 6);
    return s;
}

}  // namespace

CalibrationSpec loadCalibrationSpec(const std::string& path, const std::string& outOverride) {
    const toml::table root = parseTomlFile(path);
    StrictTable top(root, path, "");
    CalibrationSpec spec;
    spec.path = path;
    StrictTable c(top.table("calibrate"), path, "[calibrate]");
    spec.outDir = outOverride.empty() ? pathRelativeToConfig(path, c.string("out_dir")) : outOverride;
    if (!outOverride.empty() && c.has("out_dir")) c.string("out_dir");
    spec.algorithm = c.stringOr("algorithm", spec.algorithm);
    try {
        algorithmOf(spec.algorithm);
    } catch (const ValidationError&) {
        c.fail("algorithm", "'" + spec.algorithm + "' is not one of sbplx, neldermead, bobyqa, cobyla");
    }
    // A whole number in lo .. hi; the message names the key and the value given.
    const auto count = [&c](const std::string& key, std::int64_t lo, std::int64_t hi, std::int64_t fallback) {
        const std::int64_t v = c.integerOr(key, fallback);
        if (v < lo || v > hi) c.fail(key, "must be in " + std::to_string(lo) + " .. " + std::to_string(hi) + ", got " + std::to_string(v));
        return static_cast<int>(v);
    };
    spec.maxEvaluations = count("max_evaluations", 2, 10000, spec.maxEvaluations);
    spec.replicates = count("replicates", 1, 100, spec.replicates);
    spec.tolerance = c.numberInOr("tolerance", 1e-9, 0.5, spec.tolerance);
    spec.initialStep = c.numberInOr("initial_step", 1e-3, 1.0, spec.initialStep);
    spec.uncertainty = c.booleanOr("uncertainty", spec.uncertainty);
    spec.global = c.stringOr("global", spec.global);
    if (spec.global != "none" && spec.global != "multistart" && spec.global != "crs" && spec.global != "crs2" && spec.global != "isres")
        c.fail("global", "'" + spec.global + "' is not one of none, multistart, crs, crs2, isres");
    if (spec.global == "multistart") {
        spec.starts = count("starts", 2, 100, spec.starts);
        spec.parallelStarts = c.booleanOr("parallel_starts", spec.parallelStarts);
        if (spec.parallelStarts && spec.maxEvaluations < 2 * spec.starts)
            c.fail("max_evaluations", "must be at least 2 x starts (" + std::to_string(2 * spec.starts) + ") with parallel_starts: each start gets max_evaluations / starts, got " +
                                          std::to_string(spec.maxEvaluations));
    } else {
        for (const char* key : {"starts", "parallel_starts"})
            if (c.has(key)) c.fail(key, "is a key of global = \"multistart\" (global is \"" + spec.global + "\")");
    }
    if (spec.global == "crs" || spec.global == "crs2" || spec.global == "isres") {
        spec.globalEvaluations = count("global_evaluations", 2, spec.maxEvaluations - 1, spec.maxEvaluations / 2);
    } else if (c.has("global_evaluations")) {
        c.fail("global_evaluations", "is a key of global = \"crs\", \"crs2\" or \"isres\" (global is \"" + spec.global + "\")");
    }
    // crs: the population and the round's size (checked against the parameters' number below).
    if (spec.global == "crs") {
        if (c.has("population")) spec.population = count("population", 2, 10000, 0);
        if (c.has("batch")) spec.batchSize = count("batch", 1, 10000, 0);
    } else {
        for (const char* key : {"population", "batch"})
            if (c.has(key)) c.fail(key, "is a key of global = \"crs\" (global is \"" + spec.global + "\")");
    }
    if (spec.global == "none" && c.has("seed")) c.fail("seed", "is a key of a global search (global = multistart, crs, crs2 or isres)");
    {
        const std::int64_t seed = c.integerOr("seed", 1);
        if (seed < 0) c.fail("seed", "must not be negative, got " + std::to_string(seed));
        spec.seed = static_cast<std::uint64_t>(seed);
    }
    spec.membersAtOnce = count("members_at_once", 1, 256, 1);
    // The optimiser's coordinates: the keys in sorted order (toml++ keeps a table sorted), or
    // as written in the file (parameters_as_written: Subplex's subspaces and first steps
    // follow the coordinates' order, so the order changes the search's path).
    const bool asWritten = c.booleanOr("parameters_as_written", false);
    std::vector<std::pair<std::string, const toml::node*>> entries;
    for (const auto& [k, v] : c.table("parameters")) entries.emplace_back(std::string(k.str()), &v);
    if (asWritten)
        std::stable_sort(entries.begin(), entries.end(), [](const auto& a, const auto& b) {
            const auto& x = a.second->source().begin;
            const auto& y = b.second->source().begin;
            return x.line != y.line ? x.line < y.line : x.column < y.column;
        });
    for (const auto& [k, vp] : entries) {
        const toml::node& v = *vp;
        double start = 0;
        const StudyParameter p = parseStudyParameter(k, v, path, "[calibrate.parameters]", &start);
        spec.parameters.push_back(p);
        // Default: the middle of the range (of its log with a log scale).
        if (std::isnan(start)) start = p.logScale || p.integer ? p.at(0.5) : 0.5 * (p.low + p.high);
        spec.start.push_back(start);
    }
    if (spec.parameters.empty()) c.fail("parameters", "no parameter to fit");
    if (spec.parameters.size() > 50) c.fail("parameters", "more than 50 parameters");
    if (spec.global == "crs") {
        const int k = static_cast<int>(spec.parameters.size());
        const int population = crsPopulation(searchSettingsOf(spec), k);
        if (population < k + 1)
            c.fail("population", "must be at least the number of parameters + 1 (" + std::to_string(k + 1) + "), got " + std::to_string(population));
        if (c.has("batch") && spec.batchSize > population) c.fail("batch", "must be at most the population (" + std::to_string(population) + "), got " + std::to_string(spec.batchSize));
        if (spec.globalEvaluations < population)
            c.fail("global_evaluations", "must be at least the population (" + std::to_string(population) + ": its points are the first round), got " + std::to_string(spec.globalEvaluations));
    }
    if (const toml::table* scene = c.optionalTable("scene")) {
        // eco validate's forest scene instead of eco run pipelines (docs/calibration.md).
        StrictTable sc(*scene, path, "[calibrate.scene]");
        if (c.has("base")) c.fail("base", "is not used with [calibrate.scene] (the members simulate the scene)");
        spec.scene.file = pathRelativeToConfig(path, sc.string("file"));
        if (!fs::is_regular_file(spec.scene.file)) sc.fail("file", "no such file: " + spec.scene.file);
        spec.scene.biome = sc.has("biome") ? pathRelativeToConfig(path, sc.string("biome")) : "";
        if (!spec.scene.biome.empty() && !fs::is_regular_file(spec.scene.biome)) sc.fail("biome", "no such file: " + spec.scene.biome);
        spec.scene.plotSizeM = sc.numberIn("plot_size_m", 8.0, 10000.0);
        const std::int64_t years = sc.integer("years");
        if (years < 1 || years > 100000) sc.fail("years", "must be in 1 .. 100000, got " + std::to_string(years));
        spec.scene.years = static_cast<int>(years);
        for (std::int64_t seed : sc.integers("seeds")) {
            if (seed < 0) sc.fail("seeds", "must not be negative, got " + std::to_string(seed));
            spec.scene.seeds.push_back(static_cast<std::uint64_t>(seed));
        }
        if (spec.scene.seeds.empty() || spec.scene.seeds.size() > 100) sc.fail("seeds", "expected 1 .. 100 scene seeds (one per replicate)");
        if (c.has("replicates") && spec.replicates != static_cast<int>(spec.scene.seeds.size()))
            c.fail("replicates", "is the number of [calibrate.scene] seeds (" + std::to_string(spec.scene.seeds.size()) + "), got " + std::to_string(spec.replicates));
        spec.replicates = static_cast<int>(spec.scene.seeds.size());
        if (const toml::table* model = sc.optionalTable("model"))
            for (const auto& [k, v] : *model) {
                std::ostringstream line;
                if (const auto* f = v.as_floating_point()) {
                    // The shortest text that reads back as the same number (1.1225, not 1.1225000000000001).
                    line << k.str() << " = " << shortestNumber(f->get());
                } else {
                    toml::table one;
                    const toml::key& key = k;  // a lambda cannot capture a structured binding (C++17, clang)
                    v.visit([&](const auto& x) { one.insert(key, x); });
                    line << one;
                }
                spec.scene.model.push_back(line.str());
            }
        sc.finish();
        for (const StudyParameter& p : spec.parameters)
            if (p.key.rfind("biome.", 0) != 0 && p.key.rfind("model.", 0) != 0)
                throw ValidationError(path + ": [calibrate.parameters] '" + p.key + "': with [calibrate.scene] a parameter is a biome.* or model.* key");
        if (!spec.truth.empty() || c.has("truth")) c.fail("truth", "is not supported with [calibrate.scene]");
    } else {
        spec.base = studyBase(c.node("base"), path, path + ": [calibrate] base");
    }
    if (const toml::table* truth = c.optionalTable("truth")) {
        StrictTable t(*truth, path, "[calibrate.truth]");
        for (std::size_t i = 0; i < spec.parameters.size(); ++i) {
            const StudyParameter& p = spec.parameters[i];
            const double v = t.number(p.key);
            if (!(v >= p.low && v <= p.high))
                t.fail(p.key, "the true value " + formatNumber(v, 10) + " lies outside its range [" + formatNumber(p.low, 10) + ", " + formatNumber(p.high, 10) + "]");
            if (p.integer && v != std::floor(v)) t.fail(p.key, "the true value " + formatNumber(v, 10) + " of an integer parameter is not a whole number");
            spec.truth.push_back(v);
        }
        t.finish();
    }
    c.finish();
    const toml::array* targets = top.has("target") ? &top.array("target") : nullptr;
    if (!targets || targets->empty()) throw ValidationError(path + ": no [[target]]: the observations to fit");
    for (std::size_t i = 0; i < targets->size(); ++i) {
        const auto* t = targets->get(i)->as_table();
        const std::string ctx = "[[target]] " + std::to_string(i + 1);
        if (!t) throw ValidationError(path + ": " + ctx + ": expected a table");
        StrictTable tt(*t, path, ctx);
        CalibrationTarget target;
        target.output = parseSimulationOutput(tt.string("output"), path + ": " + ctx);
        if (target.output.measure == SimulationOutput::Measure::PairCorrelation) {
            // A stem map's g(r): the output is the rms difference of the simulated g(r) from
            // it, so the observed value is 0 and sd is the rms difference worth one unit of chi2.
            if (tt.has("value")) tt.fail("value", "a pcf target's observation is its stem_map (the value fitted is 0: no difference)");
            const std::string map = pathRelativeToConfig(path, tt.string("stem_map"));
            const toml::node& w = tt.node("window");
            const auto* wa = w.as_array();
            std::vector<double> win;
            if (wa)
                for (const auto& e : *wa) {
                    if (const auto* f = e.as_floating_point()) win.push_back(f->get());
                    else if (const auto* in = e.as_integer()) win.push_back(static_cast<double>(in->get()));
                }
            if (!wa || win.size() != 4 || wa->size() != 4 || !(win[0] < win[2] && win[1] < win[3]))
                tt.fail("window", "expected [X0, Y0, X1, Y1] with X0 < X1 and Y0 < Y1 (metres, the stem map's window)");
            const RectWindow window{win[0], win[1], win[2], win[3]};
            const double rMax = tt.positive("r_max");
            const int bins = static_cast<int>(tt.integerOr("bins", 20));
            if (bins < 1 || bins > 1000) tt.fail("bins", "must be in 1 .. 1000");
            const double rMin = tt.numberInOr("r_min", 0.0, rMax, 0.0);
            if (rMin >= rMax) tt.fail("r_min", "must be below r_max");
            const double minHeight = tt.numberInOr("min_height", 0.0, 1e4, 0.0);
            if (rMax > 0.5 * std::min(window.widthM(), window.heightM()) + 1e-9)
                tt.fail("r_max", "exceeds half the window's shorter side (" + formatNumber(0.5 * std::min(window.widthM(), window.heightM()), 6) + " m)");
            try {
                target.output.pcf = std::make_shared<const PairCorrelationReference>(
                    pairCorrelationReference(map, window, target.output.species, rMax, bins, rMin, minHeight));
            } catch (const ValidationError& e) {
                throw ValidationError(path + ": " + ctx + ": " + e.what());
            } catch (const IoError& e) {
                throw ValidationError(path + ": " + ctx + ": " + e.what());
            }
            target.value = 0;
        } else {
            for (const char* key : {"stem_map", "window", "r_max", "r_min", "bins", "min_height"})
                if (tt.has(key)) tt.fail(key, "is a key of pcf targets (output = \"pcf[:SPECIES]@YEAR\")");
            const int bounds = (tt.has("value") ? 1 : 0) + (tt.has("min") ? 1 : 0) + (tt.has("max") ? 1 : 0);
            if (bounds > 1) tt.fail(tt.has("min") ? "min" : "max", "give one of value (two-sided), min or max (one-sided)");
            if (tt.has("min") || tt.has("max")) {
                if (!spec.truth.empty()) tt.fail(tt.has("min") ? "min" : "max", "one-sided targets are not fitted to a [calibrate.truth]");
                target.side = tt.has("min") ? CalibrationTarget::Side::AtLeast : CalibrationTarget::Side::AtMost;
                target.value = tt.number(tt.has("min") ? "min" : "max");
            } else {
                // Without a value only when the truth gives it.
                target.value = spec.truth.empty() ? tt.number("value") : tt.numberOr("value", std::nan(""));
            }
        }
        target.sd = tt.positive("sd");
        tt.finish();
        spec.targets.push_back(target);
    }
    top.finish();
    return spec;
}

std::string calibrationMemberName(int evaluation, int replicate) {
    char buf[32];
    std::snprintf(buf, sizeof buf, "e%04d-r%02d", evaluation, replicate + 1);
    return buf;
}

double CalibrationTarget::residual(double simulated) const {
    double d = simulated - value;
    if ((side == Side::AtLeast && d > 0) || (side == Side::AtMost && d < 0)) d = 0;
    return d / sd;
}

double chiSquare(const std::vector<CalibrationTarget>& targets, const std::vector<double>& simulated) {
    double chi2 = 0;
    for (std::size_t t = 0; t < targets.size(); ++t) {
        const double r = targets[t].residual(simulated.at(t));
        chi2 += r * r;
    }
    return chi2;
}

std::vector<double> linearisedSd(const std::vector<std::vector<double>>& jacobian) {
    const std::size_t rows = jacobian.size(), cols = rows ? jacobian[0].size() : 0;
    std::vector<double> sd(cols, std::nan(""));
    if (rows == 0 || cols == 0) return sd;
    Eigen::MatrixXd j(static_cast<Eigen::Index>(rows), static_cast<Eigen::Index>(cols));
    for (std::size_t r = 0; r < rows; ++r)
        for (std::size_t c = 0; c < cols; ++c) j(static_cast<Eigen::Index>(r), static_cast<Eigen::Index>(c)) = jacobian[r][c];
    // Columns scaled to unit length first, so that parameters of very different units do not
    // make a well-posed problem look singular.
    Eigen::VectorXd scale = j.colwise().norm().transpose();
    for (Eigen::Index c = 0; c < scale.size(); ++c)
        if (!(scale(c) > 0)) return sd;  // a parameter that moves no target: nothing is identifiable about it
    const Eigen::MatrixXd js = j * scale.cwiseInverse().asDiagonal();
    const Eigen::MatrixXd jtj = js.transpose() * js;
    const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(jtj);
    if (eig.eigenvalues().minCoeff() <= 1e-10 * eig.eigenvalues().maxCoeff()) return sd;
    const Eigen::MatrixXd cov = jtj.inverse();
    for (std::size_t c = 0; c < cols; ++c) sd[c] = std::sqrt(cov(static_cast<Eigen::Index>(c), static_cast<Eigen::Index>(c))) / scale(static_cast<Eigen::Index>(c));
    return sd;
}

namespace {

class Calibrator {
public:
    Calibrator(const CalibrationSpec& spec, const MemberRunner& run, Reporter& reporter, std::vector<StudyMember> members,
               const SceneRunner& scene)
        : spec_(spec), run_(run), scene_(scene), reporter_(reporter), members_(std::move(members)) {}

    /// chi2 at these parameter values (evaluated once; a repeated point is looked up).
    const Evaluation& evaluate(const std::vector<double>& values, const std::string& purpose) {
        return history_[evaluateAll({values}, purpose).front()];
    }

    /// Several points at once: the new ones (a point seen before, or twice in the list, is
    /// simulated once) become evaluations in the order given, and all their simulations run as
    /// one ensemble run (side by side in members_at_once children or MPI ranks). Returns each
    /// point's index into the history.
    std::vector<std::size_t> evaluateAll(const std::vector<std::vector<double>>& points, const std::string& purpose) {
        std::vector<std::size_t> at;
        std::vector<std::size_t> fresh;  // history indices added now
        std::vector<SceneMember> sceneMembers;  // with [calibrate.scene]: the new simulations
        for (const auto& values : points) {
            if (const auto it = seen_.find(values); it != seen_.end()) {
                at.push_back(it->second);
                continue;
            }
            Evaluation e;
            e.index = static_cast<int>(history_.size()) + 1;
            e.purpose = purpose;
            e.values = values;
            for (int r = 0; r < spec_.replicates; ++r) members_.push_back({calibrationMemberName(e.index, r), values, r + 1});
            if (!spec_.scene.file.empty())
                for (int r = 0; r < spec_.replicates; ++r)
                    sceneMembers.push_back(sceneMember(calibrationMemberName(e.index, r), values, spec_.scene.seeds[static_cast<std::size_t>(r)]));
            seen_[values] = history_.size();
            at.push_back(history_.size());
            fresh.push_back(history_.size());
            history_.push_back(std::move(e));
        }
        if (fresh.empty()) return at;
        if (!spec_.scene.file.empty()) {
            if (!scene_) throw ValidationError(spec_.path + ": [calibrate.scene] needs a scene runner (eco calibrate)");
            scene_(spec_.scene, sceneMembers);
        } else
        writer_ = run_(writeStudyEnsemble(spec_.outDir, spec_.base, spec_.membersAtOnce, spec_.parameters, members_,
                                          "# The simulations of eco calibrate " + spec_.path + ": one per evaluation and replicate\n"
                                          "# (written by eco calibrate; run.seed is the replicate).\n"));
        for (std::size_t h : fresh) {
            Evaluation& e = history_[h];
            for (const CalibrationTarget& t : spec_.targets) {
                std::vector<double> reps;
                for (int r = 0; r < spec_.replicates; ++r) reps.push_back(measureOutput(studySimulation(spec_.outDir, calibrationMemberName(e.index, r)), t.output));
                const double m = std::accumulate(reps.begin(), reps.end(), 0.0) / static_cast<double>(reps.size());
                double sq = 0;
                for (double v : reps) sq += (v - m) * (v - m);
                e.simulated.push_back(m);
                e.spread.push_back(reps.size() > 1 ? std::sqrt(sq / static_cast<double>(reps.size() - 1)) : 0.0);
            }
            e.chi2 = chiSquare(spec_.targets, e.simulated);
            if (h == 0 || e.chi2 < history_[best_].chi2) best_ = h;
            if (writer_)
                reporter_.info("calibrate: evaluation " + std::to_string(e.index) + " (" + purpose + "): " + joinValues(spec_.parameters, e.values) +
                               "; chi2 = " + formatNumber(e.chi2, 5) + " (best " + formatNumber(history_[best_].chi2, 5) + ")");
        }
        return at;
    }

    std::vector<Evaluation>& history() { return history_; }
    std::size_t best() const { return best_; }
    /// Whether this process writes the outputs (rank 0 under MPI); known after the first run.
    bool writer() const { return writer_; }

private:
    /// A scene simulation's folder (where an ensemble member's would be), its biome file (the
    /// base biome with the biome.* values) and its [model] lines (the model.* values last).
    SceneMember sceneMember(const std::string& name, const std::vector<double>& values, std::uint64_t seed) const {
        SceneMember m;
        m.dir = fs::path(studySimulation(spec_.outDir, name)).parent_path().string();
        m.seed = seed;
        m.model = spec_.scene.model;
        toml::table biome = spec_.scene.biome.empty() ? toml::parse(biomeToToml(defaultBiome())) : parseTomlFile(spec_.scene.biome);
        for (std::size_t i = 0; i < spec_.parameters.size(); ++i) {
            const StudyParameter& p = spec_.parameters[i];
            const auto parts = splitKey(p.key);
            const std::string where = spec_.path + ": [calibrate.parameters] '" + p.key + "'";
            if (parts[0] == "biome") {
                if (p.integer) setPath(biome, parts, 1, toml::value<std::int64_t>(std::llround(values[i])), where);
                else setPath(biome, parts, 1, toml::value<double>(values[i]), where);
            } else {
                const std::string key = p.key.substr(6);
                m.model.push_back(key + " = " + (p.integer ? std::to_string(std::llround(values[i])) : shortestNumber(values[i])));
            }
        }
        ensureDirectory(m.dir);
        m.biomePath = (fs::path(m.dir) / "biome.toml").string();
        std::ostringstream text;
        text << biome;
        writeTextFile(m.biomePath, text.str() + "\n");
        return m;
    }

    const CalibrationSpec& spec_;
    const MemberRunner& run_;
    const SceneRunner& scene_;
    Reporter& reporter_;
    std::vector<StudyMember> members_;
    std::vector<Evaluation> history_;
    std::map<std::vector<double>, std::size_t> seen_;
    std::size_t best_ = 0;
    bool writer_ = true;
};

struct CubeObjective {
    const std::function<double(const std::vector<double>&)>* f;
    nlopt_opt opt;
    std::exception_ptr error;
    int calls = 0;
};

double cubeObjective(unsigned n, const double* u, double* /*grad*/, void* data) {
    auto* o = static_cast<CubeObjective*>(data);
    try {
        std::vector<double> x(n);
        for (unsigned i = 0; i < n; ++i) x[i] = std::clamp(u[i], 0.0, 1.0);
        ++o->calls;
        const double v = (*o->f)(x);
        return std::isnan(v) ? HUGE_VAL : v;
    } catch (...) {
        // No exception may cross NLopt's C frames: kept, and rethrown after the optimiser stops.
        o->error = std::current_exception();
        nlopt_force_stop(o->opt);
        return HUGE_VAL;
    }
}

/// One NLopt run in the unit cube from `start`.
SearchRun runOptimiser(const std::function<double(const std::vector<double>&)>& f, nlopt_algorithm algorithm, const std::string& name,
                       const std::vector<double>& start, int maxEvaluations, const SearchSettings& s, bool global) {
    const auto k = static_cast<unsigned>(start.size());
    nlopt_opt opt = nlopt_create(algorithm, k);
    if (!opt) throw ValidationError("calibrate: NLopt could not create its optimiser");
    CubeObjective data{&f, opt, nullptr, 0};
    const std::vector<double> lower(k, 0.0), upper(k, 1.0);
    nlopt_set_lower_bounds(opt, lower.data());
    nlopt_set_upper_bounds(opt, upper.data());
    nlopt_set_min_objective(opt, cubeObjective, &data);
    nlopt_set_maxeval(opt, maxEvaluations);
    // The tolerance is a fraction of each range (docs/calibration.md): an absolute step in
    // the unit cube. (xtol_rel alone is relative to |x|: near a range's lower end, where the
    // unit coordinate is small, it asked for far smaller steps than the ranges' tolerance.)
    nlopt_set_xtol_rel(opt, s.tolerance);
    nlopt_set_xtol_abs1(opt, s.tolerance);
    if (!global) nlopt_set_initial_step1(opt, s.initialStep);
    // The global methods draw their points from NLopt's generator: seeded, so that the same
    // settings give the same points (and a rerun replays them over finished simulations).
    if (global) nlopt_srand(static_cast<unsigned long>(s.seed));
    SearchRun run;
    run.method = name;
    run.start = start;
    std::vector<double> u = start;
    double minimum = HUGE_VAL;
    const nlopt_result status = nlopt_optimize(opt, u.data(), &minimum);
    nlopt_destroy(opt);
    if (data.error) std::rethrow_exception(data.error);
    for (double& v : u) v = std::clamp(v, 0.0, 1.0);
    run.best = u;
    run.value = minimum;
    run.evaluations = data.calls;
    run.stopReason = stopText(status);
    run.converged = convergedBy(status);
    return run;
}

/// log10(chi2) of each evaluation, the search in blue, the uncertainty's in grey.
void writeConvergencePng(const std::string& path, const CalibrationResult& r) {
    ChartSeries search, extra, best;
    search.name = "search";
    search.colour = {0.12f, 0.47f, 0.71f};
    search.strokeOffsetsPx = {0, 1};
    search.pointRadiusPx = 3;
    extra.colour = {0.55f, 0.55f, 0.55f};
    extra.strokeOffsetsPx = {};
    extra.pointRadiusPx = 3;
    best.colour = {0.84f, 0.15f, 0.16f};
    best.strokeOffsetsPx = {};
    best.pointRadiusPx = 6;
    double lo = 1e300, hi = -1e300;
    for (const Evaluation& e : r.history) {
        const double y = std::log10(std::max(e.chi2, 1e-6));
        (e.purpose == "search" ? search : extra).x.push_back(e.index);
        (e.purpose == "search" ? search : extra).y.push_back(y);
        lo = std::min(lo, y);
        hi = std::max(hi, y);
    }
    best.x = {static_cast<double>(r.history[r.best].index)};
    best.y = {std::log10(std::max(r.history[r.best].chi2, 1e-6))};
    const double pad = std::max(0.1, 0.08 * (hi - lo));
    Canvas c = chartCanvas({search, extra, best}, 0, static_cast<double>(r.history.size()) + 1, std::floor(lo - pad), std::ceil(hi + pad),
                           "evaluation (blue: search, grey: uncertainty; red: best)", "log10 chi2");
    c.writePng(path);
}

/// The local searches of a multistart side by side, in rounds (docs/calibration.md,
/// parallel_starts): each search runs in its own thread, and its objective hands its point to
/// this thread and waits; when every search still running waits, the round's points (in the
/// order of the starts) go to `batch` together, and each search gets its value back. A
/// search's points depend only on the values it gets, so each search is the one it would be
/// alone, and the rounds are the same for the same settings, however `batch` runs them.
std::vector<SearchRun> multistartInRounds(const BatchObjective& batch, const std::vector<std::vector<double>>& starts, nlopt_algorithm local,
                                          const SearchSettings& s) {
    const std::size_t n = starts.size();
    const int share = s.maxEvaluations / static_cast<int>(n);
    std::mutex m;
    std::condition_variable cv;
    std::vector<const std::vector<double>*> asked(n, nullptr);
    std::vector<double> answer(n, 0.0);
    std::vector<char> answered(n, 0);
    std::size_t waiting = 0, running = n;
    bool failed = false;
    std::vector<SearchRun> runs(n);
    std::vector<std::exception_ptr> own(n);  // a search's own failure (not a failed round's)
    std::vector<std::thread> threads;
    threads.reserve(n);
    for (std::size_t i = 0; i < n; ++i)
        threads.emplace_back([&, i] {
            const std::function<double(const std::vector<double>&)> f = [&, i](const std::vector<double>& x) {
                std::unique_lock<std::mutex> lock(m);
                if (failed) throw ValidationError("calibrate: stopped");
                asked[i] = &x;
                answered[i] = 0;
                ++waiting;
                cv.notify_all();
                cv.wait(lock, [&] { return answered[i] != 0 || failed; });
                if (!answered[i]) throw ValidationError("calibrate: stopped");
                return answer[i];
            };
            try {
                runs[i] = runOptimiser(f, local, s.algorithm, starts[i], share, s, false);
            } catch (...) {
                own[i] = std::current_exception();  // after a failed round, the round's error is rethrown instead
            }
            const std::lock_guard<std::mutex> lock(m);
            --running;
            cv.notify_all();
        });
    std::exception_ptr error;
    {
        std::unique_lock<std::mutex> lock(m);
        while (true) {
            cv.wait(lock, [&] { return waiting == running; });
            if (running == 0) break;
            std::vector<std::size_t> who;
            std::vector<std::vector<double>> points;
            for (std::size_t i = 0; i < n; ++i)
                if (asked[i]) {
                    who.push_back(i);
                    points.push_back(*asked[i]);
                }
            lock.unlock();
            std::vector<double> values;
            try {
                values = batch(points);
                if (values.size() != points.size()) throw ValidationError("calibrate: a batch of " + std::to_string(points.size()) + " points gave " + std::to_string(values.size()) + " values");
            } catch (...) {
                error = std::current_exception();
            }
            lock.lock();
            for (std::size_t j = 0; j < who.size(); ++j) {
                asked[who[j]] = nullptr;
                if (!error) {
                    answer[who[j]] = std::isnan(values[j]) ? HUGE_VAL : values[j];
                    answered[who[j]] = 1;
                }
            }
            waiting = 0;
            if (error) {
                failed = true;
                cv.notify_all();
                cv.wait(lock, [&] { return running == 0; });
                break;
            }
            cv.notify_all();
        }
    }
    for (std::thread& t : threads) t.join();
    if (error) std::rethrow_exception(error);
    for (const std::exception_ptr& e : own)
        if (e) std::rethrow_exception(e);
    return runs;
}


/// A batch objective that evaluates the points one after the other through f.
BatchObjective oneAfterAnother(const std::function<double(const std::vector<double>&)>& f) {
    return [&f](const std::vector<std::vector<double>>& points) {
        std::vector<double> v;
        for (const auto& x : points) v.push_back(f(x));
        return v;
    };
}

/// The global phase of global = "crs" (docs/calibration.md, "Controlled random search in
/// rounds"): a population in the unit cube, improved a round of trial points at a time.
/// Trial n (counted over the whole phase) is mostly Price's CRS2 reflection: the best
/// point and k - 1 others drawn from the population give a centroid G, and a k-th drawn
/// point x is reflected through it, 2 G - x; a reflection that leaves the cube, and every
/// fourth trial (n % 4 == 3), is instead Kaelo and Ali's local mutation around the best b:
/// coordinate i at (1 + w_i) b_i - w_i x_i with w_i uniform in [0, 1] and x another drawn
/// point, clamped to the cube; so is a trial that repeats a point of the population or of
/// the round (drawn again, up to 8 times). The draws come from a stream seeded with settings.seed, in the minimiser's own
/// thread, from the population as it stood at the round's start, so the rounds depend on the
/// settings alone.
SearchRun controlledRandomSearch(const BatchObjective& batch, const std::vector<double>& start, const SearchSettings& s, int budget) {
    const int k = static_cast<int>(start.size());
    const int size = crsPopulation(s, k), perRound = crsBatchSize(s, k);
    if (budget < size) throw ValidationError("calibrate: crs needs global_evaluations >= population (" + std::to_string(size) + ")");
    const auto evaluate = [&batch](const std::vector<std::vector<double>>& points) {
        std::vector<double> values = batch(points);
        if (values.size() != points.size()) throw ValidationError("calibrate: a batch of " + std::to_string(points.size()) + " points gave " + std::to_string(values.size()) + " values");
        for (double& v : values)
            if (std::isnan(v)) v = HUGE_VAL;
        return values;
    };
    std::vector<std::vector<double>> pop = multistartPoints(k, size, start, s.seed);
    std::vector<double> value = evaluate(pop);
    SearchRun run;
    run.method = "crs";
    run.start = start;
    run.evaluations = size;
    RandomStream rs(s.seed, 0x4372734261746368ull);  // "CrsBatch"
    const auto bestOf = [&] { return static_cast<std::size_t>(std::min_element(value.begin(), value.end()) - value.begin()); };
    // Contracted: every point within the tolerance of the best in every coordinate.
    const auto contracted = [&] {
        const std::vector<double>& b = pop[bestOf()];
        for (const auto& x : pop)
            for (int i = 0; i < k; ++i)
                if (std::abs(x[static_cast<std::size_t>(i)] - b[static_cast<std::size_t>(i)]) > s.tolerance) return false;
        return true;
    };
    long trial = 0;
    run.stopReason = "global_evaluations reached";
    while (true) {
        if (contracted()) {
            run.stopReason = "the population contracted within the tolerance";
            run.converged = true;
            break;
        }
        const int count = std::min(perRound, budget - run.evaluations);
        if (count <= 0) break;
        const std::size_t b = bestOf();
        std::vector<std::vector<double>> trials;
        for (int t = 0; t < count; ++t, ++trial) {
            // k distinct points other than the best (a partial Fisher-Yates shuffle).
            std::vector<std::size_t> others;
            for (std::size_t j = 0; j < pop.size(); ++j)
                if (j != b) others.push_back(j);
            const std::size_t draw = std::min(others.size(), static_cast<std::size_t>(k));
            for (std::size_t j = 0; j < draw; ++j) std::swap(others[j], others[j + rs.below(static_cast<std::uint32_t>(others.size() - j))]);
            std::vector<double> y(static_cast<std::size_t>(k));
            bool inside = false;
            if (trial % 4 != 3) {
                const std::vector<double>& reflected = pop[others[draw - 1]];
                inside = true;
                for (std::size_t i = 0; i < y.size(); ++i) {
                    double g = pop[b][i];
                    for (std::size_t j = 0; j + 1 < draw; ++j) g += pop[others[j]][i];
                    g /= static_cast<double>(draw);
                    y[i] = 2 * g - reflected[i];
                    if (y[i] < 0 || y[i] > 1) inside = false;
                }
            }
            // A point already in the population or in this round (two reflections of the same
            // drawn points) would tell nothing new: a mutation instead (a few tries).
            const auto known = [&](const std::vector<double>& p) {
                return std::find(pop.begin(), pop.end(), p) != pop.end() || std::find(trials.begin(), trials.end(), p) != trials.end();
            };
            for (int attempt = 0; attempt < 8 && (!inside || known(y)); ++attempt) {
                const std::vector<double>& x = pop[others[static_cast<std::size_t>(attempt) % draw]];
                for (std::size_t i = 0; i < y.size(); ++i) {
                    const double w = rs.uniform();
                    y[i] = std::clamp((1 + w) * pop[b][i] - w * x[i], 0.0, 1.0);
                }
                inside = true;
            }
            trials.push_back(std::move(y));
        }
        const std::vector<double> got = evaluate(trials);
        run.evaluations += count;
        for (std::size_t t = 0; t < trials.size(); ++t) {
            const std::size_t worst = static_cast<std::size_t>(std::max_element(value.begin(), value.end()) - value.begin());
            if (got[t] < value[worst]) {
                pop[worst] = trials[t];
                value[worst] = got[t];
            }
        }
    }
    const std::size_t b = bestOf();
    run.best = pop[b];
    run.value = value[b];
    return run;
}

}  // namespace

int crsPopulation(const SearchSettings& settings, int k) { return settings.population > 0 ? settings.population : 10 * (k + 1); }
int crsBatchSize(const SearchSettings& settings, int k) { return settings.batchSize > 0 ? settings.batchSize : k + 1; }

SearchSettings searchSettingsOf(const CalibrationSpec& spec) {
    SearchSettings s;
    s.algorithm = spec.algorithm;
    s.global = spec.global;
    s.starts = spec.starts;
    s.parallelStarts = spec.parallelStarts;
    s.globalEvaluations = spec.globalEvaluations;
    s.population = spec.population;
    s.batchSize = spec.batchSize;
    s.seed = spec.seed;
    s.maxEvaluations = spec.maxEvaluations;
    s.tolerance = spec.tolerance;
    s.initialStep = spec.initialStep;
    return s;
}

std::vector<std::vector<double>> multistartPoints(int k, int starts, const std::vector<double>& first, std::uint64_t seed) {
    if (k < 1 || static_cast<int>(first.size()) != k || starts < 1) throw ValidationError("multistart: needs k >= 1, a first point of k values and starts >= 1");
    std::vector<std::vector<double>> points{first};
    if (starts == 1) return points;
    const SobolSequence seq(k);
    RandomStream rs(seed, 0x4d756c7469737461ull);
    std::vector<double> shift(static_cast<std::size_t>(k));
    for (double& v : shift) v = rs.uniform();
    for (int n = 1; n < starts; ++n) {
        std::vector<double> x = seq.point(static_cast<std::uint32_t>(n));
        for (std::size_t i = 0; i < x.size(); ++i) {
            x[i] += shift[i];
            if (x[i] >= 1) x[i] -= 1;
        }
        points.push_back(std::move(x));
    }
    return points;
}

SearchResult minimiseInUnitCube(const std::function<double(const std::vector<double>&)>& f, const std::vector<double>& start,
                                const SearchSettings& settings, const BatchObjective& batch) {
    if (start.empty()) throw ValidationError("calibrate: nothing to search (no parameter)");
    const nlopt_algorithm local = algorithmOf(settings.algorithm);
    SearchResult r;
    const auto add = [&](SearchRun run) {
        r.evaluations += run.evaluations;
        if (r.runs.empty() || run.value < r.value) {
            r.value = run.value;
            r.best = run.best;
            r.bestRun = r.runs.size();
        }
        r.runs.push_back(std::move(run));
    };
    if (settings.global == "none") {
        add(runOptimiser(f, local, settings.algorithm, start, settings.maxEvaluations, settings, false));
    } else if (settings.global == "multistart") {
        // The budget is shared: each start gets an equal share of what the earlier ones left
        // (a start that converges early leaves its rest to the later ones), at least 2.
        const std::vector<std::vector<double>> starts = multistartPoints(static_cast<int>(start.size()), settings.starts, start, settings.seed);
        if (settings.parallelStarts) {
            if (settings.maxEvaluations / settings.starts < 2) throw ValidationError("calibrate: parallel starts need max_evaluations >= 2 x starts");
            for (SearchRun& run : multistartInRounds(batch ? batch : oneAfterAnother(f), starts, local, settings)) add(std::move(run));
        }
        for (std::size_t n = 0; n < starts.size() && !settings.parallelStarts; ++n) {
            const int left = settings.maxEvaluations - r.evaluations;
            const int share = left / static_cast<int>(starts.size() - n);
            if (share < 2) break;
            add(runOptimiser(f, local, settings.algorithm, starts[n], share, settings, false));
        }
    } else if (settings.global == "crs2" || settings.global == "isres") {
        const int globalBudget = settings.globalEvaluations > 0 ? settings.globalEvaluations : settings.maxEvaluations / 2;
        add(runOptimiser(f, settings.global == "crs2" ? NLOPT_GN_CRS2_LM : NLOPT_GN_ISRES, settings.global, start, globalBudget, settings, true));
        const int left = settings.maxEvaluations - r.evaluations;
        // The local method polishes the global phase's best.
        if (left >= 2) add(runOptimiser(f, local, settings.algorithm, r.best, left, settings, false));
    } else if (settings.global == "crs") {
        const int globalBudget = settings.globalEvaluations > 0 ? settings.globalEvaluations : settings.maxEvaluations / 2;
        add(controlledRandomSearch(batch ? batch : oneAfterAnother(f), start, settings, globalBudget));
        const int left = settings.maxEvaluations - r.evaluations;
        if (left >= 2) add(runOptimiser(f, local, settings.algorithm, r.best, left, settings, false));
    } else {
        throw ValidationError("calibrate: unknown global search '" + settings.global + "' (none, multistart, crs, crs2, isres)");
    }
    const SearchRun& best = r.runs[r.bestRun];
    r.converged = best.converged;
    r.stopReason = r.runs.size() == 1 ? best.stopReason
                                      : "run " + std::to_string(r.bestRun + 1) + " of " + std::to_string(r.runs.size()) + " (" + best.method +
                                            ", the best) " + best.stopReason;
    return r;
}

CalibrationResult calibrate(const CalibrationSpec& given, const MemberRunner& run, Reporter& reporter, const SceneRunner& scene) {
    const std::size_t k = given.parameters.size();
    CalibrationSpec spec = given;
    CalibrationResult result;
    // A known truth: the targets' values are its simulations' outputs (other seeds).
    bool writer = true;  // this process writes the outputs (rank 0 under MPI)
    std::vector<StudyMember> truthMembers;
    for (std::size_t r = 0; r < given.truth.size() && r < static_cast<std::size_t>(given.replicates); ++r)
        truthMembers.push_back({"truth-r" + std::string(r < 9 ? "0" : "") + std::to_string(r + 1), given.truth, 1001 + static_cast<int>(r)});
    if (!truthMembers.empty()) {
        writer = run(writeStudyEnsemble(spec.outDir, spec.base, spec.membersAtOnce, spec.parameters, truthMembers,
                                        "# The simulations of eco calibrate " + spec.path + " (written by eco calibrate).\n"));
        for (CalibrationTarget& t : spec.targets) {
            if (t.output.pcf) continue;  // fitted to its stem map
            double sum = 0;
            for (const StudyMember& m : truthMembers) sum += measureOutput(studySimulation(spec.outDir, m.name), t.output);
            t.value = sum / static_cast<double>(truthMembers.size());
        }
        std::string line = "calibrate: targets from the truth (" + joinValues(spec.parameters, given.truth) + "):";
        for (const CalibrationTarget& t : spec.targets) line += " " + t.output.text + " = " + formatNumber(t.value, 6);
        if (writer) reporter.info(line);
    }
    for (const CalibrationTarget& t : spec.targets) result.targetValues.push_back(t.value);
    Calibrator cal(spec, run, reporter, truthMembers, scene);
    // The search in the unit cube: every parameter's range is [0, 1] to the optimiser.
    std::vector<double> u(k);
    for (std::size_t i = 0; i < k; ++i) {
        const StudyParameter& p = spec.parameters[i];
        u[i] = p.logScale || p.integer ? std::clamp(p.unitOf(spec.start[i]), 0.0, 1.0) : (spec.start[i] - p.low) / (p.high - p.low);
    }
    const auto valuesAt = [&](const std::vector<double>& x) {
        std::vector<double> values(k);
        for (std::size_t i = 0; i < k; ++i) values[i] = spec.parameters[i].at(x[i]);
        return values;
    };
    const auto chi2At = [&](const std::vector<double>& x) { return cal.evaluate(valuesAt(x), "search").chi2; };
    // Parallel starts: a round's points are simulated together.
    const BatchObjective chi2AtAll = [&](const std::vector<std::vector<double>>& xs) {
        std::vector<std::vector<double>> points;
        for (const auto& x : xs) points.push_back(valuesAt(x));
        std::vector<double> chi2;
        for (std::size_t h : cal.evaluateAll(points, "search")) chi2.push_back(cal.history()[h].chi2);
        return chi2;
    };
    const SearchResult search = minimiseInUnitCube(chi2At, u, searchSettingsOf(spec), chi2AtAll);
    result.stopReason = search.stopReason;
    result.converged = search.converged;
    result.runs = search.runs;
    if (cal.history().empty()) throw ValidationError("calibrate: the optimiser stopped before any evaluation (" + result.stopReason + ")");
    const Evaluation bestSearch = cal.history()[cal.best()];

    // Uncertainty: the Jacobian of the normalised residuals by forward differences of a tenth
    // of each range (backwards at the upper bound), at the same replicate seeds; the k points
    // are simulated together.
    result.parameterSd.assign(k, std::nan(""));
    if (spec.uncertainty) {
        std::vector<std::vector<double>> jac(spec.targets.size(), std::vector<double>(k, 0.0));
        std::vector<std::vector<double>> steps;
        for (std::size_t i = 0; i < k; ++i) {
            std::vector<double> v = bestSearch.values;
            const StudyParameter& p = spec.parameters[i];
            // A tenth of the range in the search's unit interval (of the log with a log scale);
            // an integer at least one whole step.
            if (!p.logScale && !p.integer) {
                const double h = 0.1 * (p.high - p.low);
                v[i] = v[i] + h <= p.high ? v[i] + h : v[i] - h;
            } else {
                const double u0 = p.unitOf(v[i]);
                const double moved = p.at(u0 + 0.1 <= 1 ? u0 + 0.1 : u0 - 0.1);
                if (p.integer && moved == v[i]) v[i] = v[i] + 1 <= p.high ? v[i] + 1 : v[i] - 1;
                else v[i] = moved;
            }
            steps.push_back(std::move(v));
        }
        const std::vector<std::size_t> at = cal.evaluateAll(steps, "uncertainty");
        for (std::size_t i = 0; i < k; ++i) {
            const Evaluation& e = cal.history()[at[i]];
            for (std::size_t t = 0; t < spec.targets.size(); ++t)
                jac[t][i] = (spec.targets[t].residual(e.simulated[t]) - spec.targets[t].residual(bestSearch.simulated[t])) / (steps[i][i] - bestSearch.values[i]);
        }
        result.parameterSd = linearisedSd(jac);
    }
    result.history = cal.history();
    // The best of the search (an uncertainty step may score lower by chance; it is not a fit).
    result.best = static_cast<std::size_t>(bestSearch.index - 1);
    const Evaluation& best = result.history[result.best];
    result.writer = writer && cal.writer();
    if (!result.writer) return result;  // another MPI rank's: rank 0 writes the outputs

    // Outputs, together: the history, the report, the picture, the best configuration files.
    AtomicOutputSet outputs;
    const auto at = [&](const std::string& name) { return (fs::path(spec.outDir) / name).string(); };
    std::ostringstream csv;
    csv << "evaluation,purpose";
    for (const auto& p : spec.parameters) csv << "," << csvField(p.key);
    for (const auto& t : spec.targets) csv << "," << csvField(t.output.text);
    csv << ",chi2\n";
    for (const Evaluation& e : result.history) {
        csv << e.index << "," << e.purpose;
        for (double v : e.values) csv << "," << formatNumber(v, 12);
        for (double v : e.simulated) csv << "," << formatNumber(v, 10);
        csv << "," << formatNumber(e.chi2, 10) << "\n";
    }
    result.historyPath = at("history.csv");
    writeTextFile(result.historyPath, csv.str());
    const std::string bestDir = (fs::path(spec.outDir) / "ensemble" / "members" / calibrationMemberName(best.index, 0)).string();
    for (const auto& [name, out] : {std::pair<std::string, std::string*>{"biome.toml", &result.bestBiome}, {"simulate.toml", &result.bestSimulation}}) {
        const fs::path src = fs::path(bestDir) / name;
        if (!fs::exists(src)) continue;
        *out = at("best-" + name);
        writeTextFile(*out, "# eco calibrate " + spec.path + ": the best fit, evaluation " + std::to_string(best.index) + " (chi2 " +
                                formatNumber(best.chi2, 6) + ")\n" + readTextFile(src.string()));
    }
    ensureDirectory(at("png"));
    writeConvergencePng(at("png/chi2.png"), result);
    std::ostringstream md;
    md << "# Calibration\n\n"
       << "Specification `" << spec.path << "`: " << k << " parameter" << (k > 1 ? "s" : "") << ", " << spec.targets.size() << " target"
       << (spec.targets.size() > 1 ? "s" : "") << ", NLopt `" << spec.algorithm << "` in the unit cube of the ranges (first step "
       << formatNumber(spec.initialStep, 3) << ", tolerance " << formatNumber(spec.tolerance, 3) << "), " << spec.replicates
       << " replicate" << (spec.replicates > 1 ? "s" : "") << " per evaluation (" << sceneOrSeeds(spec) << ", the same at every evaluation). "
       << (spec.global == "multistart" ? "Multistart: " + std::to_string(spec.starts) + " local searches (the start, then quasi-random points, seed " + std::to_string(spec.seed) + ")" +
                                                 (spec.parallelStarts ? " side by side (parallel_starts: in rounds, one evaluation of each start per round, " + std::to_string(spec.maxEvaluations / spec.starts) + " evaluations each). "
                                                                      : " sharing the budget. ")
           : spec.global == "none" ? std::string()
           : spec.global == "crs"
               ? "Global search: controlled random search in rounds (crs, seed " + std::to_string(spec.seed) + "): a population of " +
                     std::to_string(crsPopulation(searchSettingsOf(spec), static_cast<int>(k))) + " points, then rounds of " +
                     std::to_string(crsBatchSize(searchSettingsOf(spec), static_cast<int>(k))) + " trial points evaluated together, for " +
                     std::to_string(spec.globalEvaluations) + " evaluations, then `" + spec.algorithm + "` from its best. "
                                   : "Global search: NLopt " + std::string(spec.global == "crs2" ? "GN_CRS2_LM" : "GN_ISRES") + " (seed " + std::to_string(spec.seed) + ") for " +
                                         std::to_string(spec.globalEvaluations) + " evaluations, then `" + spec.algorithm + "` from its best. ")
       << result.history.size() << " evaluations (" << result.history.size() * static_cast<std::size_t>(spec.replicates)
       << " simulations); the search stopped: " << result.stopReason << ". chi2 = sum over targets of ((simulated - observed) / sd)^2.\n\n"
       << (spec.truth.empty() ? "" : "The targets' values are the outputs of simulations at known parameter values (`[calibrate.truth]`, seeds 1001 .. 1000 + replicates): a test of whether the calibration recovers them.\n\n")
       << (result.converged ? "The search converged: the best was found by a local search that stopped on the tolerance.\n\n"
                            : "The search did not converge: the best was found by a run that stopped on its budget (max_evaluations).\n\n")
       << "## Parameters\n\n| parameter | range | start | best | ± sd (linearised) |" << (spec.truth.empty() ? "" : " truth | best - truth |")
       << "\n|---|---|---:|---:|---:|" << (spec.truth.empty() ? "" : "---:|---:|") << "\n";
    for (std::size_t i = 0; i < k; ++i)
        md << "| `" << spec.parameters[i].key << "` | " << spec.parameters[i].describe() << " | " << formatNumber(spec.start[i], 6) << " | " << formatNumber(best.values[i], 6) << " | "
           << (std::isfinite(result.parameterSd[i]) ? formatNumber(result.parameterSd[i], 3) : std::string(spec.uncertainty ? "not identifiable" : "-")) << " |"
           << (spec.truth.empty() ? std::string() : " " + formatNumber(spec.truth[i], 6) + " | " + formatNumber(best.values[i] - spec.truth[i], 3) + " |") << "\n";
    md << "\nThe sd comes from the Jacobian of the residuals at the best point (forward differences of a tenth of each range, "
          "same seeds): (J^T J)^-1 with the targets' sd as the residuals' scale. It says how far a parameter can move before "
          "the fit gets worse by one sd of the targets; \"not identifiable\": the targets cannot tell the parameters apart.\n\n"
       << "## Fit (evaluation " << best.index << ", chi2 " << formatNumber(best.chi2, 5) << ")\n\n"
       << "| target | observed | sd | simulated (mean of replicates) | replicate sd | residual / sd |\n|---|---:|---:|---:|---:|---:|\n";
    for (std::size_t t = 0; t < spec.targets.size(); ++t)
        md << "| `" << spec.targets[t].output.text << "` | "
           << (spec.targets[t].side == CalibrationTarget::Side::AtLeast ? ">= " : spec.targets[t].side == CalibrationTarget::Side::AtMost ? "<= " : "")
           << formatNumber(spec.targets[t].value, 5) << " | " << formatNumber(spec.targets[t].sd, 3) << " | "
           << formatNumber(best.simulated[t], 5) << " | " << formatNumber(best.spread[t], 3) << " | "
           << formatNumber(spec.targets[t].residual(best.simulated[t]), 3) << " |\n";
    if (result.runs.size() > 1 || spec.global != "none") {
        md << "\n## Search runs\n\n| run | method | start (unit cube) | best (unit cube) | chi2 | evaluations | stopped |\n|---:|---|---|---|---:|---:|---|\n";
        const auto unit = [](const std::vector<double>& x) {
            std::string t;
            for (std::size_t i = 0; i < x.size(); ++i) t += (i ? ", " : "") + formatNumber(x[i], 3);
            return t;
        };
        for (std::size_t i = 0; i < result.runs.size(); ++i) {
            const SearchRun& r = result.runs[i];
            md << "| " << i + 1 << " | " << r.method << " | " << unit(r.start) << " | " << unit(r.best) << " | " << formatNumber(r.value, 5) << " | "
               << r.evaluations << " | " << r.stopReason << " |\n";
        }
    }
    md << "\n![chi2 per evaluation](png/chi2.png)\n\nFiles: `history.csv` (every evaluation)"
       << (result.bestBiome.empty() ? "" : ", `best-biome.toml` (the biome with the best values)")
       << (result.bestSimulation.empty() ? "" : ", `best-simulate.toml` (the simulation configuration with the best values)")
       << ", the simulations in `ensemble/`.\n";
    result.reportPath = at("calibration.md");
    writeTextFile(result.reportPath, md.str());
    outputs.commit();
    return result;
}

}  // namespace eco::pipeline
