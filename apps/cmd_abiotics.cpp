#include "cli_common.h"
namespace eco::cli {
void registerAbioticsCommand(CLI::App&) {}
}
