// Benchmark of the species map and the canopy placer on the paper's Table 1 scene sizes:
// 1024^2, 2048^2 and 3072^2 cells of 0.914 m with about 70k, 280k and 630k canopy trees
// (paper, GTX 1070: canopy placement 2.51 s, 11.6 s, 58.98 s).
//
// The CHM comes from core's stand-in generator (generateChm) with a dense spacing of 2.0 m
// and heights of 3.5..11 m, which gives the paper's density of about 70k trees per 1024^2;
// the terrain from generateTerrain; the abiotics from computeAbiotics (sun sampled every
// 30 minutes to keep the benchmark short; only the species map reads them, and its cost
// does not depend on their values). Species map and placement are timed separately, the
// placement per iteration. Wall time and process CPU time are both recorded: on a shared
// machine CPU time / threads is what the run would take on idle cores.
//
// Usage: bench_canopy [OUT (default bench/results/canopy.txt)] [SIZES, e.g. 1024,2048] [KEY=VALUE ...]
// (KEY=VALUE: canopy parameters, docs/canopy.md, over the defaults)
// Goal (issue 3): 1024^2 with ~70k trees placed in <= 1 s on 2 cores.
#include <omp.h>

#include <chrono>
#include <cstdint>
#include <cstdio>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "abiotics.h"
#include "biome.h"
#include "canopy_placer.h"
#include "eco_version.h"
#include "generate.h"
#include "species_map.h"
#include "bench_common.h"

namespace {

using namespace eco::bench;


}  // namespace

int main(int argc, char** argv) {
    if (eco::bench::wantsUsage(argc, argv, "usage: bench_canopy [OUT [SIZES [KEY=VALUE ...]]]\nTimes species map and canopy placement on generated CHMs of SIZES cells square (default 1024,2048,3072) beside the paper's; writes OUT (default bench/results/canopy.txt). KEY=VALUE pairs (canopy parameters, docs/canopy.md) change the placer's defaults.\n")) return 0;
    const std::string outPath = argc > 1 ? argv[1] : "bench/results/canopy.txt";
    const std::vector<int> sizes = parseSizes(argc > 2 ? argv[2] : "1024,2048,3072");
    const double paperSeconds[] = {2.51, 11.6, 58.98};
    std::ostringstream report;
    try {
        eco::synth::CanopyParams params;
        std::string overrides;
        for (int a = 3; a < argc; ++a) {
            const std::string kv = argv[a];
            const eco::bench::KeyValue p = eco::bench::parseKeyValue(kv);
            eco::synth::setCanopyParam(params, p.key, p.value);
            overrides += (overrides.empty() ? "" : ", ") + kv;
        }
        eco::synth::validateCanopyParams(params);
        const eco::Biome biome = eco::defaultBiome();
        report << "canopy benchmark (eco " << ECO_VERSION_STRING << ")\n"
               << "OpenMP threads: " << omp_get_max_threads() << ", load average at start: " << loadAverage() << "\n"
               << "CHM: generateChm, dense spacing 2.0 m, sparse 5 m, heights 3.5..11 m, sketch 20 % empty / 50 % "
                  "dense; cells of 0.914 m\n"
               << "placer: default CanopyParams (docs/canopy.md)" << (overrides.empty() ? "" : ", with " + overrides) << "\n\n";
        std::cout << report.str() << std::flush;
        for (const int n : sizes) {
            std::ostringstream sec;
            eco::TerrainGenParams tp;
            tp.width = tp.height = n;
            const eco::Grid<float> terrain = eco::generateTerrain(tp);
            const eco::Grid<std::int32_t> sketch = eco::generateDensitySketch(terrain, eco::SketchParams{});
            eco::ChmGenParams cp;
            cp.denseSpacingM = 2.0;
            cp.sparseSpacingM = 5.0;
            cp.minHeightM = 3.5;
            cp.maxHeightM = 11;
            std::vector<eco::GeneratedTree> generated;
            const eco::Grid<float> chm = eco::generateChm(sketch, cp, generated);
            eco::AbioticParams ap;
            ap.sun.stepMinutes = 30;
            const auto tAb = Clock::now();
            const eco::Abiotics abiotics = eco::computeAbiotics(terrain, biome, ap);
            const double abioticsS = secondsSince(tAb);

            const eco::synth::SpeciesMapInputs inputs = eco::synth::speciesMapInputs(abiotics, chm);
            auto t = Clock::now();
            double cpu = processCpuSeconds();
            const eco::Grid<std::int32_t> map = eco::synth::computeSpeciesMap(biome, inputs);
            const double mapS = secondsSince(t), mapCpu = processCpuSeconds() - cpu;

            eco::synth::SpeciesMapParams smp;
            t = Clock::now();
            cpu = processCpuSeconds();
            const auto target = eco::synth::meetTarget(biome, inputs, smp, biome.speciesIndex("Redwood"), 0.4);
            const double targetS = secondsSince(t), targetCpu = processCpuSeconds() - cpu;

            t = Clock::now();
            cpu = processCpuSeconds();
            const eco::synth::CanopyResult r = eco::synth::placeCanopy(chm, terrain, map, biome, params);
            const double placeS = secondsSince(t), placeCpu = processCpuSeconds() - cpu;

            char line[256];
            sec << "== " << n << " x " << n << " cells (" << n * 0.914 << " m square); generated CHM from "
                << generated.size() << " trees; abiotics " << abioticsS << " s (untimed input)\n";
            std::snprintf(line, sizeof line, "species map       %7.3f s wall, %7.3f s CPU\n", mapS, mapCpu);
            sec << line;
            std::snprintf(line, sizeof line,
                          "target Redwood=0.4 %6.3f s wall, %7.3f s CPU (%d evaluations, reached %.4f)\n", targetS,
                          targetCpu, target.iterations, target.achieved);
            sec << line;
            sec << "  iter     trees  removed    added  coverage   rmse_m  seconds\n";
            auto row = [&](const eco::IterationStats& s) {
                if (s.iteration < 0)
                    std::snprintf(line, sizeof line, "  final %8zu %8zu %8s %9.4f %8.3f %8.3f\n", s.trees, s.removed, "-",
                                  s.coverage, s.rmseM, s.seconds);
                else
                    std::snprintf(line, sizeof line, "  %5d %8zu %8zu %8zu %9.4f %8.3f %8.3f\n", s.iteration, s.trees,
                                  s.removed, s.added, s.coverage, s.rmseM, s.seconds);
                sec << line;
            };
            double iterSeconds = 0;
            for (const auto& s : r.iterations) {
                row(s);
                if (s.iteration > 0) iterSeconds += s.seconds;
            }
            row(r.final);
            const int iterations = static_cast<int>(r.iterations.size()) - 1;
            const double paper = n == 1024 ? paperSeconds[0] : n == 2048 ? paperSeconds[1] : n == 3072 ? paperSeconds[2] : 0;
            std::snprintf(line, sizeof line,
                          "placement         %7.3f s wall, %7.3f s CPU (%.3f s per %d threads); %d iterations, "
                          "%.4f s per iteration; %zu trees, coverage %.4f, RMSE %.3f m; stop: %s\n",
                          placeS, placeCpu, placeCpu / omp_get_max_threads(), omp_get_max_threads(), iterations,
                          iterations > 0 ? iterSeconds / iterations : 0.0, r.trees.size(), r.final.coverage,
                          r.final.rmseM, r.stopReason.c_str());
            sec << line;
            std::snprintf(line, sizeof line, "trees hash        %016llx (species, x, y, ground z, height, crown radius)\n",
                          static_cast<unsigned long long>(plantsHash(r.trees)));
            sec << line;
            if (paper > 0) {
                std::snprintf(line, sizeof line, "paper (GTX 1070)  %7.3f s canopy placement\n", paper);
                sec << line;
            }
            sec << "load average after: " << loadAverage() << "\n\n";
            std::cout << sec.str() << std::flush;
            report << sec.str();
        }
        writeReport(outPath, report.str());
    } catch (const std::exception& e) {
        std::cerr << "bench_canopy: " << e.what() << "\n";
        return 1;
    }
    return 0;
}
