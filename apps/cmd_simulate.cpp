#include "cli_common.h"
namespace eco::cli {
void registerSimulateCommand(CLI::App&) {}
}  // namespace eco::cli
