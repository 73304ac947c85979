#include "validate.h"

#include <omp.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <map>
#include <sstream>

#include "atomic_file.h"
#include "biome_db.h"
#include "eco_version.h"
#include "error.h"
#include "provenance.h"
#include "scenario_context.h"
#include "text_format.h"

namespace eco::validate {

int SuiteResult::checkCount() const {
    int n = 0;
    for (const auto& s : scenarios) n += static_cast<int>(s.checks.size());
    return n;
}

int SuiteResult::failedCount() const {
    int n = 0;
    for (const auto& s : scenarios)
        for (const auto& c : s.checks) n += c.pass || c.knownDeviation() ? 0 : 1;
    return n;
}

int SuiteResult::knownDeviationCount() const {
    int n = 0;
    for (const auto& s : scenarios)
        for (const auto& c : s.checks) n += c.knownDeviation() ? 1 : 0;
    return n;
}

int exitStatus(const SuiteResult& result) { return result.allPassed() ? 0 : kChecksFailedExit; }

double studentT975(int dof) {
    // Two-sided 95 % quantiles t(0.975, dof) for dof 1..30; beyond, the normal's 1.96 plus
    // the first term of its expansion in 1/dof (error under 0.002 from dof 31 on).
    static const double table[] = {12.706, 4.303, 3.182, 2.776, 2.571, 2.447, 2.365, 2.306, 2.262, 2.228,
                                   2.201,  2.179, 2.160, 2.145, 2.131, 2.120, 2.110, 2.101, 2.093, 2.086,
                                   2.080,  2.074, 2.069, 2.064, 2.060, 2.056, 2.052, 2.048, 2.045, 2.042};
    if (dof < 1) throw Error("studentT975: " + std::to_string(dof) + " degrees of freedom");
    if (dof <= 30) return table[dof - 1];
    return 1.959964 + 2.37 / dof;
}

CheckResult combineReplicates(const std::vector<CheckResult>& reps) {
    if (reps.empty()) throw Error("combineReplicates: no replicate");
    CheckResult out = reps.front();
    out.replicateValues.clear();
    int missing = 0;
    for (const CheckResult& c : reps) {
        if (c.spec.id != out.spec.id || c.scenario != out.scenario)
            throw Error("combineReplicates: check " + c.scenario + "/" + c.spec.id + " among replicates of " + out.scenario +
                        "/" + out.spec.id);
        out.replicateValues.push_back(c.value);
        missing += std::isfinite(c.value) ? 0 : 1;
    }
    const auto n = static_cast<int>(reps.size());
    // A bound that follows each replicate's own reference level (e.g. the fidelity checks'
    // max(factor x replicate level, floor)) is judged against the mean of the replicates' bounds.
    bool boundsDiffer = false;
    double targetSum = 0;
    for (const CheckResult& c : reps) {
        boundsDiffer = boundsDiffer || c.spec.target != out.spec.target;
        targetSum += c.spec.target;
    }
    if (boundsDiffer) {
        out.spec.target = targetSum / n;
        out.note = "bound: the mean of the replicates' bounds, " + num(out.spec.target, 3) + "; replicate 1: " + out.note;
    }
    if (missing > 0) {
        out.value = out.ciLow = out.ciHigh = kNaN;
        out.pass = false;
        const std::string why = std::to_string(missing) + " of " + std::to_string(n) + " replicate(s) gave no value";
        out.note = out.note.empty() ? why : why + "; " + out.note;
        return out;
    }
    out.value = mean(out.replicateValues);
    if (n == 1) {
        out.ciLow = out.ciHigh = out.value;
    } else {
        double ss = 0;
        for (double v : out.replicateValues) ss += (v - out.value) * (v - out.value);
        const double sd = std::sqrt(ss / (n - 1));
        const double half = studentT975(n - 1) * sd / std::sqrt(static_cast<double>(n));
        out.ciLow = out.value - half;
        out.ciHigh = out.value + half;
    }
    out.pass = out.spec.intervalPasses(out.ciLow, out.ciHigh);
    return out;
}

namespace {

/// "0.512 [0.47, 0.55]": the mean and its 95 % interval ("0.512" for one replicate).
std::string intervalText(const CheckResult& c) {
    if (c.replicateValues.size() < 2 || std::isnan(c.value)) return num(c.value);
    return num(c.value) + " [" + num(c.ciLow, 3) + ", " + num(c.ciHigh, 3) + "]";
}

/// The replicate counts of scenarios (name, count) in a line: "5 per scenario" when they are
/// equal, else the count most of them have and the others by name, "5 per scenario;
/// fidelity 10" (a tie goes to the smaller count); with `bold`, the counts in Markdown bold.
std::string replicateCountsText(const std::vector<std::pair<std::string, int>>& counts, bool bold = false) {
    const std::string b = bold ? "**" : "";
    std::map<int, int> scenariosWith;
    for (const auto& nc : counts) ++scenariosWith[nc.second];
    int common = 1, most = 0;
    for (const auto& cn : scenariosWith)
        if (cn.second > most) {
            common = cn.first;
            most = cn.second;
        }
    std::string text = b + std::to_string(common) + b + " per scenario";
    for (const auto& nc : counts)
        if (nc.second != common) text += "; " + nc.first + " " + b + std::to_string(nc.second) + b;
    return text;
}

/// One scenario: its kind's run() (scenario.h), timed.
ScenarioResult runScenario(const ScenarioConfig& sc, ScenarioContext& context) {
    ScenarioResult r;
    r.name = sc.name;
    r.title = sc.title;
    r.description = sc.description;
    r.configPath = sc.path;
    r.kind = sc.kind;
    r.sharesSimulation = sc.usesForestScene();
    const auto t0 = Clock::now();
    sc.scenario->run(sc, context, r);
    r.seconds = secondsSince(t0);
    return r;
}

}  // namespace

SuiteResult runSuite(const SuiteOptions& options) {
    const auto t0 = Clock::now();
    SuiteResult result;
    result.mode = options.mode;
    result.configSource = options.configs.describe();
    result.threads = omp_get_max_threads();
    result.startedUtc = utcTimestamp();
    Biome biome = options.biomePath.empty() ? defaultBiome() : loadBiome(options.biomePath);
    result.biomeName = options.biomePath.empty() ? biome.name : biome.name + " (" + options.biomePath + ")";
    SuiteConfig suite = loadSuiteConfig(options.configs, biome);
    std::vector<const ScenarioConfig*> selected;
    for (const std::string& name : options.only) {
        bool found = false;
        for (const auto& s : suite.scenarios) found = found || s.name == name;
        if (!found) {
            std::string names;
            for (const auto& s : suite.scenarios) names += (names.empty() ? "" : ", ") + s.name;
            throw ValidationError("--only: no scenario '" + name + "' (scenarios: " + names + ")");
        }
    }
    for (const auto& s : suite.scenarios)
        if (options.only.empty() || std::find(options.only.begin(), options.only.end(), s.name) != options.only.end())
            selected.push_back(&s);
    if (options.replicates < 0 || options.replicates > kMaxReplicates)
        throw ValidationError("--replicates: " + std::to_string(options.replicates) + " is not a count of replicates (1 to " +
                              std::to_string(kMaxReplicates) + ", or 0 for each scenario's own)");
    result.replicates = options.replicates;
    // Each scenario's count: --replicates when given, else its file's.
    std::vector<int> counts;
    std::vector<std::pair<std::string, int>> named;
    for (const ScenarioConfig* sc : selected) {
        counts.push_back(options.replicates > 0 ? options.replicates : sc->replicateCount(options.mode));
        named.emplace_back(sc->name, counts.back());
    }
    const int rounds = counts.empty() ? 0 : *std::max_element(counts.begin(), counts.end());
    if (options.log)
        options.log("validate: replicates: " + replicateCountsText(named) +
                    (options.replicates > 0 ? " (--replicates)" : " (the scenario files'; default " +
                                                                      std::to_string(kDefaultReplicates) + ")"));
    ensureDirectory(options.outDir);
    // Replicate 0 writes its figures into the output directory; the others into a scratch
    // directory removed afterwards (the report shows replicate 0's pictures).
    const std::string scratch = options.outDir + "/.replicates";
    struct ScratchGuard {
        std::string dir;
        ~ScratchGuard() {
            std::error_code ec;
            std::filesystem::remove_all(dir, ec);
        }
    } guard{scratch};
    // runs[i][k]: scenario i, replicate k (k < counts[i]).
    std::vector<std::vector<ScenarioResult>> runs(selected.size());
    for (int k = 0; k < rounds; ++k) {
        // Replicate k runs the scenarios that have more than k replicates.
        std::vector<std::size_t> running;
        for (std::size_t i = 0; i < selected.size(); ++i)
            if (counts[i] > k) running.push_back(i);
        std::string figureDir = options.outDir;
        if (k > 0) {
            figureDir = scratch + "/" + std::to_string(k);
            ensureDirectory(figureDir);
        }
        ScenarioContext context(options, biome, suite, k, figureDir);
        // Planned for every selected scenario, not only those running now: a forest run is
        // simulated only when a running scenario asks for it, but with the same length and
        // kept years in every replicate, so a scenario's replicates do not depend on how many
        // replicates the scenarios sharing its scene have (an extra kept year adds a snapshot
        // to a window measure).
        context.planForestRuns(selected);
        for (std::size_t j = 0; j < running.size(); ++j) {
            const std::size_t i = running[j];
            const ScenarioConfig& sc = *selected[i];
            const std::string rep = counts[i] > 1 ? "replicate " + std::to_string(k + 1) + "/" + std::to_string(counts[i]) +
                                                        " (seeds + " + std::to_string(k * kReplicateSeedStep) + "), "
                                                  : std::string();
            if (options.log)
                options.log("validate: " + rep + "[" + std::to_string(j + 1) + "/" + std::to_string(running.size()) + "] " +
                            sc.name + " (" + sc.path + ")");
            ScenarioResult r = runScenario(sc, context);
            r.replicates = counts[i];
            if (options.log)
                for (const CheckResult& c : r.checks)
                    options.log("validate:   " + sc.name + "/" + c.spec.id + " = " + num(c.value) + " (expected " +
                                c.spec.expectedText() + ")" + (c.note.empty() ? "" : "; " + c.note));
            runs[i].push_back(std::move(r));
        }
    }
    for (std::size_t i = 0; i < selected.size(); ++i) {
        ScenarioResult merged = std::move(runs[i][0]);
        for (std::size_t k = 1; k < runs[i].size(); ++k) merged.seconds += runs[i][k].seconds;
        for (std::size_t c = 0; c < merged.checks.size(); ++c) {
            std::vector<CheckResult> reps;
            reps.push_back(merged.checks[c]);
            for (std::size_t k = 1; k < runs[i].size(); ++k) reps.push_back(runs[i][k].checks.at(c));
            merged.checks[c] = combineReplicates(reps);
        }
        if (options.log)
            for (const CheckResult& c : merged.checks)
                options.log("validate: " + std::string(c.pass ? "PASS " : c.knownDeviation() ? "KNOWN DEVIATION " : "FAIL ") +
                            merged.name + "/" + c.spec.id + " = " + intervalText(c) + " (expected " + c.spec.expectedText() + ")");
        result.scenarios.push_back(std::move(merged));
    }
    result.seconds = secondsSince(t0);
    return result;
}

// ---------------------------------------------------------------------------------------

namespace {

std::string resultText(const CheckResult& c) {
    if (c.pass) return c.spec.knownDeviation.empty() ? "pass" : "pass (declared a known deviation: update its configuration)";
    return c.knownDeviation() ? "known deviation" : "**FAIL**";
}

std::string csvNum(double v) {
    if (std::isnan(v)) return "";
    char buf[64];
    std::snprintf(buf, sizeof buf, "%.10g", v);
    return buf;
}

/// The replicates' values separated by spaces ("nan" for a missing one), one CSV field.
std::string joinValues(const std::vector<double>& v) {
    std::string out;
    for (double x : v) out += (out.empty() ? "" : " ") + (std::isnan(x) ? std::string("nan") : csvNum(x));
    return out;
}

}  // namespace

std::vector<std::string> writeReport(const SuiteResult& res, const std::string& outDir) {
    ensureDirectory(outDir);
    std::ostringstream md;
    md << "# Ecological validation report\n\n";
    md << "- Mode: **" << modeName(res.mode) << "**" << (res.mode == Mode::Quick ? " (small plots, short spans: a smoke test of the behaviour)" : "")
       << "\n";
    md << "- Started: " << res.startedUtc << "; wall time " << fixed(res.seconds, 1) << " s on " << res.threads << " thread(s)\n";
    md << "- eco " << ECO_VERSION_STRING << ", biome " << res.biomeName << ", configurations: " << res.configSource << "\n";
    std::vector<std::pair<std::string, int>> counts;
    int mostReplicates = 0;
    for (const auto& s : res.scenarios) {
        counts.emplace_back(s.name, s.replicates);
        mostReplicates = std::max(mostReplicates, s.replicates);
    }
    // The counts' source only when they come from the files (the text of a --replicates run is as before).
    const std::string source = res.replicates > 0 ? std::string()
                                                  : " (the scenario files' `replicates` / `quick_replicates`; default " +
                                                        std::to_string(kDefaultReplicates) + ")";
    if (mostReplicates > 1)
        md << "- Replicates: " << replicateCountsText(counts, true) << source << ": replicate k runs with every configured seed + "
           << kReplicateSeedStep << " k. A value is the mean over the replicates with its 95 % interval (Student's t) in "
           << "brackets; a check passes when the whole interval lies inside the accepted region. Figures and detail "
           << "lines show replicate 1 (the seeds as configured)\n";
    else
        md << "- Replicates: **1** (every seed as configured): a check passes on its single value; the suite's claims "
           << "need " << kDefaultReplicates << " (" << (res.replicates > 0 ? "--replicates" : "the scenario files") << ")\n";
    const int passed = res.checkCount() - res.failedCount() - res.knownDeviationCount();
    md << "- Result: **" << passed << " of " << res.checkCount() << " checks passed**";
    if (res.knownDeviationCount() > 0)
        md << "; " << res.knownDeviationCount() << " known deviation(s) from the paper, measured and reported but not "
           << "failing the suite (each explained in its scenario below and in docs/validation.md)";
    md << (res.allPassed() ? "" : "; failing checks are listed first below and make `eco validate` exit with status 3") << "\n\n";
    md << "| scenario | check | value | expected | result |\n|---|---|---|---|---|\n";
    // Failures first, then known deviations, then passes.
    auto rank = [](const CheckResult& c) { return c.pass ? 2 : c.knownDeviation() ? 1 : 0; };
    for (int group = 0; group < 3; ++group)
        for (const auto& s : res.scenarios)
            for (const auto& c : s.checks) {
                if (rank(c) != group) continue;
                md << "| " << s.name << " | " << c.spec.id << " | " << intervalText(c) << (c.spec.units.empty() ? "" : " " + c.spec.units)
                   << " | " << c.spec.expectedText() << " | " << resultText(c) << " |\n";
            }
    md << "\n";
    html::Document page("Ecological validation report");
    page.markdown(md.str() + "\nThe Markdown version of this report is `report.md` beside it; every check is also in "
                             "`results.csv`.\n",
                  outDir);
    for (const auto& s : res.scenarios) {
        const std::size_t sectionStart = md.str().size();
        md << "## " << s.title << " (`" << s.name << "`)\n\n";
        md << s.description << "\n\n";
        md << "Configuration `" << s.configPath << "`, kind `" << s.kind << "`, " << s.replicates
           << (s.replicates == 1 ? " replicate" : " replicates") << ", " << fixed(s.seconds, 1) << " s"
           << (s.sharesSimulation ? " (a forest simulation shared with an earlier scenario is counted there)" : "") << ".\n\n";
        md << "| check | measured | value | expected | result |\n|---|---|---|---|---|\n";
        for (const auto& c : s.checks) {
            std::string measured = c.title;
            if (!c.note.empty()) measured += " (" + c.note + ")";
            if (!c.spec.why.empty()) measured += ". Bound: " + c.spec.why;
            if (!c.spec.knownDeviation.empty()) measured += ". Known deviation: " + c.spec.knownDeviation;
            if (c.replicateValues.size() > 1) {
                measured += ". Replicates:";
                for (double v : c.replicateValues) measured += " " + num(v, 3);
            }
            md << "| " << c.spec.id << " | " << markdownCell(measured) << " | " << intervalText(c)
               << (c.spec.units.empty() ? "" : " " + c.spec.units) << " | " << c.spec.expectedText() << " | "
               << resultText(c) << " |\n";
        }
        md << "\n";
        for (const auto& d : s.details) md << d << "\n";
        md << "\n";
        page.markdown(md.str().substr(sectionStart), outDir);
        for (const auto& f : s.figures) {
            if (f.file.empty())
                md << "*" << f.caption << "* (an interactive view, in report.html only)\n\n";
            else
                md << "![" << f.caption << "](" << f.file << ")\n\n*" << f.caption << "*\n\n";
            const bool interactive = !f.plot.groups.empty() || f.scene.has_value();
            if (!f.plot.groups.empty()) page.linePlot(f.plot);
            if (f.scene) page.sceneView(*f.scene);
            if (f.file.empty()) {
                page.raw("<p class=\"eco-caption\">" + html::escape(f.caption) + "</p>\n");
            } else if (!interactive) {
                page.picture(outDir + "/" + f.file, f.caption);
            } else {  // the interactive view, its picture folded away below it
                page.raw("<details><summary>" + html::escape(f.caption) + " (picture)</summary>\n");
                page.picture(outDir + "/" + f.file, f.caption);
                page.raw("</details>\n");
            }
        }
    }
    const std::string reportPath = outDir + "/report.md", csvPath = outDir + "/results.csv", htmlPath = outDir + "/report.html";
    // The report and the table appear together or not at all (a kill between them would
    // leave a new report beside the old table). The figures were each written whole as their
    // scenario finished.
    AtomicOutputSet outputs;
    writeTextFile(reportPath, md.str());
    std::ostringstream csv;
    csv << "mode,scenario,check,value,comparator,target,tolerance,expected,result,units,note,replicates,ci_low,ci_high,"
           "replicate_values\n";
    for (const auto& s : res.scenarios)
        for (const auto& c : s.checks)
            csv << modeName(res.mode) << "," << csvField(s.name) << "," << csvField(c.spec.id) << "," << csvNum(c.value) << ","
                << c.spec.comparator() << "," << csvNum(c.spec.target) << ","
                << (c.spec.kind == CheckSpec::Kind::Approx ? csvNum(c.spec.tolerance) : std::string()) << ","
                << csvField(c.spec.expectedText()) << "," << c.outcome() << "," << csvField(c.spec.units) << ","
                << csvField(c.note) << "," << c.replicateValues.size() << "," << csvNum(c.ciLow) << "," << csvNum(c.ciHigh)
                << "," << csvField(joinValues(c.replicateValues)) << "\n";
    writeTextFile(csvPath, csv.str());
    html::writeDocument(htmlPath, page);
    outputs.commit();
    return {reportPath, csvPath, htmlPath};
}

}  // namespace eco::validate
