// Command-line tests of `eco` for the abiotics module (split from abiotics_test.cpp, issue 23):
// they run the eco binary (ECO_BINARY) and live in eco_cli_tests, apart from the unit tests.
#include <omp.h>

#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "abiotics.h"
#include "abiotics_fixture.h"
#include "error.h"
#include "geotiff_fixture.h"
#include "h5io.h"
#include "terrain_io.h"
#include "test_util.h"

using namespace eco;

namespace {

using test::makeTerrain;
using test::roughTerrain;
using test::ThreadCountGuard;

}  // namespace

TEST_CASE("abiotics: the eco abiotics command writes the maps and pictures", "[abiotics][cli]") {
    test::TempDir dir("abiotics_cli");
    const std::string terrain = dir.file("terrain.asc");
    writeAsc(terrain, roughTerrain(31, 22, 2.0));
    const std::string out = dir.file("abiotics.h5");
    const std::string png = dir.file("png");
    const auto r = test::runEco("--threads 2 abiotics --terrain '" + terrain + "' --out '" + out + "' --png '" + png +
                                "' --sun-step 30");
    INFO(r.output);
    REQUIRE(r.exitCode == 0);
    REQUIRE(r.output.find(out) != std::string::npos);
    const Abiotics a = readAbiotics(out);
    REQUIRE(a.sunHours[0].width() == 31);
    REQUIRE(a.sunHours[0].height() == 22);
    for (const char* name : {"elevation.png", "slope.png", "wind.png", "sun_01_jan.png", "sun_12_dec.png",
                             "moisture_07_jul.png", "temperature_06_jun.png"})
        REQUIRE(std::filesystem::exists(png + "/" + name));
    REQUIRE(h5::File::openRead(out).attrDouble("/", "sun_step_minutes") == 30.0);
    // The biome's [wind] reaches the map: Sonoma has none (the defaults, 5 m/s from the
    // west); a biome blowing 9 m/s from the east records it and computes its map.
    REQUIRE(h5::File::openRead(out).attrDouble("/", "wind_direction_deg") == 270.0);
    REQUIRE(a.windMS.maxValue() == 5.f);
    const std::string windyBiome = dir.file("windy.toml");
    {
        std::ofstream b(windyBiome);
        b << biomeToToml(defaultBiome()) << "\n[wind]\ndirection_deg = 90\nstrength_m_s = 9\n";
    }
    const std::string windyOut = dir.file("windy.h5");
    const auto rw = test::runEco("--threads 2 abiotics --terrain '" + terrain + "' --out '" + windyOut + "' --biome '" +
                                 windyBiome + "' --sun-step 60");
    INFO(rw.output);
    REQUIRE(rw.exitCode == 0);
    REQUIRE(h5::File::openRead(windyOut).attrDouble("/", "wind_direction_deg") == 90.0);
    Wind east;
    east.directionDeg = 90;
    east.strengthMS = 9;
    REQUIRE(readAbiotics(windyOut).windMS.data() == windSpeedMS(a.elevationM, east).data());
}

TEST_CASE("abiotics: the eco abiotics command rejects bad input with one clear line", "[abiotics][cli]") {
    test::TempDir dir("abiotics_cli_bad");
    const std::string tiny = dir.file("tiny.asc");
    writeAsc(tiny, Grid<float>(2, 2, 1.0, 0, 0, 5.f));
    auto r = test::runEco("abiotics --terrain '" + tiny + "' --out '" + dir.file("a.h5") + "'");
    REQUIRE(r.exitCode == 1);
    REQUIRE(r.output.find("at least 3 x 3") != std::string::npos);
    REQUIRE(r.output.find(tiny) != std::string::npos);
    REQUIRE(!std::filesystem::exists(dir.file("a.h5")));

    r = test::runEco("abiotics --terrain '" + dir.file("nope.asc") + "' --out '" + dir.file("a.h5") + "'");
    REQUIRE(r.exitCode == 1);
    REQUIRE(r.output.find("nope.asc") != std::string::npos);

    r = test::runEco("abiotics --out '" + dir.file("a.h5") + "'");
    REQUIRE(r.exitCode != 0);
    REQUIRE(r.output.find("--terrain") != std::string::npos);

    const std::string ok = dir.file("ok.asc");
    writeAsc(ok, roughTerrain(8, 6, 1.0));
    r = test::runEco("abiotics --terrain '" + ok + "' --out '" + dir.file("a.h5") + "' --sun-step 0");
    REQUIRE(r.exitCode != 0);
    r = test::runEco("abiotics --terrain '" + ok + "' --out '" + dir.file("missing_dir/a.h5") + "'");
    REQUIRE(r.exitCode == 1);
    REQUIRE(r.output.find("missing_dir") != std::string::npos);
}

TEST_CASE("abiotics: a georeferenced terrain far from the biome's latitude is warned about", "[abiotics][cli][geo]") {
    // The sun's path comes from the biome's latitude_deg alone. A DEM in UTM 33N at 6,600 km
    // north (southern Norway, about 59.5 deg) with the embedded Sonoma biome (38.58 deg) had
    // Californian sun maps without a word.
    test::TempDir dir("abiotics_latitude");
    test::GeoTiffSpec s;
    s.width = 8;
    s.height = 6;
    s.geotransform[1] = 10.0;
    s.geotransform[5] = -10.0;
    for (int i = 0; i < s.width * s.height; ++i) s.northFirst.push_back(100.0 + 0.5 * (i % s.width));
    const std::string north = dir.file("norway.tif"), sonoma = dir.file("sonoma.tif");
    s.epsg = 32633;
    s.geotransform[0] = 500000.0;
    s.geotransform[3] = 6600060.0;
    test::writeGeoTiff(north, s);
    s.epsg = 32610;
    s.geotransform[0] = 545000.0;
    s.geotransform[3] = 4270060.0;  // about 38.58 deg north
    test::writeGeoTiff(sonoma, s);

    const auto far = test::runEco("abiotics --terrain " + north + " --out " + dir.file("a.h5"));
    INFO(far.output);
    REQUIRE(far.exitCode == 0);
    CHECK_THAT(far.output, Catch::Contains("warning: terrain '" + north + "' lies at latitude 59.") &&
                               Catch::Contains("latitude_deg 38.58") && Catch::Contains("eco biome show"));
    const auto near = test::runEco("abiotics --terrain " + sonoma + " --out " + dir.file("b.h5"));
    REQUIRE(near.exitCode == 0);
    CHECK_THAT(near.output, !Catch::Contains("warning"));
    // The same check where eco canopy computes the maps itself.
    std::vector<double> heights(static_cast<std::size_t>(s.width * s.height), 20.0);
    test::GeoTiffSpec c = s;
    c.epsg = 32633;
    c.geotransform[0] = 500000.0;
    c.geotransform[3] = 6600060.0;
    c.northFirst = heights;
    test::writeGeoTiff(dir.file("chm.tif"), c);
    const auto canopy = test::runEco("canopy --terrain " + north + " --chm " + dir.file("chm.tif") + " --out " + dir.file("c.h5"));
    INFO(canopy.output);
    CHECK(canopy.exitCode == 0);
    CHECK_THAT(canopy.output, Catch::Contains("lies at latitude 59."));
}
