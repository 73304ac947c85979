// eco: the command-line front end of the ecosystem toolkit.
#include <omp.h>

#include <iostream>

#include "cli_common.h"
#include "eco_version.h"
#include "error.h"

int main(int argc, char** argv) {
    CLI::App app{"eco: simulate plant ecosystems, analyse them into biome databases, and synthesize "
                 "large scenes from them.\nRun 'eco <command> --help' for each command."};
    app.set_version_flag("--version", std::string("eco ") + ECO_VERSION_STRING);
    app.require_subcommand(1);
    int threads = 0;
    app.add_option("--threads", threads, "OpenMP threads (default: all cores); results do not depend on it")
        ->check(CLI::NonNegativeNumber);
    app.parse_complete_callback([&] {
        if (threads > 0) omp_set_num_threads(threads);
    });

    eco::cli::registerTerrainCommands(app);
    eco::cli::registerAbioticsCommand(app);
    eco::cli::registerCanopyCommand(app);
    eco::cli::registerSimulateCommand(app);
    eco::cli::registerRunCommand(app);

    try {
        app.parse(argc, argv);
    } catch (const CLI::ParseError& e) {
        return app.exit(e);
    } catch (const eco::Error& e) {
        std::cerr << "eco: error: " << e.what() << "\n";
        return 1;
    } catch (const std::exception& e) {
        std::cerr << "eco: internal error: " << e.what() << "\n";
        return 2;
    }
    return 0;
}
