// eco canopy: parsing, progress and reporting only; the science is in synth/species_map and
// synth/canopy_placer (docs/canopy.md).
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include "abiotics.h"
#include "atomic_file.h"
#include "biome.h"
#include "canopy_placer.h"
#include "cli_common.h"
#include "error.h"
#include "image_out.h"
#include "plants.h"
#include "species_map.h"
#include "terrain_io.h"
#include "text_format.h"

namespace eco::cli {

namespace {

struct CanopyArgs {
    std::string terrain, chm, biome, abiotics, out, pngDir, csv, mask, config;
    std::vector<std::string> targets;
    double cellSizeM = 0, verticalScale = 1, verticalOffsetM = 0, chmVerticalScale = 1, chmVerticalOffsetM = 0;
    std::string chmGaps = "fill";  ///< nodata cells of the CHM: fill, zero or fail
    double chmFillMaxM = 2.0;
    // Overrides of CanopyParams (applied after --config when given).
    std::uint64_t seed = 1;
    int maxIterations = 0;
    double minVisibleFraction = 0, moveFactor = 0, ringFactor = 0, minTrunkDistanceM = 0, coverageEpsilon = 0,
           canopyThresholdM = 0, minSeedHeightM = 0;
    // Which overrides were given.
    CLI::Option *seedOpt = nullptr, *maxIterationsOpt = nullptr, *minVisibleOpt = nullptr, *moveOpt = nullptr,
                *ringOpt = nullptr, *trunkOpt = nullptr, *epsilonOpt = nullptr, *thresholdOpt = nullptr,
                *seedHeightOpt = nullptr;
};

std::string num(double v, int precision = 6) { return formatNumber(v, precision); }

/// The CHM and terrain must cover the same cells; CHM heights must be >= 0.
void checkInputs(const Grid<float>& terrain, const std::string& terrainPath, const Grid<float>& chm,
                 const std::string& chmPath) {
    if (!chm.sameGeometry(terrain))
        throw ValidationError("CHM '" + chmPath + "' (" + chm.geometryText() + ") and terrain '" + terrainPath + "' (" +
                              terrain.geometryText() + ") differ in geometry; they must cover the same cells");
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
void warnIfCoarse(const Grid<float>& chm, const Biome& biome, double thresholdM, const std::string& chmPath) {
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
        info("warning: " + chmPath + ": cells of " + num(chm.cellSizeM()) + " m are coarser than the crown radius of a canopy tree of the median height (" +
             num(smallest, 3) + " m at " + num(median, 3) + " m): crowns narrower than two cells cannot be resolved; "
             "a CHM of about 1 m cells or finer is expected (gdalwarp -tr 1 1 -r bilinear IN OUT)");
}

CanopyParams canopyParamsFrom(const CanopyArgs& a, SpeciesMapParams& sm) {
    CanopyParams p;
    if (!a.config.empty()) loadCanopyConfig(a.config, p, sm);
    if (a.seedOpt->count()) p.seed = a.seed;
    if (a.maxIterationsOpt->count()) p.maxIterations = a.maxIterations;
    if (a.minVisibleOpt->count()) p.minVisibleFraction = a.minVisibleFraction;
    if (a.moveOpt->count()) p.moveFactor = a.moveFactor;
    if (a.ringOpt->count()) p.ringFactor = a.ringFactor;
    if (a.trunkOpt->count()) p.minTrunkDistanceM = a.minTrunkDistanceM;
    if (a.epsilonOpt->count()) p.coverageEpsilon = a.coverageEpsilon;
    if (a.thresholdOpt->count()) p.canopyThresholdM = a.canopyThresholdM;
    if (a.seedHeightOpt->count()) p.minSeedHeightM = a.minSeedHeightM;
    sm.canopyThresholdM = p.canopyThresholdM;
    validateCanopyParams(p);
    return p;
}

void printIteration(const IterationStats& s) {
    char line[160];
    if (s.iteration < 0)
        std::snprintf(line, sizeof line, "  final   %8zu %8zu %8s %9.4f %8.3f %8.3f", s.trees, s.removed, "-", s.coverage,
                      s.rmseM, s.seconds);
    else
        std::snprintf(line, sizeof line, "  %5d   %8zu %8zu %8zu %9.4f %8.3f %8.3f", s.iteration, s.trees, s.removed,
                      s.added, s.coverage, s.rmseM, s.seconds);
    std::cout << line << "\n" << std::flush;
}

void runCanopy(const CanopyArgs& args) {
    // Everything that can be checked cheaply is checked before any heavy work.
    const Biome biome = args.biome.empty() ? defaultBiome() : loadBiome(args.biome);
    std::vector<SpeciesTarget> targets;
    for (const auto& t : args.targets) targets.push_back(parseSpeciesTarget(t, biome));
    SpeciesMapParams speciesParams;
    const CanopyParams params = canopyParamsFrom(args, speciesParams);
    if (!args.mask.empty() && targets.empty())
        throw ValidationError("--mask '" + args.mask + "' given without --target: a mask only says where targets apply");

    TerrainReadOptions readOptions;
    readOptions.cellSizeM = args.cellSizeM;
    readOptions.verticalScale = args.verticalScale;
    readOptions.verticalOffsetM = args.verticalOffsetM;
    const Grid<float> terrain = readTerrain(args.terrain, readOptions);
    ChmReadOptions chmOptions;
    chmOptions.raster.cellSizeM = args.cellSizeM;
    chmOptions.raster.verticalScale = args.chmVerticalScale;
    chmOptions.raster.verticalOffsetM = args.chmVerticalOffsetM;
    chmOptions.raster.originX = terrain.originX();  // an image CHM takes the terrain's corner
    chmOptions.raster.originY = terrain.originY();
    chmOptions.gaps = parseChmGapRule(args.chmGaps, "--chm-gaps");
    chmOptions.fillMaxM = args.chmFillMaxM;
    const ChmRead chmRead = readChm(args.chm, chmOptions);
    const Grid<float>& chm = chmRead.chm;
    if (const std::string repaired = chmRead.summary(args.chm); !repaired.empty()) info(repaired);
    checkInputs(terrain, args.terrain, chm, args.chm);
    warnIfCoarse(chm, biome, params.canopyThresholdM, args.chm);
    info("terrain: " + args.terrain + ": " + terrain.geometryText());
    info("CHM: " + args.chm + ": heights " + num(chm.minValue()) + " .. " + num(chm.maxValue()) + " m, " +
         std::to_string(forestedCells(chm, params.canopyThresholdM)) + " cells >= " + num(params.canopyThresholdM) +
         " m (forested)");
    info("biome: " + biome.name + (args.biome.empty() ? " (embedded)" : " (" + args.biome + ")"));

    // Abiotics: from the file, or computed from the terrain.
    const Abiotics abiotics = abioticsForTerrain(args.abiotics, terrain, args.terrain, biome,
                                                 "give --abiotics FILE to reuse them");

    // Species map and targets.
    const SpeciesMapInputs inputs = speciesMapInputs(abiotics, chm);
    std::shared_ptr<const Grid<std::uint8_t>> mask;
    if (!args.mask.empty()) {
        mask = std::make_shared<const Grid<std::uint8_t>>(readMaskImage(args.mask, chm));
        info("mask: " + args.mask + ": " + std::to_string(forestedCells(chm, params.canopyThresholdM, mask.get())) +
             " forested cells inside");
    }
    std::vector<TargetResult> results;
    if (!targets.empty()) {
        Progress bar("species targets", 1);
        results = meetTargets(biome, inputs, speciesParams, targets, mask, args.mask);
        bar.finish();
    }
    const Grid<std::int32_t> speciesMap = computeSpeciesMap(biome, inputs, speciesParams);
    {
        std::cout << "species map (share of the forested area" << (mask ? " inside the mask" : "") << "):\n";
        for (int s : canopySpeciesOf(biome)) {
            const double f = speciesFraction(speciesMap, chm, s, params.canopyThresholdM, mask.get());
            if (f > 0) std::cout << "  " << biome.species[static_cast<std::size_t>(s)].name << ": " << num(f, 4) << "\n";
        }
        const double none = speciesFraction(speciesMap, chm, -1, params.canopyThresholdM, mask.get());
        if (none > 0) std::cout << "  (no species can grow): " << num(none, 4) << "\n";
    }
    for (const auto& r : results) {
        if (r.feasible) {
            std::cout << "target " << r.species << " = " << num(r.requested, 4) << ": reached " << num(r.achieved, 4)
                      << " (weight " << num(r.weight, 4) << ", effective alpha " << num(r.alpha, 4) << ", "
                      << r.iterations << " evaluations)\n";
        } else {
            std::cout << "target " << r.species << " = " << num(r.requested, 4) << ": NOT FEASIBLE; best reached "
                      << num(r.achieved, 4) << " (at most " << num(r.reachable, 4) << " of the forested area"
                      << (mask ? " inside the mask" : "") << " can hold " << r.species
                      << ": elsewhere it cannot grow or the canopy is taller than it gets)\n";
        }
    }

    // Trees.
    std::cout << "canopy placement (coverage = share of CHM cells >= " << num(params.canopyThresholdM)
              << " m under a crown; RMSE of crown surface - CHM there):\n"
              << "  iter       trees  removed    added  coverage   rmse_m  seconds\n";
    const CanopyResult result = placeCanopy(chm, terrain, speciesMap, biome, params, printIteration);
    std::cout << "placed " << result.trees.size() << " canopy trees in " << num(result.seconds, 3) << " s ("
              << result.initialSeeds << " initial seeds, " << result.duplicatesRemoved << " duplicates removed; stop: "
              << result.stopReason << ")\n";
    if (result.fallbackTrees > 0)
        std::cout << "  " << result.fallbackTrees
                  << " trees stand where no canopy species can grow; they took the species of the nearest mapped cell\n";

    CanopyRecord record;
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
    writeCanopyFile(args.out, record, biome);
    std::cout << "wrote canopy: " << args.out << " (/canopy trees, /species_map, /chm/height, /terrain/elevation, "
              << "/iterations, /targets)\n";
    if (!args.csv.empty()) {
        writePlantsCsv(args.csv, result.trees, biome, "canopy");
        std::cout << "wrote trees: " << args.csv << "\n";
    }
    if (!args.pngDir.empty()) {
        ensureDirectory(args.pngDir);
        writeCanopyPng(args.pngDir + "/canopy.png", result.trees, terrain, biome);
        std::vector<std::string> names;
        for (const auto& s : biome.species) names.push_back(s.name);
        writeCategoryPng(args.pngDir + "/species_map.png", speciesMap, "Species map (dominant canopy species)", names,
                         "none (no species can grow)");
        writeMapPng(args.pngDir + "/chm.png", chm, "Canopy height model", "m", Colormap::Viridis);
        std::cout << "wrote pictures: " << args.pngDir << "/ (canopy.png, species_map.png, chm.png)\n";
    }
}

}  // namespace

void registerCanopyCommand(CLI::App& app) {
    auto args = std::make_shared<CanopyArgs>();
    CLI::App* cmd = app.add_subcommand(
        "canopy",
        "Canopy trees from a canopy height model (paper §5): a species map from the abiotics (with optional "
        "target proportions), then iterative tree positioning; written to one HDF5 file");
    cmd->add_option("--terrain", args->terrain, "Terrain (.asc, .h5, .png, .tif, .exr), elevations in metres")->required();
    cmd->add_option("--chm", args->chm,
                    "Canopy height model, metres above ground (.asc, .h5 from 'eco chm generate', images); must "
                    "cover the terrain's cells")
        ->required();
    cmd->add_option("--biome", args->biome, "Biome TOML (default: the embedded Sonoma biome)");
    cmd->add_option("--abiotics", args->abiotics,
                    "Abiotics file from 'eco abiotics' (default: computed from the terrain with default parameters)");
    cmd->add_option("--target", args->targets,
                    "SPECIES=FRACTION: share of the forested area for a canopy species, e.g. 'Redwood=0.4'; "
                    "repeatable, met one after another")
        ->take_all();
    cmd->add_option("--mask", args->mask,
                    "Grey image of the CHM's pixel size: the targets apply inside its white part (a brush)");
    cmd->add_option("--out", args->out, "Output HDF5 file, e.g. canopy.h5 (written atomically)")->required();
    cmd->add_option("--png", args->pngDir, "Also write canopy.png, species_map.png and chm.png into this directory");
    cmd->add_option("--csv", args->csv, "Also write the trees as CSV");
    cmd->add_option("--config", args->config,
                    "TOML with placer parameters ([canopy] table or top-level keys; unknown keys are errors)");
    args->seedOpt = cmd->add_option("--seed", args->seed, "Random seed of the ring seeding")->capture_default_str();
    args->maxIterationsOpt =
        cmd->add_option("--max-iterations", args->maxIterations, "Iteration cap (default 30)")->check(nonNegativeNumber());
    args->minVisibleOpt = cmd->add_option("--min-visible-fraction", args->minVisibleFraction,
                                          "Remove trees whose visible crown is below this fraction of the disc (0.2)");
    args->moveOpt = cmd->add_option("--move-factor", args->moveFactor,
                                    "Fraction of the way to the visible centroid moved per iteration (0.5; 1 = the paper)");
    args->ringOpt = cmd->add_option("--ring-factor", args->ringFactor, "Ring radius = factor * (r_i + r_new) (0.8)");
    args->trunkOpt = cmd->add_option("--min-trunk-distance", args->minTrunkDistanceM,
                                     "Duplicates: trunks closer than this, metres (1)");
    args->epsilonOpt = cmd->add_option("--coverage-epsilon", args->coverageEpsilon,
                                       "Stop when an iteration gains less coverage than this (0.0005)");
    args->thresholdOpt = cmd->add_option("--canopy-threshold", args->canopyThresholdM,
                                         "CHM cells >= this are canopy (forested), metres (3)");
    args->seedHeightOpt = cmd->add_option("--min-seed-height", args->minSeedHeightM,
                                          "Trees stand only where the CHM is >= this, metres (3)");
    cmd->add_option("--cell-size", args->cellSizeM, "Metres per cell (required for plain images; georeferenced rasters carry it)")
        ->check(positiveNumber());
    cmd->add_option("--vertical-scale", args->verticalScale, "Image terrain only: metres per stored unit")
        ->capture_default_str();
    cmd->add_option("--vertical-offset", args->verticalOffsetM, "Image terrain only: metres added after scaling")
        ->capture_default_str();
    cmd->add_option("--chm-gaps", args->chmGaps,
                    "Nodata cells of the CHM: fill (from their neighbours, up to --chm-fill-max from data; the rest 0), "
                    "zero (non-forest) or fail")
        ->capture_default_str();
    cmd->add_option("--chm-fill-max", args->chmFillMaxM, "fill: how far from data a gap is filled, metres")
        ->capture_default_str()
        ->check(CLI::NonNegativeNumber);
    cmd->add_option("--chm-vertical-scale", args->chmVerticalScale, "Image CHM only: metres per stored unit")
        ->capture_default_str();
    cmd->add_option("--chm-vertical-offset", args->chmVerticalOffsetM, "Image CHM only: metres added after scaling")
        ->capture_default_str();
    cmd->callback([args] { runCanopy(*args); });
}

}  // namespace eco::cli
