// eco: the command-line front end of the ecosystem toolkit.
#include <omp.h>

#include <algorithm>
#include <iostream>
#include <new>

#include "cli_common.h"
#include "eco_version.h"
#include "error.h"
#include "provenance.h"

namespace eco::cli {

std::unique_ptr<CLI::App> makeApp() {
    auto app = std::make_unique<CLI::App>(
        "eco: simulate plant ecosystems, analyse them into biome databases, and synthesize "
        "large scenes from them.\nRun 'eco <command> --help' for each command.",
        "eco");
    app->footer("Exit status: 0 success; 1 bad input data (a file, a value in it, or a value out of range: one line "
                "naming the file, field and value); 2 usage error (unknown option, missing or malformed argument); "
                "3 eco validate: a check failed; 4 internal error (a bug: please report it).");
    app->set_version_flag("--version", std::string("eco ") + ECO_VERSION_STRING);
    app->require_subcommand(1);
    auto threads = std::make_shared<int>(0);
    app->add_option("--threads", *threads, "OpenMP threads, 1..1024 (default: all cores); results do not depend on it")
        ->check(CLI::Range(1, 1024));
    auto noProvenance = std::make_shared<bool>(false);
    app->add_flag("--no-provenance", *noProvenance,
                  "Leave the /provenance group (wall times, thread counts, dates) out of every HDF5 output, so that "
                  "two runs of the same inputs and seed write byte-identical files, whatever --threads");
    auto quiet = std::make_shared<bool>(false);
    auto verbose = std::make_shared<bool>(false);
    CLI::Option* quietFlag = app->add_flag("--quiet", *quiet,
                                           "Errors only: no progress, no information and no summaries (results go to "
                                           "the output files; eco biome show and eco config defaults still print)");
    CLI::Option* verboseFlag =
        app->add_flag("--verbose", *verbose, "Extra detail where a command has any (phase timings, a simulation line every year)");
    quietFlag->excludes(verboseFlag);
    app->parse_complete_callback([threads, noProvenance, quiet, verbose] {
        setVerbosity(*quiet ? Verbosity::Quiet : *verbose ? Verbosity::Verbose : Verbosity::Normal);
        if (*threads > 0) omp_set_num_threads(*threads);
        setThreadsFlagGiven(*threads > 0);
        setProvenanceRecorded(!*noProvenance);
    });

    registerTerrainCommands(*app);
    registerAbioticsCommand(*app);
    registerCanopyCommand(*app);
    registerSimulateCommand(*app);
    registerRunCommand(*app);
    registerAnalyseCommand(*app);
    registerInspectCommand(*app);
    registerPcfCommand(*app);
    registerSynthCommand(*app);
    registerCompareCommand(*app);
    registerValidateCommand(*app);
    registerFidelityCommand(*app);
    registerEnsembleCommand(*app);
    registerDatabaseCommands(*app);
    registerSensitivityCommand(*app);
    registerCalibrateCommand(*app);
    registerInstanceCommand(*app);
    registerConfigCommands(*app);
    registerDocsCommands(*app);
    return app;
}

}  // namespace eco::cli

namespace {
// The exit codes, documented in eco --help and the README.
constexpr int kExitBadInput = 1;
constexpr int kExitUsage = 2;
constexpr int kExitInternal = 4;  // 3 is eco validate's "a check failed" (cmd_validate.cpp)
}  // namespace

int main(int argc, char** argv) {
    eco::setCommandLine(argc, argv);  // recorded in every output's /provenance
    auto app = eco::cli::makeApp();
    try {
        app->parse(argc, argv);
    } catch (const CLI::ParseError& e) {
        // An unknown command: CLI11 only says "A subcommand is required"; name the word.
        if (app->get_subcommands().empty()) {
            for (int i = 1; i < argc; ++i) {
                const std::string word = argv[i];
                if (word == "--threads") ++i;  // the global option's value
                if (word.empty() || word[0] == '-') continue;
                std::string commands;
                bool known = false;
                for (const CLI::App* sub : app->get_subcommands([](CLI::App*) { return true; })) {
                    commands += (commands.empty() ? "" : ", ") + sub->get_name();
                    known = known || sub->get_name() == word;
                }
                if (known) break;
                std::cerr << "eco: unknown command '" << word << "' (commands: " << commands << ")\n"
                          << "Run with --help for more information.\n";
                return kExitUsage;
            }
        }
        // --help and --version end parsing with code 0; every other parse error is a usage
        // error: CLI11's message, then one exit code (2) whatever CLI11's own code.
        const int code = app->exit(e);
        return code == 0 ? 0 : kExitUsage;
    } catch (const eco::cli::ExitStatus& e) {
        std::cerr << "eco: " << e.message << "\n";
        return e.code;
    } catch (const eco::Error& e) {
        std::cerr << "eco: error: " << e.what() << "\n";
        return kExitBadInput;
    } catch (const std::bad_alloc&) {
        std::cerr << "eco: error: out of memory (the machine could not give what this run needs; try a smaller "
                     "scene or fewer threads)\n";
        return kExitBadInput;
    } catch (const std::exception& e) {
        std::cerr << "eco: internal error: " << e.what() << "\n";
        return kExitInternal;
    }
    return 0;
}
