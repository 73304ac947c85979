#include "cli_common.h"
namespace eco::cli {
void registerTerrainCommands(CLI::App&) {}
}
