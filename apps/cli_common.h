// Shared pieces of the command-line front end: registration of subcommands, progress
// reporting (the stages' Reporter on the terminal). No science and no workflows here: the
// stages and the pipeline run are in pipeline/, the fidelity protocol in validate/.
#pragma once

#include <CLI/CLI.hpp>

#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <functional>
#include <memory>
#include <vector>
#include <string>

#include "param_desc.h"
#include "point_pattern.h"
#include "reporter.h"
#include "stage_common.h"

namespace eco::cli {

// Each cmd_*.cpp adds its subcommands to the top-level app.
void registerTerrainCommands(CLI::App& app);   // eco terrain generate|convert, eco chm generate
void registerAbioticsCommand(CLI::App& app);   // eco abiotics
void registerCanopyCommand(CLI::App& app);     // eco canopy
void registerSimulateCommand(CLI::App& app);   // eco simulate
void registerRunCommand(CLI::App& app);        // eco run CONFIG (the whole pipeline)
void registerAnalyseCommand(CLI::App& app);    // eco analyse SIM.h5 ... --out DB.h5
void registerInspectCommand(CLI::App& app);    // eco inspect DB.h5 [--png DIR]
void registerPcfCommand(CLI::App& app);        // eco pcf POINTS.csv --window x0,y0,x1,y1
void registerSynthCommand(CLI::App& app);      // eco synth --terrain --canopy --database --out SCENE.h5
void registerCompareCommand(CLI::App& app);    // eco compare SCENE.h5 DB.h5
void registerValidateCommand(CLI::App& app);   // eco validate [--quick] [--out DIR]
void registerFidelityCommand(CLI::App& app);   // eco fidelity [--config F] [--scene S --reference A --replicate B]
void registerEnsembleCommand(CLI::App& app);   // eco ensemble SPEC.toml (many simulations, MPI)
void registerDatabaseCommands(CLI::App& app);  // eco database build BIOME.toml --out DB.h5
void registerSensitivityCommand(CLI::App& app); // eco sensitivity SPEC.toml (Morris screening)
void registerCalibrateCommand(CLI::App& app);   // eco calibrate SPEC.toml (fit parameters to observations)
void registerInstanceCommand(CLI::App& app);    // eco instance SCENE.h5 --prototypes K --out DIR
void registerConfigCommands(CLI::App& app);     // eco biome show [BIOME.toml], eco config defaults [COMMAND]
void registerDocsCommands(CLI::App& app);       // eco completion bash, eco manpage (hidden)
/// The bash completion script and the man page (roff) of every visible command and option of
/// `root` (apps/cmd_docs.cpp).
std::string bashCompletion(const CLI::App& root);
std::string manPage(const CLI::App& root);
/// Runs an ensemble specification as eco ensemble does (this process, its child processes or
/// the ranks of an MPI job); returns this process' rank (0 alone). ExitStatus when a member
/// is not done. `printPaths`: the manifest's (and database's) path on stdout at the end.
int runEnsembleFile(const std::string& specPath, const std::string& outDir, bool dryRun, bool printPaths = true);

/// Thrown by a command that completed but must end with a particular non-zero exit status
/// (e.g. `eco validate` when a check failed); main() prints the message and returns `code`.
struct ExitStatus {
    int code;
    std::string message;
    ExitStatus(int c, std::string m) : code(c), message(std::move(m)) {}
};

/// The whole command line, every subcommand registered.
std::unique_ptr<CLI::App> makeApp();

/// Progress on stderr: a bar redrawn in place on a terminal, a line per 10 % otherwise
/// (CI logs). Thread-safe only when called from one thread.
class Progress : public pipeline::ProgressBar {
public:
    Progress(std::string label, long total);
    /// Report that `done` of `total` units are complete.
    void update(long done) override;
    /// Final line with the elapsed time.
    void finish() override;

private:
    std::string label_;
    long total_;
    int lastDecile_ = -1;
    bool tty_;
    std::chrono::steady_clock::time_point start_;
};

/// Option checks with plain messages ("--years: must be > 0, got -3"; "'abc' is not a
/// number"): CLI11's PositiveNumber and NonNegativeNumber print their whole double range
/// instead. The value must be a finite number, and > 0 or >= 0.
const CLI::Validator& positiveNumber();
const CLI::Validator& nonNegativeNumber();
/// A finite number in [lo, hi] ("must lie in [0.001, 10000], got 1e-300").
CLI::Validator numberIn(double lo, double hi);
/// Metres per cell: 1 mm .. 10 km (a cell size of 1e-300 m was accepted and gave nonsense).
const CLI::Validator& cellSizeRange();

/// The range of a parameter's description (core/param_desc.h) as a flag check, so that a
/// flag out of range is a usage error naming the flag ("--max-passes: must lie in [1,
/// 10000], got 0"; exit 2) rather than a message in the parameter's TOML key after parsing.
template <typename S>
CLI::Validator paramCheck(const ParamDesc<S>& f) {
    const ParamRange range = f.range;
    const bool integer = f.kind != ParamDesc<S>::Kind::Real;
    return CLI::Validator(
        [range, integer](std::string& text) -> std::string {
            char* end = nullptr;
            errno = 0;
            const double v = std::strtod(text.c_str(), &end);
            if (text.empty() || *end != '\0' || errno == ERANGE || !std::isfinite(v)) return "'" + text + "' is not a number";
            if (integer && v != std::floor(v)) return "'" + text + "' is not a whole number";
            if (!range.contains(v)) return range.text() + ", got " + text;
            return "";
        },
        (integer ? "INT " : "NUMBER ") + range.valuesText());
}

/// One of `choices` ("--growth-rule: 'slow' is not one of ideal, literal").
CLI::Validator oneOf(const std::vector<std::string>& choices);
/// oneOf's validator name; its description is "one of a, b, c" (the completion reads both).
inline const std::string kOneOfValidatorName = "oneOf";

/// A text flag checked by `parse` (which throws eco::Error with its reason) at parse time,
/// so that a malformed window, crop or list is a usage error (exit 2) naming the flag.
/// `flag` is dropped from the front of the reason (CLI11 prints it before the reason).
CLI::Validator parsedBy(const std::string& flag, const std::function<void(const std::string&)>& parse);

/// A usage error found after parsing, from flags read together (e.g. --min-height above
/// --max-height): thrown as CLI11's, so it prints and exits as every usage error (2).
[[noreturn]] void usageError(const std::string& flags, const std::string& message);

/// A flag's help text from the description of the parameter it sets (core/param_desc.h),
/// so that --help and the docs' parameter tables say the same: `prefix` and the doc line,
/// capitalised when there is no prefix, and the unit after a comma ("... this radius, m", as
/// in eco config defaults).
template <typename S>
std::string paramHelp(const ParamDesc<S>& f, const std::string& prefix = "") {
    std::string doc = paramDocWithUnit(f);
    if (prefix.empty() && !doc.empty() && doc[0] >= 'a' && doc[0] <= 'z') doc[0] = static_cast<char>(doc[0] - 'a' + 'A');
    return prefix + doc;
}

/// Which described parameter a flag sets (addParamOption): the descriptor table (its
/// address) and the key. eco config describe lists a parameter's flags from this.
struct ParamFlag {
    const void* table = nullptr;
    std::string key;
    std::string flag;  ///< the option's first long name, to tell a reused address
};
void noteParamFlag(const CLI::Option* option, const void* table, const std::string& key);
/// The parameter `option` sets, or nullptr for an option not made by addParamOption.
const ParamFlag* paramFlagOf(const CLI::Option* option);

/// The one way to declare a flag that sets a described parameter (core/param_desc.h): an
/// option `flag` (e.g. "--max-passes") bound to `target`, with the help text of the
/// parameter (paramHelp: doc, unit; `prefix` before it), the parameter's default (S{}) shown
/// as the flag's, and the range checked at parse time (paramCheck: a value
/// out of range is a usage error naming the flag, exit 2; seeds are checked by their
/// conversion). A new parameter thus gets its flag, help and docs row from its descriptor.
template <typename S, typename T>
CLI::Option* addParamOption(CLI::App* cmd, const std::string& flag, T& target, const std::vector<ParamDesc<S>>& fields,
                            const std::string& key, const std::string& prefix = "") {
    const ParamDesc<S>& f = paramField(fields, key);
    static const S defaults{};  // static: every byte initialised (see paramDocRow)
    CLI::Option* o = cmd->add_option(flag, target, paramHelp(f, prefix))->default_str(f.defaultText ? std::string(f.defaultText) : paramText(f, defaults, 6));
    if (f.kind != ParamDesc<S>::Kind::Seed) o->check(paramCheck(f));
    noteParamFlag(o, &fields, key);
    return o;
}

/// addParamOption bound to the parameter's own member of `params`.
template <typename S>
CLI::Option* addParamOption(CLI::App* cmd, const std::string& flag, S& params, const std::vector<ParamDesc<S>>& fields,
                            const std::string& key, const std::string& prefix = "") {
    const ParamDesc<S>& f = paramField(fields, key);
    switch (f.kind) {
        case ParamDesc<S>::Kind::Real: return addParamOption(cmd, flag, params.*(f.real), fields, key, prefix);
        case ParamDesc<S>::Kind::Integer: return addParamOption(cmd, flag, params.*(f.integer), fields, key, prefix);
        case ParamDesc<S>::Kind::Seed: break;
    }
    return addParamOption(cmd, flag, params.*(f.seed), fields, key, prefix);
}

/// addParamOption for every flag of a command's flag table (core/param_desc.h), bound to
/// `params`' members; returns each key with its option, for setGivenParams.
template <typename S>
std::vector<std::pair<std::string, CLI::Option*>> addParamOptions(CLI::App* cmd, const std::vector<ParamFlagName>& flags,
                                                                   S& params, const std::vector<ParamDesc<S>>& fields,
                                                                   const std::string& prefix = "") {
    std::vector<std::pair<std::string, CLI::Option*>> options;
    for (const auto& f : flags) options.emplace_back(f.key, addParamOption(cmd, f.flag, params, fields, f.key, prefix));
    return options;
}

/// The parameters whose flag was given (addParamOptions) as overrides, with the values the
/// flags wrote into `params`.
template <typename S>
void setGivenParams(ParamOverrides<S>& overrides, const std::vector<std::pair<std::string, CLI::Option*>>& options,
                    const S& params, const std::vector<ParamDesc<S>>& fields) {
    for (const auto& [key, option] : options) {
        if (!option->count()) continue;
        const ParamDesc<S>& f = paramField(fields, key);
        if (f.kind == ParamDesc<S>::Kind::Seed)
            overrides.setSeed(key, params.*(f.seed));
        else
            overrides.set(key, f.value(params));
    }
}

/// How much the command line prints: eco --quiet (errors only: no progress, no information,
/// no summaries or "wrote ..." lines on stdout) or --verbose (also the extra detail stages
/// offer, e.g. phase timings and a simulation line every year), before the command.
/// Commands whose result is the text they print (eco biome show, eco config defaults) print
/// it whatever the verbosity. One switch for every output path below.
enum class Verbosity { Quiet, Normal, Verbose };
void setVerbosity(Verbosity v);
Verbosity verbosity();

/// Print one informational line to stderr (stdout is kept for results); nothing with --quiet.
void info(const std::string& line);
/// One line of extra detail to stderr, with --verbose only.
void detail(const std::string& line);
/// Where results and summaries go: stdout, or a sink with --quiet.
std::ostream& resultStream();
/// printf to resultStream().
void printResult(const char* format, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 1, 2)))
#endif
    ;
/// True when the command line gave --threads (eco ensemble then leaves the threads alone).
bool threadsFlagGiven();
void setThreadsFlagGiven(bool given);

/// The command line's Reporter: results on stdout, information on stderr, Progress bars,
/// the simulation's year line, and SIGINT / SIGTERM during a simulation as a stop request.
class CliReporter : public pipeline::Reporter {
public:
    std::ostream& out() override;
    void info(const std::string& line) override;
    void detail(const std::string& line) override;
    std::unique_ptr<pipeline::ProgressBar> progress(const std::string& label, long total) override;
    std::unique_ptr<pipeline::SimulationProgress> simulationProgress(int totalYears) override;
    bool stopRequested() override;
};

/// "x0,y0,x1,y1" windows as the stages read them.
using pipeline::parseWindow;

}  // namespace eco::cli
