#include "database_build.h"

#include <algorithm>
#include <array>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <set>
#include <sstream>

#include "atomic_file.h"
#include "error.h"
#include "factors.h"
#include "generate.h"
#include "grid.h"
#include "terrain_io.h"
#include "stage_common.h"
#include "text_format.h"

namespace eco::pipeline {

namespace fs = std::filesystem;

namespace {

constexpr double kCellSizeM = 0.914;  // the paper's cells, as eco run's default terrain

/// Sub-biomes (0-based) that have canopy species: only they can seed a cell.
std::vector<int> canopySubBiomes(const Biome& biome) {
    std::vector<int> out;
    for (std::size_t b = 0; b < biome.subBiomes.size(); ++b)
        if (!biome.subBiomes[b].canopySpecies.empty()) out.push_back(static_cast<int>(b));
    return out;
}

/// Every non-empty set of the canopy sub-biomes, as masks (bit b for sub-biome b + 1), ascending.
std::vector<int> allowedCombinations(const Biome& biome) {
    const std::vector<int> sub = canopySubBiomes(biome);
    std::vector<int> masks;
    for (unsigned pick = 1; pick < (1u << sub.size()); ++pick) {
        int mask = 0;
        for (std::size_t k = 0; k < sub.size(); ++k)
            if (pick & (1u << k)) mask |= 1 << sub[k];
        masks.push_back(mask);
    }
    std::sort(masks.begin(), masks.end());
    return masks;
}

std::string quoted(const std::string& s) {
    std::string q = "\"";
    for (char c : s) {
        if (c == '"' || c == '\\') q += '\\';
        q += c;
    }
    return q + "\"";
}

}  // namespace

std::vector<std::string> combinationTargets(const Biome& biome, int mask) {
    const std::vector<int> sub = canopySubBiomes(biome);
    int inMix = 0;
    for (int b : sub) inMix += (mask >> b) & 1;
    std::vector<std::string> targets;
    std::vector<std::string> named;
    for (int b : sub) {
        const auto& species = biome.subBiomes[static_cast<std::size_t>(b)].canopySpecies;
        const bool in = (mask >> b) & 1;
        for (const std::string& s : species) {
            // A species of two sub-biomes is named once, with the share of the first in the mix.
            if (std::find(named.begin(), named.end(), s) != named.end()) continue;
            const bool alsoIn = std::any_of(sub.begin(), sub.end(), [&](int o) {
                const auto& os = biome.subBiomes[static_cast<std::size_t>(o)].canopySpecies;
                return ((mask >> o) & 1) && std::find(os.begin(), os.end(), s) != os.end();
            });
            if (!in && alsoIn) continue;  // its share comes with the sub-biome in the mix
            named.push_back(s);
            const double share = in ? 0.9 / inMix / static_cast<double>(species.size()) : 0.0;
            targets.push_back(s + "=" + formatNumber(share, 6));
        }
    }
    return targets;
}

std::pair<double, double> generatedTerrainShape(const DatabaseBuildOptions& o, int t, int n) {
    if (n <= 1) {
        const TerrainGenParams defaults;
        return {defaults.valleyDepthM, defaults.baseElevationM};
    }
    const double f = static_cast<double>(t - 1) / static_cast<double>(n - 1);
    return {o.valleyDepthMinM + f * (o.valleyDepthMaxM - o.valleyDepthMinM),
            o.baseElevationMinM + f * (o.baseElevationMaxM - o.baseElevationMinM)};
}

std::string writeDatabaseBuildSpec(const DatabaseBuildOptions& o) {
    if (o.out.empty()) throw ValidationError("--out: the database to build is required");
    if (o.terrains < 0 || o.terrains > 100) throw ValidationError("--terrains: must be in 0 .. 100, got " + std::to_string(o.terrains));
    if (o.terrains == 0 && o.terrainFiles.empty())
        throw ValidationError("--terrains 0 and no --terrain: the database needs at least one terrain");
    if (o.terrainCells < 32 || o.terrainCells > 4096)
        throw ValidationError("--terrain-cells: must be in 32 .. 4096, got " + std::to_string(o.terrainCells));
    const double side = o.terrainCells * kCellSizeM;
    if (o.terrains > 0 && !(o.plotM >= 10 && o.plotM <= side - 2 * kCellSizeM))
        throw ValidationError("--plot: must be in 10 .. " + formatNumber(side - 2 * kCellSizeM, 4) + " m (the terrain is " +
                              formatNumber(side, 4) + " m wide), got " + formatNumber(o.plotM, 6));
    if (!(o.plotM >= 10)) throw ValidationError("--plot: must be at least 10 m, got " + formatNumber(o.plotM, 6));
    if (o.years < 1 || o.years > 100000) throw ValidationError("--years: must be in 1 .. 100000, got " + std::to_string(o.years));
    if (o.kMax < 1 || o.kMax > 64) throw ValidationError("--kmax: must be in 1 .. 64, got " + std::to_string(o.kMax));
    if (!(o.valleyDepthMinM > 0 && o.valleyDepthMaxM >= o.valleyDepthMinM))
        throw ValidationError("--valley-depth " + formatNumber(o.valleyDepthMinM, 6) + "," + formatNumber(o.valleyDepthMaxM, 6) +
                              ": must be positive and ascending");
    if (!(o.baseElevationMaxM >= o.baseElevationMinM))
        throw ValidationError("--base-elevation " + formatNumber(o.baseElevationMinM, 6) + "," +
                              formatNumber(o.baseElevationMaxM, 6) + ": must be ascending");
    const Biome biome = o.biome.empty() ? defaultBiome() : loadBiome(o.biome);
    const std::vector<int> masks = allowedCombinations(biome);
    if (masks.empty()) throw ValidationError((o.biome.empty() ? "the default biome" : o.biome) + ": no sub-biome has canopy species");
    // The user's terrains: each read now (a bad file is refused before anything is written),
    // the plot centred in it.
    struct GivenTerrain {
        std::string path;
        std::array<double, 4> crop;
    };
    std::vector<GivenTerrain> given;
    for (const std::string& file : o.terrainFiles) {
        const Grid<float> t = readTerrain(file);
        const double w = t.width() * t.cellSizeM(), h = t.height() * t.cellSizeM();
        if (!(o.plotM <= std::min(w, h) - 2 * t.cellSizeM()))
            throw ValidationError(file + ": --terrain: " + formatNumber(w, 6) + " m x " + formatNumber(h, 6) +
                                  " m is too small for a plot of " + formatNumber(o.plotM, 6) + " m (--plot) with a cell to spare on each side");
        const double cx = t.originX() + w / 2, cy = t.originY() + h / 2;
        given.push_back({fs::absolute(file).string(), {cx - o.plotM / 2, cy - o.plotM / 2, cx + o.plotM / 2, cy + o.plotM / 2}});
    }
    ensureDirectory(o.workDir);

    std::vector<std::string> subBiomeNames;
    for (const auto& sb : biome.subBiomes) subBiomeNames.push_back(sb.name);
    const double x0 = (side - o.plotM) / 2;
    // The paths came from the command line (relative to the working directory); the file lies
    // in the work folder and its paths are read relative to it: write them absolute.
    const auto absolute = [](const std::string& path) {
        return path.empty() ? path : fs::absolute(path).lexically_normal().string();
    };
    std::ostringstream t;
    t << "# Written by eco database build: one member per combination of " << biome.name
      << "'s sub-biomes and terrain.\n# Rerun with eco database build (or eco ensemble on this file) to resume.\n\n"
      << "[ensemble]\nout_dir = " << quoted(absolute(o.workDir)) << "\ndatabase_path = " << quoted(absolute(o.out)) << "\nkmax = " << o.kMax
      << "\nseed = " << o.seed << "\nmembers_at_once = " << o.membersAtOnce << "\n\n"
      << "[ensemble.base.run]\nout_dir = \"set per member\"\n";
    if (!o.biome.empty()) t << "biome = " << quoted(absolute(o.biome)) << "\n";
    // The terrain is set per member: generated (its size, seed, valley depth and base elevation) or
    // a given file.
    t << "[ensemble.base.terrain]\n[ensemble.base.chm]\n[ensemble.base.abiotics]\nsun_step_minutes = 30\n"
      << "[ensemble.base.canopy]\n[ensemble.base.simulate]\nconfig = " << quoted(absolute(o.simConfig)) << "\nyears = " << o.years
      << "\ncrop = [" << argNumber(x0) << ", " << argNumber(x0) << ", " << argNumber(x0 + o.plotM) << ", "
      << argNumber(x0 + o.plotM) << "]\n";
    char name[64];
    const auto targetsLine = [&](int mask) {
        const auto targets = combinationTargets(biome, mask);
        std::string line = "\"canopy.targets\" = [";
        for (std::size_t k = 0; k < targets.size(); ++k) line += (k ? ", " : "") + quoted(targets[k]);
        return line + "]\n";
    };
    for (int mask : masks) {
        for (int terrain = 1; terrain <= o.terrains; ++terrain) {
            const auto [valley, base] = generatedTerrainShape(o, terrain, o.terrains);
            std::snprintf(name, sizeof name, "c%02d-t%d", mask, terrain);
            t << "\n[[member]]\nname = \"" << name << "\"  # " << combinationName(subBiomeNames, mask)
              << "\n\"terrain.seed\" = " << terrain << "\n\"terrain.width\" = " << o.terrainCells
              << "\n\"terrain.height\" = " << o.terrainCells << "\n\"terrain.cell_size_m\" = " << argNumber(kCellSizeM)
              << "\n\"terrain.valley_depth_m\" = " << argNumber(valley) << "\n\"terrain.base_elevation_m\" = " << argNumber(base)
              << "\n\"run.seed\" = " << terrain << "\n" << targetsLine(mask);
        }
        for (std::size_t f = 0; f < given.size(); ++f) {
            std::snprintf(name, sizeof name, "c%02d-f%zu", mask, f + 1);
            const auto& c = given[f].crop;
            t << "\n[[member]]\nname = \"" << name << "\"  # " << combinationName(subBiomeNames, mask) << " on "
              << fs::path(given[f].path).filename().string() << "\n\"terrain.path\" = " << quoted(given[f].path)
              << "\n\"run.seed\" = " << f + 1 << "\n\"simulate.crop\" = [" << argNumber(c[0]) << ", " << argNumber(c[1]) << ", "
              << argNumber(c[2]) << ", " << argNumber(c[3]) << "]\n" << targetsLine(mask);
        }
    }
    const std::string path = (fs::path(o.workDir) / "ensemble.toml").string();
    writeTextFile(path, t.str());
    return path;
}

std::vector<CoverageRow> coverage(const BiomeDatabase& db, const Biome& biome) {
    std::vector<CoverageRow> rows;
    for (int mask : allowedCombinations(biome)) {
        const int ci = db.combinationIndex(mask);
        if (ci < 0) {
            CoverageRow r;
            r.combination = mask;
            r.name = db.combinationName(mask);
            const int stand = db.standInCombination(mask);
            r.standIn = stand < 0 ? "none" : db.combinationName(stand);
            rows.push_back(r);
            continue;
        }
        const DbCombination& c = db.combinations[static_cast<std::size_t>(ci)];
        for (int k = 0; k < c.k; ++k) {
            const DbRegion& region = db.regions[static_cast<std::size_t>(c.firstRegion + k)];
            CoverageRow r;
            r.combination = mask;
            r.name = db.combinationName(mask);
            r.cluster = k;
            r.areaM2 = region.areaM2;
            r.plants = region.undergrowthCount;
            r.replicates = region.replicates();
            r.centroid = region.centroidRaw;
            rows.push_back(r);
        }
    }
    return rows;
}

std::string coverageText(const std::vector<CoverageRow>& rows) {
    std::size_t width = 11;
    for (const auto& r : rows) width = std::max(width, r.name.size());
    std::ostringstream s;
    char line[512];
    std::snprintf(line, sizeof line, "%-*s  %7s  %10s  %9s  %10s", static_cast<int>(width), "combination", "cluster", "area m^2",
                  "plants", "replicates");
    s << line;
    for (const FactorInfo& f : kFactors) {
        std::snprintf(line, sizeof line, "  %12s", f.key);
        s << line;
    }
    s << "\n";
    int missing = 0;
    Features lo, hi;
    lo.fill(std::numeric_limits<double>::infinity());
    hi.fill(-std::numeric_limits<double>::infinity());
    for (const auto& r : rows) {
        if (r.cluster < 0) {
            ++missing;
            std::snprintf(line, sizeof line, "%-*s  %7s  not simulated: synthesis uses %s\n", static_cast<int>(width), r.name.c_str(), "-",
                          r.standIn.c_str());
            s << line;
            continue;
        }
        std::snprintf(line, sizeof line, "%-*s  %7d  %10.0f  %9.0f  %10s", static_cast<int>(width), r.name.c_str(), r.cluster,
                      r.areaM2, r.plants, r.replicates < 0 ? "?" : std::to_string(r.replicates).c_str());
        s << line;
        for (std::size_t f = 0; f < kFactorCount; ++f) {
            std::snprintf(line, sizeof line, "  %12.2f", r.centroid[f]);
            s << line;
            lo[f] = std::min(lo[f], r.centroid[f]);
            hi[f] = std::max(hi[f], r.centroid[f]);
        }
        s << "\n";
    }
    std::set<int> combos;
    for (const auto& r : rows) combos.insert(r.combination);
    s << combos.size() - static_cast<std::size_t>(missing) << " of " << combos.size() << " combinations simulated\n";
    if (rows.size() > static_cast<std::size_t>(missing)) {
        s << "abiotic conditions the clusters cover (their mean per factor, lowest .. highest):";
        for (std::size_t f = 0; f < kFactorCount; ++f)
            s << (f ? "," : "") << " " << kFactors[f].key << " " << formatNumber(lo[f], 4) << " .. " << formatNumber(hi[f], 4) << " "
              << kFactors[f].unit;
        s << "\n";
    }
    return s.str();
}

std::string coverageCsv(const std::vector<CoverageRow>& rows) {
    std::ostringstream s;
    s << "combination,name,cluster,area_m2,plants,replicates,stand_in";
    for (const FactorInfo& f : kFactors) s << "," << f.key;
    s << "\n";
    for (const auto& r : rows) {
        s << r.combination << ",\"" << r.name << "\",";
        if (r.cluster >= 0) {
            s << r.cluster << "," << formatNumber(r.areaM2, 10) << "," << formatNumber(r.plants, 10) << "," << r.replicates << ",";
            for (double v : r.centroid) s << "," << formatNumber(v, 10);
        } else {
            s << ",,,,\"" << r.standIn << "\"";
            for (std::size_t f = 0; f < kFactorCount; ++f) s << ",";
        }
        s << "\n";
    }
    return s.str();
}

}  // namespace eco::pipeline
