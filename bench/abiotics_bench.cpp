// Benchmark of the abiotic maps: a 1024 x 1024 procedural terrain of 0.914 m cells (the
// paper's 3 ft lidar grid), the embedded Sonoma biome, default parameters. Times each stage
// and the total, prints the figures and writes them to argv[1]
// (default bench/results/abiotics.txt).
//
// Goal (issue): all 12 months of all maps in <= 10 s on 2 cores.
#include <omp.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <sstream>
#include <string>

#include "abiotics.h"
#include "biome.h"
#include "eco_version.h"
#include "generate.h"
#include "bench_common.h"

namespace {

using namespace eco::bench;

}  // namespace

int main(int argc, char** argv) {
    if (eco::bench::wantsUsage(argc, argv, "usage: bench_abiotics [OUT]\nTimes the abiotic maps of a generated 1024 x 1024 terrain; writes OUT (default bench/results/abiotics.txt).\n")) return 0;
    const std::string outPath = argc > 1 ? argv[1] : "bench/results/abiotics.txt";
    try {
        const int size = 1024;
        const double cellSizeM = 0.914;
        eco::TerrainGenParams tp;
        tp.width = size;
        tp.height = size;
        tp.cellSizeM = cellSizeM;
        tp.seed = 1;
        const auto tGen = std::chrono::steady_clock::now();
        const eco::Grid<float> terrain = eco::generateTerrain(tp);
        const double genS = secondsSince(tGen);

        const eco::Biome biome = eco::defaultBiome();
        const eco::AbioticParams params;

        const auto t0 = std::chrono::steady_clock::now();
        auto t = std::chrono::steady_clock::now();
        const auto slope = eco::slopeDegrees(terrain);
        const double slopeS = secondsSince(t);
        t = std::chrono::steady_clock::now();
        const auto temperature = eco::temperatureC(terrain, biome.climate);
        const double temperatureS = secondsSince(t);
        t = std::chrono::steady_clock::now();
        const auto sun = eco::sunHours(terrain, biome.climate, params.sun);
        const double sunS = secondsSince(t);
        t = std::chrono::steady_clock::now();
        eco::MoistureBalance balance;
        const auto moisture = eco::moistureMm(terrain, biome.climate, biome.soil, &balance, params.moistureSpinUpYears);
        const double moistureS = secondsSince(t);
        const double totalS = secondsSince(t0);

        long samples = 0;
        for (int m = 0; m < 12; ++m) {
            const double day = eco::dayLengthHours(biome.climate.latitudeDeg, eco::dayOfYearFor(m, params.sun.dayOfMonth));
            samples += day > 0 ? std::max(1L, std::lround(day * 60.0 / params.sun.stepMinutes)) : 0;
        }

        std::ostringstream r;
        r << "abiotics benchmark (eco " << ECO_VERSION_STRING << ")\n";
        r << "terrain: " << size << " x " << size << " cells of " << cellSizeM << " m (generateTerrain seed 1, "
          << genS << " s to generate)\n";
        r << "biome: " << biome.name << ", latitude " << biome.climate.latitudeDeg << " deg\n";
        r << "sun: step " << params.sun.stepMinutes << " min (" << samples << " sun directions over 12 months), sky "
          << params.sun.skyAzimuths << " x " << params.sun.skyElevations << " directions; moisture spin-up "
          << params.moistureSpinUpYears << " year(s)\n";
        r << "OpenMP threads: " << omp_get_max_threads() << "\n";
        char line[160];
        std::snprintf(line, sizeof line, "slope        %8.3f s\n", slopeS);
        r << line;
        std::snprintf(line, sizeof line, "temperature  %8.3f s (12 months)\n", temperatureS);
        r << line;
        std::snprintf(line, sizeof line, "sun          %8.3f s (12 months, incl. sky view)\n", sunS);
        r << line;
        std::snprintf(line, sizeof line, "moisture     %8.3f s (12 months + spin-up)\n", moistureS);
        r << line;
        std::snprintf(line, sizeof line, "total        %8.3f s\n", totalS);
        r << line;
        std::snprintf(line, sizeof line, "moisture mass balance relative error %.3g\n", balance.relativeError());
        r << line;
        // Keep the results alive (and give a sanity figure): annual means at the grid centre.
        const int c = size / 2;
        std::snprintf(line, sizeof line, "centre cell: sun %.2f h/day (Jun), moisture %.1f mm (Jan), %.1f C (Jul), slope %.1f deg\n",
                      static_cast<double>(sun[5](c, c)), static_cast<double>(moisture[0](c, c)),
                      static_cast<double>(temperature[6](c, c)), static_cast<double>(slope(c, c)));
        r << line;

        std::cout << r.str();
        const std::filesystem::path p(outPath);
        if (p.has_parent_path()) std::filesystem::create_directories(p.parent_path());
        std::ofstream f(outPath);
        if (!f) {
            std::cerr << "abiotics_bench: cannot write " << outPath << "\n";
            return 1;
        }
        f << r.str();
        std::cout << "written to " << outPath << "\n";
    } catch (const std::exception& e) {
        std::cerr << "abiotics_bench: " << e.what() << "\n";
        return 1;
    }
    return 0;
}
