// The canopy file ("eco-canopy"): written by the canopy placer (`eco canopy`), read by the
// simulator, the abiotics (canopy shade) and the synthesizer. Its one home: the format name,
// the schema version, the writer and the reader (as biome_db.h is the database's).
// docs/canopy.md describes it.
//
// Layout, one HDF5 file:
//   /canopy                 the trees (plants.h layout), attribute layer = "canopy"
//   /species_map            int32 grid, "species id, -1 none" (ids index /canopy/species_names)
//   /chm/height             float grid, m: the input CHM
//   /terrain/elevation      float grid, m: the input terrain
//   /iterations/{iteration, trees, removed, added (int32), coverage, rmse_m}  per iteration
//                           (iteration -1 = the final clean-up) and attributes stop_reason,
//                           initial_seeds, duplicates_removed, fallback_trees
//   /provenance             attributes placement_seconds and iteration_seconds (wall times, in
//                           /iterations order; core/provenance.h): absent with --no-provenance
//   /targets/{species, requested, achieved, reachable, feasible, weight, alpha, iterations}
//                           and /targets/mask (int32 grid, 1 = inside) when a brush was used
//   root attributes: format = "eco-canopy", schema_version = 2 (1: the wall times were
//   /iterations/seconds and the attribute /iterations seconds; still read), code_version, seed, every
//   placer parameter by key, species_weights (global user weights, biome order), biome_name,
//   biome_toml, and the sources terrain_source, chm_source, abiotics_source, biome_source,
//   mask_source.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "biome.h"
#include "grid.h"
#include "h5io.h"
#include "plants.h"

namespace eco {

inline constexpr const char* kCanopyFormat = "eco-canopy";
/// 2: wall times moved to /provenance (1: /iterations/seconds; still read).
inline constexpr std::int64_t kCanopySchemaVersion = 2;

/// One iteration of the canopy placer: one row of /iterations.
struct IterationStats {
    int iteration = 0;
    std::size_t trees = 0;     ///< trees after the iteration
    std::size_t removed = 0;   ///< sun-starved trees removed in it
    std::size_t added = 0;     ///< trees seeded in it
    double coverage = 0;       ///< fraction of the CHM footprint covered by some crown
    double rmseM = 0;          ///< RMS of (rendered crown surface - CHM) over the footprint, metres
    double seconds = 0;        ///< wall time of the iteration (provenance; 0 when not recorded)
};

/// One species target of the species map: one row of /targets.
struct CanopyTargetRow {
    std::string species;
    double requested = 0, achieved = 0, reachable = 0, weight = 0, alpha = 0;
    bool feasible = false;
    int iterations = 0;
};

/// Everything a canopy file holds, as the writer takes it.
struct CanopyFileContents {
    std::vector<Plant> trees;
    Grid<std::int32_t> speciesMap;
    Grid<float> chmM;
    Grid<float> terrainM;
    std::vector<IterationStats> iterations;  ///< the iterations, then the final clean-up (iteration -1)
    std::string stopReason;
    std::int64_t initialSeeds = 0, duplicatesRemoved = 0, fallbackTrees = 0;
    double seconds = 0;
    std::vector<CanopyTargetRow> targets;
    std::optional<Grid<std::int32_t>> targetMask;  ///< 1 inside the brush
    std::uint64_t seed = 0;
    std::vector<std::pair<std::string, double>> realParameters;            ///< root attributes, in order
    std::vector<std::pair<std::string, std::int64_t>> integerParameters;   ///< root attributes, after the reals
    std::vector<double> speciesWeights;
    std::string terrainSource, chmSource, abioticsSource, biomeSource, maskSource;
};

/// Write a canopy file atomically (temporary file, then rename). IoError on failure.
void writeCanopyFile(const std::string& path, const CanopyFileContents& contents, const Biome& biome);

/// What later stages read back from a canopy file.
struct CanopyFileData {
    std::vector<Plant> trees;            ///< species mapped by name onto the given biome
    Grid<std::int32_t> speciesMap;       ///< ids of the FILE's species order (/canopy/species_names)
    Grid<float> chmM;
    Grid<float> terrainM;
    std::vector<IterationStats> iterations;
    std::uint64_t seed = 0;
};

/// The parts of a canopy file a reader needs.
enum class CanopyFileParts {
    TreesAndChm,  ///< /canopy and /chm/height only (the simulator)
    All,
};

/// Read a canopy file. IoError naming the file and the dataset when it is not an eco-canopy
/// file of a known schema version or misses a dataset.
CanopyFileData readCanopyFile(const std::string& path, const Biome& biome, CanopyFileParts parts = CanopyFileParts::All);

/// The root attributes that make an HDF5 file an eco-canopy file of this schema version
/// (the writer sets them; for hand-made fixtures and benchmark scenes).
void setCanopyFormat(h5::File& file);

}  // namespace eco
