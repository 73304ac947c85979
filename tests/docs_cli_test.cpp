// eco completion bash, eco manpage and cmake --install (issue 31 item 7): generated from the
// command tree, so the tests check them against what eco itself accepts and prints.
#include <catch2/catch.hpp>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <regex>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "test_util.h"

using eco::test::runEco;
using eco::test::TempDir;

namespace {

std::string shellQuote(const std::string& s) {
    std::string q = "'";
    for (char c : s) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
    return q + "'";
}

/// Run a shell command line, capturing stdout and stderr; the exit code in `status`.
std::string shell(const std::string& cmd, int& status) {
    std::string out;
    FILE* pipe = ::popen((cmd + " 2>&1").c_str(), "r");
    REQUIRE(pipe != nullptr);
    char buf[4096];
    std::size_t n;
    while ((n = std::fread(buf, 1, sizeof buf, pipe)) > 0) out.append(buf, n);
    const int s = ::pclose(pipe);
    status = WIFEXITED(s) ? WEXITSTATUS(s) : -1;
    return out;
}

/// The words bash's completion offers after the command line `line` (the last word is the one
/// being completed, "" for a new word), in a directory with no files.
std::set<std::string> complete(const std::string& script, const std::string& line, const std::string& emptyDir) {
    std::istringstream in(line);
    std::vector<std::string> words;
    for (std::string w; in >> w;) words.push_back(w);
    if (line.empty() || line.back() == ' ') words.push_back("");
    std::string array;
    for (const auto& w : words) array += " " + shellQuote(w);
    const std::string program = "source " + shellQuote(script) + " && cd " + shellQuote(emptyDir) + " && COMP_WORDS=(" + array +
                                ") && COMP_CWORD=" + std::to_string(words.size() - 1) +
                                " && _eco && printf '%s\\n' \"${COMPREPLY[@]}\"";
    int status = 0;
    const std::string out = shell("bash -c " + shellQuote(program), status);
    INFO(line << " -> " << out);
    REQUIRE(status == 0);
    std::set<std::string> offered;
    std::istringstream lines(out);
    for (std::string w; std::getline(lines, w);)
        if (!w.empty()) offered.insert(w);
    return offered;
}

/// The top-level commands eco --help lists.
std::vector<std::string> helpCommands() {
    const auto help = runEco("--help");
    REQUIRE(help.exitCode == 0);
    const auto at = help.output.find("Subcommands:");
    REQUIRE(at != std::string::npos);
    std::vector<std::string> commands;
    std::istringstream in(help.output.substr(at));
    std::string line;
    std::getline(in, line);
    const std::regex command("^  ([a-z0-9-]+) ");
    for (std::smatch m; std::getline(in, line);)
        if (std::regex_search(line, m, command)) commands.push_back(m[1]);
    return commands;
}

}  // namespace

TEST_CASE("eco completion bash: bash completes commands, options, option values and choices", "[cli][docs]") {
    TempDir dir("completion");
    std::filesystem::create_directories(dir.file("empty"));
    const auto r = runEco("completion bash");
    REQUIRE(r.exitCode == 0);
    const std::string script = dir.file("eco.bash");
    std::ofstream(script) << r.output;
    int status = 0;
    INFO(shell("bash -n " + shellQuote(script), status));
    REQUIRE(status == 0);
    const std::string empty = dir.file("empty");

    // Every command of eco --help, and nothing hidden (the man page generator).
    const std::set<std::string> top = complete(script, "eco ", empty);
    const std::vector<std::string> commands = helpCommands();
    REQUIRE(commands.size() > 15);
    for (const auto& c : commands) CHECK(top.count(c) == 1);
    CHECK(top.count("manpage") == 0);
    CHECK(complete(script, "eco sy", empty) == std::set<std::string>{"synth"});
    // Nested commands, after a global option and its value.
    CHECK(complete(script, "eco --threads 2 terrain ", empty) == std::set<std::string>{"generate", "convert"});
    // Options of the command being typed, not of another.
    const std::set<std::string> synthOptions = complete(script, "eco synth --me", empty);
    CHECK(synthOptions == std::set<std::string>{"--method"});
    CHECK(complete(script, "eco instance --me", empty).empty());
    // The fixed choices of an option and of a positional argument.
    CHECK(complete(script, "eco synth --method ", empty) == std::set<std::string>{"structured", "darts", "deussen", "xu2015"});
    CHECK(complete(script, "eco synth --method x", empty) == std::set<std::string>{"xu2015"});
    CHECK(complete(script, "eco config defaults ", empty) == std::set<std::string>{"simulate", "canopy"});
    CHECK(complete(script, "eco instance --weight ", empty) == std::set<std::string>{"area", "none"});
    CHECK(complete(script, "eco simulate --model ", empty) == std::set<std::string>{"monthly", "ecomod"});
    // A value that is a file: the directory's files are offered.
    std::ofstream(dir.file("empty/demo.toml")) << "";
    CHECK(complete(script, "eco run de", empty) == std::set<std::string>{"demo.toml"});
}

TEST_CASE("eco manpage: every command and option, roff that man renders without warnings", "[cli][docs]") {
    TempDir dir("manpage");
    const auto r = runEco("manpage");
    REQUIRE(r.exitCode == 0);
    const std::string page = dir.file("eco.1");
    std::ofstream(page) << r.output;
    CHECK(r.output.rfind(".\\\" Generated by 'eco manpage'", 0) == 0);
    CHECK(r.output.find(".TH ECO 1") != std::string::npos);
    for (const auto& c : helpCommands()) {
        INFO(c);
        CHECK(r.output.find(".SS \"eco " + c + "\"") != std::string::npos);
    }
    CHECK(r.output.find(".SS \"eco terrain generate\"") != std::string::npos);
    CHECK(r.output.find(".SS \"eco manpage\"") == std::string::npos);
    // Every option of eco synth --help, with roff's \- for each dash.
    const auto help = runEco("synth --help");
    REQUIRE(help.exitCode == 0);
    const std::regex option("(--[a-z0-9-]+)");
    int options = 0;
    for (auto it = std::sregex_iterator(help.output.begin(), help.output.end(), option); it != std::sregex_iterator(); ++it) {
        const std::string name = (*it)[1];
        std::string roff;
        for (char c : name) roff += c == '-' ? std::string("\\-") : std::string(1, c);
        INFO(name);
        CHECK(r.output.find("\\fB" + roff + "\\fR") != std::string::npos);
        ++options;
    }
    CHECK(options > 10);
    // groff in warning mode: no line it cannot parse, no unknown escape, no bad macro.
    int status = 0;
    const std::string warnings = shell("groff -man -Tutf8 -ww -z " + shellQuote(page), status);
    INFO(warnings);
    CHECK(status == 0);
    CHECK(warnings.empty());
    // The rendered text names the exit codes of --help's footer.
    const std::string text = shell("groff -man -Tascii -P -cbou " + shellQuote(page), status);
    const std::string words = std::regex_replace(text, std::regex("\\s+"), " ");
    INFO(text.substr(text.size() > 1500 ? text.size() - 1500 : 0));
    CHECK(words.find("2 usage error") != std::string::npos);
}

TEST_CASE("cmake --install: a program of one's own builds with find_package(eco) and runs", "[cli][install]") {
    // tests/install/run.cmake: installs this build into a fresh prefix, checks the files (binary,
    // man page, completion, headers, libraries, CMake package, LICENSE, CITATION.cff), then
    // configures, builds and runs tests/install/consumer against that prefix alone.
    TempDir dir("install");
    int status = 0;
    const std::string out = shell("cmake -DBUILD=" + shellQuote(ECO_BUILD_DIR) + " -DSOURCE=" + shellQuote(ECO_SOURCE_DIR) +
                                      " -DWORK=" + shellQuote(dir.file("work")) + " -P " +
                                      shellQuote(eco::test::sourcePath("tests/install/run.cmake")),
                                  status);
    INFO(out);
    CHECK(status == 0);
    CHECK(out.find("biome Sonoma species 16") != std::string::npos);
}

TEST_CASE("docs: every parameter table in docs/ is what eco config describe prints from the descriptors", "[cli][docs]") {
    // Issue 23 item 5: the parameter tables of the docs are generated from the descriptors
    // (core/param_desc.h) by tools/param_docs.py between marker lines; a table edited by hand,
    // or a descriptor changed without regenerating the docs, fails here (the difference shown).
    const std::regex begin(R"(^<!-- generated: eco (config describe [^(]*?) \(tools/param_docs\.py; do not edit\) -->$)");
    // What eco prints for each block: every table at once ("### NAME (...)" before each; one
    // eco run instead of one per table), the index on its own.
    std::map<std::string, std::string> printed;
    {
        const auto all = runEco("config describe --markdown");
        REQUIRE(all.exitCode == 0);
        std::istringstream in(all.output);
        std::string name;
        for (std::string line; std::getline(in, line);) {
            if (line.rfind("### ", 0) == 0) {
                name = "config describe --markdown " + line.substr(4, line.find(' ', 4) - 4);
                std::getline(in, line);  // the blank line after the heading
            } else if (!line.empty() && !name.empty()) {
                printed[name] += line + "\n";
            }
        }
        const auto index = runEco("config describe --index");
        REQUIRE(index.exitCode == 0);
        printed["config describe --index"] = index.output;
    }
    std::set<std::string> blocks;
    for (const auto& entry : std::filesystem::directory_iterator(eco::test::sourcePath("docs"))) {
        if (entry.path().extension() != ".md") continue;
        std::ifstream in(entry.path());
        std::vector<std::string> lines;
        for (std::string line; std::getline(in, line);) lines.push_back(line);
        for (std::size_t i = 0; i < lines.size(); ++i) {
            std::smatch m;
            if (!std::regex_match(lines[i], m, begin)) continue;
            const std::string args = m[1];
            std::string text;
            std::size_t end = i + 1;
            for (; end < lines.size() && lines[end] != "<!-- end generated -->"; ++end) text += lines[end] + "\n";
            INFO(entry.path().filename().string() << ": eco " << args << " (regenerate: tools/param_docs.py build/apps/eco)");
            REQUIRE(end < lines.size());
            REQUIRE(printed.count(args) == 1);
            CHECK(text == printed.at(args));
            blocks.insert(args);
            i = end;
        }
    }
    // Every table eco describes has its block somewhere in docs/, and so has the list of tables.
    const auto all = runEco("config describe");
    REQUIRE(all.exitCode == 0);
    std::set<std::string> tables;
    std::istringstream rows(all.output);
    for (std::string row; std::getline(rows, row);) tables.insert(row.substr(0, row.find('\t')));
    CHECK(tables.size() >= 12);
    for (const std::string& t : tables) {
        INFO("table " << t);
        CHECK(blocks.count("config describe --markdown " + t) == 1);
    }
    CHECK(blocks.count("config describe --index") == 1);
    // The rows carry what the brief asks for: default, unit, an allowed range and the flags
    // declared from the descriptor (addParamOption), found from the command tree.
    const auto canopy = runEco("config describe --markdown canopy");
    CHECK_THAT(canopy.output, Catch::Contains("| `max_iterations` | 30 | - | iterations of the placer at most | [0, 100000] | "
                                              "`eco canopy --max-iterations` |"));
    CHECK_THAT(canopy.output, Catch::Contains("| `min_trunk_distance_m` | 1 | m | duplicates: trunks closer than this | >= 0 | "
                                              "`eco canopy --min-trunk-distance` |"));
    // A flag declared from its descriptor: help text with the unit, the default and the range.
    const auto help = runEco("canopy --help");
    CHECK_THAT(help.output, Catch::Contains("--min-trunk-distance FLOAT:NUMBER >= 0=1") &&
                                Catch::Contains("Duplicates: trunks closer than this, m"));
    const auto unknown = runEco("config describe nope");
    CHECK(unknown.exitCode == 2);
    CHECK_THAT(unknown.output, Catch::Contains("unknown parameter table 'nope'"));
}
