#include "plugin.h"

#include <dlfcn.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <map>
#include <mutex>

#include "error.h"

namespace eco {

namespace {

namespace fs = std::filesystem;

/// The folder of the running executable ("" when /proc is not there).
std::string executableDir() {
    std::error_code ec;
    const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
    return ec ? std::string() : exe.parent_path().string();
}

std::string loadedList(const std::vector<std::string>& dirs) {
    std::string out;
    for (const std::string& d : dirs) out += (out.empty() ? "" : ", ") + d;
    return out;
}

}  // namespace

std::vector<std::string> pluginDirs() {
    std::vector<std::string> dirs;
    if (const char* env = std::getenv("ECO_PLUGIN_DIR"); env && *env) dirs.emplace_back(env);
    if (const std::string exe = executableDir(); !exe.empty())
        dirs.push_back((fs::path(exe) / ECO_PLUGIN_RELATIVE_DIR).lexically_normal().string());
    dirs.emplace_back(ECO_PLUGIN_INSTALL_DIR);
    dirs.emplace_back(ECO_PLUGIN_BUILD_DIR);
    return dirs;
}

void* pluginEntry(const std::string& file, const char* symbol) {
    // Loaded once per process: a second thread asking at the same time waits for the first.
    static std::mutex mutex;
    static std::map<std::string, void*> loaded;
    const std::lock_guard<std::mutex> lock(mutex);
    const std::string key = file + ":" + symbol;
    if (const auto it = loaded.find(key); it != loaded.end()) return it->second;
    const std::vector<std::string> dirs = pluginDirs();
    for (const std::string& dir : dirs) {
        const std::string path = (fs::path(dir) / file).string();
        std::error_code ec;
        if (!fs::is_regular_file(path, ec)) continue;
        // RTLD_NODELETE: never unloaded, so objects it made stay valid until the process ends.
        void* handle = ::dlopen(path.c_str(), RTLD_NOW | RTLD_LOCAL | RTLD_NODELETE);
        if (!handle) {
            const char* why = ::dlerror();
            throw IoError("cannot load the plugin " + path + ": " + (why ? why : "unknown reason"));
        }
        void* entry = ::dlsym(handle, symbol);
        if (!entry) throw IoError("the plugin " + path + " has no entry point " + symbol + " (from another version of eco?)");
        loaded[key] = entry;
        return entry;
    }
    throw IoError("the plugin " + file + " was not found (looked in " + loadedList(dirs) +
                  "); set ECO_PLUGIN_DIR to the folder that holds it (docs/install.md)");
}

void pluginAbiMismatch(const std::string& file) {
    throw IoError("the plugin " + file + " was built for another version of eco; rebuild or reinstall it");
}

}  // namespace eco
