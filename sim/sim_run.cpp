#include "sim_run.h"

#include <omp.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <sstream>

#include "atomic_file.h"
#include "eco_version.h"
#include "error.h"
#include "sim_render.h"
#include "terrain_io.h"

namespace eco::sim {

namespace {

std::string yearGroup(const std::string& parent, int year) {
    char buf[32];
    std::snprintf(buf, sizeof buf, "/year_%04d", year);
    return parent + buf;
}

void requireFile(const std::string& path, const std::string& what) {
    if (path.empty()) throw ValidationError("no " + what + " file given");
    std::error_code ec;
    if (!std::filesystem::is_regular_file(path, ec))
        throw IoError(path + ": " + what + " file not found");
}

std::vector<std::string> speciesNames(const Biome& b) {
    std::vector<std::string> names;
    for (const auto& s : b.species) names.push_back(s.name);
    return names;
}

}  // namespace

Biome loadRunBiome(const RunConfig& config) {
    return config.biomePath.empty() ? defaultBiome() : loadBiome(config.biomePath);
}

SimInputs loadSimInputs(const RunConfig& config, Biome biome) {
    SimInputs in;
    in.biome = std::move(biome);
    requireFile(config.abioticsPath, "abiotics");
    requireFile(config.canopyPath, "canopy");
    in.abiotics = readAbiotics(config.abioticsPath);
    if (!in.abiotics.canopyShadeSource.empty())
        throw ValidationError(config.abioticsPath + ": its sun is already shaded by the canopy of " +
                              in.abiotics.canopyShadeSource + "; the simulator shades with its canopy itself: give "
                              "the terrain's own abiotics (eco abiotics without --canopy)");
    if (!config.terrainPath.empty()) {
        requireFile(config.terrainPath, "terrain");
        Grid<float> terrain = readTerrain(config.terrainPath);
        if (!terrain.sameGeometry(in.abiotics.slopeDeg, 1e-3))
            throw ValidationError(config.terrainPath + ": the terrain's geometry (" + std::to_string(terrain.width()) + " x " +
                                  std::to_string(terrain.height()) + " cells of " + std::to_string(terrain.cellSizeM()) +
                                  " m) differs from the abiotics in " + config.abioticsPath);
        in.abiotics.elevationM = std::move(terrain);
    }
    const h5::File f = h5::File::openRead(config.canopyPath);
    if (!f.exists("/canopy"))
        throw IoError(config.canopyPath + ": no /canopy plant group (is this a canopy file written by 'eco canopy'?)");
    in.canopy = readPlants(f, "/canopy", in.biome);
    if (!f.exists("/chm/height"))
        throw IoError(config.canopyPath + ": no /chm/height dataset (the canopy height model is needed for the canopy limit)");
    in.chmM = f.readGrid("/chm/height");
    in.area = config.crop;
    return in;
}

// ------------------------------------------------------------------ initial plants

namespace {

std::vector<std::string> splitCsvLine(const std::string& line) {
    std::vector<std::string> out;
    std::string cur;
    bool quoted = false;
    for (std::size_t i = 0; i < line.size(); ++i) {
        const char c = line[i];
        if (quoted) {
            if (c == '"' && i + 1 < line.size() && line[i + 1] == '"') { cur += '"'; ++i; }
            else if (c == '"') quoted = false;
            else cur += c;
        } else if (c == '"') quoted = true;
        else if (c == ',') { out.push_back(cur); cur.clear(); }
        else if (c != '\r') cur += c;
    }
    out.push_back(cur);
    return out;
}

std::vector<UndergrowthPlant> readInitialCsv(const std::string& path, const Biome& biome) {
    std::ifstream in(path);
    if (!in) throw IoError(path + ": cannot open initial plant CSV");
    std::string line;
    if (!std::getline(in, line)) throw IoError(path + ": empty CSV (a header is required)");
    const auto header = splitCsvLine(line);
    std::map<std::string, std::size_t> col;
    for (std::size_t i = 0; i < header.size(); ++i) col[header[i]] = i;
    for (const char* need : {"x_m", "y_m", "height_m"})
        if (!col.count(need)) throw IoError(path + ": header has no column '" + need + "'");
    if (!col.count("species") && !col.count("species_id"))
        throw IoError(path + ": header has no column 'species' (name) or 'species_id'");
    std::vector<UndergrowthPlant> out;
    int lineNo = 1;
    while (std::getline(in, line)) {
        ++lineNo;
        if (line.empty() || line == "\r") continue;
        const auto f = splitCsvLine(line);
        const std::string where = path + ":" + std::to_string(lineNo);
        auto num = [&](const char* name, double fallback) {
            auto it = col.find(name);
            if (it == col.end()) return fallback;
            if (it->second >= f.size()) throw IoError(where + ": missing column '" + name + "'");
            try {
                std::size_t used = 0;
                const double v = std::stod(f[it->second], &used);
                if (used != f[it->second].size() || !std::isfinite(v)) throw std::invalid_argument("");
                return v;
            } catch (const std::exception&) {
                throw IoError(where + ": column '" + name + "': '" + f[it->second] + "' is not a finite number");
            }
        };
        UndergrowthPlant p;
        if (col.count("species")) {
            const std::size_t i = col["species"];
            if (i >= f.size()) throw IoError(where + ": missing column 'species'");
            try {
                p.speciesId = biome.speciesIndex(f[i]);
            } catch (const ValidationError& e) {
                throw ValidationError(where + ": " + e.what());
            }
        } else {
            const double id = num("species_id", -1);
            if (id < 0 || id >= static_cast<double>(biome.species.size()) || id != std::floor(id))
                throw ValidationError(where + ": species_id " + std::to_string(id) + " outside the biome's species");
            p.speciesId = static_cast<int>(id);
        }
        p.xM = num("x_m", 0);
        p.yM = num("y_m", 0);
        p.heightM = num("height_m", 0);
        if (p.heightM < 0) throw ValidationError(where + ": negative height");
        p.ageYears = num("age_years", 0);
        p.growthAgeYears = num("growth_age_years", 0);
        p.pool = num("pool", 0);
        p.vigour = num("vigour", 0);
        out.push_back(p);
    }
    return out;
}

}  // namespace

std::vector<UndergrowthPlant> readInitialPlants(const std::string& spec, const Biome& biome) {
    std::string path = spec, group;
    const auto colon = spec.find(":/");
    if (colon != std::string::npos) {
        path = spec.substr(0, colon);
        group = spec.substr(colon + 1);
    }
    requireFile(path, "initial plants");
    std::string ext = path.size() >= 4 ? path.substr(path.size() - 4) : "";
    std::transform(ext.begin(), ext.end(), ext.begin(), ::tolower);
    if (ext == ".csv") return readInitialCsv(path, biome);
    const h5::File f = h5::File::openRead(path);
    if (group.empty()) {
        if (f.exists("/snapshots") && !f.list("/snapshots").empty()) {
            auto names = f.list("/snapshots");
            std::sort(names.begin(), names.end());
            group = "/snapshots/" + names.back();
        } else {
            group = "/undergrowth";
        }
    }
    if (!f.exists(group)) throw IoError(path + ": no plant group '" + group + "'");
    return readSnapshot(f, group, biome);
}

// ------------------------------------------------------------------ snapshots and CSV

void writeSnapshot(h5::File& f, const std::string& group, int year, const std::vector<UndergrowthPlant>& plants,
                   const Biome& biome) {
    std::vector<Plant> basic;
    basic.reserve(plants.size());
    for (const auto& p : plants) basic.push_back(Plant{p.speciesId, p.xM, p.yM, p.groundZM, p.heightM, p.crownRadiusM});
    writePlants(f, group, basic, biome);
    const hsize_t n = plants.size();
    std::vector<double> id(n), age(n), ga(n), vig(n), pool(n), sun(n), water(n);
    for (std::size_t i = 0; i < n; ++i) {
        id[i] = static_cast<double>(plants[i].id);  // exact below 2^53
        age[i] = plants[i].ageYears;
        ga[i] = plants[i].growthAgeYears;
        vig[i] = plants[i].vigour;
        pool[i] = plants[i].pool;
        sun[i] = plants[i].sunShare;
        water[i] = plants[i].waterShare;
    }
    f.writeF64(group + "/id", id, {n});
    f.writeF64(group + "/age", age, {n});
    f.writeF64(group + "/growth_age", ga, {n});
    f.writeF64(group + "/vigour", vig, {n});
    f.writeF64(group + "/pool", pool, {n});
    f.writeF64(group + "/sun_share", sun, {n});
    f.writeF64(group + "/water_share", water, {n});
    f.setAttr(group, "year", static_cast<std::int64_t>(year));
    f.setAttr(group, "units", std::string("x, y, ground_z, height, crown_radius: m; age, growth_age: years; "
                                          "sun_share: hours/day; water_share: mm/month; vigour, pool: dimensionless"));
}

std::vector<UndergrowthPlant> readSnapshot(const h5::File& f, const std::string& group, const Biome& biome) {
    const auto basic = readPlants(f, group, biome);
    std::vector<UndergrowthPlant> out(basic.size());
    auto opt = [&](const char* name) {
        std::vector<double> v;
        if (f.exists(group + "/" + name)) {
            v = f.readF64(group + "/" + name);
            if (v.size() != basic.size()) throw IoError(f.path() + ": " + group + "/" + name + ": length differs from species_id");
        }
        return v;
    };
    const auto id = opt("id"), age = opt("age"), ga = opt("growth_age"), vig = opt("vigour"), pool = opt("pool"),
               sun = opt("sun_share"), water = opt("water_share");
    for (std::size_t i = 0; i < basic.size(); ++i) {
        UndergrowthPlant& p = out[i];
        p.speciesId = basic[i].speciesId;
        p.xM = basic[i].xM;
        p.yM = basic[i].yM;
        p.groundZM = basic[i].groundZM;
        p.heightM = basic[i].heightM;
        p.crownRadiusM = basic[i].crownRadiusM;
        if (!id.empty()) p.id = static_cast<std::uint64_t>(id[i]);
        if (!age.empty()) p.ageYears = age[i];
        if (!ga.empty()) p.growthAgeYears = ga[i];
        if (!vig.empty()) p.vigour = vig[i];
        if (!pool.empty()) p.pool = pool[i];
        if (!sun.empty()) p.sunShare = sun[i];
        if (!water.empty()) p.waterShare = water[i];
    }
    return out;
}

void writeUndergrowthCsv(const std::string& path, const std::vector<UndergrowthPlant>& plants, const Biome& biome) {
    AtomicOutput out(path);
    {
        std::FILE* f = std::fopen(out.tempPath().c_str(), "w");
        if (!f) throw IoError(path + ": cannot write CSV");
        std::fprintf(f, "species_id,species,x_m,y_m,ground_z_m,height_m,crown_radius_m,id,age_years,growth_age_years,vigour,pool\n");
        for (const auto& p : plants)
            std::fprintf(f, "%d,\"%s\",%.4f,%.4f,%.3f,%.5f,%.5f,%llu,%.4f,%.6f,%.6f,%.6f\n", p.speciesId,
                         biome.species[static_cast<std::size_t>(p.speciesId)].name.c_str(), p.xM, p.yM, p.groundZM, p.heightM,
                         p.crownRadiusM, static_cast<unsigned long long>(p.id), p.ageYears, p.growthAgeYears, p.vigour, p.pool);
        if (std::fclose(f) != 0) throw IoError(path + ": error while writing CSV");
    }
    out.commit();
}

// ------------------------------------------------------------------ record I/O

namespace {

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
    f.writeI32(group + "/year", year, {ny});
    f.writeI32(group + "/count", count, {ny, ns});
    f.writeF64(group + "/mean_height", h, {ny, ns});
    f.writeF64(group + "/mean_vigour", v, {ny, ns});
    f.writeF64(group + "/crown_area", a, {ny, ns});
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

constexpr const char* kCheckpointFormat = "eco-simulation-checkpoint";

}  // namespace

void writeSimulationH5(const std::string& path, const Simulation& sim, const RunRecord& record, const RunConfig& config,
                       double wallSeconds, int threads) {
    const std::filesystem::path parent = std::filesystem::path(path).parent_path();
    if (!parent.empty()) ensureDirectory(parent.string());
    AtomicOutput out(path);
    {
        h5::File f = h5::File::create(out.tempPath());
        const Biome& biome = sim.biome();
        f.setAttr("/", "format", std::string("eco-simulation"));
        f.setAttr("/", "schema_version", static_cast<std::int64_t>(1));
        f.setAttr("/", "code_version", std::string(ECO_VERSION_STRING));
        f.setAttr("/", "seed", static_cast<std::int64_t>(sim.seed()));
        f.setAttr("/", "years", static_cast<std::int64_t>(sim.yearsDone()));
        f.setAttr("/", "wall_time_s", wallSeconds);
        f.setAttr("/", "threads", static_cast<std::int64_t>(threads));
        f.setAttr("/", "resumed_from_year", static_cast<std::int64_t>(record.resumedFromYear));
        const SimArea a = sim.area();
        f.setAttr("/", "x0", a.x0);
        f.setAttr("/", "y0", a.y0);
        f.setAttr("/", "x1", a.x1);
        f.setAttr("/", "y1", a.y1);
        f.setAttr("/", "area_units", std::string("m, world coordinates (x east, y north)"));
        for (const auto& [key, value] : sim.params().namedValues()) f.setAttr("/", key, value);
        f.setAttr("/", "model_toml", sim.params().toToml());
        f.setAttr("/", "biome_name", biome.name);
        f.setAttr("/", "biome_toml", biomeToToml(biome));
        f.setAttr("/", "terrain_path", config.terrainPath);
        f.setAttr("/", "abiotics_path", config.abioticsPath);
        f.setAttr("/", "canopy_path", config.canopyPath);
        f.setAttr("/", "biome_path", config.biomePath.empty() ? std::string("(embedded Sonoma biome)") : config.biomePath);
        f.setAttr("/", "initial_path", config.initialPath);
        f.setAttr("/", "config_path", config.sourcePath);
        const SimCounters& c = sim.counters();
        f.setAttr("/", "germinated", static_cast<std::int64_t>(c.germinated));
        f.setAttr("/", "died_background_or_stress", static_cast<std::int64_t>(c.diedBackgroundOrStress));
        f.setAttr("/", "died_at_canopy", static_cast<std::int64_t>(c.diedAtCanopy));
        f.setAttr("/", "died_dominated", static_cast<std::int64_t>(c.diedDominated));
        f.setAttr("/", "plant_months", static_cast<std::int64_t>(c.plantMonths));
        f.setAttr("/", "plant_cell_months", static_cast<std::int64_t>(c.plantCellMonths));
        f.setAttr("/", "units", std::string("metres, years, hours of sun per day, mm of water per month, degrees C"));
        f.ensureGroup("/snapshots");
        for (const auto& [year, plants] : record.snapshots) writeSnapshot(f, yearGroup("/snapshots", year), year, plants, biome);
        writeTimeseries(f, "/timeseries", record.timeseries, biome);
        writePlants(f, "/canopy", sim.relevantCanopy(), biome);
        f.setAttr("/canopy", "selection", std::string("canopy trees whose crown or seeding disc (outer factor x r) reaches the area"));
        f.writeStrings("/species_names", speciesNames(biome));
    }
    out.commit();
}

void writeCheckpoint(const std::string& path, const Simulation& sim, const RunRecord& record) {
    const std::filesystem::path parent = std::filesystem::path(path).parent_path();
    if (!parent.empty()) ensureDirectory(parent.string());
    AtomicOutput out(path);
    {
        h5::File f = h5::File::create(out.tempPath());
        f.setAttr("/", "format", std::string(kCheckpointFormat));
        f.setAttr("/", "schema_version", static_cast<std::int64_t>(1));
        f.setAttr("/", "code_version", std::string(ECO_VERSION_STRING));
        f.setAttr("/", "years_done", static_cast<std::int64_t>(sim.yearsDone()));
        f.setAttr("/", "wall_seconds_before", record.wallSecondsBefore);
        sim.saveState(f, "/state");
        writeTimeseries(f, "/record/timeseries", record.timeseries, sim.biome());
        f.ensureGroup("/record/snapshots");
        for (const auto& [year, plants] : record.snapshots)
            writeSnapshot(f, yearGroup("/record/snapshots", year), year, plants, sim.biome());
    }
    out.commit();
}

void readCheckpoint(const std::string& path, Simulation& sim, RunRecord& record) {
    const h5::File f = h5::File::openRead(path);
    if (!f.hasAttr("/", "format") || f.attrString("/", "format") != kCheckpointFormat)
        throw IoError(path + ": not an eco simulation checkpoint (attribute format != '" + kCheckpointFormat + "')");
    sim.loadState(f, "/state");
    RunRecord r;
    r.timeseries = readTimeseries(f, "/record/timeseries", sim.biome().species.size());
    auto names = f.list("/record/snapshots");
    std::sort(names.begin(), names.end());
    for (const auto& n : names) {
        const std::string g = "/record/snapshots/" + n;
        r.snapshots.emplace_back(static_cast<int>(f.attrInt(g, "year")), readSnapshot(f, g, sim.biome()));
    }
    r.wallSecondsBefore = f.attrDouble("/", "wall_seconds_before");
    r.resumedFromYear = sim.yearsDone();
    record = std::move(r);
}

// ------------------------------------------------------------------ the run

RunSummary runSimulation(const RunConfig& config, bool resume, const RunHooks& hooks) {
    config.validate();
    auto log = [&](const std::string& s) {
        if (hooks.log) hooks.log(s);
    };
    const auto start = std::chrono::steady_clock::now();
    auto elapsed = [&] { return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(); };

    Biome biome = loadRunBiome(config);
    SimInputs inputs = loadSimInputs(config, biome);
    std::vector<UndergrowthPlant> initial;
    if (!config.initialPath.empty()) initial = readInitialPlants(config.initialPath, biome);
    Simulation sim(std::move(inputs), config.params, config.seed, initial);
    if (sim.droppedInitialPlants() > 0)
        log("initial plants outside the area dropped: " + std::to_string(sim.droppedInitialPlants()));

    RunRecord record;
    const std::string checkpoint = config.effectiveCheckpointPath();
    if (resume) {
        std::error_code ec;
        if (std::filesystem::exists(checkpoint, ec)) {
            readCheckpoint(checkpoint, sim, record);
            if (sim.yearsDone() > config.years)
                throw ValidationError(checkpoint + ": the checkpoint is at year " + std::to_string(sim.yearsDone()) +
                                      ", beyond the configured " + std::to_string(config.years) + " years");
            log("resumed from " + checkpoint + " at year " + std::to_string(sim.yearsDone()));
        } else {
            log("no checkpoint at " + checkpoint + "; starting from year 0");
        }
    }
    std::set<int> snapshotYears;
    std::string skipped;
    for (int y : config.snapshotYears) {
        if (y <= config.years) snapshotYears.insert(y);
        else skipped += (skipped.empty() ? "" : ", ") + std::to_string(y);
    }
    if (!skipped.empty()) log("snapshot years beyond the " + std::to_string(config.years) + " simulated years skipped: " + skipped);
    snapshotYears.insert(config.years);
    auto takeSnapshot = [&](int year) {
        record.snapshots.erase(std::remove_if(record.snapshots.begin(), record.snapshots.end(),
                                              [&](const auto& s) { return s.first == year; }),
                               record.snapshots.end());
        record.snapshots.emplace_back(year, sim.plants());
    };
    if (record.timeseries.empty()) {
        record.timeseries.push_back(sim.census());
        if (snapshotYears.count(0)) takeSnapshot(0);
    }
    const std::int64_t plantMonthsBefore = sim.counters().plantMonths;
    RunSummary summary;
    if (hooks.onYear) hooks.onYear(sim, record);
    while (sim.yearsDone() < config.years) {
        sim.stepYear();
        const int year = sim.yearsDone();
        record.timeseries.push_back(sim.census());
        if (snapshotYears.count(year)) takeSnapshot(year);
        if (hooks.onYear) hooks.onYear(sim, record);
        const bool stop = hooks.stopRequested && hooks.stopRequested() && year < config.years;
        if (config.checkpointEveryYears > 0 && (year % config.checkpointEveryYears == 0 || stop || year == config.years)) {
            RunRecord r = record;
            r.wallSecondsBefore = record.wallSecondsBefore + elapsed();
            writeCheckpoint(checkpoint, sim, r);
        }
        if (stop) {
            summary.stoppedEarly = true;
            break;
        }
    }
    summary.years = sim.yearsDone();
    summary.finalPlants = sim.plantCount();
    summary.plantMonths = sim.counters().plantMonths - plantMonthsBefore;
    if (summary.stoppedEarly) {
        summary.wallSeconds = elapsed();
        return summary;
    }
    const double wall = record.wallSecondsBefore + elapsed();
    writeSimulationH5(config.outputPath, sim, record, config, wall, omp_get_max_threads());
    summary.written.push_back(config.outputPath);
    const std::vector<UndergrowthPlant> finalPlants = sim.plants();
    if (!config.csvPath.empty()) {
        const std::filesystem::path parent = std::filesystem::path(config.csvPath).parent_path();
        if (!parent.empty()) ensureDirectory(parent.string());
        writeUndergrowthCsv(config.csvPath, finalPlants, sim.biome());
        summary.written.push_back(config.csvPath);
    }
    if (!config.pngDir.empty()) {
        ensureDirectory(config.pngDir);
        for (const auto& [year, plants] : record.snapshots) {
            char name[64];
            std::snprintf(name, sizeof name, "/plants_year_%04d.png", year);
            const std::string p = config.pngDir + name;
            renderPlantsPng(p, plants, sim.relevantCanopy(), sim.area(), sim.biome(),
                            "Undergrowth after " + std::to_string(year) + " years (" + std::to_string(plants.size()) + " plants)");
            summary.written.push_back(p);
        }
        const std::string plot = config.pngDir + "/species_counts.png";
        plotSpeciesCountsPng(plot, record.timeseries, sim.biome(), "Plants per species per year");
        summary.written.push_back(plot);
    }
    summary.wallSeconds = elapsed();
    return summary;
}

}  // namespace eco::sim
