#include "validate.h"

#include <omp.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
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

namespace {

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
    Biome biome = defaultBiome();
    result.biomeName = biome.name;
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
    ensureDirectory(options.outDir);
    ScenarioContext context(options, biome, suite);
    context.planForestRuns(selected);
    for (std::size_t i = 0; i < selected.size(); ++i) {
        const ScenarioConfig& sc = *selected[i];
        if (options.log)
            options.log("validate: [" + std::to_string(i + 1) + "/" + std::to_string(selected.size()) + "] " + sc.name + " (" +
                        sc.path + ")");
        ScenarioResult r = runScenario(sc, context);
        if (options.log)
            for (const CheckResult& c : r.checks)
                options.log("validate:   " + std::string(c.pass ? "PASS " : c.knownDeviation() ? "KNOWN DEVIATION " : "FAIL ") + sc.name + "/" + c.spec.id + " = " +
                            num(c.value) + " (expected " + c.spec.expectedText() + ")" + (c.note.empty() ? "" : "; " + c.note));
        result.scenarios.push_back(std::move(r));
    }
    result.seconds = secondsSince(t0);
    return result;
}

// ---------------------------------------------------------------------------------------

namespace {

std::string mdCell(std::string s) {
    for (std::size_t p = 0; (p = s.find('|', p)) != std::string::npos; p += 2) s.replace(p, 1, "\\|");
    return s;
}

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

}  // namespace

std::vector<std::string> writeReport(const SuiteResult& res, const std::string& outDir) {
    ensureDirectory(outDir);
    std::ostringstream md;
    md << "# Ecological validation report\n\n";
    md << "- Mode: **" << modeName(res.mode) << "**" << (res.mode == Mode::Quick ? " (small plots, short spans: a smoke test of the behaviour)" : "")
       << "\n";
    md << "- Started: " << res.startedUtc << "; wall time " << fixed(res.seconds, 1) << " s on " << res.threads << " thread(s)\n";
    md << "- eco " << ECO_VERSION_STRING << ", biome " << res.biomeName << ", configurations: " << res.configSource << "\n";
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
                md << "| " << s.name << " | " << c.spec.id << " | " << num(c.value) << (c.spec.units.empty() ? "" : " " + c.spec.units)
                   << " | " << c.spec.expectedText() << " | " << resultText(c) << " |\n";
            }
    md << "\n";
    for (const auto& s : res.scenarios) {
        md << "## " << s.title << " (`" << s.name << "`)\n\n";
        md << s.description << "\n\n";
        md << "Configuration `" << s.configPath << "`, kind `" << s.kind << "`, " << fixed(s.seconds, 1) << " s"
           << (s.sharesSimulation ? " (a forest simulation shared with an earlier scenario is counted there)" : "") << ".\n\n";
        md << "| check | measured | value | expected | result |\n|---|---|---|---|---|\n";
        for (const auto& c : s.checks) {
            std::string measured = c.title;
            if (!c.note.empty()) measured += " (" + c.note + ")";
            if (!c.spec.why.empty()) measured += ". Bound: " + c.spec.why;
            if (!c.spec.knownDeviation.empty()) measured += ". Known deviation: " + c.spec.knownDeviation;
            md << "| " << c.spec.id << " | " << mdCell(measured) << " | " << num(c.value)
               << (c.spec.units.empty() ? "" : " " + c.spec.units) << " | " << c.spec.expectedText() << " | "
               << resultText(c) << " |\n";
        }
        md << "\n";
        for (const auto& d : s.details) md << d << "\n";
        md << "\n";
        for (const auto& f : s.figures) md << "![" << f.caption << "](" << f.file << ")\n\n*" << f.caption << "*\n\n";
    }
    const std::string reportPath = outDir + "/report.md", csvPath = outDir + "/results.csv";
    // The report and the table appear together or not at all (a kill between them would
    // leave a new report beside the old table). The figures were each written whole as their
    // scenario finished.
    AtomicOutputSet outputs;
    writeTextFile(reportPath, md.str());
    std::ostringstream csv;
    csv << "mode,scenario,check,value,comparator,target,tolerance,expected,result,units,note\n";
    for (const auto& s : res.scenarios)
        for (const auto& c : s.checks)
            csv << modeName(res.mode) << "," << csvField(s.name) << "," << csvField(c.spec.id) << "," << csvNum(c.value) << ","
                << c.spec.comparator() << "," << csvNum(c.spec.target) << ","
                << (c.spec.kind == CheckSpec::Kind::Approx ? csvNum(c.spec.tolerance) : std::string()) << ","
                << csvField(c.spec.expectedText()) << "," << c.outcome() << "," << csvField(c.spec.units) << ","
                << csvField(c.note) << "\n";
    writeTextFile(csvPath, csv.str());
    outputs.commit();
    return {reportPath, csvPath};
}

}  // namespace eco::validate
