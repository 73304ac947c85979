// Plugins: shared modules that eco loads on first use, for the libraries whose loading at
// start would cost every process far more than its work (OpenImageIO: about 260 shared
// libraries, 0.3 s of each start). A plugin is the file eco_NAME.so in the first of these
// folders that holds it:
//   1. $ECO_PLUGIN_DIR, when set;
//   2. ../LIBDIR/eco next to the running executable (LIBDIR as installed, e.g. lib): the
//      installed eco, and every executable of a build tree (apps/, tests/, fuzz/, bench/ one
//      level below the build folder, whose plugins are in BUILD/LIBDIR/eco);
//   3. the install folder CMAKE_INSTALL_FULL_LIBDIR/eco configured at build time (programs
//      of one's own linked with the installed libraries);
//   4. the build tree's plugin folder (programs linked with a build tree's libraries).
// The plugin and the library must come from the same build: each entry point takes the ABI
// version it was built for and returns nothing on a mismatch.
#pragma once

#include <string>
#include <vector>

namespace eco {

/// The folders searched for plugins, in order (those that do not exist included).
std::vector<std::string> pluginDirs();

/// The entry point `symbol` of the plugin file `file` (e.g. "eco_oiio.so"), loaded once per
/// process and never unloaded. IoError naming the file, the folders searched and
/// ECO_PLUGIN_DIR when it is not found, and dlopen's reason when it does not load.
void* pluginEntry(const std::string& file, const char* symbol);

/// IoError: the plugin `file` was built for another version of eco.
[[noreturn]] void pluginAbiMismatch(const std::string& file);

/// The object a plugin's entry point `symbol` makes for the interface version `abi`: every
/// entry point has the signature `Plugin* entry(int abi)` and returns nullptr on a mismatch.
template <typename Plugin>
Plugin& loadPlugin(const std::string& file, const char* symbol, int abi) {
    using Entry = Plugin* (*)(int);
    Plugin* p = reinterpret_cast<Entry>(pluginEntry(file, symbol))(abi);
    if (p == nullptr) pluginAbiMismatch(file);
    return *p;
}

}  // namespace eco
