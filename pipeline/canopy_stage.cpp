#include "canopy_stage.h"

#include <algorithm>
#include <cstdio>
#include <memory>
#include <ostream>
#include <vector>

#include "abiotics.h"
#include "atomic_file.h"
#include "biome.h"
#include "error.h"
#include "geo_raster.h"
#include "image_out.h"
#include "plants.h"
#include "species_map.h"
#include "terrain_io.h"
#include "text_format.h"

namespace eco::pipeline {

namespace {

std::string num(double v, int precision = 6) { return formatNumber(v, precision); }

/// The CHM and terrain must cover the same cells; CHM heights must be >= 0.
void checkInputs(const Grid<float>& terrain, const std::string& terrainPath, const Grid<float>& chm,
                 const std::string& chmPath) {
    if (!chm.sameGeometry(terrain))
        throw ValidationError("CHM '" + chmPath + "' (" + chm.geometryText() + ") and terrain '" + terrainPath + "' (" +
                              terrain.geometryText() + ") differ in geometry; they must cover the same cells: give "
                              "--resample-terrain to resample the terrain onto the CHM's cells, or align them with "
                              "gdalwarp -te <CHM extent> -tr <CHM cell size> TERRAIN OUT.tif");
    for (int iy = 0; iy < chm.height(); ++iy)
        for (int ix = 0; ix < chm.width(); ++ix)
            if (chm(ix, iy) < 0)
                throw ValidationError(chmPath + ": negative canopy height " + num(chm(ix, iy)) + " m at cell (" +
                                      std::to_string(ix) + ", " + std::to_string(iy) +
                                      ") (column, row from the south); a CHM holds heights above the ground");
}

/// Crowns narrower than two cells cannot be placed on the CHM: a warning when the crown of
/// the median forested height (the smallest of the canopy species' at that height) is
/// narrower than two cells.
void warnIfCoarse(const Grid<float>& chm, const Biome& biome, double thresholdM, const std::string& chmPath, Reporter& reporter) {
    std::vector<float> forested;
    for (const float v : chm.data())
        if (v >= thresholdM) forested.push_back(v);
    if (forested.empty()) return;
    std::nth_element(forested.begin(), forested.begin() + static_cast<std::ptrdiff_t>(forested.size() / 2), forested.end());
    const double median = forested[forested.size() / 2];
    double smallest = 0;
    for (const Species& s : biome.species)
        if (s.canopy) {
            const double r = s.allometry.crownRadiusM(median);
            if (r > 0 && (smallest == 0 || r < smallest)) smallest = r;
        }
    if (smallest > 0 && chm.cellSizeM() > smallest)
        reporter.info("warning: " + chmPath + ": cells of " + num(chm.cellSizeM()) +
                      " m are coarser than the crown radius of a canopy tree of the median height (" + num(smallest, 3) +
                      " m at " + num(median, 3) + " m): crowns narrower than two cells cannot be resolved; "
                      "a CHM of about 1 m cells or finer is expected (gdalwarp -tr 1 1 -r bilinear IN OUT)");
}

synth::CanopyParams canopyParamsFrom(const CanopyOptions& a, synth::SpeciesMapParams& sm) {
    synth::CanopyParams p;
    if (!a.config.empty()) synth::loadCanopyConfig(a.config, p, sm);
    a.params.applyTo(p, synth::canopyParamFields(), "canopy parameter");
    sm.canopyThresholdM = p.canopyThresholdM;
    synth::validateCanopyParams(p);
    return p;
}

}  // namespace

void checkCanopyOptions(const CanopyOptions& a) {
    synth::SpeciesMapParams sm;
    canopyParamsFrom(a, sm);
    const Biome biome = a.biome.empty() ? defaultBiome() : loadBiome(a.biome);
    for (const auto& t : a.targets) synth::parseSpeciesTarget(t, biome);
}

namespace {

void printIteration(std::ostream& out, const IterationStats& s) {
    char line[160];
    if (s.iteration < 0)
        std::snprintf(line, sizeof line, "  final   %8zu %8zu %8s %9.4f %8.3f %8.3f", s.trees, s.removed, "-", s.coverage,
                      s.rmseM, s.seconds);
    else
        std::snprintf(line, sizeof line, "  %5d   %8zu %8zu %8zu %9.4f %8.3f %8.3f", s.iteration, s.trees, s.removed,
                      s.added, s.coverage, s.rmseM, s.seconds);
    out << line << "\n" << std::flush;
}

}  // namespace

CanopyStageResult canopyStage(const CanopyOptions& args, Reporter& reporter) {
    // Everything that can be checked cheaply is checked before any heavy work.
    requireOutputsNotInputs({{"--out", args.out}, {"--csv", args.csv}, {"--gpkg", args.gpkg}},
                            {args.terrain, args.chm, args.biome, args.abiotics, args.mask, args.config});
    const Biome biome = args.biome.empty() ? defaultBiome() : loadBiome(args.biome);
    std::vector<synth::SpeciesTarget> targets;
    for (const auto& t : args.targets) targets.push_back(synth::parseSpeciesTarget(t, biome));
    synth::SpeciesMapParams speciesParams;
    const synth::CanopyParams params = canopyParamsFrom(args, speciesParams);
    if (!args.mask.empty() && targets.empty())
        throw ValidationError("--mask '" + args.mask + "' given without --target: a mask only says where targets apply");

    // Every output's directory before any work: a bad --gpkg or --csv must not leave the
    // canopy file written alone.
    for (const std::string* o : {&args.out, &args.csv, &args.gpkg})
        if (!o->empty()) prepareOutput(*o);
    if (!args.geotiffDir.empty()) prepareOutputDirectory(args.geotiffDir);
    if (!args.pngDir.empty()) cleanUpDirectoryAfterDeadWriters(args.pngDir);
    const TerrainReadOptions readOptions = args.terrainRead.options();
    Grid<float> terrain = readTerrain(args.terrain, readOptions);
    ChmReadOptions chmOptions;
    chmOptions.raster.cellSizeM = readOptions.cellSizeM;
    chmOptions.raster.verticalScale = args.chmVerticalScale;
    chmOptions.raster.verticalOffsetM = args.chmVerticalOffsetM;
    chmOptions.raster.originX = terrain.originX();  // an image CHM takes the terrain's corner
    chmOptions.raster.originY = terrain.originY();
    chmOptions.gaps = parseChmGapRule(args.chmGaps, "--chm-gaps");
    chmOptions.fillMaxM = args.chmFillMaxM;
    ChmRead chmRead = readChm(args.chm, chmOptions);
    // One CRS for both (an image CHM takes the terrain's, as it takes its corner); it goes
    // into the canopy file's grids and the GeoPackage.
    const std::string crs = sharedCrs(terrain.crsWkt(), args.terrain, chmRead.chm.crsWkt(), args.chm);
    terrain.setCrsWkt(crs);
    chmRead.chm.setCrsWkt(crs);
    const Grid<float>& chm = chmRead.chm;
    if (const std::string repaired = chmRead.summary(args.chm); !repaired.empty()) reporter.info(repaired);
    if (args.resampleTerrain && !chm.sameGeometry(terrain)) {
        const std::string before = terrain.geometryText();
        terrain = resampledOnto(terrain, chm, "terrain '" + args.terrain + "'");
        reporter.info("terrain: " + args.terrain + " (" + before + ") resampled bilinearly onto the CHM's cells; the canopy "
                      "file keeps it, so give the canopy file as --terrain to eco abiotics, simulate and synth");
    }
    checkInputs(terrain, args.terrain, chm, args.chm);
    warnIfCoarse(chm, biome, params.canopyThresholdM, args.chm, reporter);
    reporter.info("terrain: " + args.terrain + ": " + terrain.geometryText());
    reporter.info("CHM: " + args.chm + ": heights " + num(chm.minValue()) + " .. " + num(chm.maxValue()) + " m, " +
                  std::to_string(synth::forestedCells(chm, params.canopyThresholdM)) + " cells >= " +
                  num(params.canopyThresholdM) + " m (forested)");
    reporter.info("biome: " + biome.name + (args.biome.empty() ? " (embedded)" : " (" + args.biome + ")"));

    // Abiotics: from the file, or computed from the terrain.
    const Abiotics abiotics = abioticsForTerrain(args.abiotics, terrain, args.terrain, biome,
                                                 "give --abiotics FILE to reuse them", reporter);

    // Species map and targets.
    std::ostream& out = reporter.out();
    const synth::SpeciesMapInputs inputs = synth::speciesMapInputs(abiotics, chm);
    std::shared_ptr<const Grid<std::uint8_t>> mask;
    if (!args.mask.empty()) {
        mask = std::make_shared<const Grid<std::uint8_t>>(synth::readMaskImage(args.mask, chm));
        reporter.info("mask: " + args.mask + ": " +
                      std::to_string(synth::forestedCells(chm, params.canopyThresholdM, mask.get())) + " forested cells inside");
    }
    std::vector<synth::TargetResult> results;
    if (!targets.empty()) {
        auto bar = reporter.progress("species targets", 1);
        results = synth::meetTargets(biome, inputs, speciesParams, targets, mask, args.mask);
        bar->finish();
    }
    const Grid<std::int32_t> speciesMap = synth::computeSpeciesMap(biome, inputs, speciesParams);
    {
        out << "species map (share of the forested area" << (mask ? " inside the mask" : "") << "):\n";
        for (int s : synth::canopySpeciesOf(biome)) {
            const double f = synth::speciesFraction(speciesMap, chm, s, params.canopyThresholdM, mask.get());
            if (f > 0) out << "  " << biome.species[static_cast<std::size_t>(s)].name << ": " << num(f, 4) << "\n";
        }
        const double none = synth::speciesFraction(speciesMap, chm, -1, params.canopyThresholdM, mask.get());
        if (none > 0) out << "  (no species can grow): " << num(none, 4) << "\n";
    }
    for (const auto& r : results) {
        if (r.feasible) {
            out << "target " << r.species << " = " << num(r.requested, 4) << ": reached " << num(r.achieved, 4)
                << " (weight " << num(r.weight, 4) << ", effective alpha " << num(r.alpha, 4) << ", " << r.iterations
                << " evaluations)\n";
        } else {
            out << "target " << r.species << " = " << num(r.requested, 4) << ": NOT FEASIBLE; best reached "
                << num(r.achieved, 4) << " (at most " << num(r.reachable, 4) << " of the forested area"
                << (mask ? " inside the mask" : "") << " can hold " << r.species
                << ": elsewhere it cannot grow or the canopy is taller than it gets)\n";
        }
    }

    // Trees.
    out << "canopy placement (coverage = share of CHM cells >= " << num(params.canopyThresholdM)
        << " m under a crown; RMSE of crown surface - CHM there):\n"
        << "  iter       trees  removed    added  coverage   rmse_m  seconds\n";
    CanopyStageResult stageResult;
    stageResult.placement =
        synth::placeCanopy(chm, terrain, speciesMap, biome, params, [&](const IterationStats& s) { printIteration(out, s); });
    const synth::CanopyResult& result = stageResult.placement;
    out << "placed " << result.trees.size() << " canopy trees in " << num(result.seconds, 3) << " s ("
        << result.initialSeeds << " initial seeds, " << result.seedsMerged << " merged, " << result.duplicatesRemoved
        << " duplicates removed; stop: "
        << result.stopReason << ")\n";
    if (result.fallbackTrees > 0)
        out << "  " << result.fallbackTrees
            << " trees stand where no canopy species can grow; they took the species of the nearest mapped cell\n";

    synth::CanopyRecord record;
    record.result = result;
    record.speciesMap = speciesMap;
    record.chmM = chm;
    record.terrainM = terrain;
    record.params = params;
    record.speciesParams = speciesParams;
    record.targets = results;
    record.terrainSource = args.terrain;
    record.chmSource = args.chm;
    record.abioticsSource = args.abiotics.empty() ? "computed from the terrain (default parameters)" : args.abiotics;
    record.biomeSource = args.biome.empty() ? "embedded" : args.biome;
    record.maskSource = args.mask;
    AtomicOutputSet outputs;  // the canopy file, side files and pictures together
    synth::writeCanopyFile(args.out, record, biome);
    stageResult.written.push_back(args.out);
    out << "wrote canopy: " << args.out << " (/canopy trees, /species_map, /chm/height, /terrain/elevation, "
        << "/iterations, /targets)\n";
    if (!args.gpkg.empty()) {
        writePlantsGpkg(args.gpkg, {PlantLayer{"canopy", &result.trees}}, biome, crs);
        stageResult.written.push_back(args.gpkg);
        out << "wrote trees: " << args.gpkg << " (GeoPackage" << (crs.empty() ? ", no CRS" : ", the input's CRS") << ")\n";
    }
    if (!args.geotiffDir.empty()) writeGeoTiffs(args.out, outputs, args.geotiffDir, reporter, stageResult.written);
    if (!args.csv.empty()) {
        writePlantsCsv(args.csv, result.trees, biome, "canopy");
        stageResult.written.push_back(args.csv);
        out << "wrote trees: " << args.csv << "\n";
    }
    if (!args.pngDir.empty()) {
        ensureDirectory(args.pngDir);
        synth::writeCanopyPng(args.pngDir + "/canopy.png", result.trees, terrain, biome);
        std::vector<std::string> names;
        for (const auto& s : biome.species) names.push_back(s.name);
        writeCategoryPng(args.pngDir + "/species_map.png", speciesMap, "Species map (dominant canopy species)", names,
                         "none (no species can grow)");
        writeMapPng(args.pngDir + "/chm.png", chm, "Canopy height model", "m", Colormap::Viridis);
        stageResult.written.insert(stageResult.written.end(), {args.pngDir + "/canopy.png", args.pngDir + "/species_map.png",
                                                               args.pngDir + "/chm.png"});
        out << "wrote pictures: " << args.pngDir << "/ (canopy.png, species_map.png, chm.png)\n";
    }
    outputs.commit();
    return stageResult;
}

const std::vector<ParamFlagName>& canopyParamFlags() {
    static const std::vector<ParamFlagName> flags = {
        {"--seed", "seed"},
        {"--max-iterations", "max_iterations"},
        {"--min-visible-fraction", "min_visible_fraction"},
        {"--move-factor", "move_factor"},
        {"--ring-factor", "ring_factor"},
        {"--min-trunk-distance", "min_trunk_distance_m"},
        {"--coverage-epsilon", "coverage_epsilon"},
        {"--canopy-threshold", "canopy_threshold_m"},
        {"--min-seed-height", "min_seed_height_m"},
        {"--seed-merge-radius-fraction", "seed_merge_radius_fraction"},
    };
    return flags;
}

std::vector<std::string> commandLine(const CanopyOptions& a) {
    std::vector<std::string> args = {"canopy", "--terrain", a.terrain, "--chm", a.chm};
    if (!a.abiotics.empty()) args.insert(args.end(), {"--abiotics", a.abiotics});
    args.insert(args.end(), {"--out", a.out});
    if (!a.pngDir.empty()) args.insert(args.end(), {"--png", a.pngDir});
    if (!a.csv.empty()) args.insert(args.end(), {"--csv", a.csv});
    if (!a.gpkg.empty()) args.insert(args.end(), {"--gpkg", a.gpkg});
    if (!a.geotiffDir.empty()) args.insert(args.end(), {"--geotiff", a.geotiffDir});
    // The seed here and the other parameters below, where the command line has always shown them.
    const std::vector<ParamFlagName>& flags = canopyParamFlags();
    checkParamFlags(a.params, flags);
    appendParamArgs(args, a.params, {flags.begin(), flags.begin() + 1});
    a.terrainRead.appendArgs(args);
    if (a.chmVerticalScale != 1) args.insert(args.end(), {"--chm-vertical-scale", argNumber(a.chmVerticalScale)});
    if (a.chmVerticalOffsetM != 0) args.insert(args.end(), {"--chm-vertical-offset", argNumber(a.chmVerticalOffsetM)});
    if (a.chmGaps != "fill") args.insert(args.end(), {"--chm-gaps", a.chmGaps});
    if (a.chmFillMaxM != 2.0) args.insert(args.end(), {"--chm-fill-max", argNumber(a.chmFillMaxM)});
    if (a.resampleTerrain) args.push_back("--resample-terrain");
    if (!a.config.empty()) args.insert(args.end(), {"--config", a.config});
    for (const auto& t : a.targets) args.insert(args.end(), {"--target", t});
    if (!a.mask.empty()) args.insert(args.end(), {"--mask", a.mask});
    appendParamArgs(args, a.params, {flags.begin() + 1, flags.end()});
    if (!a.biome.empty()) args.insert(args.end(), {"--biome", a.biome});
    return args;
}

}  // namespace eco::pipeline
