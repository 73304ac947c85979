// A small simulation file for the tests of reading simulations (analysis_test.cpp) and of
// `eco analyse` / `eco inspect` (analysis_cli_test.cpp); a file of snapshots only for the
// outputs of parameter studies (sensitivity_test.cpp, calibrate_test.cpp).
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "abiotics.h"
#include "abiotics_fixture.h"
#include "biome.h"
#include "h5io.h"
#include "plants.h"
#include "rng.h"
#include "sim_file.h"

namespace eco::test {

/// A small simulation file in the layout of `eco simulate` (docs/simulator.md), with its
/// abiotics file; `omit` leaves out one dataset or attribute.
inline void writeFakeSimulation(const std::string& simPath, const std::string& abioticsPath, const std::string& omit = "") {
    static const Biome biome = defaultBiome();
    auto plant = [&](const std::string& species, double x, double y, double hM, double rM) {
        Plant p;
        p.speciesId = biome.speciesIndex(species);
        p.xM = x;
        p.yM = y;
        p.heightM = hM;
        p.crownRadiusM = rM;
        return p;
    };
    const int w = 50, h = 40;
    Abiotics ab = uniformAbiotics(Grid<float>(w, h, 1.0, 1000, 2000, 0.f), 100,
                                  {{Factor::Temperature, 15}, {Factor::Slope, 3}, {Factor::Wind, 4}});
    for (int m = 0; m < 12; ++m) {
        ab.sunHours[m].fill(static_cast<float>(8 + m % 3));
        for (int iy = 0; iy < h; ++iy)
            for (int ix = 0; ix < w; ++ix) ab.moistureMm[m](ix, iy) = ix < 25 ? 160.f : 60.f;
    }
    writeAbiotics(abioticsPath, ab, biome, AbioticParams{});

    h5::File f = h5::File::create(simPath);
    f.setAttr("/", "format", std::string(kSimulationFormat));
    f.setAttr("/", "schema_version", static_cast<std::int64_t>(kSimulationSchemaVersion));
    f.setAttr("/", "seed", static_cast<std::int64_t>(42));
    f.setAttr("/", "biome_toml", biomeToToml(biome));
    f.setAttr("/", "x0", 1000.0);
    f.setAttr("/", "y0", 2000.0);
    f.setAttr("/", "x1", 1050.0);
    f.setAttr("/", "y1", 2040.0);
    f.setAttr("/", "seed_outer_radius_factor", 12.0);
    f.setAttr("/", "abiotics_path", std::filesystem::path(abioticsPath).filename().string());  // relative: beside the file
    f.setAttr("/", "model_toml", std::string("[model]\ncell_size_m = 0.2\n"));
    std::vector<Plant> canopy = {plant("Redwood", 1012, 2020, 60, 3), plant("Coast Live Oak", 1040, 2020, 20, 3)};
    RandomStream rng(5, 5);
    std::vector<Plant> early, late;
    for (int i = 0; i < 1500; ++i) {
        const char* name = i % 2 ? "Redwood Sorrel" : "Toyon";
        late.push_back(plant(name, rng.uniform(1000, 1050), rng.uniform(2000, 2040), 0.2, 0.3));
        if (i < 100) early.push_back(late.back());
    }
    if (omit != "/snapshots") {
        writePlants(f, "/snapshots/year_0001", early, biome);
        writePlants(f, "/snapshots/year_0010", late, biome);
        if (omit == "x") {  // a snapshot whose /x dataset is missing
            f.ensureGroup("/snapshots/year_0020");
            f.writeI32("/snapshots/year_0020/species_id", {0}, {1}, "1");
        }
    }
    if (omit != "/canopy") writePlants(f, "/canopy", canopy, biome);
}

/// A simulation file of the 20 m square (0, 0)-(20, 20) holding `snapshots` (year, plants)
/// and an empty census of the years 0 .. `years`, no canopy.
inline void writeSnapshotSimulation(const std::string& path, const Biome& biome, int years, const SnapshotList& snapshots) {
    SimulationFileInfo info;
    info.years = years;
    info.x0 = info.y0 = 0;
    info.x1 = info.y1 = 20;
    std::vector<YearRecord> series;
    for (int year = 0; year <= years; ++year) {
        YearRecord r;
        r.year = year;
        r.count.assign(biome.species.size(), 0);
        r.meanHeightM.assign(biome.species.size(), 0);
        r.meanVigour.assign(biome.species.size(), 0);
        r.crownAreaM2.assign(biome.species.size(), 0);
        series.push_back(r);
    }
    writeSimulationFile(path, info, biome, snapshots, series, {});
}

}  // namespace eco::test
