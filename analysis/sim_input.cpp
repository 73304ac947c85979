#include "sim_input.h"

#include <algorithm>
#include <cstdlib>
#include <filesystem>

#include "abiotics.h"
#include "error.h"
#include "h5io.h"
#include "plants.h"

namespace eco {

namespace {

constexpr const char* kSimFormat = "eco-simulation";
constexpr std::int64_t kSimSchemaVersion = 1;

std::string firstAttr(const h5::File& f, std::initializer_list<const char*> names) {
    for (const char* n : names)
        if (f.hasAttr("/", n)) return f.attrString("/", n);
    return {};
}

/// Year of a snapshot group name "year_NNNN", or -1.
int yearOfGroup(const std::string& name) {
    if (name.rfind("year_", 0) != 0 || name.size() == 5) return -1;
    for (std::size_t i = 5; i < name.size(); ++i)
        if (name[i] < '0' || name[i] > '9') return -1;
    return std::atoi(name.c_str() + 5);
}

std::string resolveBeside(const std::string& target, const std::string& besideFile) {
    std::error_code ec;
    if (target.empty() || std::filesystem::exists(target, ec)) return target;
    const std::filesystem::path p(target);
    if (p.is_absolute()) return target;
    const std::filesystem::path alt = std::filesystem::path(besideFile).parent_path() / p;
    return std::filesystem::exists(alt, ec) ? alt.string() : target;
}

}  // namespace

LoadedSimulation readSimulation(const std::string& path, const SimulationReadOptions& options) {
    const h5::File f = h5::File::openRead(path);
    if (!f.hasAttr("/", "format"))
        throw IoError(path + ": not a simulation file (root attribute 'format' is missing; expected '" +
                      std::string(kSimFormat) + "')");
    const std::string format = f.attrString("/", "format");
    if (format != kSimFormat)
        throw IoError(path + ": not a simulation file (format '" + format + "', expected '" + kSimFormat + "')");
    if (f.hasAttr("/", "schema_version")) {
        const std::int64_t v = f.attrInt("/", "schema_version");
        if (v != kSimSchemaVersion)
            throw IoError(path + ": simulation schema_version " + std::to_string(v) + " found, version " +
                          std::to_string(kSimSchemaVersion) + " expected");
    }
    if (!f.hasAttr("/", "biome_toml")) throw IoError(path + ": root attribute 'biome_toml' (the biome) is missing");
    LoadedSimulation out;
    auto biome = std::make_shared<Biome>(parseBiome(f.attrString("/", "biome_toml"), path + ": attribute biome_toml"));
    out.biome = biome;
    AnalysisInput& in = out.input;
    in.biome = out.biome.get();

    // Snapshot.
    if (!f.exists("/snapshots")) throw IoError(path + ": group /snapshots is missing (no undergrowth snapshot)");
    std::vector<std::pair<int, std::string>> snaps;
    for (const std::string& name : f.list("/snapshots")) {
        const int y = yearOfGroup(name);
        if (y >= 0) snaps.emplace_back(y, name);
    }
    std::sort(snaps.begin(), snaps.end());
    if (snaps.empty()) throw IoError(path + ": /snapshots has no year_NNNN group");
    for (const auto& s : snaps) out.years.push_back(s.first);
    std::string group;
    int year = -1;
    if (options.year < 0) {
        year = snaps.back().first;
        group = "/snapshots/" + snaps.back().second;
    } else {
        for (const auto& s : snaps)
            if (s.first == options.year) {
                year = s.first;
                group = "/snapshots/" + s.second;
            }
        if (group.empty()) {
            std::string list;
            for (int y : out.years) list += (list.empty() ? "" : ", ") + std::to_string(y);
            throw IoError(path + ": no snapshot of year " + std::to_string(options.year) + " (years present: " + list + ")");
        }
    }
    in.undergrowth = readPlants(f, group, *biome);
    if (!f.exists("/canopy")) throw IoError(path + ": plant group /canopy is missing");
    in.canopy = readPlants(f, "/canopy", *biome);

    // Abiotics: annual means.
    const std::string recorded = firstAttr(f, {"abiotics_path", "abiotics"});
    std::string abioticsPath = options.abioticsPath;
    if (abioticsPath.empty()) {
        if (recorded.empty())
            throw IoError(path + ": root attribute 'abiotics_path' is missing; give the abiotics file with --abiotics");
        abioticsPath = resolveBeside(recorded, path);
    }
    Abiotics ab;
    try {
        ab = readAbiotics(abioticsPath);
    } catch (const IoError& e) {
        throw IoError(std::string(e.what()) + " (abiotics of simulation " + path +
                      (options.abioticsPath.empty() ? "; override with --abiotics" : "") + ")");
    }
    if (!ab.canopyShadeSource.empty())
        throw ValidationError(abioticsPath + ": its sun is already shaded by the canopy of " + ab.canopyShadeSource +
                              "; the analyser shades with the simulation's canopy itself: give the terrain's own "
                              "abiotics (eco abiotics without --canopy)");
    // Region features: the sun under the simulation's canopy, so that clearings, forest edges
    // and deep shade can fall into different regions (the synthesizer shades its target alike).
    in.sunHours = applyCanopyShade(ab.sunHours, shadingTrees(in.canopy, *biome)).annualMean();
    in.moistureMm = ab.moistureMm.annualMean();
    in.temperatureC = ab.temperatureC.annualMean();
    in.slopeDeg = ab.slopeDeg;

    // Area.
    if (f.hasAttr("/", "x0") && f.hasAttr("/", "y0") && f.hasAttr("/", "x1") && f.hasAttr("/", "y1")) {
        in.window = RectWindow{f.attrDouble("/", "x0"), f.attrDouble("/", "y0"), f.attrDouble("/", "x1"),
                               f.attrDouble("/", "y1")};
    } else {
        const Grid<float>& g = in.slopeDeg;
        in.window = RectWindow{g.originX(), g.originY(), g.originX() + g.extentX(), g.originY() + g.extentY()};
    }
    try {
        in.window.validate(path + ": area x0, y0, x1, y1");
    } catch (const ValidationError& e) {
        throw IoError(e.what());
    }

    // Provenance.
    DbInput& p = in.provenance;
    p.path = path;
    p.abioticsPath = abioticsPath;
    p.terrainPath = firstAttr(f, {"terrain_path", "terrain"});
    p.canopyPath = firstAttr(f, {"canopy_path", "canopy"});
    p.seed = f.hasAttr("/", "seed") ? static_cast<std::uint64_t>(f.attrInt("/", "seed")) : 0;
    p.year = year;
    p.parameters = firstAttr(f, {"model_toml", "parameters"});
    if (f.hasAttr("/", "seed_outer_radius_factor")) out.seedOuterRadiusFactor = f.attrDouble("/", "seed_outer_radius_factor");
    return out;
}

}  // namespace eco
