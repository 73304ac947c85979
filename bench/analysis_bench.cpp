// Benchmark of the analyser (issue 5): pairs per second per core of the pair-correlation
// estimator and of the analyser's region pair loop, 1 -> 2 thread scaling, and the whole
// database build (read, analyse, write) of simulation files. Prints its figures and writes
// them to bench/results/analysis_bench.txt (or --out FILE).
//
//   bench_analysis [--quick] [--out FILE] [SIM.h5 ...]
//
// SIM.h5: outputs of `eco simulate`, e.g. on the scene of `bench_sim --make-scene DIR`
// (docs/analysis.md gives the commands). Goal: >= 100 million pairs per second per core.
#include <omp.h>
#include <time.h>

#include <cstdlib>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <sstream>
#include <string>
#include <vector>

#include "analysis.h"
#include "biome_db.h"
#include "eco_version.h"
#include "point_pattern.h"
#include "rng.h"
#include "sim_input.h"
#include "bench_common.h"

using namespace eco;

namespace {

using namespace eco::bench;

double now() { return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count(); }

/// CPU seconds used by the whole process (all threads): pairs per CPU second is pairs per
/// second per core, and stays meaningful when other work shares the machine.
double cpuNow() {
    timespec ts{};
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
    return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
}

PointPattern poisson(std::size_t n, const RectWindow& w, std::uint64_t seed) {
    PointPattern p;
    p.typeNames = {"a", "b", "c", "d"};
    RandomStream rng(seed, 1);
    for (std::size_t i = 0; i < n; ++i) {
        p.x.push_back(rng.uniform(w.x0, w.x1));
        p.y.push_back(rng.uniform(w.y0, w.y1));
        p.type.push_back(static_cast<int>(rng.below(4)));
    }
    return p;
}

/// A simulation-like input: 512 x 512 cells of 0.914 m, canopy trees on a jittered grid,
/// `perM2` undergrowth plants per m^2 clustered under and around the crowns.
analysis::AnalysisInput syntheticScene(const Biome& biome, double perM2, std::uint64_t seed) {
    analysis::AnalysisInput in;
    in.biome = &biome;
    const int n = 512;
    const double cs = 0.914;
    in.features = FactorGrids::uniform(Grid<float>(n, n, cs), {10, 100, 15, 5});
    RandomStream rng(seed, 2);
    for (int iy = 0; iy < n; ++iy)
        for (int ix = 0; ix < n; ++ix) {
            in.features[Factor::Moisture](ix, iy) = static_cast<float>(60 + 100.0 * ix / n + 5 * rng.normal());
            in.features[Factor::Sun](ix, iy) = static_cast<float>(8 + 4.0 * iy / n + 0.3 * rng.normal());
            in.features[Factor::Slope](ix, iy) = static_cast<float>(10 + 5 * rng.normal());
        }
    const double side = n * cs;
    in.window = RectWindow{0, 0, side, side};
    const char* canopy[] = {"Redwood", "Douglas-Fir", "Coast Live Oak", "California Black Oak", "Gray Pine",
                            "Oregon White Oak", "Pacific Madrone"};
    for (double y = 10; y < side; y += 25)
        for (double x = 10; x < side; x += 25) {
            Plant p;
            p.speciesId = biome.speciesIndex(canopy[rng.below(7)]);
            p.xM = x + rng.uniform(-8, 8);
            p.yM = y + rng.uniform(-8, 8);
            p.heightM = rng.uniform(15, 40);
            p.crownRadiusM = rng.uniform(2, 5);
            in.canopy.push_back(p);
        }
    const char* under[] = {"Redwood Sorrel", "Western Swordfern", "Toyon", "California Sagebrush", "Chamise",
                           "Whiteleaf Manzanita", "Pacific Poison Oak", "Tanoak", "California Laurel"};
    const std::size_t count = static_cast<std::size_t>(perM2 * side * side);
    for (std::size_t i = 0; i < count; ++i) {
        Plant p;
        p.speciesId = biome.speciesIndex(under[rng.below(9)]);
        if (rng.uniform() < 0.6) {  // clustered around a canopy tree
            const Plant& t = in.canopy[rng.below(static_cast<std::uint32_t>(in.canopy.size()))];
            p.xM = std::clamp(t.xM + 3.0 * t.crownRadiusM * rng.normal(), 0.0, side - 1e-6);
            p.yM = std::clamp(t.yM + 3.0 * t.crownRadiusM * rng.normal(), 0.0, side - 1e-6);
        } else {
            p.xM = rng.uniform(0, side);
            p.yM = rng.uniform(0, side);
        }
        p.heightM = rng.uniform(0.05, 1.5);
        p.crownRadiusM = rng.uniform(0.05, 0.8);
        in.undergrowth.push_back(p);
    }
    in.provenance.path = "synthetic scene";
    return in;
}

double totalPairs(const BiomeDatabase& db) {
    double s = 0;
    for (const auto& r : db.regions)
        for (const auto& p : r.pairs)
            for (double c : p.pairCount) s += c;
    return s;
}

}  // namespace

int main(int argc, char** argv) {
    std::string outPath = "bench/results/analysis_bench.txt";
    bool quick = false;
    std::vector<std::string> sims;
    for (int i = 1; i < argc; ++i) {
        if (!std::strcmp(argv[i], "--quick")) quick = true;
        else if (!std::strcmp(argv[i], "--out") && i + 1 < argc) outPath = argv[++i];
        else sims.emplace_back(argv[i]);
    }
    std::ostringstream rep;
    auto line = [&](const std::string& s) {
        std::cout << s << std::endl;
        rep << s << "\n";
    };
    char buf[512];
    try {
        line(std::string("eco ") + ECO_VERSION_STRING + " analysis benchmark" + (quick ? " (quick)" : ""));
        std::snprintf(buf, sizeof buf, "machine: %d logical cores, load average %.2f at start", omp_get_num_procs(), loadAverage());
        line(buf);

        // 1. The estimator of core/point_pattern (eco pcf, the synthesizer).
        const RectWindow w{0, 0, 1000, 1000};
        const std::size_t n = quick ? 200000 : 1000000;
        const PointPattern p = poisson(n, w, 1);
        for (bool iso : {false, true}) {
            PcfOptions opt;
            opt.bins = DistanceBins{5.0, 40};
            opt.isotropic = iso;
            double t1 = 0;
            for (int threads : {1, 2}) {
                omp_set_num_threads(threads);
                countPairs(p, w, opt);  // warm-up
                const int reps = quick ? 1 : 3;
                const double t0 = now(), c0 = cpuNow();
                PairSums s;
                for (int r = 0; r < reps; ++r) s = countPairs(p, w, opt);
                const double t = (now() - t0) / reps, cpu = (cpuNow() - c0) / reps;
                if (threads == 1) t1 = t;
                double ordered = 0;
                for (auto c : s.pairCount) ordered += static_cast<double>(c);
                std::snprintf(buf, sizeof buf,
                              "pcf estimator, %zu Poisson points, 4 types, rmax 5 m, %s, %d thread(s): wall %.3f s, cpu %.3f s; "
                              "%.1f M pairs (unordered) -> %.1f M pairs/s/core by wall, %.1f M by cpu "
                              "(ordered: %.1f M / %.1f M); speed-up %.2f",
                              n, iso ? "translate + isotropic" : "translate", threads, t, cpu, ordered / 2e6,
                              ordered / 2e6 / t / threads, ordered / 2e6 / cpu, ordered / 1e6 / t / threads, ordered / 1e6 / cpu,
                              t1 / t);
                line(buf);
            }
        }

        // 2. The analyser on a simulation-like scene (the region pair loop dominates).
        const Biome biome = defaultBiome();
        const analysis::AnalysisInput scene = syntheticScene(biome, quick ? 0.2 : 1.0, 3);
        analysis::AnalysisParams params;
        for (int threads : {1, 2}) {
            omp_set_num_threads(threads);
            double tStage = now(), cStage = cpuNow(), tStats = 0, cStats = 0;
            std::string stage;
            const double t0 = now();
            const BiomeDatabase db = analysis::analyse({scene}, params, [&](const std::string& s, double) {
                if (s != stage) {
                    const double t = now(), c = cpuNow();
                    if (stage == "statistics") {
                        tStats += t - tStage;
                        cStats += c - cStage;
                    }
                    tStage = t;
                    cStage = c;
                    stage = s;
                }
            });
            const double total = now() - t0;
            tStats += now() - tStage;
            cStats += cpuNow() - cStage;
            const double pairs = totalPairs(db);
            std::snprintf(buf, sizeof buf,
                          "analyse, synthetic 468 x 468 m scene, %zu undergrowth + %zu canopy, %zu regions, %d thread(s): "
                          "%.2f s total; pair statistics wall %.2f s, cpu %.2f s, %.1f M ordered pcf pairs -> "
                          "%.1f M pairs/s/core by wall, %.1f M by cpu",
                          scene.undergrowth.size(), scene.canopy.size(), db.regions.size(), threads, total, tStats, cStats,
                          pairs / 1e6, pairs / 1e6 / tStats / threads, pairs / 1e6 / cStats);
            line(buf);
        }

        // 3. Whole database builds from simulation files.
        omp_set_num_threads(omp_get_num_procs());
        if (!sims.empty()) {
            double t0 = now();
            std::vector<analysis::LoadedSimulation> loaded;
            for (const auto& s : sims) loaded.push_back(analysis::readSimulation(s, {}));
            const double tRead = now() - t0;
            std::vector<analysis::AnalysisInput> inputs;
            std::size_t plants = 0;
            for (auto& l : loaded) {
                plants += l.input.undergrowth.size();
                inputs.push_back(std::move(l.input));
            }
            t0 = now();
            const double c0 = cpuNow();
            const BiomeDatabase db = analysis::analyse(inputs, params);
            const double tAnalyse = now() - t0, cAnalyse = cpuNow() - c0;
            const double pairs = totalPairs(db);
            t0 = now();
            const std::string dbPath = outPath + ".db.h5";
            writeBiomeDatabase(dbPath, db);
            const double tWrite = now() - t0;
            std::remove(dbPath.c_str());
            std::snprintf(buf, sizeof buf,
                          "database build, %zu simulation(s), %zu undergrowth plants, %zu regions, %d threads: read %.2f s, "
                          "analyse %.2f s (cpu %.2f s, %.0f M ordered pcf pairs -> %.1f M pairs per cpu second), "
                          "write %.2f s, total %.2f s",
                          sims.size(), plants, db.regions.size(), omp_get_max_threads(), tRead, tAnalyse, cAnalyse,
                          pairs / 1e6, pairs / 1e6 / cAnalyse, tWrite, tRead + tAnalyse + tWrite);
            line(buf);
        } else {
            line("database build: no simulation file given (bench_analysis SIM.h5 ...)");
        }
    } catch (const std::exception& e) {
        std::cerr << "bench_analysis: " << e.what() << "\n";
        return 1;
    }
    const std::filesystem::path parent = std::filesystem::path(outPath).parent_path();
    if (!parent.empty()) std::filesystem::create_directories(parent);
    std::ofstream(outPath) << rep.str();
    std::cout << "wrote " << outPath << "\n";
    return 0;
}
