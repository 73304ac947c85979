// The test world of synth_world_fixture.h written as files for the command-line tests
// (synth_cli_test.cpp, kill_test.cpp): terrain, canopy, abiotics and biome database.
#pragma once

#include <string>

#include "abiotics.h"
#include "abiotics_fixture.h"
#include "biome_db.h"
#include "canopy_placer.h"
#include "synth_world_fixture.h"
#include "terrain_io.h"
#include "test_util.h"

namespace eco::test {

/// Files of the world for the command-line tests.
struct WorldFiles {
    std::string terrain, canopy, abiotics, db;
};

inline WorldFiles writeWorld(const World& w, const TempDir& dir) {
    WorldFiles f{dir.file("terrain.h5"), dir.file("canopy.h5"), dir.file("abiotics.h5"), dir.file("db.h5")};
    writeTerrainH5(f.terrain, w.terrain);
    synth::CanopyRecord rec;
    rec.result.trees = w.canopy;
    rec.speciesMap = Grid<std::int32_t>::like(w.terrain, -1);
    rec.chmM = Grid<float>::like(w.terrain, 0.0f);
    rec.terrainM = w.terrain;
    rec.terrainSource = f.terrain;
    synth::writeCanopyFile(f.canopy, rec, w.biome);
    writeAbiotics(f.abiotics, abioticsFrom(w.terrain, w.features), w.biome, AbioticParams{});
    writeBiomeDatabase(f.db, w.db);
    return f;
}

}  // namespace eco::test
