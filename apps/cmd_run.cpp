#include "cli_common.h"
namespace eco::cli {
void registerRunCommand(CLI::App&) {}
}  // namespace eco::cli
