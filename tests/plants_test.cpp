// Plant lists in HDF5 and CSV (core/plants.h).
#include <catch2/catch.hpp>

#include <fstream>

#include "error.h"
#include "plants.h"
#include "test_util.h"

using namespace eco;

TEST_CASE("plants round-trip through HDF5 and map species by name", "[plants]") {
    test::TempDir dir("plants");
    const Biome biome = defaultBiome();
    const std::vector<Plant> plants = {{biome.speciesIndex("Redwood"), 10.5, 20.25, 100.0, 60.0, 5.5},
                                       {biome.speciesIndex("Douglas-Fir"), 30.0, 5.0, 90.0, 40.0, 4.0}};
    const std::string path = dir.file("c.h5");
    {
        auto f = h5::File::create(path);
        writePlants(f, "/canopy", plants, biome);
    }
    auto f = h5::File::openRead(path);
    const auto back = readPlants(f, "/canopy", biome);
    REQUIRE(back.size() == 2);
    CHECK(back[1].speciesId == plants[1].speciesId);
    CHECK(back[0].xM == 10.5);
    CHECK(back[0].yM == 20.25);
    CHECK(back[1].crownRadiusM == 4.0);

    // A biome with the species in another order still reads the right species.
    Biome reordered = biome;
    std::swap(reordered.species.front(), reordered.species.back());
    for (std::size_t i = 0; i < reordered.species.size(); ++i) reordered.species[i].id = static_cast<int>(i);
    const auto mapped = readPlants(f, "/canopy", reordered);
    CHECK(reordered.species[static_cast<std::size_t>(mapped[0].speciesId)].name == "Redwood");
}

TEST_CASE("plant files with problems are refused with the dataset named", "[plants]") {
    test::TempDir dir("plants");
    const Biome biome = defaultBiome();
    const std::string path = dir.file("bad.h5");
    {
        auto f = h5::File::create(path);
        writePlants(f, "/canopy", {{0, 1, 1, 0, 1, 1}}, biome);
        f.writeF64("/canopy/x", {1.0, 2.0}, {2});  // lengths now disagree
        writePlants(f, "/other", {{0, 1, 1, 0, 1, 1}}, biome);
        f.writeStrings("/other/species_names", {"Unknown Tree"});
    }
    auto f = h5::File::openRead(path);
    CHECK_THROWS_WITH(readPlants(f, "/canopy", biome), Catch::Contains("bad.h5") && Catch::Contains("differ in length"));
    CHECK_THROWS_WITH(readPlants(f, "/other", biome), Catch::Contains("Unknown Tree"));
    CHECK_THROWS_WITH(readPlants(f, "/missing", biome), Catch::Contains("/missing"));
}

TEST_CASE("plants CSV has a header and one row per plant", "[plants]") {
    test::TempDir dir("plants");
    const Biome biome = defaultBiome();
    const std::string path = dir.file("p.csv");
    writePlantsCsv(path, {{0, 1, 2, 3, 0.2, 0.8}, {3, 4, 5, 6, 1.0, 0.5}}, biome, "undergrowth");
    std::ifstream in(path);
    std::string header, row;
    std::getline(in, header);
    CHECK(header == "layer,species_id,species,x_m,y_m,ground_z_m,height_m,crown_radius_m");
    std::getline(in, row);
    CHECK(row == "undergrowth,0,\"Redwood Sorrel\",1.000,2.000,3.000,0.200,0.800");
}
