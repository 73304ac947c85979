// Pieces shared by the stages: how a stage reads its terrain, the abiotic maps of a terrain,
// windows given as text, and the command-line form of a stage's options.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "abiotics.h"
#include "atomic_file.h"
#include "biome.h"
#include "grid.h"
#include "param_desc.h"
#include "point_pattern.h"
#include "reporter.h"
#include "terrain_io.h"

namespace eco::pipeline {

/// How a stage reads an input terrain (or an image CHM): the options a user may give, each
/// unset unless given, so that the stage's command line shows exactly what was given.
struct TerrainReadFlags {
    std::optional<double> cellSizeM;        ///< --cell-size: metres per cell (required for images)
    std::optional<double> verticalScale;    ///< --vertical-scale: image metres per stored unit
    std::optional<double> verticalOffsetM;  ///< --vertical-offset: image metres added after scaling
    /// The reader's options (cell size 0 = from the file, scale 1, offset 0 when unset).
    TerrainReadOptions options() const;
    /// Append the given flags: --cell-size, --vertical-scale, --vertical-offset.
    void appendArgs(std::vector<std::string>& args) const;
};

/// A number as the command line of a stage shows it (%.10g).
std::string argNumber(double v);
/// The overrides that `flags` names (part of a command's flag table, core/param_desc.h) as
/// command-line arguments, in the table's order: seeds in full, numbers as argNumber. Keys the
/// part does not name are left to the caller (checkParamFlags checks the whole table has them).
template <typename S>
void appendParamArgs(std::vector<std::string>& args, const ParamOverrides<S>& overrides,
                     const std::vector<ParamFlagName>& flags) {
    for (const auto& f : flags)
        if (const auto* v = overrides.find(f.key))
            args.insert(args.end(), {f.flag, v->isSeed ? std::to_string(v->seed) : argNumber(v->number)});
}
/// std::logic_error when an override has no flag in the command's table (a programming error).
template <typename S>
void checkParamFlags(const ParamOverrides<S>& overrides, const std::vector<ParamFlagName>& flags) {
    for (const auto& v : overrides.values()) paramFlagFor(flags, v.key);
}
/// The value a stage gets when `v` is given on its command line as argNumber(v): a stage run
/// from a plan gets the same bits as the same stage run from the printed command line.
double asOnCommandLine(double v);
/// "eco a b 'c d'": a command line a user can copy.
std::string quotedCommand(const std::vector<std::string>& args);

/// Create the folder an output file goes into, before any heavy work, and clean up after
/// killed writers of that file (core/atomic_file.h cleanUpAfterDeadWriters: an interrupted
/// set commit is completed, dead temporaries removed).
void prepareOutput(const std::string& path);
/// The same for a directory of outputs (pictures, GeoTIFFs): created, dead writers' files removed.
void prepareOutputDirectory(const std::string& dir);

/// ValidationError when an output file (`outputs`: {flag, path}, "" = not written) is the
/// same file as one of the `inputs` ("" skipped): `eco analyse sim.h5 --out sim.h5`
/// replaced the simulation by the database (issue 26). Checked before any work.
void requireOutputsNotInputs(const std::vector<std::pair<std::string, std::string>>& outputs,
                             const std::vector<std::string>& inputs);

/// ValidationError when two output files of one stage (`outputs`: {flag, path}, "" = not
/// written) are the same file: the second would silently replace the first.
void requireDistinctOutputs(const std::vector<std::pair<std::string, std::string>>& outputs);

/// --geotiff DIR of a stage: every grid of the stage's HDF5 output as a GeoTIFF in `dir`
/// (named <output stem>_<dataset>.tif, with the grid's geotransform and CRS; see
/// core/geo_raster.h exportGridsAsGeoTiff), one line to the user, the files added to `written`.
/// `outputs` is the stage's open output set, which holds the HDF5 output until it commits.
void writeGeoTiffs(const std::string& h5Path, const AtomicOutputSet& outputs, const std::string& dir, Reporter& reporter,
                   std::vector<std::string>& written);

/// Biome latitude and terrain latitude differ by more than this (degrees): a warning.
inline constexpr double kLatitudeWarningDeg = 2.0;

/// A warning when a georeferenced terrain (one with a CRS) lies at a latitude more than
/// kLatitudeWarningDeg from the biome's `latitude_deg`, which alone sets the sun's path:
/// the sun maps are then those of another latitude. Nothing for a terrain without a CRS.
void warnLatitudeMismatch(const Grid<float>& terrain, const std::string& terrainPath, const Biome& biome,
                          const std::string& biomePath, Reporter& reporter);

/// The abiotic maps of a terrain: read from `abioticsPath` and checked against the
/// terrain's geometry, or, when the path is empty, computed with default parameters (as
/// 'eco abiotics' would) with progress; `note` tells the user how to avoid that.
Abiotics abioticsForTerrain(const std::string& abioticsPath, const Grid<float>& terrain,
                            const std::string& terrainPath, const Biome& biome, const std::string& note,
                            Reporter& reporter);

/// A window "x0,y0,x1,y1" in metres (or "x,y,side", a square around (x, y), when
/// allowSquare). ValidationError naming the option, the text and the part that is wrong.
RectWindow parseWindow(const std::string& text, const std::string& option, bool allowSquare = false);

}  // namespace eco::pipeline
