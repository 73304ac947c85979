#include "strict_toml.h"
#include "provenance.h"

#include <filesystem>
#include <fstream>

namespace eco {

std::string pathRelativeToConfig(const std::string& configPath, const std::string& value) {
    namespace fs = std::filesystem;
    // "embedded:NAME" names a configuration built into eco (sim::loadRunConfig), not a file.
    if (value.empty() || fs::path(value).is_absolute() || value.rfind("embedded:", 0) == 0) return value;
    const fs::path dir = fs::path(configPath).parent_path();
    if (dir.empty()) return value;
    return (dir / value).lexically_normal().string();
}

void absolutizeConfigPaths(toml::table& config, const std::string& configPath,
                           const std::vector<std::pair<std::string, std::string>>& pathKeys) {
    for (const auto& [table, key] : pathKeys) {
        toml::table* t = table.empty() ? &config : config[table].as_table();
        if (!t) continue;
        toml::value<std::string>* v = t->get_as<std::string>(key);
        if (!v || v->get().empty() || v->get().rfind("embedded:", 0) == 0) continue;  // built in, not a file
        v->get() = std::filesystem::absolute(pathRelativeToConfig(configPath, v->get())).lexically_normal().string();
    }
}

toml::table parseTomlText(const std::string& text, const std::string& sourceName) {
    try {
        return toml::parse(text, sourceName);
    } catch (const toml::parse_error& e) {
        throw IoError(sourceName + ":" + std::to_string(e.source().begin.line) + ": invalid TOML: " +
                      std::string(e.description()));
    }
}

toml::table parseTomlFile(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    if (!in) throw IoError(path + ": cannot open file (missing or unreadable)");
    noteInputFile(path);  // recorded in /provenance with its hash
    std::ostringstream ss;
    ss << in.rdbuf();
    if (in.bad()) throw IoError(path + ": error while reading");
    return parseTomlText(ss.str(), path);
}

}  // namespace eco
