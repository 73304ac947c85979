// eco sensitivity end to end (issue 28 item 3) on a tiny scene: a Morris screening of two
// model constants, one of which cannot act (the Deussen model's survival while the resource
// model runs): with the replicates' seeds shared by every design point its effects must be
// exactly zero, while the seeding probability drives the density; a rerun reuses every
// simulation; a bad specification is refused before anything runs.
#include <catch2/catch.hpp>

#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>

#include "atomic_file.h"
#include "test_util.h"

using namespace eco;

namespace {

namespace fs = std::filesystem;

std::string writeSensitivitySpec(const test::TempDir& dir, const std::string& outputs) {
    const std::string path = dir.file("sensitivity.toml");
    std::ofstream(path) << "[sensitivity]\nout_dir = \"" << dir.file("out") << "\"\ntrajectories = 2\nlevels = 4\nreplicates = 2\n"
                        << "outputs = " << outputs << "\n"
                        << "[sensitivity.parameters]\n\"model.seeding_probability\" = [0.0005, 0.003]\n"
                        << "\"model.deussen_dominated_survival\" = [0.2, 0.8]\n"
                        << "[sensitivity.base.run]\nout_dir = \"unused\"\n"
                        << "[sensitivity.base.terrain]\nwidth = 48\nheight = 48\n"
                        << "[sensitivity.base.chm]\n[sensitivity.base.abiotics]\nsun_step_minutes = 60\n[sensitivity.base.canopy]\n"
                        << "[sensitivity.base.simulate]\nconfig = \"" << test::sourcePath("configs/sim-default.toml") << "\"\n"
                        << "years = 3\ncrop = [4.0, 4.0, 40.0, 40.0]\n";
    return path;
}

/// sensitivity.csv as (output, parameter) -> column -> value.
std::map<std::pair<std::string, std::string>, std::map<std::string, std::string>> readCsv(const std::string& path) {
    std::map<std::pair<std::string, std::string>, std::map<std::string, std::string>> rows;
    for (auto& row : test::readCsvRows(path)) {
        REQUIRE(row.count("<fields>") == 0);
        rows[{row["output"], row["parameter"]}] = row;
    }
    return rows;
}

}  // namespace

TEST_CASE("eco sensitivity: Morris screening through the ensemble, a parameter without effect scores exactly 0", "[sensitivity][cli]") {
    test::TempDir dir("sensitivity_cli");
    const std::string spec = writeSensitivitySpec(dir, "[\"density@3\", \"share:Redwood Sorrel@3\", \"cv@1-3\"]");
    const auto r = test::runEco("sensitivity " + spec);
    INFO(r.output);
    REQUIRE(r.exitCode == 0);
    CHECK(r.output.find("12 of 12 done") != std::string::npos);
    for (const char* f : {"sensitivity.md", "sensitivity.csv", "design.csv", "ensemble.toml", "png/morris_1.png", "png/morris_3.png"})
        CHECK(fs::exists(dir.file(std::string("out/") + f)));
    const auto rows = readCsv(dir.file("out/sensitivity.csv"));
    REQUIRE(rows.size() == 6);
    for (const char* out : {"density@3", "cv@1-3"}) {
        INFO(out);
        const auto& none = rows.at({out, "model.deussen_dominated_survival"});
        CHECK(std::stod(none.at("mu_star")) == 0);
        CHECK(std::stod(none.at("sigma")) == 0);
        CHECK(none.at("rank") == "2");
        CHECK(none.at("above_noise") == "no");
    }
    const auto& seeding = rows.at({"density@3", "model.seeding_probability"});
    CHECK(std::stod(seeding.at("mu")) > 0);  // more seeds, more plants
    CHECK(seeding.at("rank") == "1");
    CHECK(seeding.at("above_noise") == "yes");
    CHECK(std::stod(seeding.at("mu_star_seed_noise")) > 0);

    // The same command again: every simulation reused, the same report.
    const std::string csv = readTextFile(dir.file("out/sensitivity.csv"));
    const auto again = test::runEco("sensitivity " + spec);
    INFO(again.output);
    REQUIRE(again.exitCode == 0);
    CHECK(again.output.find("started") == std::string::npos);
    CHECK(readTextFile(dir.file("out/sensitivity.csv")) == csv);
}

TEST_CASE("eco sensitivity: a bad specification is refused with its file and key, before anything runs", "[sensitivity][cli]") {
    test::TempDir dir("sensitivity_bad");
    for (const auto& [outputs, expect] : std::vector<std::pair<std::string, std::string>>{
             {"[]", "no output"}, {"[\"height@3\"]", "unknown measure"}, {"[\"density@3\"]\nlevels = 3", "levels"}}) {
        const auto r = test::runEco("sensitivity " + writeSensitivitySpec(dir, outputs));
        INFO(r.output);
        CHECK(r.exitCode == 1);
        CHECK(r.output.find("sensitivity.toml") != std::string::npos);
        CHECK(r.output.find(expect) != std::string::npos);
        CHECK_FALSE(fs::exists(dir.file("out")));
    }
    // A key the members' configuration does not have: found when the members are checked
    // (after the design and the members' specification are written), before any runs.
    std::string spec = writeSensitivitySpec(dir, "[\"density@3\"]");
    {
        std::string text = readTextFile(spec);
        text.replace(text.find("\"model.deussen_dominated_survival\""), 34, "\"model.no_such_constant\"");
        std::ofstream(spec) << text;
    }
    const auto r = test::runEco("sensitivity " + spec);
    INFO(r.output);
    CHECK(r.exitCode == 1);
    CHECK(r.output.find("no_such_constant") != std::string::npos);
    CHECK_FALSE(fs::exists(dir.file("out/ensemble/members")));
}

TEST_CASE("eco sensitivity: Sobol indices through the ensemble, log-scaled range, a parameter without effect has S = ST = 0", "[sensitivity][cli]") {
    test::TempDir dir("sensitivity_sobol_cli");
    std::string spec = writeSensitivitySpec(dir, "[\"density@3\", \"height_q90@3\"]");
    {
        std::string text = readTextFile(spec);
        // One replicate (16 simulations; the seed noise is then not measured).
        text.replace(text.find("trajectories = 2\nlevels = 4\nreplicates = 2\n"), 43, "method = \"sobol\"\nsamples = 4\nbootstrap = 100\nreplicates = 1\n");
        text.replace(text.find("[0.0005, 0.003]"), 15, "{ low = 0.0003, high = 0.003, scale = \"log\" }");
        std::ofstream(spec) << text;
    }
    const auto r = test::runEco("sensitivity " + spec);
    INFO(r.output);
    REQUIRE(r.exitCode == 0);
    CHECK(r.output.find("16 of 16 done") != std::string::npos);  // N (k + 2) R = 4 x 4 x 1
    for (const char* f : {"sensitivity.md", "sensitivity.csv", "design.csv", "png/sobol_1.png", "png/sobol_2.png"})
        CHECK(fs::exists(dir.file(std::string("out/") + f)));
    const auto rows = readCsv(dir.file("out/sensitivity.csv"));
    REQUIRE(rows.size() == 4);
    for (const char* out : {"density@3", "height_q90@3"}) {
        INFO(out);
        const auto& none = rows.at({out, "model.deussen_dominated_survival"});
        CHECK(std::stod(none.at("first")) == 0);
        CHECK(std::stod(none.at("total")) == 0);
        CHECK(std::stod(none.at("total_high")) == 0);
        CHECK(none.at("rank") == "2");
    }
    const auto& seeding = rows.at({"density@3", "model.seeding_probability"});
    CHECK(seeding.at("scale") == "log");
    CHECK(std::stod(seeding.at("total")) > 0.5);  // the only parameter that acts
    CHECK(std::stod(seeding.at("total_low")) <= std::stod(seeding.at("total")));
    CHECK(seeding.at("rank") == "1");
    CHECK(seeding.at("seed_noise_share").empty());
    CHECK(seeding.at("above_noise") == "unknown");
    // The design's seeding probabilities lie in the range and spread over its decade.
    double lo = 1, hi = 0;
    for (auto& row : test::readCsvRows(dir.file("out/design.csv"))) {
        const double p = std::stod(row.at("model.seeding_probability"));
        lo = std::min(lo, p);
        hi = std::max(hi, p);
    }
    CHECK(lo >= 0.0003);
    CHECK(hi <= 0.003);
    CHECK(hi / lo > 2);
}
