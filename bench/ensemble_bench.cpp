// Benchmark of eco ensemble and eco database build (issue 27 item 3), running the eco binary.
//
// 1. Scaling: an ensemble of 8 members (128 x 128 cells, a 100 m plot, 60 years; terrain
//    seeds 1..4 x simulation seeds 1..2) run three ways from scratch: one process with one
//    thread, one process with two threads (OpenMP within each member), and two MPI ranks of
//    one thread each (mpirun -n 2), without the database (analysed once at the end by one
//    process, a serial part timed on its own after). Speed-up of the ranks over one process,
//    members per hour, and the overhead per member (wall time x ranks, less the members' own
//    time, per member). The three runs' outputs are compared byte for byte (--no-provenance;
//    each run in the same folder, which the files record, then moved aside).
// 2. With `--full`: the complete Sonoma database of eco database build with its defaults
//    (15 sub-biome combinations x 2 terrains, 160 x 160 cells, 100 m plots, 150 years), its
//    wall time on this machine and its coverage table.
//
// Usage: bench_ensemble [OUT (default bench/results/ensemble.txt)] [--full | --full-only]
// Run from the repository root (the members read configs/sim-default.toml).
#include <sys/wait.h>

#include <array>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <string>

#include "bench_common.h"

using namespace eco::bench;
namespace fs = std::filesystem;

namespace {

struct Run {
    double seconds = 0;
    int exitCode = -1;
    std::string output;
};

Run run(const std::string& command) {
    Run r;
    const auto t0 = Clock::now();
    FILE* pipe = ::popen((command + " 2>&1").c_str(), "r");
    if (!pipe) return r;
    std::array<char, 4096> buf{};
    for (std::size_t n; (n = std::fread(buf.data(), 1, buf.size(), pipe)) > 0;) r.output.append(buf.data(), n);
    const int status = ::pclose(pipe);
    r.seconds = secondsSince(t0);
    r.exitCode = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
    return r;
}

/// Sum of the members' own seconds in a manifest (third column).
double memberSeconds(const std::string& manifest) {
    std::ifstream in(manifest);
    std::string line;
    std::getline(in, line);
    double sum = 0;
    while (std::getline(in, line)) {
        std::stringstream ss(line);
        std::string id, state, secs;
        std::getline(ss, id, ',');
        std::getline(ss, state, ',');
        std::getline(ss, secs, ',');
        sum += std::stod(secs);
    }
    return sum;
}

/// Every HDF5 output under `dir` by relative path (the members' files and the database).
std::map<std::string, std::string> h5Files(const fs::path& dir) {
    std::map<std::string, std::string> out;
    for (const auto& e : fs::recursive_directory_iterator(dir))
        if (e.is_regular_file() && e.path().extension() == ".h5") {
            std::ifstream in(e.path(), std::ios::binary);
            out[fs::relative(e.path(), dir).string()] = std::string(std::istreambuf_iterator<char>(in), {});
        }
    return out;
}

}  // namespace

int main(int argc, char** argv) {
    if (wantsUsage(argc, argv, "Usage: bench_ensemble [OUT (default bench/results/ensemble.txt)] [--full | --full-only]\n")) return 0;
    const std::string out = argc > 1 ? argv[1] : "bench/results/ensemble.txt";
    bool full = false, scaling = true;
    for (int i = 2; i < argc; ++i) {
        full = full || std::string(argv[i]) == "--full" || std::string(argv[i]) == "--full-only";
        scaling = scaling && std::string(argv[i]) != "--full-only";
    }
    const std::string eco = ECO_BINARY;
    const fs::path work = fs::temp_directory_path() / "eco-bench-ensemble";
    fs::remove_all(work);
    fs::create_directories(work);
    std::ostringstream report;
    report << "ensemble benchmark (" << eco << ")\nload average at start: " << loadAverage() << "\n\n";

    const std::string spec = (work / "scaling.toml").string();
    const std::string runDir = (work / "run").string();
    std::ofstream(spec) << "[ensemble]\nout_dir = \"" << runDir << "\"\nkmax = 2\ndatabase = false\n"
                        << "[ensemble.base.run]\nout_dir = \"set per member\"\n"
                        << "[ensemble.base.terrain]\nwidth = 128\nheight = 128\n"
                        << "[ensemble.base.chm]\n[ensemble.base.abiotics]\nsun_step_minutes = 30\n[ensemble.base.canopy]\n"
                        << "[ensemble.base.simulate]\nconfig = \"" << fs::absolute("configs/sim-default.toml").string() << "\"\nyears = 60\ncrop = [8.5, 8.5, 108.5, 108.5]\n"
                        << "[vary]\n\"terrain.seed\" = [1, 2, 3, 4]\n\"run.seed\" = [1, 2]\n";
    const int members = 8;
    struct Way {
        std::string label, command, dir;
        int workers;
    };
    const std::vector<Way> ways = {
        {"1 process, 1 thread", eco + " --threads 1 --no-provenance ensemble " + spec, (work / "one").string(), 1},
        {"1 process, 2 threads", eco + " --threads 2 --no-provenance ensemble " + spec, (work / "threads").string(), 1},
        {"2 MPI ranks x 1 thread",
         "OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 mpirun --oversubscribe -n 2 " + eco +
             " --threads 1 --no-provenance ensemble " + spec,
         (work / "mpi").string(), 2},
    };
    if (scaling) {
    report << "== scaling: " << members << " members (128 x 128 cells, 100 m plot, 60 years), each way from scratch\n";
    std::map<std::string, double> wall;
    for (const Way& w : ways) {
        const Run r = run(w.command);
        if (r.exitCode != 0) {
            report << w.label << ": FAILED (exit " << r.exitCode << ")\n" << r.output << "\n";
            continue;
        }
        fs::rename(runDir, w.dir);
        wall[w.label] = r.seconds;
        const double own = memberSeconds(w.dir + "/manifest.csv");
        char line[300];
        std::snprintf(line, sizeof line,
                      "%-24s %7.1f s wall, %6.0f members/hour; members' own time %.1f s, overhead per member %.2f s\n",
                      w.label.c_str(), r.seconds, members / r.seconds * 3600, own, (r.seconds * w.workers - own) / members);
        report << line;
    }
    if (wall.count(ways[0].label) && wall.count(ways[2].label)) {
        char line[200];
        std::snprintf(line, sizeof line, "speed-up of 2 MPI ranks over 1 process of 1 thread: %.2fx (goal >= 1.8x); of 2 threads: %.2fx\n",
                      wall[ways[0].label] / wall[ways[2].label], wall[ways[0].label] / wall[ways[1].label]);
        report << line;
        const auto a = h5Files(work / "one"), b = h5Files(work / "threads"), c = h5Files(work / "mpi");
        report << "HDF5 outputs (" << a.size() << " files) byte-identical across the three ways: "
               << (a == b && a == c ? "yes" : "NO") << "\n";
        // The serial part: the database of the 8 members, by one process (2 threads).
        fs::rename(ways[0].dir, runDir);
        std::string sims, abiotics;
        for (const auto& e : fs::directory_iterator(fs::path(runDir) / "members")) {
            sims += (e.path() / "simulation.h5").string() + " ";
            abiotics += " --abiotics " + (e.path() / "abiotics.h5").string();
        }
        const Run db = run(eco + " --threads 2 --no-provenance analyse " + sims + "--kmax 2 --out " + (work / "db.h5").string() + abiotics);
        std::snprintf(line, sizeof line, "the database of the 8 members (eco analyse, 1 process of 2 threads; the serial part): %.1f s%s\n",
                      db.seconds, db.exitCode == 0 ? "" : " FAILED");
        report << line;
    }
    report << "load average after: " << loadAverage() << "\n";
    }

    if (full) {
        report << "\n== the complete Sonoma database: eco database build with its defaults\n";
        const Run r = run(eco + " database build --out " + (work / "sonoma.h5").string());
        char line[200];
        std::snprintf(line, sizeof line, "exit %d, %.1f s wall (%.1f min; goal <= 60 min), load average after %.2f\n", r.exitCode,
                      r.seconds, r.seconds / 60, loadAverage());
        report << line;
        const auto at = r.output.find("coverage of ");
        report << (at == std::string::npos ? r.output : r.output.substr(at)) << "\n";
    }
    writeReport(out, report.str());
    fs::remove_all(work);
    return 0;
}
