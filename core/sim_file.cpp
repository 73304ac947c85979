#include "sim_file.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>

#include "atomic_file.h"
#include "eco_version.h"
#include "error.h"
#include "provenance.h"

namespace eco {

namespace {

std::vector<std::string> speciesNames(const Biome& b) {
    std::vector<std::string> names;
    for (const auto& s : b.species) names.push_back(s.name);
    return names;
}

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

}  // namespace

std::string snapshotGroup(const std::string& parent, int year) {
    char buf[32];
    std::snprintf(buf, sizeof buf, "/year_%04d", year);
    return parent + buf;
}

// ------------------------------------------------------------------ snapshots and time series

void writeSnapshot(h5::File& f, const std::string& group, int year, const std::vector<UndergrowthPlant>& plants,
                   const Biome& biome) {
    writeUndergrowthPlants(f, group, plants, biome);
    f.setAttr(group, "year", static_cast<std::int64_t>(year));
    f.setAttr(group, "units", std::string("x, y, ground_z, height, crown_radius: m; age, growth_age: years; "
                                          "sun_share: hours/day; water_share: mm/month; vigour, pool: dimensionless"));
}

std::vector<UndergrowthPlant> readSnapshot(const h5::File& f, const std::string& group, const Biome& biome) {
    return readUndergrowthPlants(f, group, biome);
}

void writeTimeseries(h5::File& f, const std::string& group, const std::vector<YearRecord>& ts, const Biome& biome) {
    const hsize_t ny = ts.size(), ns = biome.species.size();
    std::vector<std::int32_t> year(ny), count(ny * ns);
    std::vector<double> h(ny * ns), v(ny * ns), a(ny * ns);
    for (std::size_t y = 0; y < ny; ++y) {
        year[y] = ts[y].year;
        for (std::size_t s = 0; s < ns; ++s) {
            count[y * ns + s] = ts[y].count[s];
            h[y * ns + s] = ts[y].meanHeightM[s];
            v[y * ns + s] = ts[y].meanVigour[s];
            a[y * ns + s] = ts[y].crownAreaM2[s];
        }
    }
    f.ensureGroup(group);
    f.writeI32(group + "/year", year, {ny}, "years");
    f.writeI32(group + "/count", count, {ny, ns}, "1");
    f.writeF64(group + "/mean_height", h, {ny, ns}, "m");
    f.writeF64(group + "/mean_vigour", v, {ny, ns}, "1");
    f.writeF64(group + "/crown_area", a, {ny, ns}, "m2");
    f.writeStrings(group + "/species_names", speciesNames(biome));
    f.setAttr(group, "units", std::string("year: complete years simulated (0 = initial state); count: plants; "
                                          "mean_height: m; mean_vigour: dimensionless; crown_area: m^2 (sum of pi r^2)"));
    f.setAttr(group, "layout", std::string("[year][species], species in the order of species_names"));
}

std::vector<YearRecord> readTimeseries(const h5::File& f, const std::string& group, std::size_t ns) {
    std::vector<hsize_t> dims;
    const auto year = f.readI32(group + "/year");
    const auto count = f.readI32(group + "/count", &dims);
    const auto h = f.readF64(group + "/mean_height");
    const auto v = f.readF64(group + "/mean_vigour");
    const auto a = f.readF64(group + "/crown_area");
    if (dims.size() != 2 || dims[0] != year.size() || dims[1] != ns || h.size() != count.size() || v.size() != count.size() ||
        a.size() != count.size())
        throw IoError(f.path() + ": " + group + ": time series arrays have inconsistent shapes");
    std::vector<YearRecord> ts(year.size());
    for (std::size_t y = 0; y < year.size(); ++y) {
        ts[y].year = year[y];
        for (std::size_t s = 0; s < ns; ++s) {
            ts[y].count.push_back(count[y * ns + s]);
            ts[y].meanHeightM.push_back(h[y * ns + s]);
            ts[y].meanVigour.push_back(v[y * ns + s]);
            ts[y].crownAreaM2.push_back(a[y * ns + s]);
        }
    }
    return ts;
}

// ------------------------------------------------------------------ disturbance events

Grid<std::uint8_t> DisturbanceMask::grid() const {
    if (!present()) return {};
    Grid<std::uint8_t> g(width, height, cellSizeM, originX, originY, 0);
    for (std::int32_t c : cells) g.data()[static_cast<std::size_t>(c)] = 1;
    return g;
}

bool DisturbanceMask::contains(double xM, double yM) const {
    if (!present()) return false;
    const double fx = std::floor((xM - originX) / cellSizeM), fy = std::floor((yM - originY) / cellSizeM);
    if (!(fx >= 0 && fy >= 0 && fx < width && fy < height)) return false;
    const auto c = static_cast<std::int32_t>(static_cast<std::int64_t>(fy) * width + static_cast<std::int64_t>(fx));
    return std::binary_search(cells.begin(), cells.end(), c);
}

void writeDisturbanceTable(h5::File& f, const std::string& group, const std::vector<DisturbanceRecord>& ev,
                           const Biome& biome) {
    const hsize_t ne = ev.size(), ns = biome.species.size();
    std::vector<std::int32_t> year(ne), month(ne), killed(ne * ns, 0), total(ne, 0);
    std::vector<double> area(ne), x(ne), y(ne);
    std::vector<std::string> kind(ne);
    for (std::size_t e = 0; e < ne; ++e) {
        year[e] = ev[e].year;
        month[e] = ev[e].month;
        kind[e] = ev[e].kind;
        area[e] = ev[e].areaM2;
        x[e] = ev[e].xM;
        y[e] = ev[e].yM;
        for (std::size_t s = 0; s < ns && s < ev[e].killed.size(); ++s) {
            killed[e * ns + s] = ev[e].killed[s];
            total[e] += ev[e].killed[s];
        }
    }
    f.ensureGroup(group);
    f.setAttr(group, "events", static_cast<std::int64_t>(ne));
    f.writeI32(group + "/year", year, {ne}, "years");
    f.writeI32(group + "/month", month, {ne}, "1");
    f.writeStrings(group + "/kind", kind);
    f.writeF64(group + "/area", area, {ne}, "m2");
    f.writeF64(group + "/x", x, {ne}, "m");
    f.writeF64(group + "/y", y, {ne}, "m");
    f.writeI32(group + "/killed", killed, {ne, ns}, "1");
    f.writeI32(group + "/killed_total", total, {ne}, "1");
    f.writeStrings(group + "/species_names", speciesNames(biome));
    // The masks, sparse (docs/disturbance.md "Output"): event e's cells are
    // mask_cells[mask_offset[e] : mask_offset[e + 1]] on its grid of mask_width x mask_height.
    std::vector<std::int64_t> offset(ne + 1, 0);
    std::vector<std::int32_t> cells, mw(ne), mh(ne);
    std::vector<double> mx(ne), my(ne), mc(ne);
    for (std::size_t e = 0; e < ne; ++e) {
        const DisturbanceMask& m = ev[e].mask;
        mw[e] = m.width;
        mh[e] = m.height;
        mx[e] = m.originX;
        my[e] = m.originY;
        mc[e] = m.cellSizeM;
        cells.insert(cells.end(), m.cells.begin(), m.cells.end());
        offset[e + 1] = static_cast<std::int64_t>(cells.size());
    }
    f.writeI64(group + "/mask_offset", offset, {ne + 1}, "1");
    f.writeI32(group + "/mask_cells", cells, {cells.size()}, "1");
    f.writeI32(group + "/mask_width", mw, {ne}, "cells");
    f.writeI32(group + "/mask_height", mh, {ne}, "cells");
    f.writeF64(group + "/mask_origin_x", mx, {ne}, "m");
    f.writeF64(group + "/mask_origin_y", my, {ne}, "m");
    f.writeF64(group + "/mask_cell_size", mc, {ne}, "m");
    f.setAttr(group, "layout", std::string("one row per event in the order they struck; killed: [event][species], species in "
                                           "the order of species_names; mask: event e struck the cells "
                                           "mask_cells[mask_offset[e]:mask_offset[e+1]] (iy * mask_width + ix, row 0 "
                                           "south) of its grid, lower-left corner (mask_origin_x, mask_origin_y), cells "
                                           "of mask_cell_size; fire: burnt cells, storm: cells with a plant thrown"));
}

std::vector<DisturbanceRecord> readDisturbanceTable(const h5::File& f, const std::string& group, std::size_t ns) {
    std::vector<hsize_t> dims;
    const auto year = f.readI32(group + "/year");
    const auto month = f.readI32(group + "/month");
    const auto kind = year.empty() ? std::vector<std::string>{} : f.readStrings(group + "/kind");
    const auto area = f.readF64(group + "/area");
    const auto x = f.readF64(group + "/x");
    const auto y = f.readF64(group + "/y");
    const auto killed = f.readI32(group + "/killed", &dims);
    const std::size_t ne = year.size();
    if (month.size() != ne || kind.size() != ne || area.size() != ne || x.size() != ne || y.size() != ne ||
        killed.size() != ne * ns)
        throw IoError(f.path() + ": " + group + ": disturbance arrays have inconsistent shapes");
    std::vector<DisturbanceRecord> out(ne);
    for (std::size_t e = 0; e < ne; ++e) {
        out[e].year = year[e];
        out[e].month = month[e];
        out[e].kind = kind[e];
        out[e].areaM2 = area[e];
        out[e].xM = x[e];
        out[e].yM = y[e];
        out[e].killed.assign(killed.begin() + static_cast<std::ptrdiff_t>(e * ns),
                             killed.begin() + static_cast<std::ptrdiff_t>((e + 1) * ns));
    }
    if (!f.exists(group + "/mask_offset")) return out;  // written before the masks (2026-11-27)
    const auto offset = f.readI64(group + "/mask_offset");
    const auto cells = f.readI32(group + "/mask_cells");
    const auto mw = f.readI32(group + "/mask_width"), mh = f.readI32(group + "/mask_height");
    const auto mx = f.readF64(group + "/mask_origin_x"), my = f.readF64(group + "/mask_origin_y");
    const auto mc = f.readF64(group + "/mask_cell_size");
    if (offset.size() != ne + 1 || mw.size() != ne || mh.size() != ne || mx.size() != ne || my.size() != ne ||
        mc.size() != ne || offset[0] != 0 || offset[ne] != static_cast<std::int64_t>(cells.size()))
        throw IoError(f.path() + ": " + group + ": disturbance mask arrays have inconsistent shapes");
    for (std::size_t e = 0; e < ne; ++e) {
        DisturbanceMask& m = out[e].mask;
        const std::int64_t b = offset[e], en = offset[e + 1];
        const std::int64_t n = static_cast<std::int64_t>(mw[e]) * mh[e];
        if (b > en || mw[e] < 0 || mh[e] < 0 || (n > 0 && !(mc[e] > 0)))
            throw IoError(f.path() + ": " + group + ": disturbance mask of event " + std::to_string(e) + " is malformed");
        m.width = mw[e];
        m.height = mh[e];
        m.originX = mx[e];
        m.originY = my[e];
        m.cellSizeM = mc[e];
        m.cells.assign(cells.begin() + b, cells.begin() + en);
        for (std::size_t i = 0; i < m.cells.size(); ++i)
            if (m.cells[i] < 0 || m.cells[i] >= n || (i > 0 && m.cells[i] <= m.cells[i - 1]))
                throw IoError(f.path() + ": " + group + "/mask_cells: event " + std::to_string(e) +
                              ": cell indices must be ascending and inside its " + std::to_string(mw[e]) + " x " +
                              std::to_string(mh[e]) + " grid");
    }
    return out;
}

// ------------------------------------------------------------------ the file

void writeSimulationFile(const std::string& path, const SimulationFileInfo& info, const Biome& biome,
                         const SnapshotList& snapshots, const std::vector<YearRecord>& timeseries,
                         const std::vector<Plant>& canopy) {
    const std::filesystem::path parent = std::filesystem::path(path).parent_path();
    if (!parent.empty()) ensureDirectory(parent.string());
    AtomicOutput out(path);
    {
        h5::File f = h5::File::create(out.tempPath());
        f.setAttr("/", "format", std::string(kSimulationFormat));
        f.setAttr("/", "schema_version", kSimulationSchemaVersion);
        f.setAttr("/", "code_version", std::string(ECO_VERSION_STRING));
        f.setAttr("/", "seed", static_cast<std::int64_t>(info.seed));
        f.setAttr("/", "years", static_cast<std::int64_t>(info.years));
        f.setAttr("/", "x0", info.x0);
        f.setAttr("/", "y0", info.y0);
        f.setAttr("/", "x1", info.x1);
        f.setAttr("/", "y1", info.y1);
        f.setAttr("/", "area_units", std::string("m, world coordinates (x east, y north)"));
        for (const h5::NamedAttr& a : info.parameters) f.setAttr("/", a);
        f.setAttr("/", "model_toml", info.modelToml);
        f.setAttr("/", "biome_name", biome.name);
        f.setAttr("/", "biome_toml", biomeToToml(biome));
        f.setAttr("/", "terrain_path", info.terrainPath);
        f.setAttr("/", "abiotics_path", info.abioticsPath);
        f.setAttr("/", "canopy_path", info.canopyPath);
        f.setAttr("/", "biome_path", info.biomePath);
        f.setAttr("/", "initial_path", info.initialPath);
        f.setAttr("/", "config_path", info.configPath);
        f.setAttr("/", "germinated", info.germinated);
        f.setAttr("/", "died_background_or_stress", info.diedBackgroundOrStress);
        f.setAttr("/", "died_at_canopy", info.diedAtCanopy);
        f.setAttr("/", "died_dominated", info.diedDominated);
        f.setAttr("/", "plant_months", info.plantMonths);
        f.setAttr("/", "plant_cell_months", info.plantCellMonths);
        if (!info.disturbanceToml.empty()) {
            f.setAttr("/", "died_disturbance", info.diedDisturbance);
            f.setAttr("/", "disturbance_toml", info.disturbanceToml);
        }
        f.setAttr("/", "units", std::string("metres, years, hours of sun per day, mm of water per month, degrees C"));
        f.ensureGroup("/snapshots");
        for (const auto& [year, plants] : snapshots) writeSnapshot(f, snapshotGroup("/snapshots", year), year, plants, biome);
        writeTimeseries(f, "/timeseries", timeseries, biome);
        if (!info.disturbanceToml.empty()) writeDisturbanceTable(f, "/disturbance", info.disturbances, biome);
        writePlants(f, "/canopy", canopy, biome);
        f.setAttr("/canopy", "selection", std::string("canopy trees whose crown or seeding disc (outer factor x r) reaches the area"));
        f.writeStrings("/species_names", speciesNames(biome));
        // How the run went, not what it computed: a resumed run writes the same bytes as
        // an uninterrupted one everywhere else.
        writeProvenance(f, {{"wall_time_s", info.wallSeconds},
                            {"threads", static_cast<std::int64_t>(info.threads)},
                            {"resumed_from_year", static_cast<std::int64_t>(info.resumedFromYear)}});
    }
    out.commit();
}

SimulationFileData readSimulationFile(const std::string& path, int wantedYear) {
    const h5::File f = h5::File::openRead(path);
    if (!f.hasAttr("/", "format"))
        throw IoError(path + ": not a simulation file (root attribute 'format' is missing; expected '" +
                      std::string(kSimulationFormat) + "')");
    const std::string format = f.attrString("/", "format");
    if (format != kSimulationFormat)
        throw IoError(path + ": not a simulation file (format '" + format + "', expected '" + kSimulationFormat + "')");
    if (f.hasAttr("/", "schema_version")) {
        const std::int64_t v = f.attrInt("/", "schema_version");
        if (v < 1 || v > kSimulationSchemaVersion)
            throw IoError(path + ": simulation schema_version " + std::to_string(v) + " found, versions 1 to " +
                          std::to_string(kSimulationSchemaVersion) + " expected");
    }
    if (!f.hasAttr("/", "biome_toml")) throw IoError(path + ": root attribute 'biome_toml' (the biome) is missing");
    SimulationFileData out;
    out.biome = parseBiome(f.attrString("/", "biome_toml"), path + ": attribute biome_toml");

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
    if (wantedYear < 0) {
        out.year = snaps.back().first;
        group = "/snapshots/" + snaps.back().second;
    } else {
        for (const auto& s : snaps)
            if (s.first == wantedYear) {
                out.year = s.first;
                group = "/snapshots/" + s.second;
            }
        if (group.empty()) {
            std::string list;
            for (int y : out.years) list += (list.empty() ? "" : ", ") + std::to_string(y);
            throw IoError(path + ": no snapshot of year " + std::to_string(wantedYear) + " (years present: " + list + ")");
        }
    }
    out.undergrowth = readPlants(f, group, out.biome);
    if (!f.exists("/canopy")) throw IoError(path + ": plant group /canopy is missing");
    out.canopy = readPlants(f, "/canopy", out.biome);

    out.abioticsPath = firstAttr(f, {"abiotics_path", "abiotics"});
    if (f.hasAttr("/", "x0") && f.hasAttr("/", "y0") && f.hasAttr("/", "x1") && f.hasAttr("/", "y1"))
        out.area = std::array<double, 4>{f.attrDouble("/", "x0"), f.attrDouble("/", "y0"), f.attrDouble("/", "x1"),
                                         f.attrDouble("/", "y1")};
    out.terrainPath = firstAttr(f, {"terrain_path", "terrain"});
    out.canopyPath = firstAttr(f, {"canopy_path", "canopy"});
    out.seed = f.hasAttr("/", "seed") ? static_cast<std::uint64_t>(f.attrInt("/", "seed")) : 0;
    out.modelToml = firstAttr(f, {"model_toml", "parameters"});
    if (f.hasAttr("/", "seed_outer_radius_factor")) out.seedOuterRadiusFactor = f.attrDouble("/", "seed_outer_radius_factor");
    if (f.exists("/disturbance")) out.disturbances = readDisturbanceTable(f, "/disturbance", out.biome.species.size());
    return out;
}

std::string lastSnapshotGroup(const h5::File& f) {
    if (!f.exists("/snapshots")) return {};
    auto names = f.list("/snapshots");
    if (names.empty()) return {};
    std::sort(names.begin(), names.end());
    return "/snapshots/" + names.back();
}

}  // namespace eco
