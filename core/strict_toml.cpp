#include "strict_toml.h"
#include "provenance.h"

#include <fstream>

namespace eco {

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
