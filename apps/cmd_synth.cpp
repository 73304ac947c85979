// eco synth and eco compare: parsing only; the stages are in pipeline/synth_stages (the
// science in synth/undergrowth, synth/forest_floor and synth/scene, docs/synth.md).
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <utility>

#include "cli_common.h"
#include "synth_stages.h"
#include "forest_floor.h"
#include "memory.h"
#include "undergrowth.h"

namespace eco::cli {

namespace {

struct SynthArgs {
    pipeline::SynthOptions options;
    std::string method = "structured";
    double cellSizeM = 0, verticalScale = 1, verticalOffsetM = 0;
    CLI::Option *methodOpt = nullptr, *cellOpt = nullptr, *scaleOpt = nullptr, *offsetOpt = nullptr;
    synth::RefineParams refine;  // the --refine-* values (defaults shown in --help)
    std::vector<std::pair<std::string, CLI::Option*>> refineOpts;  // key, option
    CLI::Option *lloydOpt = nullptr, *minDistanceOpt = nullptr;
    std::vector<CLI::Option*> xuOnly;  // --exemplar and the --xu-* options
};

void runSynth(SynthArgs& a) {
    retainFreedMemory();  // the stages recycle each other's memory (core/memory.h)
    pipeline::SynthOptions& o = a.options;
    if (a.methodOpt->count()) o.method = a.method;
    for (CLI::Option* deussenOnly : {a.lloydOpt, a.minDistanceOpt})
        if (deussenOnly->count() && a.method != "deussen")
            usageError(deussenOnly->get_name(), "read by --method deussen only (method is '" + a.method + "')");
    for (CLI::Option* xuOnly : a.xuOnly)
        if (xuOnly->count() && a.method != "xu2015")
            usageError(xuOnly->get_name(), "read by --method xu2015 only (method is '" + a.method + "')");
    if (a.method == "xu2015" && o.exemplar.empty())
        usageError("--method", "xu2015 needs an exemplar stand: --exemplar FILE (a simulation file or a plant CSV)");
    if (a.cellOpt->count()) o.terrainRead.cellSizeM = a.cellSizeM;
    if (a.scaleOpt->count()) o.terrainRead.verticalScale = a.verticalScale;
    if (a.offsetOpt->count()) o.terrainRead.verticalOffsetM = a.verticalOffsetM;
    setGivenParams(o.refineParams, a.refineOpts, a.refine, synth::refineParamFields());
    CliReporter reporter;
    pipeline::synthStage(o, reporter);
}

}  // namespace

void registerSynthCommand(CLI::App& app) {
    auto args = std::make_shared<SynthArgs>();
    pipeline::SynthOptions* a = &args->options;
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
    // The parameters' flags from their descriptions (synth/synth_params.cpp): help, unit,
    // default and range check (addParamOption).
    cmd->add_option("--refine-window", a->refineWindow,
                    "Refinement: only inside x0,y0,x1,y1 (metres); the rest of the undergrowth stays as sampled")
        ->check(parsedBy("--refine-window", [](const std::string& t) { parseWindow(t, "--refine-window"); }))
        ->needs(refine);
    args->refineOpts = addParamOptions(cmd, pipeline::refineParamFlags(), args->refine, synth::refineParamFields(), "Refinement: ");
    for (auto& keyOption : args->refineOpts) keyOption.second->needs(refine);
    cmd->add_option("--png", a->pngDir,
                    "Also write scene.png, scene_zoom.png, grass.png, litter.png and cluster_map.png into this directory");
    cmd->add_option("--zoom", a->zoom, "Crop of scene_zoom.png: x,y,side or x0,y0,x1,y1 in metres (default: 60 m at the centre)")
        ->check(parsedBy("--zoom", [](const std::string& t) { parseWindow(t, "--zoom", true); }));
    cmd->add_option("--csv", a->csv, "Also write all plants as CSV (layer, species, x, y, z, height, crown radius)");
    cmd->add_option("--pdb", a->pdb, "Also write all plants as a PDB plant list (the paper's authors' viewers)");
    cmd->add_option("--pdb-canopy", a->pdbCanopy,
                    "Also write the canopy trees alone as a PDB plant list (EcoLearn's viewer reads canopy and undergrowth "
                    "as two files)");
    cmd->add_option("--pdb-undergrowth", a->pdbUndergrowth, "Also write the undergrowth alone as a PDB plant list");
    cmd->add_option("--gpkg", a->gpkg, "Also write all plants as a GeoPackage point layer, in the terrain's CRS (QGIS, ArcGIS)");
    cmd->add_option("--geotiff", a->geotiffDir,
                    "Also write the scene's grids (grass, litter, cluster and combination maps, terrain) as GeoTIFFs into "
                    "this directory, in the terrain's geotransform and CRS");
    addParamOption(cmd, "--seed", a->params, synth::synthParamFields(), "seed");
    args->methodOpt = cmd->add_option("--method", args->method,
                    "Undergrowth sampler: 'structured' (conditioned on the canopy context and clustered as the "
                    "database's pair correlation; heights below the crown above, radius by allometry), 'darts' "
                    "(the earlier uniform darts with sizes from the histograms) or 'deussen' (Deussen et al. 1998: "
                    "the density map half-toned by Floyd-Steinberg error diffusion, then Lloyd relaxation with "
                    "minimum distances, canopy fixed; sizes as 'structured') or 'xu2015' (Xu et al. 2015: the pattern "
                    "of an exemplar stand (--exemplar) grown outwards by copying the neighbourhood of the exemplar plant "
                    "whose shells x sectors histogram matches best; sizes copied, canopy and cluster map respected)")
        ->check(oneOf({"structured", "darts", "deussen", "xu2015"}))
        ->capture_default_str();
    cmd->add_option("--density-image", a->densityImage,
                    "--method deussen: a greyscale image (PNG, TIFF) of the terrain's size, value = relative density "
                    "of the whole undergrowth (white densest, black none) multiplying the database's density map; the "
                    "undergrowth keeps the database's total over the terrain");
    const auto& deussenFields = synth::deussenParamFields();
    args->lloydOpt = addParamOption(cmd, "--lloyd-iterations", a->params.deussen, deussenFields, "deussen_lloyd_iterations", "--method deussen: ");
    args->minDistanceOpt =
        addParamOption(cmd, "--min-distance-factor", a->params.deussen, deussenFields, "deussen_min_distance_factor", "--method deussen: ");
    args->xuOnly.push_back(cmd->add_option(
        "--exemplar", a->exemplar,
        "--method xu2015: the exemplar stand, a simulation file of 'eco simulate' (HDF5: the undergrowth of a snapshot "
        "in the simulated area) or a plant CSV with the columns x, y, species (names of the database's biome), height "
        "and crown_radius (x_m, y_m, height_m, crown_radius_m also; other columns ignored; with a 'layer' column only "
        "its 'undergrowth' rows, so eco synth's and eco simulate's CSVs are read as they are)"));
    args->xuOnly.push_back(cmd->add_option("--exemplar-year", a->exemplarYear,
                                           "--method xu2015: snapshot year of a simulation exemplar (default: the last)")
                               ->check(CLI::NonNegativeNumber));
    args->xuOnly.push_back(
        cmd->add_option("--exemplar-window", a->exemplarWindow,
                        "--method xu2015: the exemplar's plot x0,y0,x1,y1 in metres; plants outside are left out (default: "
                        "a simulation's area, a CSV's bounding box)")
            ->check(parsedBy("--exemplar-window", [](const std::string& t) { parseWindow(t, "--exemplar-window"); })));
    const auto& xuFields = synth::xuParamFields();
    for (const auto& [flag, key] : {std::pair<const char*, const char*>{"--xu-radius-factor", "xu_radius_factor"},
                                    {"--xu-sigma", "xu_sigma"}, {"--xu-candidates", "xu_candidates"}, {"--xu-tile", "xu_tile_m"}})
        args->xuOnly.push_back(addParamOption(cmd, flag, a->params.xu, xuFields, key, "--method xu2015: "));
    const auto& synthFields = synth::synthParamFields();
    addParamOption(cmd, "--max-passes", a->params, synthFields, "max_passes");
    addParamOption(cmd, "--seed-inner-radius-factor", a->params, synthFields, "seed_inner_radius_factor");
    addParamOption(cmd, "--trunk-exclusion", a->params, synthFields, "trunk_exclusion_factor");
    addParamOption(cmd, "--litter-full-alpha", a->floorParams, synth::forestFloorParamFields(), "litter_full_alpha", "Forest floor: ");
    cmd->add_flag("--no-undergrowth-shade", a->noUndergrowthShade,
                  "Forest floor: only canopy crowns shade the grass and drop litter");
    args->cellOpt = cmd->add_option("--cell-size", args->cellSizeM, "Metres per cell (required for image terrains)")->check(cellSizeRange());
    args->scaleOpt = cmd->add_option("--vertical-scale", args->verticalScale, "Image terrain only: metres per stored unit")->capture_default_str();
    args->offsetOpt = cmd->add_option("--vertical-offset", args->verticalOffsetM, "Image terrain only: metres added after scaling")
        ->capture_default_str();
    cmd->callback([args] { runSynth(*args); });
}

void registerCompareCommand(CLI::App& app) {
    auto a = std::make_shared<pipeline::CompareOptions>();
    CLI::App* cmd = app.add_subcommand(
        "compare",
        "Re-analyse a synthesized scene against the biome database it came from: per region density, species "
        "proportions, size-histogram and pair-correlation distances (Markdown table on stdout)");
    cmd->add_option("scene", a->scene, "Scene file from 'eco synth'")->required();
    cmd->add_option("database", a->database, "Biome database")->required();
    cmd->add_option("--png", a->pngDir,
                    "Also write compare.png (the pair correlations, scene against database) into this directory")
        ->check(CLI::Validator(
            [](std::string& dir) -> std::string {
                // Until issue 31 --png was the picture's file; say so rather than make a folder "x.png".
                const std::string ext = std::filesystem::path(dir).extension().string();
                if (ext == ".png" || ext == ".PNG")
                    return "is a directory now (eco compare writes DIR/compare.png, as every command's --png DIR); "
                           "got the file name '" + dir + "'";
                return "";
            },
            "DIR"));
    cmd->add_option("--window", a->window, "Compare only inside x0,y0,x1,y1 (metres)")
        ->check(parsedBy("--window", [](const std::string& t) { parseWindow(t, "--window"); }));
    cmd->add_option("--out", a->out, "Also write the Markdown table to this file");
    cmd->add_option("--pcf-sources", a->pcfSources,
                    "Pair correlation: at most this many undergrowth plants per region as sources (a random sample; "
                    "every plant is a neighbour); 0 = all")
        ->capture_default_str()
        ->check(numberIn(0, 1e9));
    cmd->callback([a] {
        CliReporter reporter;
        pipeline::compareStage(*a, reporter);
    });
}

}  // namespace eco::cli
