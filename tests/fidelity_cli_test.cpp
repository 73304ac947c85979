// eco fidelity from the command line: error paths and a tiny plot end to end (the
// measures themselves are tested in fidelity_test.cpp).
#include <omp.h>

#include <catch2/catch.hpp>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>

#include "h5_compare.h"
#include "test_util.h"

using namespace eco;


TEST_CASE("eco fidelity: bad input gives one clear line and exit 1", "[fidelity][cli]") {
    test::TempDir dir("fidelity_cli");
    auto r = test::runEco("fidelity --scene " + dir.file("missing.h5") + " --out-dir " + dir.file("out"));
    CHECK(r.exitCode == 1);
    CHECK(r.output.find("--scene") != std::string::npos);
    CHECK(r.output.find("missing.h5") != std::string::npos);

    // An unknown sampler is refused before any stage runs: nothing is written.
    r = test::runEco("fidelity --synth-method foo --out-dir " + dir.file("never"));
    CHECK(r.exitCode == 1);
    CHECK(r.output.find("'foo'") != std::string::npos);
    CHECK_FALSE(std::filesystem::exists(dir.file("never")));

    r = test::runEco("fidelity --crop 1,2,3 --out-dir " + dir.file("out"));
    CHECK(r.exitCode == 1);
    CHECK(r.output.find("--crop") != std::string::npos);

    r = test::runEco("fidelity --crop 0,0,15,15 --out-dir " + dir.file("out"));  // rmax 10 m > half of 15 m
    CHECK(r.exitCode == 1);
    CHECK(r.output.find("rmax") != std::string::npos);

    {
        std::ofstream cfg(dir.file("bad.toml"));
        cfg << "[fidelity]\nyears = 150\nseed_z = 3\n";
    }
    r = test::runEco("fidelity --config " + dir.file("bad.toml"));
    CHECK(r.exitCode == 1);
    CHECK(r.output.find("bad.toml") != std::string::npos);
    CHECK(r.output.find("seed_z") != std::string::npos);

    {
        std::ofstream cfg(dir.file("neg.toml"));
        cfg << "[fidelity]\nyears = -5\n";
    }
    r = test::runEco("fidelity --config " + dir.file("neg.toml"));
    CHECK(r.exitCode == 1);
    CHECK(r.output.find("years") != std::string::npos);

    // A canopy placer file: missing, with a bad key or value, or beside --canopy; refused
    // before any stage runs (nothing written).
    r = test::runEco("fidelity --canopy-config " + dir.file("nofile.toml") + " --out-dir " + dir.file("never"));
    CHECK(r.exitCode == 1);
    CHECK(r.output.find("--canopy-config") != std::string::npos);
    CHECK(r.output.find("nofile.toml") != std::string::npos);
    {
        std::ofstream cfg(dir.file("placer-key.toml"));
        cfg << "[canopy]\ncrown_fit_pases = 0\n";
        std::ofstream cfg2(dir.file("placer-value.toml"));
        cfg2 << "[canopy]\ncrown_fit_passes = 11\n";
    }
    r = test::runEco("fidelity --canopy-config " + dir.file("placer-key.toml") + " --out-dir " + dir.file("never"));
    CHECK(r.exitCode == 1);
    CHECK(r.output.find("placer-key.toml") != std::string::npos);
    CHECK(r.output.find("crown_fit_pases") != std::string::npos);
    r = test::runEco("fidelity --canopy-config " + dir.file("placer-value.toml") + " --out-dir " + dir.file("never"));
    CHECK(r.exitCode == 1);
    CHECK(r.output.find("crown_fit_passes") != std::string::npos);
    CHECK(r.output.find("11") != std::string::npos);
    r = test::runEco("fidelity --canopy-config " + dir.file("placer-key.toml") + " --canopy " + dir.file("bad.toml") +
                     " --out-dir " + dir.file("never"));
    CHECK(r.exitCode == 1);
    CHECK(r.output.find("--canopy-config") != std::string::npos);
    CHECK_FALSE(std::filesystem::exists(dir.file("never")));

    r = test::runEco("fidelity --seed-a 3 --seed-b 3 --out-dir " + dir.file("out"));
    CHECK(r.exitCode == 1);
    CHECK(r.output.find("seed") != std::string::npos);

    r = test::runEco("fidelity --help");
    CHECK(r.exitCode == 0);
    CHECK(r.output.find("--replicate") != std::string::npos);
}

TEST_CASE("eco fidelity end to end on a tiny plot: stages cached, same bits for 1 thread", "[fidelity][cli]") {
    // 64 x 64 cells, a 40 m plot, one simulated year: every stage in about 5 s.
    test::TempDir dir("fidelity_e2e");
    const std::string common = "fidelity --width 64 --height 64 --crop 5,5,45,45 --years 1 --sun-step 60 --sim-config " +
                               test::sourcePath("configs/sim-default.toml") + " --out-dir " + dir.file("out");
    auto r = test::runEco(common);
    REQUIRE(r.exitCode == 0);
    CHECK(r.output.find("| figure | scope | scene | replicate | CSR | score |") != std::string::npos);
    CHECK(r.output.find("reusing") == std::string::npos);
    CHECK(std::filesystem::exists(dir.file("out/fidelity.md")));
    CHECK(std::filesystem::exists(dir.file("out/sim-A.h5.cmd")));
    r = test::runEco("--threads 1 " + common + " --out-csv " + dir.file("again.csv"));
    REQUIRE(r.exitCode == 0);
    std::size_t reused = 0;
    for (std::size_t at = r.output.find("reusing"); at != std::string::npos; at = r.output.find("reusing", at + 1)) ++reused;
    CHECK(reused == 8);  // terrain, CHM, abiotics, canopy, A, B, database, scene
    std::ifstream a(dir.file("out/fidelity.csv")), b(dir.file("again.csv"));
    const std::string ta((std::istreambuf_iterator<char>(a)), {}), tb((std::istreambuf_iterator<char>(b)), {});
    CHECK(!ta.empty());
    CHECK(ta == tb);
    // Another seed for B: only B and what follows it are redone.
    r = test::runEco(common + " --seed-b 5");
    REQUIRE(r.exitCode == 0);
    CHECK(r.output.find("simulation A (seed 1): reusing") != std::string::npos);
    CHECK(r.output.find("simulation B (seed 5): reusing") == std::string::npos);
    // The methods compared: the stages and the structured scene are reused, the darts scene
    // made; the structured column holds the single-method report's figures.
    r = test::runEco(common + " --seed-b 5 --synth-method structured,darts");
    REQUIRE(r.exitCode == 0);
    CHECK(r.output.find("synthesis: reusing") != std::string::npos);
    CHECK(std::filesystem::exists(dir.file("out/scene-darts.h5")));
    const auto rows = test::readCsvRows(dir.file("out/methods.csv"));
    const auto single = test::readCsvRows(dir.file("out/fidelity.csv"));
    REQUIRE(rows.size() > 10);
    std::map<std::string, std::string> structured, darts;
    for (const auto& row : rows)
        if (row.at("kind") == "distance") (row.at("method") == "structured" ? structured : darts)[row.at("quantity")] = row.at("value");
    std::size_t matched = 0;
    for (const auto& row : single)
        if (row.at("kind") == "figure" && row.at("scope") == "overall") {
            INFO(row.at("quantity"));
            REQUIRE(structured.count(row.at("quantity")) == 1);
            // (fidelity.csv has 8 significant digits)
            CHECK(std::stod(structured[row.at("quantity")]) == Approx(std::stod(row.at("scene"))).epsilon(1e-6));
            ++matched;
        }
    CHECK(matched >= 10);
    // Darts ignore the canopy: their under-crown shares are further from B's than the
    // structured sampler's (0.46 against 0.02 on this plot).
    const std::string underCrown = "under-crown share (|difference|, weighted by species)";
    CHECK(std::stod(darts.at(underCrown)) > std::stod(structured.at(underCrown)) + 0.1);
    const std::string md = test::fileBytes(dir.file("out/methods.md"));
    CHECK(md.find("| figure | replicate | CSR | structured | darts |") != std::string::npos);
    CHECK(md.find("### Speed of the undergrowth sampler") != std::string::npos);
    // Bad lists are refused before anything runs.
    r = test::runEco(common + " --synth-method structured,bogus");
    CHECK(r.exitCode == 1);
    CHECK(r.output.find("bogus") != std::string::npos);
    // A canopy placer file reaches the canopy stage: the canopy is placed again with it (the
    // terrain, CHM and abiotics reused), and its recorded command line names the file.
    {
        std::ofstream cfg(dir.file("fit-on.toml"));
        cfg << "[canopy]\ncrown_fit_passes = 2\n";
    }
    r = test::runEco(common + " --canopy-config " + dir.file("fit-on.toml"));
    REQUIRE(r.exitCode == 0);
    CHECK(r.output.find("abiotics: reusing") != std::string::npos);
    CHECK(r.output.find("canopy: reusing") == std::string::npos);
    CHECK(test::fileBytes(dir.file("out/canopy.h5.cmd")).find("fit-on.toml") != std::string::npos);
}
