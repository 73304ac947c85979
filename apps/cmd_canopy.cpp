#include "cli_common.h"
namespace eco::cli {
void registerCanopyCommand(CLI::App&) {}
}  // namespace eco::cli
