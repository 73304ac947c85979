// eco synth and eco compare: a complete ecosystem on a terrain from a biome database
// (synth/undergrowth, synth/forest_floor, synth/scene; docs/synth.md), and the comparison
// of a scene with its database.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "forest_floor.h"
#include "reporter.h"
#include "scene.h"
#include "stage_common.h"
#include "undergrowth.h"

namespace eco::pipeline {

struct SynthOptions {
    std::string terrain, canopy, database;
    std::string out;       ///< scene HDF5 (atomic)
    std::string abiotics;  ///< abiotics of the terrain; "" = computed with default parameters
    std::string pngDir, csv, pdb;  ///< optional outputs ("" = none); pdb: both layers in one list
    std::string pdbCanopy, pdbUndergrowth;  ///< optional: one layer's PDB plant list each (EcoLearn's viewer reads two)
    std::string gpkg;              ///< optional: all plants as a GeoPackage in the terrain's CRS
    std::string geotiffDir;        ///< optional: the scene's grids (forest floor, cluster maps, terrain) as GeoTIFFs
    std::string zoom;          ///< crop of scene_zoom.png, "x,y,side" or "x0,y0,x1,y1"; "" = 60 m at the centre
    std::string refineWindow;  ///< refinement only inside "x0,y0,x1,y1"; "" = everywhere
    std::optional<std::string> method;  ///< undergrowth sampler by name; unset = structured
    std::string densityImage;  ///< --method deussen: relative density image of the terrain's size; "" = the database's map
    std::string exemplar;      ///< --method xu2015: exemplar stand, a simulation file or a plant CSV (readExemplar)
    int exemplarYear = -1;     ///< --method xu2015, simulation exemplar: snapshot year; -1 = the last
    std::string exemplarWindow;  ///< --method xu2015: the exemplar's plot "x0,y0,x1,y1"; "" = recorded area or bounding box
    TerrainReadFlags terrainRead;
    bool refine = false;
    synth::SynthParams params;  ///< params.method is set from `method`
    /// Refinement parameters set over the defaults, by key of synth::refineParamFields(); on
    /// the command line as the flags of refineParamFlags(). Its seed is params.seed.
    ParamOverrides<synth::RefineParams> refineParams;
    synth::ForestFloorParams floorParams;
    bool noUndergrowthShade = false;  ///< only canopy crowns shade the forest floor
};
/// The exemplar stand of `eco synth --method xu2015` (docs/synth.md 2d): a simulation file
/// from `eco simulate` (HDF5, recognised by its signature; the undergrowth of snapshot `year`,
/// -1 = the last, in the simulated area it records) or a plant CSV (readPlantsCsv: columns x,
/// y, species, height, crown_radius; with a layer column only its "undergrowth" rows, as in
/// eco synth's CSV). Species are mapped by name onto `biome`. `windowText` "x0,y0,x1,y1" gives
/// the plot and crops the plants to it; without it a simulation's recorded area, else the
/// plants' bounding box. IoError /
/// ValidationError naming the file for a missing or unreadable file, a missing column or
/// snapshot, an unknown species, no plants, or a plant outside the window.
synth::XuExemplar readExemplar(const std::string& path, int year, const std::string& windowText, const Biome& biome);

struct SynthResult {
    std::size_t canopyTrees = 0, undergrowthPlants = 0;
    std::vector<std::string> written;
};
SynthResult synthStage(const SynthOptions& options, Reporter& reporter);
/// The refinement parameters eco synth takes as flags (--refine-*): flag and key.
const std::vector<ParamFlagName>& refineParamFlags();
std::vector<std::string> commandLine(const SynthOptions& options);

struct CompareOptions {
    std::string scene, database;
    std::string pngDir;  ///< "" = no picture; else pngDir/compare.png
    std::string window;  ///< "x0,y0,x1,y1"; "" = the whole scene
    std::string out;     ///< "" = table on the reporter only; else also this Markdown file
    std::size_t pcfSources = 20000;  ///< sources per region for the pair correlation; 0 = all
};
struct CompareResult {
    synth::SceneComparison comparison;
    std::string table;
};
CompareResult compareStage(const CompareOptions& options, Reporter& reporter);
std::vector<std::string> commandLine(const CompareOptions& options);

}  // namespace eco::pipeline
