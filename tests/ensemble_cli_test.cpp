// eco ensemble (issue 27): members, manifest and database; a failing member recorded while
// the others go on; a run killed at a checkpoint write and at a random time, then finished,
// gives the uninterrupted run's bytes; members in child processes and under MPI give the
// same bytes as one process.
#include <catch2/catch.hpp>

#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>

#include "eco_child.h"
#include "test_util.h"

using namespace eco;

namespace {

namespace fs = std::filesystem;

/// A specification of three tiny members (48 x 48 cells, 4 years, a checkpoint every year):
/// two terrain seeds, and one with a tenth of the seeding probability. `extra` is appended.
std::string writeEnsembleSpec(const test::TempDir& dir, const std::string& extra = "") {
    const std::string path = dir.file("ensemble.toml");
    std::ofstream(path) << "[ensemble]\nout_dir = \"" << dir.file("out") << "\"\nkmax = 2\n" << extra << "\n"
                        << "[ensemble.base.run]\nout_dir = \"unused\"\n"
                        << "[ensemble.base.terrain]\nwidth = 48\nheight = 48\n"
                        << "[ensemble.base.chm]\n[ensemble.base.abiotics]\nsun_step_minutes = 60\n[ensemble.base.canopy]\n"
                        << "[ensemble.base.simulate]\nconfig = \"" << test::sourcePath("configs/sim-default.toml") << "\"\n"
                        << "years = 4\ncrop = [4.0, 4.0, 40.0, 40.0]\n"
                        << "[vary]\n\"terrain.seed\" = [1, 2]\n\"simulation.run.checkpoint_every_years\" = [1]\n"
                        << "[[member]]\nname = \"sparse\"\n\"model.seeding_probability\" = 0.0003\n";
    return path;
}

/// The manifest's rows by member: its fields by column name.
std::map<std::string, std::map<std::string, std::string>> readManifest(const std::string& path) {
    std::map<std::string, std::map<std::string, std::string>> rows;
    for (auto& row : test::readCsvRows(path)) {
        REQUIRE(row.count("<fields>") == 0);
        rows[row["member"]] = row;
    }
    return rows;
}

/// The outputs of an ensemble folder without what records how the run went (logs, the
/// members' status files and the manifest carry wall times).
std::map<std::string, std::string> results(const fs::path& dir) {
    auto files = test::snapshotFiles(dir);
    for (auto it = files.begin(); it != files.end();) {
        const std::string name = fs::path(it->first).filename().string();
        if (name == "log.txt" || name == "database-log.txt" || name == "status.toml" || name == "manifest.csv") it = files.erase(it);
        else ++it;
    }
    return files;
}

void requireSameResults(const fs::path& a, const fs::path& b) {
    const auto ra = results(a), rb = results(b);
    REQUIRE(ra.size() > 20);
    for (const auto& [name, bytes] : ra) {
        INFO(name);
        REQUIRE(rb.count(name) == 1);
        CHECK(rb.at(name) == bytes);
    }
    CHECK(ra.size() == rb.size());
}

}  // namespace

TEST_CASE("eco ensemble: every member simulated, a manifest and one database, a rerun reuses all of it", "[ensemble][cli]") {
    test::TempDir dir("ensemble");
    const std::string spec = writeEnsembleSpec(dir);
    const auto dry = test::runEco("ensemble " + spec + " --dry-run");
    INFO(dry.output);
    REQUIRE(dry.exitCode == 0);
    CHECK(dry.output.find("m01\tpending\tsimulation.run.checkpoint_every_years = 1, terrain.seed = 1") != std::string::npos);
    CHECK(dry.output.find("sparse\tpending\tmodel.seeding_probability = 0.0003") != std::string::npos);

    const auto r = test::runEco("ensemble " + spec);
    INFO(r.output);
    REQUIRE(r.exitCode == 0);
    const auto manifest = readManifest(dir.file("out/manifest.csv"));
    REQUIRE(manifest.size() == 3);
    for (const auto& [id, row] : manifest) {
        INFO(id);
        CHECK(row.at("state") == "done");
        CHECK(row.at("years") == "4");
        CHECK(std::stol(row.at("plants")) > 0);
    }
    // The overrides reached the members: another terrain, fewer seedlings.
    CHECK(manifest.at("m01").at("terrain.seed") == "1");
    CHECK(manifest.at("m02").at("terrain.seed") == "2");
    CHECK(test::fileBytes(dir.file("out/members/m01/terrain.h5")) != test::fileBytes(dir.file("out/members/m02/terrain.h5")));
    CHECK(std::stol(manifest.at("sparse").at("plants")) * 3 < std::stol(manifest.at("m01").at("plants")));
    // One database of all three simulations.
    const std::string summary = test::fileBytes(dir.file("out/database.txt"));
    for (const char* id : {"m01", "m02", "sparse"})
        CHECK(summary.find(dir.file(std::string("out/members/") + id + "/simulation.h5")) != std::string::npos);

    const auto before = test::snapshotFiles(dir.path() / "out");
    const auto again = test::runEco("ensemble " + spec);
    INFO(again.output);
    REQUIRE(again.exitCode == 0);
    CHECK(again.output.find("started") == std::string::npos);
    CHECK(again.output.find("reusing " + dir.file("out/biome-db.h5")) != std::string::npos);
    CHECK(test::snapshotFiles(dir.path() / "out") == before);
}

TEST_CASE("eco ensemble: a failing member is recorded with its error, the others go on, no database", "[ensemble][cli]") {
    test::TempDir dir("ensemble_fail");
    const std::string spec = writeEnsembleSpec(dir);
    std::ofstream(spec, std::ios::app) << "[[member]]\nname = \"outside\"\n\"simulate.crop\" = [500.0, 500.0, 600.0, 600.0]\n";
    const auto r = test::runEco("ensemble " + spec);
    INFO(r.output);
    CHECK(r.exitCode == 1);
    CHECK(r.output.find("1 of 4 members not done (1 failed") != std::string::npos);
    const auto manifest = readManifest(dir.file("out/manifest.csv"));
    REQUIRE(manifest.size() == 4);
    CHECK(manifest.at("outside").at("state") == "failed");
    CHECK(manifest.at("outside").at("error").find("not inside the abiotics extent") != std::string::npos);
    for (const char* id : {"m01", "m02", "sparse"}) CHECK(manifest.at(id).at("state") == "done");
    CHECK_FALSE(fs::exists(dir.file("out/biome-db.h5")));
}

TEST_CASE("eco ensemble: bad specifications are refused before anything runs", "[ensemble][cli]") {
    test::TempDir dir("ensemble_bad");
    const std::vector<std::pair<std::string, std::string>> cases = {
        {"[[member]]\nname = \"typo\"\n\"terrain.widht\" = 10\n", "member 'typo'"},
        {"[[member]]\nname = \"m01\"\n", "two members are named 'm01'"},
        {"[[member]]\nname = \"bad/name\"\n", "field 'name'"},
        {"[[member]]\nname = \"nospecies\"\n\"biome.species.Nonesuch.alpha\" = 0.5\n", "no element named 'Nonesuch'"},
        {"[[member]]\nname = \"badalpha\"\n\"biome.species.Toyon.alpha\" = -3.0\n", "alpha"},
        {"[[member]]\nname = \"short\"\n\"seed\" = 3\n", "expected TABLE.KEY"},
    };
    for (const auto& [member, expect] : cases) {
        const std::string spec = writeEnsembleSpec(dir);
        std::ofstream(spec, std::ios::app) << member;
        const auto r = test::runEco("ensemble " + spec);
        INFO(member << "\n" << r.output);
        CHECK(r.exitCode == 1);
        CHECK(r.output.find(expect) != std::string::npos);
        // Checked before anything is written: no member's files, no output folder at all,
        // and the messages name the real folder, not the scratch copy they were checked in.
        CHECK_FALSE(fs::exists(dir.file("out")));
        CHECK(r.output.find("eco-ensemble-check") == std::string::npos);
    }
    // --dry-run lists the members and writes nothing either.
    const auto dry = test::runEco("ensemble --dry-run " + writeEnsembleSpec(dir));
    INFO(dry.output);
    CHECK(dry.exitCode == 0);
    CHECK(dry.output.find("sparse") != std::string::npos);
    CHECK_FALSE(fs::exists(dir.file("out")));
    const std::string emptyVary = writeEnsembleSpec(dir, "");
    std::ofstream(emptyVary, std::ios::app) << "[vary]\n";
    const auto r = test::runEco("ensemble " + emptyVary);
    CHECK(r.exitCode == 1);  // [vary] twice: a TOML error naming the file
    CHECK(r.output.find(emptyVary) != std::string::npos);
}

TEST_CASE("eco ensemble: killed at a checkpoint write and at a random time, then finished, gives the uninterrupted bytes",
          "[ensemble][kill][cli]") {
    test::TempDir dir("ensemble_kill");
    const std::string spec = writeEnsembleSpec(dir);
    const auto ref = test::runEco("--no-provenance ensemble " + spec);
    INFO(ref.output);
    REQUIRE(ref.exitCode == 0);
    fs::rename(dir.path() / "out", dir.path() / "ref");

    const std::vector<std::string> command = {"--no-provenance", "ensemble", spec};
    const std::string log = dir.file("killed.log");
    {
        // The sixth checkpoint write of the process: the second member's second year.
        test::EcoChild child(command, "write:simulation.h5.checkpoint.h5#6", log);
        REQUIRE(child.killAtPausePoint());
    }
    CHECK(fs::exists(dir.file("out/members/m01/status.toml")));
    CHECK_FALSE(fs::exists(dir.file("out/members/m02/status.toml")));
    std::mt19937 rng(27);
    for (int k = 0; k < 2; ++k) {
        test::EcoChild child(command, "", log);
        child.killAfter(std::chrono::milliseconds(std::uniform_int_distribution<int>(200, 2500)(rng)));
    }
    const auto last = test::runEco("--no-provenance ensemble " + spec);
    INFO(test::fileBytes(log) << last.output);
    REQUIRE(last.exitCode == 0);
    requireSameResults(dir.path() / "ref", dir.path() / "out");
    for (const auto& [id, row] : readManifest(dir.file("out/manifest.csv"))) CHECK(row.at("state") == "done");
}

TEST_CASE("eco ensemble: members in child processes and under MPI give the bytes of one process", "[ensemble][mpi][cli]") {
    test::TempDir dir("ensemble_procs");
    const std::string spec = writeEnsembleSpec(dir);
    const auto ref = test::runEco("--no-provenance --threads 1 ensemble " + spec);
    INFO(ref.output);
    REQUIRE(ref.exitCode == 0);
    fs::rename(dir.path() / "out", dir.path() / "ref");

    // Two members at once, each in its own process.
    const std::string atOnce = writeEnsembleSpec(dir, "members_at_once = 2");
    const auto r = test::runEco("--no-provenance ensemble " + atOnce);
    INFO(r.output);
    REQUIRE(r.exitCode == 0);
    CHECK(r.output.find("2 members at once, 1 threads each") != std::string::npos);
    requireSameResults(dir.path() / "ref", dir.path() / "out");
    fs::remove_all(dir.path() / "out");

    // Two MPI ranks.
#ifdef ECO_TEST_HAVE_MPI
    const auto mpi = test::runEcoMpi(2, "--no-provenance ensemble " + spec);
    const std::string& output = mpi.output;
    INFO(output);
    REQUIRE(mpi.exitCode == 0);
    CHECK(output.find("2 MPI ranks") != std::string::npos);
    CHECK(output.find("[rank 1]: member") != std::string::npos);
    requireSameResults(dir.path() / "ref", dir.path() / "out");
#else
    WARN("MPI part skipped: this build has no MPI (install libopenmpi-dev and configure again)");
#endif
}
