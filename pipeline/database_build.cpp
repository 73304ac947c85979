#include "database_build.h"

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <set>
#include <sstream>

#include "atomic_file.h"
#include "error.h"
#include "grid.h"
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

std::string writeDatabaseBuildSpec(const DatabaseBuildOptions& o) {
    if (o.out.empty()) throw ValidationError("--out: the database to build is required");
    if (o.terrains < 1 || o.terrains > 100) throw ValidationError("--terrains: must be in 1 .. 100, got " + std::to_string(o.terrains));
    if (o.terrainCells < 32 || o.terrainCells > 4096)
        throw ValidationError("--terrain-cells: must be in 32 .. 4096, got " + std::to_string(o.terrainCells));
    const double side = o.terrainCells * kCellSizeM;
    if (!(o.plotM >= 10 && o.plotM <= side - 2 * kCellSizeM))
        throw ValidationError("--plot: must be in 10 .. " + formatNumber(side - 2 * kCellSizeM, 4) + " m (the terrain is " +
                              formatNumber(side, 4) + " m wide), got " + formatNumber(o.plotM, 6));
    if (o.years < 1 || o.years > 100000) throw ValidationError("--years: must be in 1 .. 100000, got " + std::to_string(o.years));
    if (o.kMax < 1 || o.kMax > 64) throw ValidationError("--kmax: must be in 1 .. 64, got " + std::to_string(o.kMax));
    const Biome biome = o.biome.empty() ? defaultBiome() : loadBiome(o.biome);
    const std::vector<int> masks = allowedCombinations(biome);
    if (masks.empty()) throw ValidationError((o.biome.empty() ? "the default biome" : o.biome) + ": no sub-biome has canopy species");
    ensureDirectory(o.workDir);

    std::vector<std::string> subBiomeNames;
    for (const auto& sb : biome.subBiomes) subBiomeNames.push_back(sb.name);
    const double x0 = (side - o.plotM) / 2;
    std::ostringstream t;
    t << "# Written by eco database build: one member per combination of " << biome.name
      << "'s sub-biomes and terrain.\n# Rerun with eco database build (or eco ensemble on this file) to resume.\n\n"
      << "[ensemble]\nout_dir = " << quoted(o.workDir) << "\ndatabase_path = " << quoted(o.out) << "\nkmax = " << o.kMax
      << "\nseed = " << o.seed << "\nmembers_at_once = " << o.membersAtOnce << "\n\n"
      << "[ensemble.base.run]\nout_dir = \"set per member\"\n";
    if (!o.biome.empty()) t << "biome = " << quoted(o.biome) << "\n";
    t << "[ensemble.base.terrain]\nwidth = " << o.terrainCells << "\nheight = " << o.terrainCells
      << "\ncell_size_m = " << argNumber(kCellSizeM) << "\n[ensemble.base.chm]\n[ensemble.base.abiotics]\nsun_step_minutes = 30\n"
      << "[ensemble.base.canopy]\n[ensemble.base.simulate]\nconfig = " << quoted(o.simConfig) << "\nyears = " << o.years
      << "\ncrop = [" << argNumber(x0) << ", " << argNumber(x0) << ", " << argNumber(x0 + o.plotM) << ", "
      << argNumber(x0 + o.plotM) << "]\n";
    char name[64];
    for (int mask : masks)
        for (int terrain = 1; terrain <= o.terrains; ++terrain) {
            std::snprintf(name, sizeof name, "c%02d-t%d", mask, terrain);
            t << "\n[[member]]\nname = \"" << name << "\"  # " << combinationName(subBiomeNames, mask)
              << "\n\"terrain.seed\" = " << terrain << "\n\"run.seed\" = " << terrain << "\n\"canopy.targets\" = [";
            const auto targets = combinationTargets(biome, mask);
            for (std::size_t k = 0; k < targets.size(); ++k) t << (k ? ", " : "") << quoted(targets[k]);
            t << "]\n";
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
    std::snprintf(line, sizeof line, "%-*s  %7s  %10s  %9s  %10s\n", static_cast<int>(width), "combination", "cluster", "area m^2",
                  "plants", "replicates");
    s << line;
    int missing = 0;
    for (const auto& r : rows) {
        if (r.cluster < 0) {
            ++missing;
            std::snprintf(line, sizeof line, "%-*s  %7s  not simulated: synthesis uses %s\n", static_cast<int>(width), r.name.c_str(), "-",
                          r.standIn.c_str());
        } else {
            std::snprintf(line, sizeof line, "%-*s  %7d  %10.0f  %9.0f  %10s\n", static_cast<int>(width), r.name.c_str(), r.cluster,
                          r.areaM2, r.plants, r.replicates < 0 ? "?" : std::to_string(r.replicates).c_str());
        }
        s << line;
    }
    std::set<int> combos;
    for (const auto& r : rows) combos.insert(r.combination);
    s << combos.size() - static_cast<std::size_t>(missing) << " of " << combos.size() << " combinations simulated\n";
    return s.str();
}

std::string coverageCsv(const std::vector<CoverageRow>& rows) {
    std::ostringstream s;
    s << "combination,name,cluster,area_m2,plants,replicates,stand_in\n";
    for (const auto& r : rows) {
        s << r.combination << ",\"" << r.name << "\",";
        if (r.cluster >= 0) s << r.cluster << "," << formatNumber(r.areaM2, 10) << "," << formatNumber(r.plants, 10) << "," << r.replicates << ",";
        else s << ",,,,\"" << r.standIn << "\"";
        s << "\n";
    }
    return s.str();
}

}  // namespace eco::pipeline
