#include "canopy_file.h"

#include "atomic_file.h"
#include "eco_version.h"
#include "geo_raster.h"
#include "error.h"
#include "provenance.h"

namespace eco {

void setCanopyFormat(h5::File& f) {
    f.setAttr("/", "format", std::string(kCanopyFormat));
    f.setAttr("/", "schema_version", kCanopySchemaVersion);
}

namespace {

void writeIterations(h5::File& f, const CanopyFileContents& c) {
    const std::vector<IterationStats>& its = c.iterations;
    const hsize_t n = its.size();
    std::vector<std::int32_t> iteration(n), trees(n), removed(n), added(n);
    std::vector<double> coverage(n), rmse(n);
    for (std::size_t i = 0; i < its.size(); ++i) {
        iteration[i] = its[i].iteration;
        trees[i] = static_cast<std::int32_t>(its[i].trees);
        removed[i] = static_cast<std::int32_t>(its[i].removed);
        added[i] = static_cast<std::int32_t>(its[i].added);
        coverage[i] = its[i].coverage;
        rmse[i] = its[i].rmseM;
    }
    f.ensureGroup("/iterations");
    f.writeI32("/iterations/iteration", iteration, {n}, "1");
    f.writeI32("/iterations/trees", trees, {n}, "1");
    f.writeI32("/iterations/removed", removed, {n}, "1");
    f.writeI32("/iterations/added", added, {n}, "1");
    f.writeF64("/iterations/coverage", coverage, {n}, "1");
    f.writeF64("/iterations/rmse_m", rmse, {n}, "m");
    f.setAttr("/iterations", "stop_reason", c.stopReason);
    f.setAttr("/iterations", "initial_seeds", c.initialSeeds);
    f.setAttr("/iterations", "duplicates_removed", c.duplicatesRemoved);
    f.setAttr("/iterations", "fallback_trees", c.fallbackTrees);
    f.setAttr("/iterations", "note", std::string("iteration 0 = initial seeding, -1 = final clean-up; coverage "
                                                 "= fraction of CHM cells >= canopy_threshold_m under a crown"));
}

void writeTargets(h5::File& f, const CanopyFileContents& c) {
    f.ensureGroup("/targets");
    const hsize_t m = c.targets.size();
    std::vector<std::string> species;
    std::vector<double> requested, achieved, reachable, weight, alpha;
    std::vector<std::int32_t> feasible, iterations;
    for (const auto& t : c.targets) {
        species.push_back(t.species);
        requested.push_back(t.requested);
        achieved.push_back(t.achieved);
        reachable.push_back(t.reachable);
        weight.push_back(t.weight);
        alpha.push_back(t.alpha);
        feasible.push_back(t.feasible ? 1 : 0);
        iterations.push_back(t.iterations);
    }
    if (m > 0) {
        f.writeStrings("/targets/species", species);
        f.writeF64("/targets/requested", requested, {m}, "1");
        f.writeF64("/targets/achieved", achieved, {m}, "1");
        f.writeF64("/targets/reachable", reachable, {m}, "1");
        f.writeF64("/targets/weight", weight, {m}, "1");
        f.writeF64("/targets/alpha", alpha, {m}, "1");
        f.writeI32("/targets/feasible", feasible, {m}, "1");
        f.writeI32("/targets/iterations", iterations, {m}, "1");
    }
    f.setAttr("/targets", "count", static_cast<std::int64_t>(m));
    f.setAttr("/targets", "note", std::string("fractions of the forested area (CHM >= canopy_threshold_m), inside "
                                              "/targets/mask when present"));
    if (c.targetMask) {
        f.writeGridI32("/targets/mask", *c.targetMask, "1");
        f.setAttr("/targets/mask", "long_name", std::string("1 inside the brush, 0 outside"));
    }
}

}  // namespace

void writeCanopyFile(const std::string& path, const CanopyFileContents& c, const Biome& biome) {
    AtomicOutput out(path);
    {
        h5::File f = h5::File::create(out.tempPath());
        writePlants(f, "/canopy", c.trees, biome);
        f.setAttr("/canopy", "layer", std::string("canopy"));
        f.writeGridI32("/species_map", c.speciesMap, "1");
        f.setAttr("/species_map", "long_name", std::string("species id (index into /canopy/species_names), -1 none"));
        f.setAttr("/species_map", "names", std::string("/canopy/species_names"));
        f.ensureGroup("/chm");
        f.writeGrid("/chm/height", c.chmM, "m");
        f.ensureGroup("/terrain");
        f.writeGrid("/terrain/elevation", c.terrainM, "m");
        writeIterations(f, c);
        writeTargets(f, c);

        setCanopyFormat(f);
        f.setAttr("/", "code_version", std::string(ECO_VERSION_STRING));
        f.setAttr("/", "seed", static_cast<std::int64_t>(c.seed));
        for (const auto& [key, value] : c.realParameters) f.setAttr("/", key, value);
        for (const auto& [key, value] : c.integerParameters) f.setAttr("/", key, value);
        f.setAttr("/", "species_weights", c.speciesWeights);
        f.setAttr("/", "biome_name", biome.name);
        f.setAttr("/", "biome_toml", biomeToToml(biome));
        f.setAttr("/", "terrain_source", c.terrainSource);
        f.setAttr("/", "chm_source", c.chmSource);
        f.setAttr("/", "abiotics_source", c.abioticsSource);
        f.setAttr("/", "biome_source", c.biomeSource);
        f.setAttr("/", "mask_source", c.maskSource);
        f.setAttr("/", "units", std::string("metres; x east, y north, world coordinates of the input grids"));
        // Wall times are measured, not computed (docs/hdf5.md): /provenance, in /iterations order.
        std::vector<double> iterationSeconds;
        for (const IterationStats& s : c.iterations) iterationSeconds.push_back(s.seconds);
        writeProvenance(f, {{"placement_seconds", c.seconds}, {"iteration_seconds", iterationSeconds}});
    }
    out.commit();
}

CanopyFileData readCanopyFile(const std::string& path, const Biome& biome, CanopyFileParts parts) {
    const h5::File f = h5::File::openRead(path);
    if (!f.hasAttr("/", "format") || f.attrString("/", "format") != kCanopyFormat)
        throw IoError(path + ": not an eco-canopy file (root attribute format != '" + std::string(kCanopyFormat) +
                      "'; is this a canopy file written by 'eco canopy'?)");
    const std::int64_t version = f.attrInt("/", "schema_version");
    if (version != kCanopySchemaVersion && version != 1)
        throw IoError(path + ": eco-canopy schema version " + std::to_string(version) + " is not supported (expected 1 or " +
                      std::to_string(kCanopySchemaVersion) + ")");
    CanopyFileData d;
    if (!f.exists("/canopy")) throw IoError(path + ": no /canopy plant group");
    d.trees = readPlants(f, "/canopy", biome);
    if (!f.exists("/chm/height"))
        throw IoError(path + ": no /chm/height dataset (the canopy height model is needed for the canopy limit)");
    d.chmM = f.readGrid("/chm/height");
    requireGridIn(d.chmM, 0, 500, path, "/chm/height");
    if (parts == CanopyFileParts::TreesAndChm) return d;
    d.speciesMap = f.readGridI32("/species_map");
    d.terrainM = f.readGrid("/terrain/elevation");
    d.seed = static_cast<std::uint64_t>(f.attrInt("/", "seed"));
    const auto iteration = f.readI32("/iterations/iteration");
    const auto trees = f.readI32("/iterations/trees");
    const auto removed = f.readI32("/iterations/removed");
    const auto added = f.readI32("/iterations/added");
    const auto coverage = f.readF64("/iterations/coverage");
    const auto rmse = f.readF64("/iterations/rmse_m");
    // Wall times: /provenance (version 2; absent with --no-provenance), /iterations/seconds in version 1.
    const std::vector<double> seconds = [&] {
        if (f.hasAttr(kProvenanceGroup, "iteration_seconds")) {
            auto s = f.attrDoubles(kProvenanceGroup, "iteration_seconds");
            if (s.size() != iteration.size())
                throw IoError(path + ": /provenance iteration_seconds has " + std::to_string(s.size()) +
                              " values for " + std::to_string(iteration.size()) + " iterations");
            return s;
        }
        if (version == 1) return f.readF64("/iterations/seconds");
        return std::vector<double>(iteration.size(), 0.0);
    }();
    for (const auto* v : {&trees, &removed, &added})
        if (v->size() != iteration.size()) throw IoError(path + ": /iterations arrays differ in length");
    for (const auto* v : {&coverage, &rmse, &seconds})
        if (v->size() != iteration.size()) throw IoError(path + ": /iterations arrays differ in length");
    for (std::size_t i = 0; i < iteration.size(); ++i) {
        IterationStats s;
        s.iteration = iteration[i];
        s.trees = static_cast<std::size_t>(trees[i]);
        s.removed = static_cast<std::size_t>(removed[i]);
        s.added = static_cast<std::size_t>(added[i]);
        s.coverage = coverage[i];
        s.rmseM = rmse[i];
        s.seconds = seconds[i];
        d.iterations.push_back(s);
    }
    return d;
}

}  // namespace eco
