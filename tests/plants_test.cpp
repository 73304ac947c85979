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
        f.writeF64("/canopy/x", {1.0, 2.0}, {2}, "m");  // lengths now disagree
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

TEST_CASE("undergrowth tables round-trip their state columns, plain readers see plain plants", "[plants]") {
    test::TempDir dir("plants");
    const Biome biome = defaultBiome();
    UndergrowthPlant a;
    a.id = (std::uint64_t{1} << 40) + 7;
    a.speciesId = 2;
    a.xM = 1.25;
    a.yM = 2.5;
    a.groundZM = 3;
    a.heightM = 0.75;
    a.crownRadiusM = 0.3;
    a.ageYears = 4.5;
    a.growthAgeYears = 3.25;
    a.vigour = 0.125;
    a.pool = 0.5;
    a.sunShare = 6.5;
    a.waterShare = 20.25;
    const std::string path = dir.file("u.h5");
    {
        auto f = h5::File::create(path);
        writeUndergrowthPlants(f, "/u", {a}, biome);
        writePlants(f, "/plain", {Plant{1, 5, 6, 7, 8, 9}}, biome);
    }
    auto f = h5::File::openRead(path);
    const auto back = readUndergrowthPlants(f, "/u", biome);
    REQUIRE(back.size() == 1);
    const UndergrowthPlant& b = back[0];
    CHECK(b.id == a.id);
    CHECK(b.speciesId == a.speciesId);
    CHECK((b.xM == a.xM && b.yM == a.yM && b.groundZM == a.groundZM && b.heightM == a.heightM));
    CHECK(b.crownRadiusM == a.crownRadiusM);
    CHECK((b.ageYears == a.ageYears && b.growthAgeYears == a.growthAgeYears && b.vigour == a.vigour));
    CHECK((b.pool == a.pool && b.sunShare == a.sunShare && b.waterShare == a.waterShare));
    const auto plain = readPlants(f, "/u", biome);
    REQUIRE(plain.size() == 1);
    CHECK(plain[0].heightM == a.heightM);
    // A plain plant group reads as undergrowth with the state at zero.
    const auto fromPlain = readUndergrowthPlants(f, "/plain", biome);
    REQUIRE(fromPlain.size() == 1);
    CHECK(fromPlain[0].id == 0);
    CHECK(fromPlain[0].crownRadiusM == 9);
    CHECK(fromPlain[0].pool == 0);
}

TEST_CASE("layered plant CSV: one header with a layer column, the layers in order", "[plants]") {
    test::TempDir dir("plants");
    const Biome biome = defaultBiome();
    const std::vector<Plant> canopy = {{0, 1, 2, 3, 20, 4}}, undergrowth = {{1, 5, 6, 7, 0.5, 0.25}, {2, 8, 9, 1, 1, 0.5}};
    const std::string path = dir.file("layers.csv");
    writePlantLayersCsv(path, {{"canopy", &canopy}, {"undergrowth", &undergrowth}}, biome);
    std::ifstream in(path);
    std::string line;
    std::vector<std::string> lines;
    while (std::getline(in, line)) lines.push_back(line);
    REQUIRE(lines.size() == 4);
    CHECK(lines[0] == "layer,species_id,species,x_m,y_m,ground_z_m,height_m,crown_radius_m");
    CHECK(lines[1].rfind("canopy,0,", 0) == 0);
    CHECK(lines[3].rfind("undergrowth,2,", 0) == 0);
    CHECK(lines[3].find(",8.000,9.000,1.000,1.000,0.500") != std::string::npos);
}
