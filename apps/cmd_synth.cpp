// eco synth and eco compare: parsing, progress and reporting only; the science is in
// synth/undergrowth, synth/forest_floor and synth/scene (docs/synth.md).
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include "abiotics.h"
#include "atomic_file.h"
#include "biome_db.h"
#include "canopy_placer.h"
#include "cli_common.h"
#include "error.h"
#include "forest_floor.h"
#include "image_out.h"
#include "scene.h"
#include "terrain_io.h"
#include "text_format.h"
#include "undergrowth.h"

namespace eco::cli {

namespace {

using Clock = std::chrono::steady_clock;
double secondsSince(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

std::string num(double v, int precision = 6) { return formatNumber(v, precision); }

/// Create the folder an output file goes into, before any heavy work.
void prepareOutput(const std::string& path) {
    const std::filesystem::path p(path);
    if (p.has_parent_path()) ensureDirectory(p.parent_path().string());
}

struct SynthArgs {
    std::string terrain, canopy, database, out, abiotics, pngDir, csv, pdb, zoom, refineWindow;
    std::string method = "structured";
    double cellSizeM = 0, verticalScale = 1, verticalOffsetM = 0;
    bool refine = false;
    SynthParams params;
    RefineParams refineParams;
    ForestFloorParams floorParams;
    bool noUndergrowthShade = false;
};

void runSynth(const SynthArgs& a) {
    const auto tStart = Clock::now();
    // Everything cheap is checked before any heavy work.
    SynthParams params = a.params;
    params.method = parseSynthMethod(a.method);
    params.validate();
    RefineParams refineParams = a.refineParams;
    refineParams.seed = params.seed;
    if (!a.refineWindow.empty()) {
        refineParams.useWindow = true;
        refineParams.window = parseWindow(a.refineWindow, "--refine-window", false);
    }
    refineParams.validate();
    ForestFloorParams floorParams = a.floorParams;
    floorParams.undergrowthShades = !a.noUndergrowthShade;
    floorParams.validate();
    RectWindow zoom{};
    if (!a.zoom.empty()) zoom = parseWindow(a.zoom, "--zoom", true);

    const BiomeDatabase db = readBiomeDatabase(a.database);
    const Biome biome = databaseBiome(db);
    info("database: " + a.database + ": biome " + biome.name + ", " + std::to_string(db.regions.size()) + " regions in " +
         std::to_string(db.combinations.size()) + " combinations; seeding disc " + num(db.seedingRadiusFactor) +
         " x crown radius");
    if (db.regions.empty()) throw ValidationError(a.database + ": the database holds no region; nothing to synthesize from");

    TerrainReadOptions readOptions;
    readOptions.cellSizeM = a.cellSizeM;
    readOptions.verticalScale = a.verticalScale;
    readOptions.verticalOffsetM = a.verticalOffsetM;
    const Grid<float> terrain = readTerrain(a.terrain, readOptions);
    info("terrain: " + a.terrain + ": " + terrain.geometryText());
    const CanopyFileData canopyFile = readCanopyFile(a.canopy, biome);
    if (!canopyFile.terrainM.sameGeometry(terrain))
        throw ValidationError("canopy '" + a.canopy + "' was placed on a terrain of " + canopyFile.terrainM.geometryText() +
                              " but --terrain '" + a.terrain + "' is " + terrain.geometryText() +
                              "; give the terrain the canopy was made for");
    validateCanopy(canopyFile.trees, terrain, biome, a.canopy);
    const std::vector<Plant>& canopy = canopyFile.trees;
    info("canopy: " + a.canopy + ": " + std::to_string(canopy.size()) + " trees");
    for (const std::string* out : {&a.out, &a.csv, &a.pdb})
        if (!out->empty()) prepareOutput(*out);
    if (!a.pngDir.empty()) ensureDirectory(a.pngDir);

    const Abiotics abiotics = abioticsForTerrain(a.abiotics, terrain, a.terrain, biome,
                                                 "the database's biome; give --abiotics FILE to reuse them");
    if (!abiotics.canopyShadeSource.empty())
        throw ValidationError("abiotics '" + a.abiotics + "': its sun is already shaded by the canopy of " +
                              abiotics.canopyShadeSource + "; eco synth shades with --canopy itself: give the "
                              "terrain's own abiotics (eco abiotics without --canopy)");
    // The forest floor works from the open-sky maps (it shades under every crown itself); the
    // cluster map from the sun under the canopy, as the analyser's regions were made.
    const FactorGrids features = annualFactors(abiotics);
    Abiotics shaded = abiotics;
    shaded.sunHours = applyCanopyShade(abiotics.sunHours, shadingTrees(canopy, biome));
    const FactorGrids shadedFeatures = annualFactors(shaded);

    auto t = Clock::now();
    const ClusterMap clusters = computeClusterMap(db, biome, canopy, shadedFeatures, params);
    const double clusterS = secondsSince(t);
    std::int64_t seeded = 0, labelled = 0;
    for (std::size_t i = 0; i < clusters.region.size(); ++i) {
        seeded += clusters.combination.data()[i] != 0;
        labelled += clusters.region.data()[i] >= 0;
    }
    info("cluster map: " + num(clusterS, 3) + " s; " + std::to_string(seeded) + " of " + std::to_string(clusters.region.size()) +
         " cells seeded by a canopy tree, " + std::to_string(labelled) + " in a database region");

    UndergrowthSample sample = sampleUndergrowth(db, biome, canopy, clusters, terrain, params);
    info("sampling: " + num(sample.seconds, 3) + " s; " + std::to_string(sample.plants.size()) + " undergrowth plants in " +
         std::to_string(sample.passes) + " passes (" + std::to_string(sample.darts) + " darts, " +
         std::to_string(sample.dartsOnTrunks) + " on trunks)");
    for (const std::string& w : sample.warnings) info("warning: database " + a.database + ": " + w);
    if (params.method == SynthMethod::Structured) {
        for (const RegionStructure& st : sample.structure) {
            const RegionSampling& rs = sample.regions[static_cast<std::size_t>(st.region)];
            if (rs.cells == 0) continue;
            std::string text = "structure: region " + std::to_string(st.region) + ": ";
            if (st.scales == 0) text += "no clustering beyond the canopy context";
            for (int k = 0; k < st.scales; ++k)
                text += (k ? "; " : "") + std::string("clusters of sigma ") + num(st.sigmaM[k], 3) + " m, " +
                        num(st.parentsPerM2[k] * 100.0, 3) + " per 100 m2, pooled excess " + num(st.pooledAmplitude[k], 3);
            text += "; pooled g fit RMS " + num(st.pooledFitRms, 3) + " (canopy context alone " + num(st.pooledContextRms, 3) + ")";
            const std::size_t ns = db.speciesNames.size();
            for (std::size_t i = 0; i < st.hardCoreM.size(); ++i)
                if (st.hardCoreM[i] > 0 && i / ns <= i % ns)
                    text += "; hard core " + db.speciesNames[i / ns] + " - " + db.speciesNames[i % ns] + " " + num(st.hardCoreM[i], 3) + " m";
            info(text);
        }
        info("heights: " + std::to_string(sample.heightsLimitedByCrown) + " plants drawn below the lowest crown above them");
    }
    std::vector<Plant> undergrowth = std::move(sample.plants);
    sample.plants.clear();

    RefineResult refined;
    if (a.refine) {
        Progress bar("refinement sweeps", refineParams.sweeps);
        refined = refineUndergrowth(undergrowth, canopy, clusters, terrain, db, params, refineParams,
                                    [&](int done, int) { bar.update(done); });
        bar.finish();
    }

    t = Clock::now();
    const ForestFloor floor = computeForestFloor(features, canopy, undergrowth, biome, floorParams);
    const double floorS = secondsSince(t);
    info("forest floor: " + num(floorS, 3) + " s");

    // Report.
    std::cout << "undergrowth per region (target = database density x the region's area here):\n"
              << "| region | combination / cluster | area m2 | target /m2 | target | placed |\n"
              << "|---:|---|---:|---:|---:|---:|\n";
    std::int64_t totalTarget = 0;
    for (const auto& r : sample.regions) {
        if (r.cells == 0) continue;
        const DbRegion& dr = db.regions[static_cast<std::size_t>(r.region)];
        char line[400];
        std::snprintf(line, sizeof line, "| %d | %s / cluster %d | %.0f | %.4f | %lld | %lld |\n", r.region,
                      db.combinationName(dr.combination).c_str(), dr.cluster, r.areaM2, r.targetDensityPerM2,
                      static_cast<long long>(r.targetCount), static_cast<long long>(r.placed));
        std::cout << line;
        totalTarget += r.targetCount;
    }
    std::cout << "canopy trees: " << canopy.size() << "; undergrowth plants: " << undergrowth.size() << " (target "
              << totalTarget << ")\n";
    std::cout << "timing: cluster map " << num(clusterS, 3) << " s, sampling " << num(sample.seconds, 3) << " s"
              << (a.refine ? ", refinement " + num(refined.seconds, 3) + " s" : std::string()) << ", forest floor "
              << num(floorS, 3) << " s\n";
    if (a.refine) {
        std::cout << "refinement: pair-correlation distance " << num(refined.distanceBefore, 5) << " -> "
                  << num(refined.distanceAfter, 5) << " over the database's " << num(db.pcfBins.rMaxM, 4) << " m ("
                  << refined.accepted << " of " << refined.proposals << " moves accepted, " << refined.movable
                  << " plants movable; matched to " << num(refined.rMaxM, 4) << " m, distance there per sweep:";
        for (double v : refined.objectivePerSweep) std::cout << " " << num(v, 4);
        std::cout << ")\n";
    }

    SceneRecord record;
    record.canopy = canopy;
    record.undergrowth = std::move(undergrowth);
    record.clusterMap = clusters;
    record.floor = floor;
    record.terrainM = terrain;
    record.params = params;
    record.floorParams = floorParams;
    record.sampling = std::move(sample);
    record.refined = a.refine;
    record.refineParams = refineParams;
    record.refineResult = refined;
    record.databasePath = a.database;
    record.terrainSource = a.terrain;
    record.canopySource = a.canopy;
    record.abioticsSource = a.abiotics.empty() ? "computed from the terrain (default parameters)" : a.abiotics;
    writeSceneFile(a.out, record, biome, db);
    std::cout << "wrote scene: " << a.out
              << " (/canopy, /undergrowth, /forest_floor/{grass,litter}, /cluster_map, /combination_map, /terrain, /regions"
              << (a.refine ? ", /refinement" : "") << ")\n";
    if (!a.csv.empty()) {
        writeScenePlantsCsv(a.csv, record.canopy, record.undergrowth, biome);
        std::cout << "wrote plants: " << a.csv << "\n";
    }
    if (!a.pdb.empty()) {
        writePdb(a.pdb, record.canopy, record.undergrowth);
        std::cout << "wrote PDB plant list: " << a.pdb << "\n";
    }
    if (!a.pngDir.empty()) {
        const std::string dir = a.pngDir + "/";
        writeScenePng(dir + "scene.png", record.canopy, record.undergrowth, terrain, &floor, biome, "Synthesized scene");
        const RectWindow crop = a.zoom.empty() ? defaultZoomWindow(terrain) : zoom;
        writeScenePng(dir + "scene_zoom.png", record.canopy, record.undergrowth, terrain, &floor, biome,
                      "Zoom " + num(crop.x0, 5) + ".." + num(crop.x1, 5) + " x " + num(crop.y0, 5) + ".." + num(crop.y1, 5) + " m",
                      &crop, 900);
        writeMapPng(dir + "grass.png", floor.grass, "Forest floor: grass / forb density", "density (0..1)",
                    Colormap::Viridis, 0, 1);
        writeMapPng(dir + "litter.png", floor.litter, "Forest floor: litter density", "density (0..1)", Colormap::Heat, 0, 1);
        std::vector<std::string> names;
        for (const auto& r : db.regions)
            names.push_back(std::to_string(names.size()) + ": " + db.combinationName(r.combination) + " / " +
                            std::to_string(r.cluster));
        writeCategoryPng(dir + "cluster_map.png", clusters.region, "Cluster map (database region of each cell)", names,
                         "no region (not seeded)");
        std::cout << "wrote pictures: " << a.pngDir << "/ (scene.png, scene_zoom.png, grass.png, litter.png, cluster_map.png)\n";
    }
    info("synthesis finished in " + num(secondsSince(tStart), 3) + " s");
}

struct CompareArgs {
    std::string scene, database, png, window, out;
    std::size_t pcfSources = 20000;
};

void runCompare(const CompareArgs& a) {
    const BiomeDatabase db = readBiomeDatabase(a.database);
    const Biome biome = databaseBiome(db);
    const SceneData scene = readSceneFile(a.scene, biome);
    RectWindow window{};
    if (!a.window.empty()) window = parseWindow(a.window, "--window", false);
    if (!a.png.empty()) prepareOutput(a.png);
    const auto t = Clock::now();
    const SceneComparison c = compareScene(scene.canopy, scene.undergrowth, scene.clusterMap, db,
                                           a.window.empty() ? nullptr : &window, a.pcfSources);
    info("compared in " + num(secondsSince(t), 3) + " s");
    std::ostringstream text;
    text << "scene " << a.scene << " (" << scene.canopy.size() << " canopy, " << scene.undergrowth.size()
         << " undergrowth) against database " << a.database
         << (a.window.empty() ? std::string() : " inside " + a.window) << "\n\n"
         << comparisonTable(c, db);
    std::cout << text.str();
    if (!a.out.empty()) {
        writeTextFile(a.out, text.str());
        std::cout << "wrote table: " << a.out << "\n";
    }
    if (!a.png.empty()) {
        writeComparisonPng(a.png, c, db);
        std::cout << "wrote picture: " << a.png << "\n";
    }
}

}  // namespace

void registerSynthCommand(CLI::App& app) {
    auto a = std::make_shared<SynthArgs>();
    CLI::App* cmd = app.add_subcommand(
        "synth",
        "A complete ecosystem on a terrain (paper §6.2-6.3): undergrowth synthesized from a biome database around the "
        "canopy trees of 'eco canopy', optionally refined, and the forest floor; written to one HDF5 scene file");
    cmd->add_option("--terrain", a->terrain, "Terrain (.asc, .h5, .png, .tif, .exr), elevations in metres")->required();
    cmd->add_option("--canopy", a->canopy, "Canopy file from 'eco canopy' (placed on this terrain)")->required();
    cmd->add_option("--database", a->database, "Biome database from 'eco analyse'")->required();
    cmd->add_option("--out", a->out, "Output scene file, e.g. scene.h5 (written atomically)")->required();
    cmd->add_option("--abiotics", a->abiotics,
                    "Abiotics file from 'eco abiotics' for this terrain (default: computed with default parameters)");
    CLI::Option* refine = cmd->add_flag(
        "--refine", a->refine, "Refine the undergrowth towards the database's pair correlation (slow; canopy never moves)");
    cmd->add_option("--refine-sweeps", a->refineParams.sweeps, "Refinement: proposals per plant")
        ->capture_default_str()
        ->needs(refine);
    cmd->add_option("--refine-rmax", a->refineParams.rMaxM,
                    "Refinement: match pair correlation up to this distance, m (0 = automatic, about 400 neighbours "
                    "in the densest region)")
        ->capture_default_str()
        ->needs(refine);
    cmd->add_option("--refine-window", a->refineWindow,
                    "Refinement: only inside x0,y0,x1,y1 (metres); the rest of the undergrowth stays as sampled")
        ->needs(refine);
    cmd->add_option("--refine-move", a->refineParams.moveRadiusM, "Refinement: displacement radius, m")
        ->capture_default_str()
        ->needs(refine);
    cmd->add_option("--refine-swap", a->refineParams.swapRadiusM, "Refinement: swap partner radius, m")
        ->capture_default_str()
        ->needs(refine);
    cmd->add_option("--png", a->pngDir,
                    "Also write scene.png, scene_zoom.png, grass.png, litter.png and cluster_map.png into this directory");
    cmd->add_option("--zoom", a->zoom, "Crop of scene_zoom.png: x,y,side or x0,y0,x1,y1 in metres (default: 60 m at the centre)");
    cmd->add_option("--csv", a->csv, "Also write all plants as CSV (layer, species, x, y, z, height, crown radius)");
    cmd->add_option("--pdb", a->pdb, "Also write all plants as a PDB plant list (the paper's authors' viewers)");
    cmd->add_option("--seed", a->params.seed, "Random seed")->capture_default_str();
    cmd->add_option("--method", a->method,
                    "Undergrowth sampler: 'structured' (conditioned on the canopy context and clustered as the "
                    "database's pair correlation; heights below the crown above, radius by allometry) or 'darts' "
                    "(the earlier uniform darts with sizes from the histograms)")
        ->capture_default_str();
    cmd->add_option("--max-passes", a->params.maxPasses, "Largest number of dart-throwing passes")->capture_default_str();
    cmd->add_option("--seed-inner-radius-factor", a->params.seedInnerRadiusFactor,
                    "Seeding kernel: full weight within this x crown radius")
        ->capture_default_str();
    cmd->add_option("--trunk-exclusion", a->params.trunkExclusionFactor,
                    "No undergrowth within this x crown radius of a canopy trunk")
        ->capture_default_str();
    cmd->add_option("--litter-full-alpha", a->floorParams.litterFullAlpha,
                    "Forest floor: cumulative crown alpha at which litter density reaches 1")
        ->capture_default_str();
    cmd->add_flag("--no-undergrowth-shade", a->noUndergrowthShade,
                  "Forest floor: only canopy crowns shade the grass and drop litter");
    cmd->add_option("--cell-size", a->cellSizeM, "Metres per cell (required for image terrains)")->check(positiveNumber());
    cmd->add_option("--vertical-scale", a->verticalScale, "Image terrain only: metres per stored unit")->capture_default_str();
    cmd->add_option("--vertical-offset", a->verticalOffsetM, "Image terrain only: metres added after scaling")
        ->capture_default_str();
    cmd->callback([a] { runSynth(*a); });
}

void registerCompareCommand(CLI::App& app) {
    auto a = std::make_shared<CompareArgs>();
    CLI::App* cmd = app.add_subcommand(
        "compare",
        "Re-analyse a synthesized scene against the biome database it came from: per region density, species "
        "proportions, size-histogram and pair-correlation distances (Markdown table on stdout)");
    cmd->add_option("scene", a->scene, "Scene file from 'eco synth'")->required();
    cmd->add_option("database", a->database, "Biome database")->required();
    cmd->add_option("--png", a->png, "Also write a picture of the pair correlations, scene against database");
    cmd->add_option("--window", a->window, "Compare only inside x0,y0,x1,y1 (metres)");
    cmd->add_option("--out", a->out, "Also write the Markdown table to this file");
    cmd->add_option("--pcf-sources", a->pcfSources,
                    "Pair correlation: at most this many undergrowth plants per region as sources (a random sample; "
                    "every plant is a neighbour); 0 = all")
        ->capture_default_str();
    cmd->callback([a] { runCompare(*a); });
}

}  // namespace eco::cli
