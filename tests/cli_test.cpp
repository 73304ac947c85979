// The command-line front end as a user meets it: --help, --version, and one clear error
// line with a non-zero exit for bad input, leaving no output behind.
#include <catch2/catch.hpp>

#include <filesystem>
#include <fstream>

#include "eco_version.h"
#include "test_util.h"

using eco::test::runEco;

namespace {

int lineCount(const std::string& s) {
    int n = 0;
    for (char c : s) n += c == '\n';
    return n;
}

}  // namespace

TEST_CASE("eco --version and --help", "[cli]") {
    const auto v = runEco("--version");
    CHECK(v.exitCode == 0);
    CHECK_THAT(v.output, Catch::Contains(ECO_VERSION_STRING));
    const auto h = runEco("--help");
    CHECK(h.exitCode == 0);
    for (const char* cmd : {"terrain", "chm", "abiotics", "canopy", "simulate", "run"})
        CHECK_THAT(h.output, Catch::Contains(cmd));
}

TEST_CASE("every command has --help", "[cli]") {
    for (const char* cmd : {"terrain generate", "terrain convert", "chm generate", "abiotics", "canopy", "simulate", "run"}) {
        INFO(cmd);
        const auto r = runEco(std::string(cmd) + " --help");
        CHECK(r.exitCode == 0);
        CHECK_THAT(r.output, Catch::Contains("Usage") || Catch::Contains("usage"));
    }
}

TEST_CASE("no command or an unknown one is an error", "[cli]") {
    CHECK(runEco("").exitCode != 0);
    const auto r = runEco("frobnicate");
    CHECK(r.exitCode != 0);
}

TEST_CASE("a missing terrain gives one line naming it and leaves no output", "[cli]") {
    eco::test::TempDir dir("cli");
    const std::string out = dir.file("abiotics.h5");
    const auto r = runEco("abiotics --terrain " + dir.file("nope.asc") + " --out " + out);
    CHECK(r.exitCode == 1);
    CHECK_THAT(r.output, Catch::StartsWith("eco: error: ") && Catch::Contains("nope.asc"));
    CHECK(lineCount(r.output) == 1);
    CHECK_FALSE(std::filesystem::exists(out));
    CHECK(std::distance(std::filesystem::directory_iterator(dir.path()), std::filesystem::directory_iterator()) == 0);
}

TEST_CASE("a bad biome file through the CLI names the file, species and field", "[cli]") {
    eco::test::TempDir dir("cli");
    const std::string terrain = dir.file("t.asc");
    {
        std::ofstream t(terrain);
        t << "ncols 4\nnrows 3\nxllcorner 0\nyllcorner 0\ncellsize 1\n";
        for (int i = 0; i < 3; ++i) t << "1 2 3 4\n";
    }
    std::ifstream in(eco::test::sourcePath("biomes/sonoma.toml"));
    std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    const auto p = text.find("alpha = 0.45");  // Redwood, the last species
    REQUIRE(p != std::string::npos);
    text.replace(p, 12, "alpha = 2.0");
    const std::string biome = dir.file("bad.toml");
    std::ofstream(biome) << text;
    const std::string out = dir.file("a.h5");
    const auto r = runEco("abiotics --terrain " + terrain + " --biome " + biome + " --out " + out);
    CHECK(r.exitCode == 1);
    CHECK_THAT(r.output, Catch::Contains("bad.toml") && Catch::Contains("species 'Redwood'") && Catch::Contains("alpha"));
    CHECK_FALSE(std::filesystem::exists(out));
}
