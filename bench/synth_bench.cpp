// Benchmark of the whole synthesis on the paper's Table 1 scene sizes: 1024^2, 2048^2 and
// 3072^2 cells of 0.914 m. Paper (i5-3570 + GTX 1070): canopy placement + sampling
// 3.81 s for ~569k plants, 14.64 s for ~2.31M, 69.82 s for ~5.37M. Goal (issue 6): at least
// 5x faster on 2 CPU cores.
//
// Inputs (untimed): core's generated terrain and density sketch, the stand-in CHM of
// generateChm with the canopy benchmark's dense spacing (about the paper's canopy density),
// abiotics from computeAbiotics with the sun sampled every 60 minutes (only the species map
// and the cluster map read them; their cost does not depend on the values).
//
// Database: SYNTHESIZED here, not analysed from a simulation (a simulation of a 1 km^2
// scene is out of a benchmark's reach): every combination of the four Sonoma sub-biomes,
// two regions each (split by sun), densities of 0.45 and 0.75 undergrowth plants / m^2 (about
// the paper's ~500k undergrowth plants per 1024^2 scene), species proportions spread over the
// species whose sub-biomes meet the combination, triangular height histograms, and a target
// pair correlation with 0.5 m inhibition for the refinement.
//
// Timed: species map, canopy placement, cluster map, dart-throwing sampling (the paper's
// "sampling"), forest floor, and the refinement separately (one sweep over a 100 x 100 m
// window and, on 1024^2, one sweep over the whole scene). Wall and process CPU time.
//
// With a third argument DATABASE (a biome database that `eco analyse` made from real
// simulations, schema 3) that database is used instead, and the sampler is the structured
// one (docs/synth.md); the dart sampler is timed on the same scene beside it.
//
// Environment: ECO_BENCH_REPEAT=N times the placement, cluster map and sampling N times and
// keeps each one's fastest run (for a machine with other load); ECO_BENCH_NO_REFINE=1
// leaves the refinement out.
//
// Usage: bench_synth [OUT (default bench/results/synth.txt)] [SIZES, e.g. 1024,2048] [DATABASE]
#include <omp.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <sstream>
#include <string>
#include <vector>

#include "abiotics.h"
#include "biome.h"
#include "biome_db.h"
#include "canopy_placer.h"
#include "eco_version.h"
#include "provenance.h"
#include "forest_floor.h"
#include "generate.h"
#include "memory.h"
#include "species_map.h"
#include "undergrowth.h"
#include "bench_common.h"

namespace {

using namespace eco::bench;

/// A timed call: wall and CPU seconds.
struct Timing {
    double wall = 0, cpu = 0;
};
template <typename F>
Timing timed(F&& f) {
    const auto t = Clock::now();
    const double c = processCpuSeconds();
    f();
    return Timing{secondsSince(t), processCpuSeconds() - c};
}


/// The fastest of `repeats` runs of f (each run redoes the work).
template <typename F>
Timing timedBest(int repeats, F&& f) {
    Timing best = timed(f);
    for (int i = 1; i < repeats; ++i) {
        const Timing t = timed(f);
        if (t.wall < best.wall) best = t;
    }
    return best;
}

int envInt(const char* name, int fallback) {
    const char* v = std::getenv(name);
    return v != nullptr && *v != '\0' ? std::max(1, std::atoi(v)) : fallback;
}

eco::DbHistogram triangle(double maxValue, int bins, double peak, double scale) {
    eco::DbHistogram h;
    for (int k = 0; k <= bins; ++k) h.edges.push_back(maxValue * k / bins);
    for (int k = 0; k < bins; ++k) {
        const double mid = (k + 0.5) / bins;
        h.counts.push_back(std::round(scale * (mid < peak ? mid / peak : (1 - mid) / (1 - peak))) + 1);
    }
    return h;
}

/// The synthesized database (see the top of the file).
eco::BiomeDatabase benchmarkDatabase(const eco::Biome& b) {
    eco::BiomeDatabase db;
    db.codeVersion = ECO_VERSION_STRING;
    db.createdUtc = eco::utcTimestamp();
    db.biomeName = b.name;
    db.biomeToml = eco::biomeToToml(b);
    for (const auto& s : b.species) db.speciesNames.push_back(s.name);
    for (const auto& sb : b.subBiomes) db.subBiomeNames.push_back(sb.name);
    db.canopySubBiomeMask.assign(b.species.size(), 0);
    for (const auto& sb : b.subBiomes)
        for (const auto& name : sb.canopySpecies)
            db.canopySubBiomeMask[static_cast<std::size_t>(b.speciesIndex(name))] |= 1 << (sb.number - 1);
    db.seedingRadiusFactor = 12;
    db.pcfBins = eco::DistanceBins{10.0, 40};
    const std::size_t ns = b.species.size();
    const int nMasks = (1 << static_cast<int>(b.subBiomes.size())) - 1;
    for (int mask = 1; mask <= nMasks; ++mask) {
        eco::DbCombination c;
        c.mask = mask;
        c.k = 2;
        c.firstRegion = static_cast<int>(db.regions.size());
        c.featureMean = {9.0, 80.0, 20.0, 15.0};
        c.featureStd = {2.0, 30.0, 2.0, 10.0, 1.0};
        for (int cluster = 0; cluster < 2; ++cluster) {
            eco::DbRegion r;
            r.combination = mask;
            r.cluster = cluster;
            r.centroidRaw = {cluster == 0 ? 7.0 : 11.0, 80.0, 20.0, 15.0};
            for (std::size_t f = 0; f < eco::kFactorCount; ++f)
                r.centroidNormalised[f] = (r.centroidRaw[f] - c.featureMean[f]) / c.featureStd[f];
            r.areaM2 = 10000;
            r.densityPerM2 = cluster == 0 ? 0.45 : 0.75;
            r.undergrowthCount = r.densityPerM2 * r.areaM2;
            r.speciesCount.assign(ns, 0.0);
            r.speciesProportion.assign(ns, 0.0);
            r.canopySpeciesCount.assign(ns, 0.0);
            r.height.resize(ns);
            r.crownRadius.resize(ns);
            double total = 0;
            std::vector<int> present;
            for (std::size_t s = 0; s < ns; ++s) {
                const eco::Species& sp = b.species[s];
                const double hMax = std::min(sp.maxHeightM, 5.0);
                int m = 0;
                for (int sb : sp.subBiomes) m |= 1 << (sb - 1);
                const bool in = (m & mask) != 0;
                r.height[s] = triangle(hMax, 20, 0.3, in ? 500 : 0);
                r.crownRadius[s] = triangle(sp.allometry.crownRadiusM(hMax), 20, 0.4, in ? 500 : 0);
                if (!in) {
                    std::fill(r.height[s].counts.begin(), r.height[s].counts.end(), 0.0);
                    std::fill(r.crownRadius[s].counts.begin(), r.crownRadius[s].counts.end(), 0.0);
                    continue;
                }
                const double w = 1.0 + static_cast<double>((s * 7 + static_cast<std::size_t>(mask) * 3 + static_cast<std::size_t>(cluster)) % 5);
                r.speciesProportion[s] = w;
                total += w;
                present.push_back(static_cast<int>(s));
            }
            for (std::size_t s = 0; s < ns; ++s) {
                r.speciesProportion[s] /= total;
                r.speciesCount[s] = std::round(r.speciesProportion[s] * r.undergrowthCount);
            }
            for (int i : present)
                for (int j : present) {
                    eco::DbPairStats p;
                    p.source = i;
                    p.target = j;
                    p.normalisation = 1;
                    for (int k = 0; k < db.pcfBins.count; ++k) {
                        const double g = db.pcfBins.hiM(k) <= 0.5 ? 0.0 : 1.0;
                        p.g.push_back(g);
                        p.translateWeighted.push_back(g * db.pcfBins.annulusAreaM2(k));
                        p.pairCount.push_back(0);
                    }
                    p.separationCount.assign(static_cast<std::size_t>(db.separationBins.count), 0.0);
                    r.pairs.push_back(std::move(p));
                }
            db.regions.push_back(std::move(r));
        }
        db.combinations.push_back(c);
    }
    return db;
}

}  // namespace

int main(int argc, char** argv) {
    if (eco::bench::wantsUsage(argc, argv, "usage: bench_synth [OUT [SIZES [DATABASE]]]\nTimes canopy placement and the structured and dart samplers on SIZES cells square (default 1024,2048,3072) with DATABASE (default: one made in the benchmark); ECO_BENCH_REPEAT=N keeps the fastest of N runs, ECO_BENCH_NO_REFINE=1 skips refinement; writes OUT (default bench/results/synth.txt).\n")) return 0;
    // As eco synth and eco canopy do: freed memory stays in the process for the next stage.
    eco::retainFreedMemory();
    const std::string outPath = argc > 1 ? argv[1] : "bench/results/synth.txt";
    const std::vector<int> sizes = parseSizes(argc > 2 ? argv[2] : "1024,2048,3072");
    std::ostringstream report;
    try {
        const eco::Biome biome = eco::defaultBiome();
        const std::string dbPath = argc > 3 ? argv[3] : "";
        const eco::BiomeDatabase db = dbPath.empty() ? benchmarkDatabase(biome) : eco::readBiomeDatabase(dbPath);
        const int threads = omp_get_max_threads();
        const int repeats = envInt("ECO_BENCH_REPEAT", 1);
        const bool refine = std::getenv("ECO_BENCH_NO_REFINE") == nullptr;
        report << "synthesis benchmark (eco " << ECO_VERSION_STRING << ")\n"
               << "OpenMP threads: " << threads << ", load average at start: " << loadAverage() << "\n"
               << (repeats > 1 ? "placement, cluster map and sampling: the fastest of " + std::to_string(repeats) + " runs each\n" : "")
               << "CHM: generateChm, dense spacing 2.0 m, sparse 5 m, heights 3.5..11 m; cells of 0.914 m\n";
        if (dbPath.empty())
            report << "database: SYNTHESIZED in the benchmark (not from a simulation): " << db.regions.size()
                   << " regions (all 15 Sonoma combinations x 2 sun clusters), 0.45 / 0.75 undergrowth plants per m^2; "
                      "dart sampler\n";
        else {
            report << "database: " << dbPath << " (schema " << db.schemaVersion << ", " << db.regions.size() << " regions, "
                   << db.inputs.size() << " analysed simulation(s):";
            for (const auto& in : db.inputs) report << " " << in.path;
            report << "); structured sampler, the dart sampler timed beside it\n";
        }
        report
               << "paper (i5-3570 + GTX 1070), canopy placement + sampling: 1024^2 3.81 s (~569k plants), 2048^2 "
                  "14.64 s (~2.31M), 3072^2 69.82 s (~5.37M)\n\n";
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
            const eco::Grid<float> chm = eco::generateChm(sketch, cp);
            eco::AbioticParams ap;
            ap.sun.stepMinutes = 60;
            const auto tAb = Clock::now();
            const eco::Abiotics abiotics = eco::computeAbiotics(terrain, biome, ap);
            const double abioticsS = secondsSince(tAb);
            const eco::FactorGrids features = eco::annualFactors(abiotics);

            eco::Grid<std::int32_t> speciesMap;
            const Timing tMap = timed([&] { speciesMap = eco::synth::computeSpeciesMap(biome, eco::synth::speciesMapInputs(abiotics, chm)); });
            eco::synth::CanopyResult canopy;
            const Timing tPlace = timedBest(repeats, [&] { canopy = eco::synth::placeCanopy(chm, terrain, speciesMap, biome, eco::synth::CanopyParams{}); });
            eco::synth::SynthParams sp;
            sp.method = dbPath.empty() ? eco::synth::SynthMethod::Darts : eco::synth::SynthMethod::Structured;
            eco::synth::ClusterMap clusters;
            const Timing tCluster = timedBest(repeats, [&] { clusters = eco::synth::computeClusterMap(db, biome, canopy.trees, features, sp); });
            eco::synth::UndergrowthSample sample;
            const Timing tSample = timedBest(repeats, [&] { sample = eco::synth::sampleUndergrowth(db, biome, canopy.trees, clusters, terrain, sp); });
            Timing tDarts;
            std::size_t dartsPlants = 0;
            if (!dbPath.empty()) {
                eco::synth::SynthParams dp = sp;
                dp.method = eco::synth::SynthMethod::Darts;
                tDarts = timedBest(repeats, [&] { dartsPlants = eco::synth::sampleUndergrowth(db, biome, canopy.trees, clusters, terrain, dp).plants.size(); });
            }
            eco::synth::ForestFloor floor;
            const Timing tFloor = timed([&] {
                floor = eco::synth::computeForestFloor(features, canopy.trees, sample.plants, biome, eco::synth::ForestFloorParams{});
            });
            // Refinement: one sweep in a 100 m window at the centre, and the whole scene on 1024^2.
            eco::synth::RefineParams rp;
            rp.sweeps = 1;
            rp.useWindow = true;
            const double cx = terrain.extentX() / 2, cy = terrain.extentY() / 2;
            rp.window = eco::RectWindow{cx - 50, cy - 50, cx + 50, cy + 50};
            std::vector<eco::Plant> refined = sample.plants;
            eco::synth::RefineResult rw;
            Timing tRefineWin;
            if (refine) tRefineWin = timed([&] { rw = eco::synth::refineUndergrowth(refined, canopy.trees, clusters, terrain, db, sp, rp); });
            eco::synth::RefineResult rAll;
            Timing tRefineAll;
            if (refine && n <= 1024) {
                rp.useWindow = false;
                refined = sample.plants;
                tRefineAll = timed([&] { rAll = eco::synth::refineUndergrowth(refined, canopy.trees, clusters, terrain, db, sp, rp); });
            }

            const std::size_t nT = canopy.trees.size(), nU = sample.plants.size();
            const double placeAndSample = tPlace.wall + tCluster.wall + tSample.wall;
            const double paper = n == 1024 ? 3.81 : n == 2048 ? 14.64 : n == 3072 ? 69.82 : 0;
            char line[400];
            sec << "== " << n << " x " << n << " cells (" << n * 0.914 << " m square); abiotics " << abioticsS
                << " s (untimed input)\n";
            std::snprintf(line, sizeof line, "plants: %zu canopy + %zu undergrowth = %zu\n", nT, nU, nT + nU);
            sec << line;
            auto row = [&](const char* what, const Timing& t) {
                std::snprintf(line, sizeof line, "  %-34s %8.3f s wall %8.3f s CPU\n", what, t.wall, t.cpu);
                sec << line;
            };
            row("species map", tMap);
            row("canopy placement", tPlace);
            row("cluster map", tCluster);
            row(dbPath.empty() ? "undergrowth sampling (darts)" : "undergrowth sampling (structured)", tSample);
            if (!dbPath.empty()) {
                row("  the dart sampler, same scene", tDarts);
                std::snprintf(line, sizeof line, "    (%zu plants by the dart sampler)\n", dartsPlants);
                sec << line;
                sec << "    phases of the structured sampler (wall / CPU s):";
                for (const eco::synth::UndergrowthSample::Phase& ph : sample.phases) {
                    std::snprintf(line, sizeof line, "%s %s %.3f / %.3f", &ph == &sample.phases.front() ? "" : ";",
                                  ph.name.c_str(), ph.wallS, ph.cpuS);
                    sec << line;
                }
                std::snprintf(line, sizeof line, "\n    result hash of the structured scene: %016llx\n",
                              static_cast<unsigned long long>(plantsHash(sample.plants)));
                sec << line;
            }
            row("forest floor", tFloor);
            std::snprintf(line, sizeof line,
                          "  canopy placement + sampling (cluster map included): %.3f s; paper %.2f s; speed-up %.1fx\n",
                          placeAndSample, paper, paper > 0 ? paper / placeAndSample : 0.0);
            sec << line;
            std::snprintf(line, sizeof line,
                          "  with the species map: %.3f s (speed-up %.1fx); sampling: %d passes, %lld darts\n",
                          placeAndSample + tMap.wall, paper > 0 ? paper / (placeAndSample + tMap.wall) : 0.0, sample.passes,
                          static_cast<long long>(sample.darts));
            sec << line;
            if (refine) {
            std::snprintf(line, sizeof line,
                          "  refinement, 1 sweep, 100 x 100 m window: %.3f s wall (%lld plants movable, %.2f us per "
                          "proposal), matched to %.2f m, distance %.4f -> %.4f\n",
                          tRefineWin.wall, static_cast<long long>(rw.movable),
                          rw.proposals > 0 ? 1e6 * rw.seconds / static_cast<double>(rw.proposals) : 0.0, rw.rMaxM,
                          rw.distanceBefore, rw.distanceAfter);
            sec << line;
            }
            if (refine && n <= 1024) {
                std::snprintf(line, sizeof line,
                              "  refinement, 1 sweep, whole scene: %.3f s wall, %.3f s CPU (%lld proposals, %lld "
                              "accepted), distance %.4f -> %.4f\n",
                              tRefineAll.wall, tRefineAll.cpu, static_cast<long long>(rAll.proposals),
                              static_cast<long long>(rAll.accepted), rAll.distanceBefore, rAll.distanceAfter);
                sec << line;
            }
            sec << "load average after: " << loadAverage() << "\n\n";
            std::cout << sec.str() << std::flush;
            report << sec.str();
        }
        writeReport(outPath, report.str());
    } catch (const std::exception& e) {
        std::cerr << "bench_synth: " << e.what() << "\n";
        return 1;
    }
    return 0;
}
