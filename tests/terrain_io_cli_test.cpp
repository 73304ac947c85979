// Command-line tests of `eco` for the terrain_io module (split from terrain_io_test.cpp, issue 23):
// they run the eco binary (ECO_BINARY) and live in eco_cli_tests, apart from the unit tests.
#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>

#include "geo_raster.h"
#include "geotiff_fixture.h"
#include "error.h"
#include "h5io.h"
#include "terrain_fixture.h"
#include "terrain_io.h"
#include "test_util.h"

using eco::Grid;
using eco::test::TempDir;
using eco::test::leftovers;
using eco::test::sampleTerrain;

TEST_CASE("terrain: CLI convert between formats", "[terrain]") {
    TempDir dir("tio_cli");
    const Grid<float> g = sampleTerrain();
    const std::string asc = dir.file("in.asc");
    eco::writeTerrain(asc, g);
    const std::string h5 = dir.file("out.h5");
    auto r = eco::test::runEco("terrain convert " + asc + " " + h5);
    INFO(r.output);
    REQUIRE(r.exitCode == 0);
    CHECK(r.output.find(h5) != std::string::npos);
    CHECK(eco::readTerrain(h5).data() == g.data());

    // To PNG: the scale is chosen and printed, and reading with it gives the terrain back.
    const std::string png = dir.file("out.png");
    r = eco::test::runEco("terrain convert " + h5 + " " + png);
    REQUIRE(r.exitCode == 0);
    const auto at = r.output.find("--vertical-scale ");
    REQUIRE(at != std::string::npos);
    const double scale = std::stod(r.output.substr(at + 17));
    CHECK(scale >= g.maxValue());
    eco::TerrainReadOptions ro;
    ro.cellSizeM = g.cellSizeM();
    ro.verticalScale = scale;
    const Grid<float> back = eco::readTerrain(png, ro);
    for (std::size_t i = 0; i < g.size(); ++i) REQUIRE(back.data()[i] == Approx(g.data()[i]).margin(scale / 65535));

    // Back from PNG needs the cell size.
    r = eco::test::runEco("terrain convert " + png + " " + dir.file("again.asc"));
    CHECK(r.exitCode == 1);
    CHECK(r.output.find("--cell-size") != std::string::npos);
    CHECK_FALSE(std::filesystem::exists(dir.file("again.asc")));
}

TEST_CASE("terrain: CLI convert of a missing file fails with one line and no output", "[terrain]") {
    TempDir dir("tio_cli_missing");
    const std::string in = dir.file("does_not_exist.asc");
    const std::string out = dir.file("out.h5");
    const auto r = eco::test::runEco("terrain convert " + in + " " + out);
    CHECK(r.exitCode != 0);
    CHECK(r.exitCode == 1);
    CHECK(r.output.find(in) != std::string::npos);
    CHECK(r.output.rfind("eco: error: ", 0) == 0);
    CHECK(std::count(r.output.begin(), r.output.end(), '\n') == 1);
    CHECK_FALSE(std::filesystem::exists(out));
    CHECK(std::filesystem::is_empty(dir.path()));

    // Conflicting cell size through the CLI: same shape of failure.
    const std::string asc = dir.file("t.asc");
    eco::writeTerrain(asc, sampleTerrain());
    const auto c = eco::test::runEco("terrain convert " + asc + " " + out + " --cell-size 3");
    CHECK(c.exitCode == 1);
    CHECK(c.output.find("wrong cell size") != std::string::npos);
    CHECK_FALSE(std::filesystem::exists(out));
    CHECK_FALSE(leftovers(dir));
}

TEST_CASE("eco terrain convert: a GeoTIFF stays a GeoTIFF with its geotransform and CRS", "[terrain][cli][geo]") {
    eco::test::TempDir dir("geo_convert");
    eco::test::GeoTiffSpec s;
    s.width = 6;
    s.height = 4;
    s.geotransform[3] = 4200002.0;  // top edge: 4 rows of 0.5 m above 4200000
    for (int i = 0; i < 24; ++i) s.northFirst.push_back(100.0 + 0.25 * i);
    const std::string in = dir.file("dem.tif"), out = dir.file("copy.tif"), asc = dir.file("copy.asc");
    eco::test::writeGeoTiff(in, s);
    const auto r = eco::test::runEco("terrain convert " + in + " " + out);
    INFO(r.output);
    REQUIRE(r.exitCode == 0);
    CHECK_THAT(r.output, Catch::Contains("GeoTIFF, the input's CRS"));
    const eco::GeoRaster a = eco::readGeoRaster(in), b = eco::readGeoRaster(out);
    CHECK(b.grid.sameGeometry(a.grid));
    CHECK(b.grid.originY() == 4200000.0);
    CHECK(eco::sameCrs(a.crsWkt, b.crsWkt));
    CHECK(b.grid.data() == a.grid.data());
    // Through an .asc (no CRS) the geometry and values survive too.
    REQUIRE(eco::test::runEco("terrain convert " + out + " " + asc).exitCode == 0);
    const eco::Grid<float> g = eco::readTerrain(asc);
    CHECK(g.sameGeometry(a.grid));
    CHECK(g(5, 3) == a.grid(5, 3));
}

TEST_CASE("eco chm generate on a GeoTIFF terrain: a .tif CHM is a GeoTIFF on its cells, a format without a CRS warns",
          "[terrain][cli][geo]") {
    // Before: chm.tif was a plain TIFF (origin 0, no cell size, no CRS), which eco canopy
    // refused next to the terrain it was made from ("an image terrain has no cell size").
    eco::test::TempDir dir("geo_chm_generate");
    eco::test::GeoTiffSpec s;
    s.width = 40;
    s.height = 30;
    s.geotransform[1] = 1.0;
    s.geotransform[5] = -1.0;
    s.geotransform[3] = 4200030.0;
    for (int i = 0; i < s.width * s.height; ++i) s.northFirst.push_back(100.0 + 0.01 * i);
    const std::string dem = dir.file("dem.tif"), chm = dir.file("chm.tif"), asc = dir.file("chm.asc");
    eco::test::writeGeoTiff(dem, s);
    const auto r = eco::test::runEco("chm generate --terrain " + dem + " --out " + chm);
    INFO(r.output);
    REQUIRE(r.exitCode == 0);
    CHECK_THAT(r.output, Catch::Contains("GeoTIFF, the terrain's CRS"));
    const eco::GeoRaster d = eco::readGeoRaster(dem), c = eco::readGeoRaster(chm);
    CHECK(c.grid.sameGeometry(d.grid));
    CHECK(eco::sameCrs(c.crsWkt, d.crsWkt));
    const auto canopy = eco::test::runEco("--quiet canopy --terrain " + dem + " --chm " + chm + " --out " + dir.file("canopy.h5"));
    INFO(canopy.output);
    CHECK(canopy.exitCode == 0);

    // An .asc keeps the geometry but cannot hold the CRS: said, not silently dropped.
    const auto a = eco::test::runEco("chm generate --terrain " + dem + " --out " + asc);
    REQUIRE(a.exitCode == 0);
    CHECK_THAT(a.output, Catch::Contains("warning: " + asc + ": an ESRI ASCII grid stores no CRS") &&
                             Catch::Contains("UTM zone 10N"));
    CHECK(eco::readTerrain(asc).sameGeometry(d.grid));
    const auto conv = eco::test::runEco("terrain convert " + dem + " " + dir.file("dem.asc"));
    REQUIRE(conv.exitCode == 0);
    CHECK_THAT(conv.output, Catch::Contains("stores no CRS, so WGS 84 / UTM zone 10N is not in the file"));
    // A terrain with no CRS has nothing to lose: no warning.
    const auto plain = eco::test::runEco("terrain convert " + asc + " " + dir.file("again.asc"));
    REQUIRE(plain.exitCode == 0);
    CHECK_THAT(plain.output, !Catch::Contains("warning"));
}
