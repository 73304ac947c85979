#include "sim_run.h"

#include <omp.h>
#include <unistd.h>

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
#include "canopy_file.h"
#include "eco_version.h"
#include "error.h"
#include "provenance.h"
#include "sim_render.h"
#include "terrain_io.h"
#include "text_format.h"

namespace eco::sim {

namespace {

void requireFile(const std::string& path, const std::string& what) {
    if (path.empty()) throw ValidationError("no " + what + " file given");
    std::error_code ec;
    if (!std::filesystem::is_regular_file(path, ec))
        throw IoError(path + ": " + what + " file not found");
}

}  // namespace

Biome loadRunBiome(const RunConfig& config) {
    return config.biomePath.empty() ? defaultBiome() : loadBiome(config.biomePath);
}

// A run whose fires or storms use the biome's prevailing wind (the spread's downwind bias,
// the storms' reference speed) on the abiotics' exposure map needs the wind that map was
// computed for: ValidationError naming both files and both winds otherwise.
static void requireMapWind(const RunConfig& config, const Biome& biome, const Abiotics& abiotics) {
    if (!config.disturbance.enabled() || !abiotics.mapWind) return;
    const Wind& map = *abiotics.mapWind;
    if (map.directionDeg == biome.wind.directionDeg && map.strengthMS == biome.wind.strengthMS) return;
    auto wind = [](const Wind& w) {
        return "from " + formatNumber(w.directionDeg, 6) + " degrees at " + formatNumber(w.strengthMS, 6) + " m/s";
    };
    throw ValidationError(config.abioticsPath + ": its wind map was computed for wind " + wind(map) +
                          " (attributes wind_direction_deg, wind_strength_m_s), the run's biome (" +
                          (config.biomePath.empty() ? std::string("the embedded default") : config.biomePath) +
                          ", [wind] direction_deg, strength_m_s) has wind " + wind(biome.wind) +
                          ": the fires and storms would use a wind the exposure map was not made for; compute the "
                          "abiotics with this biome (eco abiotics --biome) or run with the biome they were computed with");
}

SimInputs loadSimInputs(const RunConfig& config, Biome biome) {
    SimInputs in;
    in.biome = std::move(biome);
    requireFile(config.abioticsPath, "abiotics");
    if (!(config.canopyPath.empty() && config.params.kind == ModelKind::EcoMod)) requireFile(config.canopyPath, "canopy");
    in.abiotics = readAbiotics(config.abioticsPath);
    requireMapWind(config, in.biome, in.abiotics);
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
    if (!config.canopyPath.empty()) {  // none: EcoMod on empty ground
        CanopyFileData canopy = readCanopyFile(config.canopyPath, in.biome, CanopyFileParts::TreesAndChm);
        in.canopy = std::move(canopy.trees);
        in.chmM = std::move(canopy.chmM);
    }
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
    noteInputFile(path);  // recorded in /provenance with its hash
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
    if (group.empty()) group = lastSnapshotGroup(f);
    if (group.empty()) group = "/undergrowth";
    if (!f.exists(group)) throw IoError(path + ": no plant group '" + group + "'");
    return readSnapshot(f, group, biome);
}

// ------------------------------------------------------------------ the simulation file and checkpoints

namespace {

// The checkpoint is the simulator's own file (written and read here only).
constexpr const char* kCheckpointFormat = "eco-simulation-checkpoint";
// 2: wall_seconds_before moved from the root to /provenance (absent with --no-provenance).
constexpr std::int64_t kCheckpointSchemaVersion = 2;

}  // namespace

void writeSimulationH5(const std::string& path, const Simulation& sim, const RunRecord& record, const RunConfig& config,
                       double wallSeconds, int threads) {
    SimulationFileInfo info;
    info.seed = sim.seed();
    info.years = sim.yearsDone();
    info.wallSeconds = wallSeconds;
    info.threads = threads;
    info.resumedFromYear = record.resumedFromYear;
    const SimArea a = sim.area();
    info.x0 = a.x0;
    info.y0 = a.y0;
    info.x1 = a.x1;
    info.y1 = a.y1;
    info.parameters = sim.params().typedValues();
    info.modelToml = sim.params().toToml();
    info.terrainPath = config.terrainPath;
    info.abioticsPath = config.abioticsPath;
    info.canopyPath = config.canopyPath;
    info.biomePath = config.biomePath.empty() ? std::string("(embedded Sonoma biome)") : config.biomePath;
    info.initialPath = config.initialPath;
    info.configPath = config.sourcePath;
    const SimCounters& c = sim.counters();
    info.germinated = c.germinated;
    info.diedBackgroundOrStress = c.diedBackgroundOrStress;
    info.diedAtCanopy = c.diedAtCanopy;
    info.diedDominated = c.diedDominated;
    info.plantMonths = c.plantMonths;
    info.plantCellMonths = c.plantCellMonths;
    if (sim.disturbance().enabled()) {
        info.disturbanceToml = sim.disturbance().toToml();
        info.diedDisturbance = c.diedDisturbance;
        info.disturbances = sim.disturbances();
    }
    writeSimulationFile(path, info, sim.biome(), record.snapshots, record.timeseries, sim.relevantCanopy());
}

void writeCheckpoint(const std::string& path, const Simulation& sim, const RunRecord& record) {
    const std::filesystem::path parent = std::filesystem::path(path).parent_path();
    if (!parent.empty()) ensureDirectory(parent.string());
    AtomicOutput out(path);
    {
        h5::File f = h5::File::create(out.tempPath());
        f.setAttr("/", "format", std::string(kCheckpointFormat));
        f.setAttr("/", "schema_version", kCheckpointSchemaVersion);
        f.setAttr("/", "code_version", std::string(ECO_VERSION_STRING));
        f.setAttr("/", "years_done", static_cast<std::int64_t>(sim.yearsDone()));
        sim.saveState(f, "/state");
        out.midWritePoint();
        writeTimeseries(f, "/record/timeseries", record.timeseries, sim.biome());
        f.ensureGroup("/record/snapshots");
        for (const auto& [year, plants] : record.snapshots)
            writeSnapshot(f, snapshotGroup("/record/snapshots", year), year, plants, sim.biome());
        if (!record.eventPictures.empty()) {
            f.ensureGroup("/record/event_pictures");
            for (std::size_t e = 0; e < record.eventPictures.size(); ++e) {
                const std::string& png = record.eventPictures[e];
                char name[64];
                std::snprintf(name, sizeof name, "/record/event_pictures/%06zu", e);
                f.writeU8(name, std::vector<std::uint8_t>(png.begin(), png.end()), {png.size()}, "1");
            }
        }
        // The wall time so far is measured, not simulated: provenance, so that two runs of the
        // same configuration write the same checkpoint bytes (docs/hdf5.md).
        writeProvenance(f, {{"wall_seconds_before", record.wallSecondsBefore}});
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
    if (f.exists("/record/event_pictures")) {
        auto pictures = f.list("/record/event_pictures");
        std::sort(pictures.begin(), pictures.end());  // zero-padded event indices
        for (const auto& n : pictures) {
            const std::vector<std::uint8_t> png = f.readU8("/record/event_pictures/" + n);
            r.eventPictures.emplace_back(png.begin(), png.end());
        }
    }
    // Version 1 checkpoints kept it at the root; without provenance the earlier time is unknown.
    r.wallSecondsBefore = readProvenanceDouble(f, "wall_seconds_before", "wall_seconds_before").value_or(0.0);
    r.resumedFromYear = sim.yearsDone();
    record = std::move(r);
}

// The picture of a disturbance event over the plants at the end of its year (the event strikes
// at the end of its month),
// as PNG bytes: drawn into a temporary file of the pictures' folder (named after this process,
// so that a run killed meanwhile leaves nothing the next run does not remove), read back and
// removed.
static std::string eventPicture(const std::string& pngDir, const DisturbanceRecord& ev, const Simulation& sim) {
    ensureDirectory(pngDir);
    const std::string temp = pngDir + "/.event_picture.tmp" + std::to_string(::getpid()) + ".png";
    renderDisturbancePng(temp, ev, sim.plants(), sim.relevantCanopy(), sim.area(), sim.biome(),
                         describeDisturbance(ev) + "; plants at the end of its year (after " +
                             std::to_string(sim.yearsDone()) + " years)");
    std::string png = readTextFile(temp);
    std::error_code ec;
    std::filesystem::remove(temp, ec);
    if (png.empty()) throw IoError(temp + ": the event's picture could not be read back");
    return png;
}

// ------------------------------------------------------------------ the run

std::string describeDisturbance(const DisturbanceRecord& e) {
    static const char* const kMonths[12] = {"Jan", "Feb", "Mar", "Apr", "May", "Jun",
                                            "Jul", "Aug", "Sep", "Oct", "Nov", "Dec"};
    std::int64_t killed = 0;
    for (std::int32_t k : e.killed) killed += k;
    char buf[256];
    if (e.kind == "fire")
        std::snprintf(buf, sizeof buf, "year %d %s: fire from (%.1f, %.1f) burnt %.0f m2, killed %lld plants", e.year,
                      kMonths[e.month % 12], e.xM, e.yM, e.areaM2, static_cast<long long>(killed));
    else
        std::snprintf(buf, sizeof buf, "year %d %s: %s damaged %.0f m2, killed %lld plants", e.year, kMonths[e.month % 12],
                      e.kind.c_str(), e.areaM2, static_cast<long long>(killed));
    return buf;
}

RunSummary runSimulation(const RunConfig& config, bool resume, const RunHooks& hooks) {
    config.validate();
    auto log = [&](const std::string& s) {
        if (hooks.log) hooks.log(s);
    };
    const auto start = std::chrono::steady_clock::now();
    auto elapsed = [&] { return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(); };

    const std::string checkpoint = config.effectiveCheckpointPath();
    // What killed runs of these outputs left: an interrupted commit of the outputs is
    // completed, temporaries (a checkpoint's can be gigabytes) removed, before any work.
    for (const std::string* path : {&config.outputPath, &config.csvPath, &checkpoint})
        if (!path->empty()) cleanUpAfterDeadWriters(*path);
    if (!config.pngDir.empty()) cleanUpDirectoryAfterDeadWriters(config.pngDir);

    Biome biome = loadRunBiome(config);
    SimInputs inputs = loadSimInputs(config, biome);
    std::vector<UndergrowthPlant> initial;
    if (!config.initialPath.empty()) initial = readInitialPlants(config.initialPath, biome);
    Simulation sim(std::move(inputs), config.params, config.seed, initial);
    if (config.disturbance.enabled()) sim.setDisturbance(config.disturbance);
    if (sim.droppedInitialPlants() > 0)
        log("initial plants outside the area dropped: " + std::to_string(sim.droppedInitialPlants()));

    RunRecord record;
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
    std::size_t eventsLogged = sim.disturbances().size();
    while (sim.yearsDone() < config.years) {
        sim.stepYear();
        const int year = sim.yearsDone();
        for (; eventsLogged < sim.disturbances().size(); ++eventsLogged) {
            const DisturbanceRecord& ev = sim.disturbances()[eventsLogged];
            log(describeDisturbance(ev));
            if (!config.pngDir.empty()) {
                record.eventPictures.resize(eventsLogged);  // "" for events without one (before a resume)
                record.eventPictures.push_back(eventPicture(config.pngDir, ev, sim));
            }
        }
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
    // The simulation file, CSV and pictures are committed as one set (core/atomic_file.h): a
    // kill while they are written leaves the previous set, or a journal that the next run
    // completes; the checkpoint of the last year is written before, so --resume only writes them.
    AtomicOutputSet outputs;
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
        // Each disturbance event's mask over the plants just after it (drawn at the end of its
        // year); for an event without that picture (a run resumed from a checkpoint written
        // without pictures), over the plants of the first snapshot after it (the census of
        // year + 1 is the first after an event of year `year`), or the final plants.
        const std::vector<DisturbanceRecord>& events = sim.disturbances();
        for (std::size_t e = 0; e < events.size(); ++e) {
            const DisturbanceRecord& ev = events[e];
            char name[96];
            std::snprintf(name, sizeof name, "/disturbance_%03zu_year_%04d_%s.png", e, ev.year, ev.kind.c_str());
            if (e < record.eventPictures.size() && !record.eventPictures[e].empty()) {
                writeTextFile(config.pngDir + name, record.eventPictures[e]);
                summary.written.push_back(config.pngDir + name);
                continue;
            }
            const std::vector<UndergrowthPlant>* shown = &finalPlants;
            int shownYear = sim.yearsDone();
            for (const auto& [year, plants] : record.snapshots)
                if (year > ev.year) {
                    shown = &plants;
                    shownYear = year;
                    break;
                }
            const std::string p = config.pngDir + name;
            renderDisturbancePng(p, ev, *shown, sim.relevantCanopy(), sim.area(), sim.biome(),
                                 describeDisturbance(ev) + "; plants after " + std::to_string(shownYear) + " years");
            summary.written.push_back(p);
        }
        const std::string plot = config.pngDir + "/species_counts.png";
        plotSpeciesCountsPng(plot, record.timeseries, sim.biome(), "Plants per species per year");
        summary.written.push_back(plot);
    }
    outputs.commit();
    summary.wallSeconds = elapsed();
    return summary;
}

}  // namespace eco::sim
