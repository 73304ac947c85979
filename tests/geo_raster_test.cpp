// Georeferenced rasters through GDAL: geometry, CRS, nodata, scale/offset, refusals, and a
// canopy height model's gaps and negative cells (core/geo_raster.h, core/terrain_io.h).
#include <catch2/catch.hpp>

#include <cmath>
#include <cstdio>
#include <string>

#include "error.h"
#include "geo_raster.h"
#include "geotiff_fixture.h"
#include "terrain_io.h"
#include "test_util.h"

using eco::test::GeoTiffSpec;
using eco::test::TempDir;
using eco::test::writeGeoTiff;

namespace {

// 4 x 3 cells of 0.5 m, the northern row first; -9999 = nodata at (column 2, north row),
// one cell of -0.3 m.
GeoTiffSpec chmSpec() {
    GeoTiffSpec s;
    s.northFirst = {1, 2, -9999, 4,  //
                    5, 6, 7, 8,      //
                    9, -0.3, 11, 12};
    s.hasNodata = true;
    return s;
}

}  // namespace

TEST_CASE("GeoTIFF: geometry from the geotransform, rows south-first, nodata as NaN, CRS", "[geo]") {
    TempDir dir("geo_read");
    const std::string path = dir.file("chm.tif");
    writeGeoTiff(path, chmSpec());
    REQUIRE(eco::hasGeotransform(path));
    const eco::GeoRaster r = eco::readGeoRaster(path);
    CHECK(r.grid.width() == 4);
    CHECK(r.grid.height() == 3);
    CHECK(r.grid.cellSizeM() == 0.5);
    CHECK(r.grid.originX() == 500000.0);
    CHECK(r.grid.originY() == 4200000.0);  // the top edge 4200001.5 less 3 rows of 0.5 m
    CHECK(r.nodataCells == 1);
    CHECK(std::isnan(r.grid(2, 2)));       // the northern row is iy = 2
    CHECK(r.grid(0, 2) == 1.0f);
    CHECK(r.grid(0, 0) == 9.0f);           // the southern row is iy = 0
    CHECK(r.grid(3, 0) == 12.0f);
    CHECK(r.driver == "GTiff");
    CHECK_THAT(r.crsName, Catch::Contains("UTM zone 10N"));
    CHECK_THAT(r.crsWkt, Catch::Contains("32610"));
}

TEST_CASE("GeoTIFF: scale and offset of the band are applied", "[geo]") {
    TempDir dir("geo_scale");
    GeoTiffSpec s;
    s.type = GDT_Int16;
    s.northFirst = {100, 200, 300, 400, 500, 600, 700, 800, 900, 1000, 1100, 1200};
    s.scale = 0.01;
    s.offset = 10;
    const std::string path = dir.file("dem.tif");
    writeGeoTiff(path, s);
    const eco::Grid<float> g = eco::readTerrain(path);  // no --cell-size needed
    CHECK(g.cellSizeM() == 0.5);
    CHECK(g(0, 2) == Approx(11.0));
    CHECK(g(3, 0) == Approx(22.0));
}

TEST_CASE("GeoTIFF terrain: a nodata cell is refused with its position, cell size must agree", "[geo]") {
    TempDir dir("geo_terrain");
    const std::string path = dir.file("dem.tif");
    writeGeoTiff(path, chmSpec());
    CHECK_THROWS_AS(eco::readTerrain(path), eco::IoError);
    CHECK_THROWS_WITH(eco::readTerrain(path), Catch::Contains(path) && Catch::Contains("1 nodata cell") &&
                                                  Catch::Contains("column 2, row 2 from the lower left") &&
                                                  Catch::Contains("x = 500001.25 m, y = 4200001.25 m"));
    GeoTiffSpec ok = chmSpec();
    ok.hasNodata = false;
    ok.northFirst[2] = 3;
    writeGeoTiff(path, ok);
    eco::TerrainReadOptions o;
    o.cellSizeM = 1.0;
    CHECK_THROWS_WITH(eco::readTerrain(path, o), Catch::Contains("wrong cell size") && Catch::Contains("0.5"));
    o.cellSizeM = 0.5;
    CHECK(eco::readTerrain(path, o)(2, 2) == 3.0f);
}

TEST_CASE("GeoTIFF: degrees, rotation and rectangular cells are refused with the fix", "[geo]") {
    TempDir dir("geo_refuse");
    const std::string path = dir.file("x.tif");
    GeoTiffSpec geographic;
    geographic.epsg = 4326;
    geographic.geotransform[0] = -122.5;
    geographic.geotransform[1] = 1e-5;
    geographic.geotransform[3] = 38.3;
    geographic.geotransform[5] = -1e-5;
    writeGeoTiff(path, geographic);
    CHECK_THROWS_AS(eco::readTerrain(path), eco::ValidationError);
    CHECK_THROWS_WITH(eco::readTerrain(path), Catch::Contains("geographic CRS") && Catch::Contains("gdalwarp"));
    GeoTiffSpec rotated;
    rotated.geotransform[2] = 0.1;
    writeGeoTiff(path, rotated);
    CHECK_THROWS_WITH(eco::readTerrain(path), Catch::Contains("rotated"));
    GeoTiffSpec rect;
    rect.geotransform[5] = -1.0;
    writeGeoTiff(path, rect);
    CHECK_THROWS_WITH(eco::readTerrain(path), Catch::Contains("not square") && Catch::Contains("gdalwarp -tr 0.5 0.5"));
    GeoTiffSpec feet;
    feet.epsg = 2227;  // NAD83 / California zone 3 (ftUS)
    writeGeoTiff(path, feet);
    CHECK_THROWS_WITH(eco::readTerrain(path), Catch::Contains("not the metre"));
}

TEST_CASE("CHM: gaps filled from their neighbours or set to 0, negative cells clamped, counted", "[geo]") {
    TempDir dir("geo_chm");
    const std::string path = dir.file("chm.tif");
    writeGeoTiff(path, chmSpec());
    eco::ChmReadOptions o;
    const eco::ChmRead fill = eco::readChm(path, o);
    CHECK(fill.nodataCells == 1);
    CHECK(fill.filledCells == 1);
    CHECK(fill.zeroedCells == 0);
    // Neighbours of (2, 2) before the fill: 2, 4 (north row) and 6, 7, 8 (middle row).
    CHECK(fill.chm(2, 2) == Approx((2.0 + 4 + 6 + 7 + 8) / 5));
    CHECK(fill.negativeCells == 1);
    CHECK(fill.mostNegativeM == Approx(-0.3));
    CHECK(fill.chm(1, 0) == 0.0f);
    CHECK_THAT(fill.summary(path), Catch::Contains("1 nodata cell(s): 1 filled") && Catch::Contains("1 cell(s) below 0 m"));

    o.gaps = eco::ChmGapRule::Zero;
    const eco::ChmRead zero = eco::readChm(path, o);
    CHECK(zero.chm(2, 2) == 0.0f);
    CHECK(zero.zeroedCells == 1);
    CHECK(zero.filledCells == 0);

    o.gaps = eco::ChmGapRule::Fill;
    o.fillMaxM = 0;  // nothing is near enough: left as non-forest
    CHECK(eco::readChm(path, o).zeroedCells == 1);

    o.gaps = eco::ChmGapRule::Fail;
    CHECK_THROWS_WITH(eco::readChm(path, o), Catch::Contains("nodata") && Catch::Contains("column 2, row 2"));
    CHECK(eco::parseChmGapRule("zero", "--chm-gaps") == eco::ChmGapRule::Zero);
    CHECK_THROWS_WITH(eco::parseChmGapRule("smooth", "--chm-gaps"), Catch::Contains("--chm-gaps") && Catch::Contains("smooth"));
}

TEST_CASE("CHM: a wide gap is filled only near the data, an .asc NODATA cell is a gap too", "[geo]") {
    TempDir dir("geo_gap");
    GeoTiffSpec s;
    s.width = 7;
    s.height = 1;
    s.geotransform[1] = 1.0;
    s.geotransform[5] = -1.0;
    s.northFirst = {10, -9999, -9999, -9999, -9999, -9999, 20};
    s.hasNodata = true;
    const std::string path = dir.file("gap.tif");
    writeGeoTiff(path, s);
    eco::ChmReadOptions o;
    o.fillMaxM = 2.0;  // two rings of 1 m cells from each side
    const eco::ChmRead r = eco::readChm(path, o);
    CHECK(r.filledCells == 4);
    CHECK(r.zeroedCells == 1);
    CHECK(r.chm(1, 0) == 10.0f);
    CHECK(r.chm(2, 0) == 10.0f);
    CHECK(r.chm(3, 0) == 0.0f);
    CHECK(r.chm(5, 0) == 20.0f);

    const std::string asc = dir.file("gap.asc");
    {
        std::FILE* f = std::fopen(asc.c_str(), "w");
        std::fputs("ncols 3\nnrows 1\nxllcorner 0\nyllcorner 0\ncellsize 1\nNODATA_value -9999\n4 -9999 8\n", f);
        std::fclose(f);
    }
    const eco::ChmRead a = eco::readChm(asc);
    CHECK(a.nodataCells == 1);
    CHECK(a.chm(1, 0) == 6.0f);
}

TEST_CASE("CRS: the same system matches however written, two different ones are refused by name", "[geo]") {
    TempDir dir("geo_crs");
    const std::string utm10 = dir.file("utm10.tif"), utm11 = dir.file("utm11.tif"), none = dir.file("none.asc");
    writeGeoTiff(utm10, GeoTiffSpec{});
    GeoTiffSpec other;
    other.epsg = 32611;  // WGS 84 / UTM zone 11N
    writeGeoTiff(utm11, other);
    {
        std::FILE* f = std::fopen(none.c_str(), "w");
        std::fputs("ncols 1\nnrows 1\nxllcorner 0\nyllcorner 0\ncellsize 1\n5\n", f);
        std::fclose(f);
    }
    const std::string wkt = eco::rasterCrsWkt(utm10);
    CHECK_THAT(wkt, Catch::Contains("UTM zone 10N"));
    CHECK(eco::rasterCrsWkt(none).empty());
    CHECK(eco::sameCrs(wkt, eco::rasterCrsWkt(utm10)));
    CHECK_FALSE(eco::sameCrs(wkt, eco::rasterCrsWkt(utm11)));
    CHECK_FALSE(eco::sameCrs(wkt, ""));
    CHECK_NOTHROW(eco::requireSameCrs(utm10, utm10));
    CHECK_NOTHROW(eco::requireSameCrs(utm10, none));  // no CRS: nothing to compare
    CHECK_THROWS_AS(eco::requireSameCrs(utm10, utm11), eco::ValidationError);
    CHECK_THROWS_WITH(eco::requireSameCrs(utm10, utm11), Catch::Contains("UTM zone 10N") && Catch::Contains("UTM zone 11N") &&
                                                             Catch::Contains("gdalwarp"));
}

TEST_CASE("CHM: a raster with no data at all is refused, whatever the gap rule", "[geo]") {
    // A lidar CHM read with the wrong nodata value or band is all gaps: "filled" to 0 m it
    // would give a canopy of no trees with coverage 1 and exit 0.
    TempDir dir("geo_allgap");
    GeoTiffSpec s = chmSpec();
    s.northFirst.assign(12, -9999);
    const std::string path = dir.file("empty.tif");
    writeGeoTiff(path, s);
    for (eco::ChmGapRule rule : {eco::ChmGapRule::Fill, eco::ChmGapRule::Zero, eco::ChmGapRule::Fail}) {
        eco::ChmReadOptions o;
        o.gaps = rule;
        CHECK_THROWS_AS(eco::readChm(path, o), eco::IoError);
        CHECK_THROWS_WITH(eco::readChm(path, o), Catch::Contains("empty.tif") && Catch::Contains("every cell (12) is nodata"));
    }
    const std::string asc = dir.file("empty.asc");
    {
        std::FILE* f = std::fopen(asc.c_str(), "w");
        std::fputs("ncols 3\nnrows 1\nxllcorner 0\nyllcorner 0\ncellsize 1\nNODATA_value -9999\n-9999 -9999 -9999\n", f);
        std::fclose(f);
    }
    CHECK_THROWS_WITH(eco::readChm(asc), Catch::Contains("every cell (3) is nodata"));
    // One cell of data is enough.
    s.northFirst[5] = 12;
    writeGeoTiff(path, s);
    CHECK(eco::readChm(path).nodataCells == 11);
}
