#include "calibration_scene.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <numeric>

#include "atomic_file.h"
#include "demo_scene.h"
#include "error.h"
#include "processes.h"
#include "rng.h"
#include "sim_run.h"
#include "text_format.h"

namespace eco::validate {

namespace fs = std::filesystem;

namespace {
constexpr std::uint64_t kCanopySpeciesStreamTag = 0x43414E5350454331ull;  // canopy species of the scene
}  // namespace

sim::SimInputs forestSceneInputs(const ForestSceneConfig& scene, double plotSizeM, std::uint64_t seed, const Biome& biome) {
    sim::DemoSceneParams dp;
    dp.cells = std::max(8, static_cast<int>(std::ceil(plotSizeM / scene.terrainCellSizeM)));
    dp.cellSizeM = scene.terrainCellSizeM;
    dp.seed = seed;
    dp.emptyFraction = scene.emptyFraction;
    dp.denseFraction = scene.denseFraction;
    dp.uniformAbiotics = scene.uniformAbiotics;
    sim::SimInputs in = sim::makeDemoScene(dp, biome);
    // The demo scene picks canopy species by vigour; the validation scene reassigns them
    // by the configured weights among the listed species tall enough for the tree.
    std::vector<int> ids;
    for (const auto& name : scene.canopySpecies) ids.push_back(biome.speciesIndex(name));
    for (std::size_t i = 0; i < in.canopy.size(); ++i) {
        Plant& t = in.canopy[i];
        std::vector<double> w(ids.size(), 0.0);
        for (std::size_t k = 0; k < ids.size(); ++k)
            if (biome.species[static_cast<std::size_t>(ids[k])].maxHeightM >= t.heightM) w[k] = scene.canopyWeights[k];
        if (std::accumulate(w.begin(), w.end(), 0.0) <= 0) {  // taller than all: the tallest listed species
            std::size_t tallest = 0;
            for (std::size_t k = 1; k < ids.size(); ++k)
                if (biome.species[static_cast<std::size_t>(ids[k])].maxHeightM > biome.species[static_cast<std::size_t>(ids[tallest])].maxHeightM)
                    tallest = k;
            w[tallest] = 1.0;
        }
        RandomStream rs(seed, mixStream(i, kCanopySpeciesStreamTag));
        const int k = sim::rouletteSelect(w.data(), static_cast<int>(w.size()), rs.uniform());
        t.speciesId = ids[static_cast<std::size_t>(k)];
    }
    return in;
}

ForestSceneConfig loadCalibrationScene(const std::string& file, const std::vector<std::string>& model, const Biome& biome) {
    ForestSceneConfig scene = parseForestSceneConfig(readTextFile(file), file, model);
    for (const std::string& s : scene.canopySpecies)
        if (biome.speciesIndex(s) < 0) throw ValidationError(file + ": [scene] canopy_species: no species '" + s + "' in the biome");
    return scene;
}

void checkCalibrationScene(const pipeline::CalibrationScene& scene) {
    const Biome biome = scene.biome.empty() ? defaultBiome() : loadBiome(scene.biome);
    loadCalibrationScene(scene.file, scene.model, biome);
}

void runCalibrationScene(const pipeline::CalibrationScene& scene, const std::vector<pipeline::SceneMember>& members,
                         const std::function<void(const std::string&)>& log) {
    for (const pipeline::SceneMember& m : members) {
        const std::string out = (fs::path(m.dir) / "simulation.h5").string();
        const std::string stampPath = (fs::path(m.dir) / "scene-inputs.txt").string();
        // What the simulation depends on: a member with the same inputs is not run again.
        std::string stamp = "scene " + readTextFile(scene.file) + "\nplot " + formatNumber(scene.plotSizeM, 17) + "\nyears " +
                            std::to_string(scene.years) + "\nseed " + std::to_string(m.seed) + "\nbiome " + readTextFile(m.biomePath) + "\nmodel\n";
        for (const std::string& line : m.model) stamp += line + "\n";
        if (fs::exists(out) && fs::exists(stampPath) && readTextFile(stampPath) == stamp) continue;
        const auto t0 = std::chrono::steady_clock::now();
        const Biome biome = loadBiome(m.biomePath);
        const ForestSceneConfig sc = loadCalibrationScene(scene.file, m.model, biome);
        sim::Simulation s(forestSceneInputs(sc, scene.plotSizeM, m.seed, biome), sc.params, m.seed);
        sim::RunRecord record;
        record.timeseries.push_back(s.census());
        for (int y = 1; y <= scene.years; ++y) {
            s.stepYear();
            record.timeseries.push_back(s.census());
        }
        record.snapshots.emplace_back(scene.years, s.plants());
        sim::RunConfig config;
        config.sourcePath = scene.file;
        config.biomePath = m.biomePath;
        config.years = scene.years;
        config.seed = m.seed;
        config.params = sc.params;
        const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
        sim::writeSimulationH5(out, s, record, config, wall, 1);
        writeTextFile(stampPath, stamp);
        if (log)
            log("calibrate:   scene member " + fs::path(m.dir).filename().string() + " (seed " + std::to_string(m.seed) + "): " +
                std::to_string(s.plantCount()) + " plants after " + std::to_string(scene.years) + " years, " + formatNumber(wall, 3) + " s");
    }
}

}  // namespace eco::validate
