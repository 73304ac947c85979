#include "plants.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>

#include "atomic_file.h"
#include "error.h"
#include "text_format.h"
#include "provenance.h"

namespace eco {

namespace {

// A float64 column of a plant table: its dataset name, the field it stores and its units.
template <typename P>
struct PlantColumn {
    const char* name;
    double P::*field;
    const char* units;
};

// The position and size columns every plant table has, in file order (after species_id).
template <typename P>
constexpr PlantColumn<P> kPlantColumns[] = {{"x", &P::xM, "m"},
                                            {"y", &P::yM, "m"},
                                            {"ground_z", &P::groundZM, "m"},
                                            {"height", &P::heightM, "m"},
                                            {"crown_radius", &P::crownRadiusM, "m"}};

// The state columns of an undergrowth table, in file order (after the id column).
constexpr PlantColumn<UndergrowthPlant> kStateColumns[] = {{"age", &UndergrowthPlant::ageYears, "years"},
                                                          {"growth_age", &UndergrowthPlant::growthAgeYears, "years"},
                                                          {"vigour", &UndergrowthPlant::vigour, "1"},
                                                          {"pool", &UndergrowthPlant::pool, "1"},
                                                          {"sun_share", &UndergrowthPlant::sunShare, "hours/day"},
                                                          {"water_share", &UndergrowthPlant::waterShare, "mm/month"}};

template <typename P, std::size_t N>
void writeColumns(h5::File& file, const std::string& group, const std::vector<P>& plants, const PlantColumn<P> (&columns)[N]) {
    const hsize_t n = plants.size();
    std::vector<double> v(n);
    for (const PlantColumn<P>& c : columns) {
        for (std::size_t i = 0; i < plants.size(); ++i) v[i] = plants[i].*c.field;
        file.writeF64(group + "/" + c.name, v, {n}, c.units);
    }
}

// The plant table of any plant type with the Plant fields: species_id, the plant columns,
// species_names and the group's attributes.
template <typename P>
void writePlantTable(h5::File& file, const std::string& group, const std::vector<P>& plants, const Biome& biome) {
    const hsize_t n = plants.size();
    std::vector<std::int32_t> sp(n);
    for (std::size_t i = 0; i < plants.size(); ++i) sp[i] = plants[i].speciesId;
    file.ensureGroup(group);
    file.writeI32(group + "/species_id", sp, {n}, "1");
    writeColumns(file, group, plants, kPlantColumns<P>);
    std::vector<std::string> names;
    for (const auto& s : biome.species) names.push_back(s.name);
    file.writeStrings(group + "/species_names", names);
    file.setAttr(group, "count", static_cast<std::int64_t>(n));
    file.setAttr(group, "units", std::string("m"));
}

}  // namespace

void writePlants(h5::File& file, const std::string& group, const std::vector<Plant>& plants,
                 const Biome& biome) {
    writePlantTable(file, group, plants, biome);
}

void writeUndergrowthPlants(h5::File& file, const std::string& group, const std::vector<UndergrowthPlant>& plants,
                            const Biome& biome) {
    writePlantTable(file, group, plants, biome);
    const hsize_t n = plants.size();
    std::vector<std::int64_t> id(n);
    for (std::size_t i = 0; i < n; ++i) id[i] = static_cast<std::int64_t>(plants[i].id);
    file.writeI64(group + "/id", id, {n}, "1");
    writeColumns(file, group, plants, kStateColumns);
}

std::vector<Plant> readPlants(const h5::File& file, const std::string& group, const Biome& biome) {
    const std::string where = file.path() + ": " + group;
    if (!file.exists(group)) throw IoError(where + ": plant group is missing");
    const auto sp = file.readI32(group + "/species_id");
    const auto x = file.readF64(group + "/x");
    const auto y = file.readF64(group + "/y");
    const auto z = file.readF64(group + "/ground_z");
    const auto h = file.readF64(group + "/height");
    const auto r = file.readF64(group + "/crown_radius");
    const auto names = file.readStrings(group + "/species_names");
    const std::size_t n = sp.size();
    for (const auto* v : {&x, &y, &z, &h, &r})
        if (v->size() != n) throw IoError(where + ": plant arrays differ in length (species_id has " + std::to_string(n) + ")");
    // Map the file's species onto the biome by name.
    std::vector<int> remap(names.size(), -1);
    for (std::size_t i = 0; i < names.size(); ++i) {
        for (const auto& s : biome.species)
            if (s.name == names[i]) remap[i] = s.id;
    }
    std::vector<Plant> out(n);
    for (std::size_t i = 0; i < n; ++i) {
        const int id = sp[i];
        if (id < 0 || static_cast<std::size_t>(id) >= names.size())
            throw ValidationError(where + "/species_id: plant " + std::to_string(i) + " has species id " + std::to_string(id) +
                                  " outside the species_names list");
        if (remap[static_cast<std::size_t>(id)] < 0)
            throw ValidationError(where + ": species '" + names[static_cast<std::size_t>(id)] + "' (plant " + std::to_string(i) +
                                  ") is not in biome '" + biome.name + "'");
        if (!std::isfinite(x[i]) || !std::isfinite(y[i]) || !std::isfinite(z[i]) || !std::isfinite(h[i]) ||
            !std::isfinite(r[i]) || h[i] < 0 || r[i] < 0)
            throw ValidationError(where + ": plant " + std::to_string(i) + " has a non-finite or negative value");
        out[i] = Plant{remap[static_cast<std::size_t>(id)], x[i], y[i], z[i], h[i], r[i]};
    }
    return out;
}

std::vector<UndergrowthPlant> readUndergrowthPlants(const h5::File& file, const std::string& group, const Biome& biome) {
    const auto basic = readPlants(file, group, biome);
    std::vector<UndergrowthPlant> out(basic.size());
    for (std::size_t i = 0; i < basic.size(); ++i) {
        UndergrowthPlant& p = out[i];
        p.speciesId = basic[i].speciesId;
        p.xM = basic[i].xM;
        p.yM = basic[i].yM;
        p.groundZM = basic[i].groundZM;
        p.heightM = basic[i].heightM;
        p.crownRadiusM = basic[i].crownRadiusM;
    }
    auto optional = [&](const char* name) {
        std::vector<double> v;
        if (file.exists(group + "/" + name)) {
            v = file.readF64(group + "/" + name);
            if (v.size() != basic.size())
                throw IoError(file.path() + ": " + group + "/" + name + ": length differs from species_id");
        }
        return v;
    };
    // Ids: int64 since typed HDF5 (issue 31), float64 (exact below 2^53) before.
    if (file.exists(group + "/id") && file.isIntegerDataset(group + "/id")) {
        const auto id = file.readI64(group + "/id");
        if (id.size() != basic.size()) throw IoError(file.path() + ": " + group + "/id: length differs from species_id");
        for (std::size_t i = 0; i < id.size(); ++i) out[i].id = static_cast<std::uint64_t>(id[i]);
    } else {
        const auto id = optional("id");
        for (std::size_t i = 0; i < id.size(); ++i) out[i].id = static_cast<std::uint64_t>(id[i]);
    }
    for (const PlantColumn<UndergrowthPlant>& c : kStateColumns) {
        const auto v = optional(c.name);
        for (std::size_t i = 0; i < v.size(); ++i) out[i].*c.field = v[i];
    }
    return out;
}

namespace {

// Opens a CSV for writing into the temporary file of `out`, runs write(FILE*) and closes it.
template <typename F>
void writeCsv(const std::string& path, F&& write) {
    AtomicOutput out(path);
    {
        std::FILE* f = std::fopen(out.tempPath().c_str(), "w");
        if (!f) throw IoError(path + ": cannot write CSV");
        write(f);
        if (std::fclose(f) != 0) throw IoError(path + ": error while writing CSV");
    }
    out.commit();
}

constexpr const char* kPlantCsvHeader = "species_id,species,x_m,y_m,ground_z_m,height_m,crown_radius_m";

void writePlantCsvRow(std::FILE* f, const Plant& p, const Biome& biome) {
    std::fprintf(f, "%d,\"%s\",%.3f,%.3f,%.3f,%.3f,%.3f\n", p.speciesId,
                 biome.species.at(static_cast<std::size_t>(p.speciesId)).name.c_str(), p.xM, p.yM, p.groundZM, p.heightM,
                 p.crownRadiusM);
}

}  // namespace

void writePlantsCsv(const std::string& path, const std::vector<Plant>& plants, const Biome& biome,
                    const std::string& layer) {
    if (!layer.empty()) return writePlantLayersCsv(path, {{layer, &plants}}, biome);
    writeCsv(path, [&](std::FILE* f) {
        std::fprintf(f, "%s\n", kPlantCsvHeader);
        for (const auto& p : plants) writePlantCsvRow(f, p, biome);
    });
}

void writePlantLayersCsv(const std::string& path, const std::vector<PlantLayer>& layers, const Biome& biome) {
    writeCsv(path, [&](std::FILE* f) {
        std::fprintf(f, "layer,%s\n", kPlantCsvHeader);
        for (const PlantLayer& layer : layers)
            for (const Plant& p : *layer.plants) {
                std::fprintf(f, "%s,", layer.name.c_str());
                writePlantCsvRow(f, p, biome);
            }
    });
}

void writeUndergrowthCsv(const std::string& path, const std::vector<UndergrowthPlant>& plants, const Biome& biome) {
    writeCsv(path, [&](std::FILE* f) {
        std::fprintf(f, "%s,id,age_years,growth_age_years,vigour,pool\n", kPlantCsvHeader);
        for (const auto& p : plants)
            std::fprintf(f, "%d,\"%s\",%.4f,%.4f,%.3f,%.5f,%.5f,%llu,%.4f,%.6f,%.6f,%.6f\n", p.speciesId,
                         biome.species.at(static_cast<std::size_t>(p.speciesId)).name.c_str(), p.xM, p.yM, p.groundZM,
                         p.heightM, p.crownRadiusM, static_cast<unsigned long long>(p.id), p.ageYears, p.growthAgeYears,
                         p.vigour, p.pool);
    });
}

std::vector<Plant> readPlantsCsv(const std::string& path, const Biome& biome, const std::string& layer) {
    std::ifstream in(path);
    if (!in) throw IoError(path + ": cannot open file (missing or unreadable)");
    noteInputFile(path);  // recorded in /provenance with its hash
    std::string line;
    std::vector<std::string> fields;
    int lineNo = 0;
    int cx = -1, cy = -1, cs = -1, ch = -1, cr = -1, cz = -1, cl = -1;
    std::size_t nFields = 0;
    bool header = false;
    while (std::getline(in, line)) {
        ++lineNo;
        const std::string t = trimmedText(line);
        if (t.empty() || t[0] == '#') continue;
        if (!splitCsvLine(line, fields)) throw IoError(path + ":" + std::to_string(lineNo) + ": unterminated quote in the header");
        for (std::size_t i = 0; i < fields.size(); ++i) {
            std::string h = fields[i];
            std::transform(h.begin(), h.end(), h.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
            const int c = static_cast<int>(i);
            if ((h == "x" || h == "x_m") && cx < 0) cx = c;
            else if ((h == "y" || h == "y_m") && cy < 0) cy = c;
            else if (h == "species" && cs < 0) cs = c;
            else if ((h == "height" || h == "height_m") && ch < 0) ch = c;
            else if ((h == "crown_radius" || h == "crown_radius_m") && cr < 0) cr = c;
            else if ((h == "ground_z" || h == "ground_z_m") && cz < 0) cz = c;
            else if (h == "layer" && cl < 0) cl = c;
        }
        nFields = fields.size();
        header = true;
        break;
    }
    if (!header) throw IoError(path + ": no header line (the file is empty)");
    const std::pair<int, const char*> required[] = {
        {cx, "x (or x_m)"}, {cy, "y (or y_m)"}, {cs, "species"}, {ch, "height (or height_m)"}, {cr, "crown_radius (or crown_radius_m)"}};
    for (const auto& [col, name] : required)
        if (col < 0)
            throw IoError(path + ":" + std::to_string(lineNo) + ": the header has no column " + name +
                          " (a plant CSV needs x, y, species, height and crown_radius)");
    std::vector<Plant> plants;
    forEachCsvRow(in, path, lineNo, nFields, [&](const std::vector<std::string>& fields, const std::string& where) {
        if (cl >= 0 && !layer.empty() && fields[static_cast<std::size_t>(cl)] != layer) return;
        Plant p;
        const std::string& name = fields[static_cast<std::size_t>(cs)];
        try {
            p.speciesId = biome.speciesIndex(name);
        } catch (const ValidationError& e) {
            throw IoError(where + "column species: " + e.what());
        }
        p.xM = csvNumber(fields, cx, "x", where);
        p.yM = csvNumber(fields, cy, "y", where);
        p.groundZM = cz >= 0 ? csvNumber(fields, cz, "ground_z", where) : 0.0;
        p.heightM = csvNumber(fields, ch, "height", where);
        p.crownRadiusM = csvNumber(fields, cr, "crown_radius", where);
        if (p.heightM < 0) throw IoError(where + "column height: " + formatNumber(p.heightM) + " is negative");
        if (p.crownRadiusM < 0) throw IoError(where + "column crown_radius: " + formatNumber(p.crownRadiusM) + " is negative");
        plants.push_back(p);
    });
    return plants;
}

}  // namespace eco
