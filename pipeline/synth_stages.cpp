#include "synth_stages.h"

#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <ostream>
#include <sstream>

#include "abiotics.h"
#include "atomic_file.h"
#include "biome_db.h"
#include "canopy_placer.h"
#include "error.h"
#include "geo_raster.h"
#include "image_out.h"
#include "sim_file.h"
#include "terrain_io.h"
#include "text_format.h"

namespace eco::pipeline {

namespace {

using Clock = std::chrono::steady_clock;
double secondsSince(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

std::string num(double v, int precision = 6) { return formatNumber(v, precision); }

}  // namespace

synth::XuExemplar readExemplar(const std::string& path, int year, const std::string& windowText, const Biome& biome) {
    synth::XuExemplar ex;
    ex.source = "exemplar '" + path + "'";
    bool hdf5 = false;
    {
        std::ifstream in(path, std::ios::binary);
        if (!in) throw IoError(ex.source + ": cannot open file (missing or unreadable)");
        char sig[8] = {};
        in.read(sig, 8);
        hdf5 = in.gcount() == 8 && std::string(sig, 8) == std::string("\x89HDF\r\n\x1a\n", 8);
    }
    std::optional<RectWindow> recorded;
    if (hdf5) {
        const SimulationFileData sim = readSimulationFile(path, year);
        ex.source = "exemplar '" + path + "' (year " + std::to_string(sim.year) + ")";
        for (const Plant& p : sim.undergrowth) {
            Plant q = p;
            const std::string& name = sim.biome.species[static_cast<std::size_t>(p.speciesId)].name;
            try {
                q.speciesId = biome.speciesIndex(name);
            } catch (const ValidationError& e) {
                throw ValidationError(ex.source + ": " + e.what());
            }
            ex.plants.push_back(q);
        }
        if (sim.area) recorded = RectWindow{(*sim.area)[0], (*sim.area)[1], (*sim.area)[2], (*sim.area)[3]};
    } else {
        if (year >= 0) throw ValidationError("--exemplar-year " + std::to_string(year) + ": " + ex.source + " is a CSV, not a simulation file");
        ex.plants = readPlantsCsv(path, biome, "undergrowth");
    }
    if (!windowText.empty()) {  // a crop: the plants inside
        ex.window = parseWindow(windowText, "--exemplar-window");
        ex.source += " in " + windowText;
        std::vector<Plant> inside;
        for (const Plant& p : ex.plants)
            if (ex.window.contains(p.xM, p.yM)) inside.push_back(p);
        ex.plants = std::move(inside);
    }
    if (ex.plants.empty()) throw ValidationError(ex.source + ": no undergrowth plants; the Xu 2015 sampler copies an exemplar's plants");
    if (!windowText.empty()) {
    } else if (recorded) {
        ex.window = *recorded;
    } else {
        ex.window = RectWindow{ex.plants[0].xM, ex.plants[0].yM, ex.plants[0].xM, ex.plants[0].yM};
        for (const Plant& p : ex.plants) {
            ex.window.x0 = std::min(ex.window.x0, p.xM);
            ex.window.y0 = std::min(ex.window.y0, p.yM);
            ex.window.x1 = std::max(ex.window.x1, p.xM);
            ex.window.y1 = std::max(ex.window.y1, p.yM);
        }
        if (!(ex.window.x1 > ex.window.x0 && ex.window.y1 > ex.window.y0))
            throw ValidationError(ex.source + ": its " + std::to_string(ex.plants.size()) +
                                  " plants span no area (give --exemplar-window x0,y0,x1,y1)");
    }
    return ex;
}

SynthResult synthStage(const SynthOptions& a, Reporter& reporter) {
    std::ostream& out = reporter.out();
    SynthResult result;
    const auto tStart = Clock::now();
    // Everything cheap is checked before any heavy work.
    const std::vector<std::pair<std::string, std::string>> outputFiles = {
        {"--out", a.out}, {"--csv", a.csv}, {"--pdb", a.pdb}, {"--pdb-canopy", a.pdbCanopy}, {"--pdb-undergrowth", a.pdbUndergrowth},
        {"--gpkg", a.gpkg}};
    requireOutputsNotInputs(outputFiles, {a.terrain, a.canopy, a.database, a.abiotics, a.densityImage, a.exemplar});
    requireDistinctOutputs(outputFiles);
    synth::SynthParams params = a.params;
    params.method = synth::parseSynthMethod(a.method ? *a.method : std::string("structured"));
    params.validate();
    if (!a.exemplar.empty() && params.method != synth::SynthMethod::Xu2015)
        throw ValidationError("--exemplar '" + a.exemplar + "' is read by --method xu2015 only (method is '" +
                              synth::toString(params.method) + "')");
    if (a.exemplar.empty() && params.method == synth::SynthMethod::Xu2015)
        throw ValidationError("--method xu2015 needs an exemplar stand: --exemplar FILE (a simulation file or a plant CSV)");
    if (!a.densityImage.empty() && params.method != synth::SynthMethod::Deussen)
        throw ValidationError("--density-image '" + a.densityImage + "' is read by --method deussen only (method is '" +
                              synth::toString(params.method) + "')");
    synth::RefineParams refineParams;
    a.refineParams.applyTo(refineParams, synth::refineParamFields(), "refinement parameter");
    refineParams.seed = params.seed;
    if (!a.refineWindow.empty()) {
        refineParams.useWindow = true;
        refineParams.window = parseWindow(a.refineWindow, "--refine-window", false);
    }
    refineParams.validate();
    synth::ForestFloorParams floorParams = a.floorParams;
    floorParams.undergrowthShades = !a.noUndergrowthShade;
    floorParams.validate();
    RectWindow zoom{};
    if (!a.zoom.empty()) zoom = parseWindow(a.zoom, "--zoom", true);

    const BiomeDatabase db = readBiomeDatabase(a.database);
    const Biome biome = synth::databaseBiome(db);
    reporter.info("database: " + a.database + ": biome " + biome.name + ", " + std::to_string(db.regions.size()) + " regions in " +
         std::to_string(db.combinations.size()) + " combinations; seeding disc " + num(db.seedingRadiusFactor) +
         " x crown radius");
    if (db.regions.empty()) throw ValidationError(a.database + ": the database holds no region; nothing to synthesize from");

    Grid<float> terrain = readTerrain(a.terrain, a.terrainRead.options());
    reporter.info("terrain: " + a.terrain + ": " + terrain.geometryText());
    if (refineParams.useWindow) {
        const RectWindow& w = refineParams.window;
        const double tx0 = terrain.originX(), ty0 = terrain.originY();
        if (w.x0 >= tx0 + terrain.extentX() || w.x1 <= tx0 || w.y0 >= ty0 + terrain.extentY() || w.y1 <= ty0)
            throw ValidationError("--refine-window " + a.refineWindow + " lies outside the terrain '" + a.terrain + "' (" +
                                  num(tx0) + "," + num(ty0) + "," + num(tx0 + terrain.extentX()) + "," +
                                  num(ty0 + terrain.extentY()) + " in metres): nothing would be refined");
    }
    const CanopyFileData canopyFile = readCanopyFile(a.canopy, biome);
    if (!canopyFile.terrainM.sameGeometry(terrain))
        throw ValidationError("canopy '" + a.canopy + "' was placed on a terrain of " + canopyFile.terrainM.geometryText() +
                              " but --terrain '" + a.terrain + "' is " + terrain.geometryText() +
                              "; give the terrain the canopy was made for");
    // The canopy file keeps the CRS of a georeferenced input: the scene's grids and plants are
    // in it even when --terrain is a file without one.
    terrain.setCrsWkt(sharedCrs(terrain.crsWkt(), "terrain '" + a.terrain + "'", canopyFile.terrainM.crsWkt(), "canopy '" + a.canopy + "'"));
    synth::validateCanopy(canopyFile.trees, terrain, biome, a.canopy);
    std::optional<Grid<float>> densityImage;
    if (!a.densityImage.empty()) {
        densityImage = synth::readDensityImage(a.densityImage, terrain);
        reporter.info("density image: " + a.densityImage + ": relative density per cell (white densest) times the database's "
                      "density map, scaled to the database's total over the terrain");
    }
    std::optional<synth::XuExemplar> exemplar;
    if (!a.exemplar.empty()) {
        exemplar = readExemplar(a.exemplar, a.exemplarYear, a.exemplarWindow, biome);
        const RectWindow& w = exemplar->window;
        reporter.info(exemplar->source + ": " + std::to_string(exemplar->plants.size()) + " undergrowth plants in " + num(w.x0) +
                      "," + num(w.y0) + "," + num(w.x1) + "," + num(w.y1) + " (" +
                      num(static_cast<double>(exemplar->plants.size()) / w.areaM2(), 4) + " per m2)");
    }
    const std::vector<Plant>& canopy = canopyFile.trees;
    reporter.info("canopy: " + a.canopy + ": " + std::to_string(canopy.size()) + " trees");
    for (const auto& [flag, path] : outputFiles)
        if (!path.empty()) prepareOutput(path);
    if (!a.pngDir.empty()) prepareOutputDirectory(a.pngDir);
    if (!a.geotiffDir.empty()) prepareOutputDirectory(a.geotiffDir);

    const Abiotics abiotics = abioticsForTerrain(a.abiotics, terrain, a.terrain, biome,
                                                 "the database's biome; give --abiotics FILE to reuse them", reporter);
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
    const synth::ClusterMap clusters = synth::computeClusterMap(db, biome, canopy, shadedFeatures, params);
    const double clusterS = secondsSince(t);
    std::int64_t seeded = 0, labelled = 0;
    for (std::size_t i = 0; i < clusters.region.size(); ++i) {
        seeded += clusters.combination.data()[i] != 0;
        labelled += clusters.region.data()[i] >= 0;
    }
    reporter.info("cluster map: " + num(clusterS, 3) + " s; " + std::to_string(seeded) + " of " + std::to_string(clusters.region.size()) +
         " cells seeded by a canopy tree, " + std::to_string(labelled) + " in a database region");
    // Combinations of the target that no analysed simulation had: said once each, with the
    // stand-in whose statistics their cells get (or none), so that a user knows where the
    // scene rests on other conditions than its own (eco database build makes them all).
    std::map<std::int32_t, std::int64_t> cellsOfMask;
    for (std::size_t i = 0; i < clusters.combination.size(); ++i)
        if (const std::int32_t m = clusters.combination.data()[i]; m != 0 && db.combinationIndex(m) < 0) ++cellsOfMask[m];
    const double cellArea = clusters.combination.cellSizeM() * clusters.combination.cellSizeM();
    for (const auto& [mask, cells] : cellsOfMask) {
        const int stand = db.standInCombination(mask);
        reporter.info("warning: database " + a.database + " has no simulated statistics for combination '" +
                      db.combinationName(mask) + "' (" + num(static_cast<double>(cells) * cellArea, 4) + " m^2 of the target, " +
                      num(100.0 * static_cast<double>(cells) / static_cast<double>(std::max<std::int64_t>(seeded, 1)), 3) +
                      " % of the seeded cells): " +
                      (stand < 0 ? std::string("left without undergrowth")
                                 : "its cells use the statistics of '" + db.combinationName(stand) + "'"));
    }

    synth::UndergrowthSample sample =
        synth::sampleUndergrowth(db, biome, canopy, clusters, terrain, params, densityImage ? &*densityImage : nullptr,
                                 exemplar ? &*exemplar : nullptr);
    reporter.info("sampling: " + num(sample.seconds, 3) + " s; " + std::to_string(sample.plants.size()) + " undergrowth plants in " +
         std::to_string(sample.passes) + " passes (" + std::to_string(sample.darts) + " darts, " +
         std::to_string(sample.dartsOnTrunks) + " on trunks)");
    for (const std::string& w : sample.warnings) reporter.info("warning: database " + a.database + ": " + w);
    if (params.method == synth::SynthMethod::Structured) {
        for (const synth::RegionStructure& st : sample.structure) {
            const synth::RegionSampling& rs = sample.regions[static_cast<std::size_t>(st.region)];
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
            reporter.info(text);
        }
        reporter.info("heights: " + std::to_string(sample.heightsLimitedByCrown) + " plants drawn below the lowest crown above them");
        for (const auto& ph : sample.phases)
            reporter.detail("structured: " + ph.name + " " + num(ph.wallS, 3) + " s (" + num(ph.cpuS, 3) + " s CPU)");
    }
    if (params.method == synth::SynthMethod::Deussen) {
        for (const auto& d : sample.deussen) {
            std::string text = "deussen: " + biome.species[static_cast<std::size_t>(d.species)].name + ": half-toning cell " +
                               num(d.halftoneCellM, 3) + " m, " + std::to_string(d.dots) + " dots, " + std::to_string(d.dropped) +
                               " dropped (minimum distance " + num(d.minDistanceM, 3) + " m); Clark-Evans R " +
                               num(d.clarkEvansBefore, 3) + " -> " + num(d.clarkEvansAfter, 3) + "; mean move per Lloyd step (m):";
            for (double v : d.meanMoveM) text += " " + num(v, 3);
            reporter.info(text);
        }
        for (const auto& ph : sample.phases) reporter.info("deussen: " + ph.name + " " + num(ph.wallS, 3) + " s");
        reporter.info("heights: " + std::to_string(sample.heightsLimitedByCrown) + " plants drawn below the lowest crown above them");
    }
    if (params.method == synth::SynthMethod::Xu2015) {
        const synth::XuPattern& x = sample.xu;
        reporter.info("xu2015: neighbourhood radius " + num(x.radiusM, 4) + " m (" + std::to_string(params.xu.shells) + " shells x " +
                      std::to_string(params.xu.sectors) + " sectors), minimum distance " + num(x.minDistanceM, 4) + " m; " +
                      std::to_string(x.interiorCandidates) + " interior exemplar plants; " + std::to_string(x.extensions) +
                      " extensions (" + std::to_string(x.holeSeeds) + " from empty spots) in " + std::to_string(x.tiles) +
                      " tiles; " + std::to_string(x.conflicts) + " copies refused (minimum distance), " +
                      std::to_string(x.seamDrops) + " dropped at tile borders");
        reporter.info("xu2015: dropped " + std::to_string(sample.xuDroppedOutsideRegion) +
                      " where the cluster map has no region or the species cannot grow, " +
                      std::to_string(sample.xuDroppedOnTrunk) + " on canopy trunks; " +
                      std::to_string(sample.heightsLimitedByCrown) + " copied heights reached the crown above and were drawn below it");
        for (const auto& ph : sample.phases) reporter.info("xu2015: " + ph.name + " " + num(ph.wallS, 3) + " s");
    }
    std::vector<Plant> undergrowth = std::move(sample.plants);
    sample.plants.clear();

    synth::RefineResult refined;
    if (a.refine) {
        auto bar = reporter.progress("refinement sweeps", refineParams.sweeps);
        refined = synth::refineUndergrowth(undergrowth, canopy, clusters, terrain, db, params, refineParams,
                                           [&](int done, int) { bar->update(done); });
        bar->finish();
    }

    t = Clock::now();
    const synth::ForestFloor floor = synth::computeForestFloor(features, canopy, undergrowth, biome, floorParams);
    const double floorS = secondsSince(t);
    reporter.info("forest floor: " + num(floorS, 3) + " s");

    // Report.
    out << "undergrowth per region (target = database density x the region's area here):\n"
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
        out << line;
        totalTarget += r.targetCount;
    }
    out << "canopy trees: " << canopy.size() << "; undergrowth plants: " << undergrowth.size() << " (target "
              << totalTarget << ")\n";
    out << "timing: cluster map " << num(clusterS, 3) << " s, sampling " << num(sample.seconds, 3) << " s"
              << (a.refine ? ", refinement " + num(refined.seconds, 3) + " s" : std::string()) << ", forest floor "
              << num(floorS, 3) << " s\n";
    if (a.refine) {
        out << "refinement: pair-correlation distance " << num(refined.distanceBefore, 5) << " -> "
                  << num(refined.distanceAfter, 5) << " over the database's " << num(db.pcfBins.rMaxM, 4) << " m ("
                  << refined.accepted << " of " << refined.proposals << " moves accepted, " << refined.movable
                  << " plants movable; matched to " << num(refined.rMaxM, 4) << " m, distance there per sweep:";
        for (double v : refined.objectivePerSweep) out << " " << num(v, 4);
        out << ")\n";
    }

    synth::SceneRecord record;
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
    record.densityImageSource = a.densityImage;
    if (exemplar) record.exemplarSource = exemplar->source;
    record.abioticsSource = a.abiotics.empty() ? "computed from the terrain (default parameters)" : a.abiotics;
    // The scene file, side files and pictures are committed together (core/atomic_file.h):
    // a kill leaves the previous set, or a journal beside the scene that the next run completes.
    AtomicOutputSet outputs;
    synth::writeSceneFile(a.out, record, biome, db);
    result.written.push_back(a.out);
    result.canopyTrees = record.canopy.size();
    result.undergrowthPlants = record.undergrowth.size();
    out << "wrote scene: " << a.out
              << " (/canopy, /undergrowth, /forest_floor/{grass,litter}, /cluster_map, /combination_map, /terrain, /regions"
              << (a.refine ? ", /refinement" : "") << ")\n";
    if (!a.csv.empty()) {
        synth::writeScenePlantsCsv(a.csv, record.canopy, record.undergrowth, biome);
        result.written.push_back(a.csv);
        out << "wrote plants: " << a.csv << "\n";
    }
    if (!a.gpkg.empty()) {
        const std::string& crs = terrain.crsWkt();
        writePlantsGpkg(a.gpkg, {PlantLayer{"canopy", &record.canopy}, PlantLayer{"undergrowth", &record.undergrowth}}, biome, crs);
        result.written.push_back(a.gpkg);
        out << "wrote plants: " << a.gpkg << " (GeoPackage" << (crs.empty() ? ", no CRS" : ", the terrain's CRS") << ")\n";
    }
    if (!a.geotiffDir.empty()) writeGeoTiffs(a.out, outputs, a.geotiffDir, reporter, result.written);
    if (!a.pdb.empty()) {
        synth::writePdb(a.pdb, record.canopy, record.undergrowth);
        result.written.push_back(a.pdb);
        out << "wrote PDB plant list: " << a.pdb << "\n";
    }
    if (!a.pdbCanopy.empty()) {
        synth::writePdb(a.pdbCanopy, record.canopy, {});
        result.written.push_back(a.pdbCanopy);
        out << "wrote PDB plant list (canopy): " << a.pdbCanopy << "\n";
    }
    if (!a.pdbUndergrowth.empty()) {
        synth::writePdb(a.pdbUndergrowth, {}, record.undergrowth);
        result.written.push_back(a.pdbUndergrowth);
        out << "wrote PDB plant list (undergrowth): " << a.pdbUndergrowth << "\n";
    }
    if (!a.pngDir.empty()) {
        const std::string dir = a.pngDir + "/";
        synth::writeScenePng(dir + "scene.png", record.canopy, record.undergrowth, terrain, &floor, biome, "Synthesized scene");
        const RectWindow crop = a.zoom.empty() ? synth::defaultZoomWindow(terrain) : zoom;
        synth::writeScenePng(dir + "scene_zoom.png", record.canopy, record.undergrowth, terrain, &floor, biome,
                             "Zoom " + num(crop.x0, 5) + ".." + num(crop.x1, 5) + " x " + num(crop.y0, 5) + ".." + num(crop.y1, 5) + " m",
                             &crop, 900);
        writeMapPng(dir + "grass.png", floor.grass, "Forest floor: grass / forb density", "density (0..1)",
                    Colormap::Viridis, 0, 1);
        writeMapPng(dir + "litter.png", floor.litter, "Forest floor: litter density", "density (0..1)", Colormap::Browns, 0, 1);
        std::vector<std::string> names;
        for (const auto& r : db.regions)
            names.push_back(std::to_string(names.size()) + ": " + db.combinationName(r.combination) + " / " +
                            std::to_string(r.cluster));
        writeCategoryPng(dir + "cluster_map.png", clusters.region, "Cluster map (database region of each cell)", names,
                         "no region (not seeded)");
        for (const char* name : {"scene.png", "scene_zoom.png", "grass.png", "litter.png", "cluster_map.png"})
            result.written.push_back(dir + name);
        out << "wrote pictures: " << a.pngDir << "/ (scene.png, scene_zoom.png, grass.png, litter.png, cluster_map.png)\n";
    }
    outputs.commit();
    reporter.info("synthesis finished in " + num(secondsSince(tStart), 3) + " s");
    return result;
}

CompareResult compareStage(const CompareOptions& a, Reporter& reporter) {
    std::ostream& out = reporter.out();
    CompareResult result;
    const std::string png = a.pngDir.empty() ? std::string() : (std::filesystem::path(a.pngDir) / "compare.png").string();
    requireOutputsNotInputs({{"--out", a.out}, {"--png", png}}, {a.scene, a.database});
    const BiomeDatabase db = readBiomeDatabase(a.database);
    const Biome biome = synth::databaseBiome(db);
    const synth::SceneData scene = synth::readSceneFile(a.scene, biome);
    RectWindow window{};
    if (!a.window.empty()) window = parseWindow(a.window, "--window", false);
    if (!a.out.empty()) cleanUpAfterDeadWriters(a.out);  // what killed runs left
    if (!a.pngDir.empty()) prepareOutputDirectory(a.pngDir);
    const auto t = Clock::now();
    result.comparison = synth::compareScene(scene.canopy, scene.undergrowth, scene.clusterMap, db,
                                           a.window.empty() ? nullptr : &window, a.pcfSources);
    const synth::SceneComparison& c = result.comparison;
    reporter.info("compared in " + num(secondsSince(t), 3) + " s");
    std::ostringstream text;
    text << "scene " << a.scene << " (" << scene.canopy.size() << " canopy, " << scene.undergrowth.size()
         << " undergrowth) against database " << a.database
         << (a.window.empty() ? std::string() : " inside " + a.window) << "\n\n"
         << synth::comparisonTable(c, db);
    result.table = text.str();
    out << text.str();
    AtomicOutputSet outputs;  // the table and the picture together
    if (!a.out.empty()) {
        writeTextFile(a.out, text.str());
        out << "wrote table: " << a.out << "\n";
    }
    if (!png.empty()) {
        synth::writeComparisonPng(png, c, db);
        out << "wrote picture: " << png << "\n";
    }
    outputs.commit();
    return result;
}

const std::vector<ParamFlagName>& refineParamFlags() {
    static const std::vector<ParamFlagName> flags = {
        {"--refine-sweeps", "refine_sweeps"},
        {"--refine-rmax", "refine_rmax_m"},
        {"--refine-move", "refine_move_radius_m"},
        {"--refine-swap", "refine_swap_radius_m"},
    };
    return flags;
}

std::vector<std::string> commandLine(const SynthOptions& a) {
    std::vector<std::string> args = {"synth", "--terrain", a.terrain, "--canopy", a.canopy, "--database", a.database};
    if (!a.abiotics.empty()) args.insert(args.end(), {"--abiotics", a.abiotics});
    args.insert(args.end(), {"--out", a.out});
    if (!a.pngDir.empty()) args.insert(args.end(), {"--png", a.pngDir});
    if (!a.csv.empty()) args.insert(args.end(), {"--csv", a.csv});
    if (!a.pdb.empty()) args.insert(args.end(), {"--pdb", a.pdb});
    if (!a.pdbCanopy.empty()) args.insert(args.end(), {"--pdb-canopy", a.pdbCanopy});
    if (!a.pdbUndergrowth.empty()) args.insert(args.end(), {"--pdb-undergrowth", a.pdbUndergrowth});
    if (!a.gpkg.empty()) args.insert(args.end(), {"--gpkg", a.gpkg});
    if (!a.geotiffDir.empty()) args.insert(args.end(), {"--geotiff", a.geotiffDir});
    args.insert(args.end(), {"--seed", std::to_string(a.params.seed)});
    if (a.method) args.insert(args.end(), {"--method", *a.method});
    if (!a.densityImage.empty()) args.insert(args.end(), {"--density-image", a.densityImage});
    const synth::DeussenParams deussenDefaults;
    if (a.params.deussen.lloydIterations != deussenDefaults.lloydIterations)
        args.insert(args.end(), {"--lloyd-iterations", std::to_string(a.params.deussen.lloydIterations)});
    if (a.params.deussen.minDistanceFactor != deussenDefaults.minDistanceFactor)
        args.insert(args.end(), {"--min-distance-factor", argNumber(a.params.deussen.minDistanceFactor)});
    if (!a.exemplar.empty()) args.insert(args.end(), {"--exemplar", a.exemplar});
    if (a.exemplarYear >= 0) args.insert(args.end(), {"--exemplar-year", std::to_string(a.exemplarYear)});
    if (!a.exemplarWindow.empty()) args.insert(args.end(), {"--exemplar-window", a.exemplarWindow});
    const synth::XuParams xuDefaults;
    if (a.params.xu.radiusFactor != xuDefaults.radiusFactor)
        args.insert(args.end(), {"--xu-radius-factor", argNumber(a.params.xu.radiusFactor)});
    if (a.params.xu.sigma != xuDefaults.sigma) args.insert(args.end(), {"--xu-sigma", argNumber(a.params.xu.sigma)});
    if (a.params.xu.candidates != xuDefaults.candidates)
        args.insert(args.end(), {"--xu-candidates", std::to_string(a.params.xu.candidates)});
    if (a.params.xu.tileM != xuDefaults.tileM) args.insert(args.end(), {"--xu-tile", argNumber(a.params.xu.tileM)});
    a.terrainRead.appendArgs(args);
    if (!a.zoom.empty()) args.insert(args.end(), {"--zoom", a.zoom});
    const synth::SynthParams synthDefaults;
    if (a.params.maxPasses != synthDefaults.maxPasses) args.insert(args.end(), {"--max-passes", std::to_string(a.params.maxPasses)});
    if (a.params.seedInnerRadiusFactor != synthDefaults.seedInnerRadiusFactor)
        args.insert(args.end(), {"--seed-inner-radius-factor", argNumber(a.params.seedInnerRadiusFactor)});
    if (a.params.trunkExclusionFactor != synthDefaults.trunkExclusionFactor)
        args.insert(args.end(), {"--trunk-exclusion", argNumber(a.params.trunkExclusionFactor)});
    const synth::ForestFloorParams floorDefaults;
    if (a.floorParams.litterFullAlpha != floorDefaults.litterFullAlpha)
        args.insert(args.end(), {"--litter-full-alpha", argNumber(a.floorParams.litterFullAlpha)});
    if (a.noUndergrowthShade) args.push_back("--no-undergrowth-shade");
    if (a.refine) {
        args.push_back("--refine");
        if (!a.refineWindow.empty()) args.insert(args.end(), {"--refine-window", a.refineWindow});
        checkParamFlags(a.refineParams, refineParamFlags());
        appendParamArgs(args, a.refineParams, refineParamFlags());
    }
    return args;
}

std::vector<std::string> commandLine(const CompareOptions& a) {
    std::vector<std::string> args = {"compare", a.scene, a.database};
    if (!a.pngDir.empty()) args.insert(args.end(), {"--png", a.pngDir});
    if (!a.out.empty()) args.insert(args.end(), {"--out", a.out});
    if (!a.window.empty()) args.insert(args.end(), {"--window", a.window});
    if (a.pcfSources != 20000) args.insert(args.end(), {"--pcf-sources", std::to_string(a.pcfSources)});
    return args;
}

}  // namespace eco::pipeline
