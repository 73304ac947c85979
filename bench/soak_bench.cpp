// Soak run (issue 26, item 6): many short pipelines in a loop in ONE process, with the
// process's memory and open file descriptors watched between iterations. A leak that a
// single command-line run never shows (an HDF5 handle left open, an OpenImageIO or GDAL
// object never freed, a thread pool that grows) shows here as descriptors or resident
// memory that keep rising with the iteration count.
//
// Each iteration runs the whole pipeline of a small configuration (eco run: generated
// terrain, CHM, abiotics, canopy, a short undergrowth simulation, the database, the target
// terrain, synthesis with refinement, comparison, GeoTIFFs and a GeoPackage, pictures and
// the report) into a fresh folder, then one bad input per reader (each must throw eco's
// error and leave nothing behind), then removes the folder. Every third iteration checks
// that the database and the scene are the same bytes as the first iteration's (apart from
// the HDF5 files' provenance, compared through their datasets by size and hash of the
// plant arrays): the results must not drift while the process ages.
//
// Usage: bench_soak [RESULTS.txt] [ITERATIONS] [WORK_DIR]
//   defaults: bench/results/soak.txt, 30 iterations, a folder under the system temp dir.
// Bounded: a few seconds an iteration on 2 cores.
#include <dirent.h>
#include <unistd.h>

#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iomanip>
#include <iostream>
#include <sstream>
#include <string>
#include <vector>

#include "abiotics.h"
#include "bench_common.h"
#include "biome_db.h"
#include "canopy_file.h"
#include "error.h"
#include "h5io.h"
#include "reporter.h"
#include "run.h"
#include "terrain_io.h"

namespace fs = std::filesystem;
using namespace eco::bench;

namespace {

const char* kUsage =
    "bench_soak [RESULTS.txt] [ITERATIONS] [WORK_DIR]\n"
    "  Runs a small whole pipeline (eco run) ITERATIONS times in one process (default 30), plus one bad\n"
    "  input per reader each time, and records resident memory and open file descriptors after each\n"
    "  iteration into RESULTS.txt (default bench/results/soak.txt).\n";

/// Open file descriptors of this process (/proc/self/fd, minus the directory's own).
int openDescriptors() {
    int n = 0;
    if (DIR* d = ::opendir("/proc/self/fd")) {
        while (const dirent* e = ::readdir(d))
            if (e->d_name[0] != '.') ++n;
        ::closedir(d);
        --n;  // the descriptor of the opendir itself
    }
    return n;
}

/// A "VmRSS:" / "VmHWM:" / "Threads:" figure of /proc/self/status (kB or a count).
long statusField(const std::string& key) {
    std::ifstream in("/proc/self/status");
    std::string line;
    while (std::getline(in, line))
        if (line.rfind(key, 0) == 0) return std::stol(line.substr(key.size()));
    return -1;
}

void writeText(const std::string& path, const std::string& text) { std::ofstream(path, std::ios::binary) << text; }

/// A hash of a file's bytes (FNV-1a), for the text outputs.
std::uint64_t fileHash(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    std::uint64_t h = 1469598103934665603ull;
    char c;
    while (in.get(c)) h = (h ^ static_cast<unsigned char>(c)) * 1099511628211ull;
    return h;
}

/// A hash of the numbers of the HDF5 datasets listed (not of the file: its provenance
/// attributes hold times).
std::uint64_t datasetHash(const std::string& path, const std::vector<std::string>& datasets) {
    const eco::h5::File f = eco::h5::File::openRead(path);
    std::uint64_t h = 1469598103934665603ull;
    for (const std::string& name : datasets) {
        for (const double v : f.readF64(name)) {
            std::uint64_t bits;
            static_assert(sizeof bits == sizeof v);
            std::memcpy(&bits, &v, sizeof v);
            h = (h ^ bits) * 1099511628211ull;
        }
    }
    return h;
}

/// Files under `dir` (recursively).
std::vector<std::string> filesUnder(const std::string& dir) {
    std::vector<std::string> out;
    for (const auto& e : fs::recursive_directory_iterator(dir))
        if (e.is_regular_file()) out.push_back(e.path().string());
    return out;
}

std::string runConfig(const std::string& outDir, const std::string& simConfig) {
    return "[run]\nout_dir = \"" + outDir +
           "\"\nseed = 1\ngis = true\n[terrain]\nwidth = 64\nheight = 64\ncell_size_m = 1.0\n[chm]\n[abiotics]\n"
           "sun_step_minutes = 60\n[canopy]\ntargets = [\"Douglas-Fir=0.3\"]\n[simulate]\nconfig = \"" +
           simConfig + "\"\nyears = 4\ncrop = [4.0, 4.0, 60.0, 60.0]\n[analyse]\nkmax = 2\n[synth]\ntarget_seed = 2\n"
           "refine = true\n";
}

/// One bad input per reader: each must throw eco::Error (nothing else), and nothing may be
/// left in `dir` but the bad input itself. Returns the number of readers exercised.
int badInputs(const std::string& dir, const std::string& goodDb) {
    int n = 0;
    auto expectError = [&](const std::string& what, const std::function<void()>& read) {
        try {
            read();
        } catch (const eco::Error&) {
            ++n;
            return;
        }
        throw std::runtime_error("soak: bad input '" + what + "' was accepted");
    };
    writeText(dir + "/bad.asc", "ncols 4\nnrows 3\nxllcorner 0\nyllcorner 0\ncellsize 1\n1 2 3\n");
    expectError("short .asc", [&] { eco::readTerrain(dir + "/bad.asc"); });
    writeText(dir + "/bad.png", "\x89PNG\r\n\x1a\n truncated");
    expectError("truncated PNG", [&] {
        eco::TerrainReadOptions o;
        o.cellSizeM = 1;
        eco::readTerrain(dir + "/bad.png", o);
    });
    writeText(dir + "/bad.h5", "not an HDF5 file");
    expectError("not HDF5 (database)", [&] { eco::readBiomeDatabase(dir + "/bad.h5"); });
    expectError("not HDF5 (abiotics)", [&] { eco::readAbiotics(dir + "/bad.h5"); });
    expectError("database as abiotics", [&] { eco::readAbiotics(goodDb); });
    for (const char* name : {"bad.asc", "bad.png", "bad.h5"}) fs::remove(dir + "/" + name);
    if (!fs::is_empty(dir)) throw std::runtime_error("soak: a failed read left files in " + dir);
    return n;
}

}  // namespace

int main(int argc, char** argv) {
    if (wantsUsage(argc, argv, kUsage)) return 0;
    const std::string results = argc > 1 ? argv[1] : "bench/results/soak.txt";
    const int iterations = argc > 2 ? std::stoi(argv[2]) : 30;
    const std::string work = argc > 3 ? argv[3] : (fs::temp_directory_path() / ("eco_soak_" + std::to_string(::getpid()))).string();
    const std::string simConfig = fs::absolute("configs/sim-default.toml").string();
    if (!fs::exists(simConfig)) {
        std::cerr << "bench_soak: run it from the repository root (configs/sim-default.toml not found)\n";
        return 2;
    }
    fs::create_directories(work);
    std::cout << std::fixed;

    std::ostringstream table;
    table << std::fixed;
    table << " iter |  wall s | RSS MB | peak RSS MB | threads | open fds | files | bad inputs | same results\n";
    table << "------|---------|--------|-------------|---------|----------|-------|------------|-------------\n";
    std::uint64_t firstDb = 0, firstScene = 0, firstReport = 0;
    std::vector<long> rss;
    std::vector<int> fds;
    int mismatches = 0;
    const auto tAll = Clock::now();
    for (int it = 1; it <= iterations; ++it) {
        const auto t0 = Clock::now();
        const std::string dir = work + "/it";
        fs::remove_all(dir);
        fs::create_directories(dir + "/bad");
        writeText(dir + "/run.toml", runConfig(fs::absolute(dir + "/out").string(), simConfig));  // paths in a config: relative to it
        eco::pipeline::SilentReporter reporter;
        const eco::pipeline::RunPlan plan = eco::pipeline::planRun(dir + "/run.toml");
        eco::pipeline::runPlan(plan, reporter);
        const int files = static_cast<int>(filesUnder(dir + "/out").size());
        const std::string db = dir + "/out/biome-db.h5";
        const int bad = badInputs(dir + "/bad", db);
        const std::uint64_t dbHash = datasetHash(db, {"/regions/density_per_m2", "/regions/species_proportion",
                                                       "/regions/region_0000/pairs/g"});
        const std::uint64_t sceneHash =
            datasetHash(dir + "/out/scene.h5", {"/undergrowth/x", "/undergrowth/y", "/undergrowth/height"});
        const std::uint64_t csvHash = fileHash(dir + "/out/scene.csv");
        if (it == 1) {
            firstDb = dbHash;
            firstScene = sceneHash;
            firstReport = csvHash;
        }
        const bool same = dbHash == firstDb && sceneHash == firstScene && csvHash == firstReport;
        mismatches += !same;
        fs::remove_all(dir);
        const long r = statusField("VmRSS:"), peak = statusField("VmHWM:"), threads = statusField("Threads:");
        const int fd = openDescriptors();
        rss.push_back(r);
        fds.push_back(fd);
        table << std::setw(5) << it << " | " << std::setw(7) << std::setprecision(2) << secondsSince(t0) << " | "
              << std::setw(6) << std::setprecision(1) << r / 1024.0 << " | " << std::setw(11) << peak / 1024.0 << " | "
              << std::setw(7) << threads << " | " << std::setw(8) << fd << " | " << std::setw(5) << files << " | "
              << std::setw(10) << bad << " | " << (same ? "yes" : "NO") << "\n";
        std::cout << "iteration " << it << "/" << iterations << ": " << std::setprecision(2) << secondsSince(t0) << " s, RSS "
                  << std::setprecision(1) << r / 1024.0 << " MB, " << fd << " fds" << (same ? "" : ", RESULTS DIFFER") << std::endl;
    }
    fs::remove_all(work);

    // Growth: the second half's mean against the first half's (the first iterations warm
    // up allocator pools and library caches).
    auto halfMean = [](const auto& v, bool second) {
        const std::size_t h = v.size() / 2, b = second ? h : 0, e = second ? v.size() : h;
        double s = 0;
        for (std::size_t i = b; i < e; ++i) s += static_cast<double>(v[i]);
        return e > b ? s / static_cast<double>(e - b) : 0.0;
    };
    const double rssGrowthMb = (halfMean(rss, true) - halfMean(rss, false)) / 1024.0;
    const int fdGrowth = fds.empty() ? 0 : fds.back() - fds.front();
    std::ostringstream report;
    report << std::fixed;
    report << "# Soak run (bench/soak_bench.cpp, issue 26 item 6)\n"
           << "# " << iterations << " whole pipelines (eco run of a 64 x 64 m scene: terrain, CHM, abiotics, canopy,\n"
           << "# 4-year simulation, database, target terrain, refined synthesis, comparison, GeoTIFFs,\n"
           << "# GeoPackage, pictures, report) and 5 bad inputs each, in one process; after each iteration:\n"
           << "# resident memory, its peak, threads, open descriptors, files written, results against the first.\n"
           << "# Load average at the end: " << std::setprecision(2) << loadAverage() << "; total "
           << std::setprecision(1) << secondsSince(tAll) << " s.\n\n"
           << table.str() << "\n"
           << "RSS, mean of the second half minus the first half: " << std::setprecision(2) << rssGrowthMb << " MB\n"
           << "open descriptors, last minus first: " << fdGrowth << "\n"
           << "iterations whose results differ from the first: " << mismatches << "\n";
    writeReport(results, report.str());
    return mismatches == 0 ? 0 : 1;
}
