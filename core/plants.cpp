#include "plants.h"

#include <cmath>
#include <cstdio>
#include <fstream>

#include "atomic_file.h"
#include "error.h"

namespace eco {

void writePlants(h5::File& file, const std::string& group, const std::vector<Plant>& plants,
                 const Biome& biome) {
    const hsize_t n = plants.size();
    std::vector<std::int32_t> sp(n);
    std::vector<double> x(n), y(n), z(n), h(n), r(n);
    for (std::size_t i = 0; i < plants.size(); ++i) {
        sp[i] = plants[i].speciesId;
        x[i] = plants[i].xM;
        y[i] = plants[i].yM;
        z[i] = plants[i].groundZM;
        h[i] = plants[i].heightM;
        r[i] = plants[i].crownRadiusM;
    }
    file.ensureGroup(group);
    file.writeI32(group + "/species_id", sp, {n});
    file.writeF64(group + "/x", x, {n});
    file.writeF64(group + "/y", y, {n});
    file.writeF64(group + "/ground_z", z, {n});
    file.writeF64(group + "/height", h, {n});
    file.writeF64(group + "/crown_radius", r, {n});
    std::vector<std::string> names;
    for (const auto& s : biome.species) names.push_back(s.name);
    file.writeStrings(group + "/species_names", names);
    file.setAttr(group, "count", static_cast<std::int64_t>(n));
    file.setAttr(group, "units", std::string("m"));
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

void writePlantsCsv(const std::string& path, const std::vector<Plant>& plants, const Biome& biome,
                    const std::string& layer) {
    AtomicOutput out(path);
    {
        std::FILE* f = std::fopen(out.tempPath().c_str(), "w");
        if (!f) throw IoError(path + ": cannot write CSV");
        std::fprintf(f, "%sspecies_id,species,x_m,y_m,ground_z_m,height_m,crown_radius_m\n", layer.empty() ? "" : "layer,");
        for (const auto& p : plants) {
            if (!layer.empty()) std::fprintf(f, "%s,", layer.c_str());
            std::fprintf(f, "%d,\"%s\",%.3f,%.3f,%.3f,%.3f,%.3f\n", p.speciesId,
                         biome.species[static_cast<std::size_t>(p.speciesId)].name.c_str(), p.xM, p.yM, p.groundZM,
                         p.heightM, p.crownRadiusM);
        }
        if (std::fclose(f) != 0) throw IoError(path + ": error while writing CSV");
    }
    out.commit();
}

}  // namespace eco
