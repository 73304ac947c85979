// eco: the command-line front end of the ecosystem toolkit.
#include <omp.h>

#include <algorithm>
#include <iostream>

#include "cli_common.h"
#include "eco_version.h"
#include "error.h"

namespace eco::cli {

std::unique_ptr<CLI::App> makeApp() {
    auto app = std::make_unique<CLI::App>(
        "eco: simulate plant ecosystems, analyse them into biome databases, and synthesize "
        "large scenes from them.\nRun 'eco <command> --help' for each command.",
        "eco");
    app->set_version_flag("--version", std::string("eco ") + ECO_VERSION_STRING);
    app->require_subcommand(1);
    auto threads = std::make_shared<int>(0);
    app->add_option("--threads", *threads, "OpenMP threads (default: all cores); results do not depend on it")
        ->check(CLI::NonNegativeNumber);
    app->parse_complete_callback([threads] {
        if (*threads > 0) omp_set_num_threads(*threads);
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
    return app;
}

}  // namespace eco::cli

int main(int argc, char** argv) {
    auto app = eco::cli::makeApp();
    try {
        app->parse(argc, argv);
    } catch (const CLI::ParseError& e) {
        return app->exit(e);
    } catch (const eco::cli::ExitStatus& e) {
        std::cerr << "eco: " << e.message << "\n";
        return e.code;
    } catch (const eco::Error& e) {
        std::cerr << "eco: error: " << e.what() << "\n";
        return 1;
    } catch (const std::exception& e) {
        std::cerr << "eco: internal error: " << e.what() << "\n";
        return 2;
    }
    return 0;
}
