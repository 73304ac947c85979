// Terrain readers and writers: round trips per format and every promised error path.
#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <regex>
#include <string>

#include "error.h"
#include "generate.h"
#include "h5io.h"
#include "terrain_fixture.h"
#include "terrain_io.h"
#include "test_util.h"

using eco::Grid;
using eco::test::TempDir;

namespace {

using eco::test::leftovers;
using eco::test::sampleTerrain;

using eco::test::writeText;

}  // namespace

TEST_CASE("terrain: ESRI ASCII round trip is exact", "[terrain]") {
    TempDir dir("tio_asc");
    const Grid<float> g = sampleTerrain();
    const std::string path = dir.file("t.asc");
    eco::writeTerrain(path, g);
    const Grid<float> r = eco::readTerrain(path);
    CHECK(r.data() == g.data());
    CHECK(r.width() == g.width());
    CHECK(r.height() == g.height());
    CHECK(r.cellSizeM() == g.cellSizeM());
    CHECK(r.originX() == g.originX());
    CHECK(r.originY() == g.originY());
    CHECK_FALSE(leftovers(dir));
    // Consistent --cell-size is accepted.
    eco::TerrainReadOptions ro;
    ro.cellSizeM = 0.914;
    CHECK(eco::readAsc(path, ro).data() == g.data());
}

TEST_CASE("terrain: ESRI ASCII header variants", "[terrain]") {
    TempDir dir("tio_hdr");
    const std::string path = dir.file("c.ASC");
    // Mixed case keys, cell-centre origin, NODATA declared but unused, values over lines.
    writeText(path,
              "NCOLS 3\nNRows 2\nXLLCENTER 1.5\nyllcenter 11.5\nCellSize 1\nNODATA_value -9999\n"
              "1 2\n3\n4 5 6\n");
    const Grid<float> g = eco::readTerrain(path);
    CHECK(g.width() == 3);
    CHECK(g.height() == 2);
    CHECK(g.originX() == 1.0);
    CHECK(g.originY() == 11.0);
    CHECK(g(0, 1) == 1.0f);  // first value: north-west
    CHECK(g(2, 0) == 6.0f);  // last value: south-east
}

TEST_CASE("terrain: 16-bit PNG round trip within quantisation", "[terrain]") {
    TempDir dir("tio_png");
    const Grid<float> g = sampleTerrain();
    const std::string path = dir.file("t.png");
    eco::TerrainWriteOptions wo;
    wo.verticalScale = 400.0;
    wo.verticalOffsetM = -10.0;
    REQUIRE(g.minValue() > -10.0f);
    REQUIRE(g.maxValue() < 390.0f);
    eco::writeTerrain(path, g, wo);
    eco::TerrainReadOptions ro;
    ro.cellSizeM = g.cellSizeM();
    ro.verticalScale = 400.0;
    ro.verticalOffsetM = -10.0;
    ro.originX = g.originX();
    ro.originY = g.originY();
    const Grid<float> r = eco::readTerrain(path, ro);
    REQUIRE(r.sameGeometry(g));
    const double quantum = 400.0 / 65535.0;
    double worst = 0;
    for (std::size_t i = 0; i < g.size(); ++i) worst = std::max(worst, std::abs(double(r.data()[i]) - g.data()[i]));
    CHECK(worst <= 0.5 * quantum + 1e-4);
    CHECK(worst > 0);  // it really was quantised
    CHECK_FALSE(leftovers(dir));
}

TEST_CASE("terrain: PNG clamps values outside [offset, offset + scale]", "[terrain]") {
    TempDir dir("tio_clamp");
    Grid<float> g(4, 3, 1.0);
    g.fill(50.f);
    g(0, 0) = -5.f;
    g(3, 2) = 500.f;
    eco::TerrainWriteOptions wo;
    wo.verticalScale = 100.0;
    eco::writeTerrain(dir.file("c.png"), g, wo);
    eco::TerrainReadOptions ro;
    ro.cellSizeM = 1.0;
    ro.verticalScale = 100.0;
    const Grid<float> r = eco::readTerrain(dir.file("c.png"), ro);
    CHECK(r(0, 0) == 0.0f);
    CHECK(r(3, 2) == 100.0f);
    CHECK(r(1, 1) == Approx(50.0f).margin(100.0 / 65535));
}

TEST_CASE("terrain: a truncated TIFF is an error, not zeros", "[terrain][errors]") {
    // Issue 26: the strips missing from a truncated file came back as 0 m with exit 0.
    TempDir dir("tio_trunc");
    const Grid<float> g = sampleTerrain();
    const std::string whole = dir.file("whole.tif"), cut = dir.file("cut.tif");
    eco::writeTerrain(whole, g);
    const auto size = std::filesystem::file_size(whole);
    {
        std::ifstream in(whole, std::ios::binary);
        std::string bytes(static_cast<std::size_t>(size), '\0');
        in.read(bytes.data(), static_cast<std::streamsize>(size));
        std::ofstream out(cut, std::ios::binary);
        out.write(bytes.data(), static_cast<std::streamsize>(size / 2));
    }
    eco::TerrainReadOptions ro;
    ro.cellSizeM = g.cellSizeM();
    CHECK(eco::readTerrain(whole, ro).data() == g.data());
    CHECK_THROWS_AS(eco::readTerrain(cut, ro), eco::IoError);
    CHECK_THROWS_WITH(eco::readTerrain(cut, ro), Catch::Contains("cut.tif") && Catch::Contains("truncated"));
}

TEST_CASE("terrain: float TIFF and EXR round trips are exact after scaling", "[terrain]") {
    TempDir dir("tio_float");
    const Grid<float> g = sampleTerrain();
    struct Encoding {
        double scale, offset;
        bool exact;  // (z - offset) / scale and back are exact for powers of two and 1
    };
    for (const char* name : {"t.tif", "t.tiff", "t.exr", "T.EXR"})
        for (const Encoding e : {Encoding{1.0, 0.0, true}, Encoding{4.0, 64.0, true}, Encoding{0.3048, 0.0, false}}) {
            INFO(name << " scale " << e.scale << " offset " << e.offset);
            const std::string path = dir.file(name);
            eco::TerrainWriteOptions wo;
            wo.verticalScale = e.scale;
            wo.verticalOffsetM = e.offset;
            eco::writeTerrain(path, g, wo);
            eco::TerrainReadOptions ro;
            ro.cellSizeM = g.cellSizeM();
            ro.verticalScale = e.scale;
            ro.verticalOffsetM = e.offset;
            const Grid<float> r = eco::readTerrain(path, ro);
            REQUIRE(r.width() == g.width());
            REQUIRE(r.height() == g.height());
            CHECK(r.originX() == 0.0);  // images carry no origin we read
            if (e.exact) {
                CHECK(r.data() == g.data());
            } else {
                for (std::size_t i = 0; i < g.size(); ++i) REQUIRE(r.data()[i] == Approx(g.data()[i]).epsilon(1e-6));
            }
        }
    CHECK_FALSE(leftovers(dir));
}

TEST_CASE("terrain: HDF5 round trip is exact, a CHM file reads as /chm/height", "[terrain]") {
    TempDir dir("tio_h5");
    const Grid<float> g = sampleTerrain();
    const std::string path = dir.file("t.h5");
    eco::writeTerrain(path, g);
    const Grid<float> r = eco::readTerrain(path);
    CHECK(r.data() == g.data());
    CHECK(r.sameGeometry(g, 0.0));
    CHECK(eco::h5::File::openRead(path).attrString("/terrain/elevation", "units") == "m");

    const std::string chm = dir.file("chm.hdf5");
    {
        auto f = eco::h5::File::create(chm);
        f.writeGrid("/chm/height", g, "m above ground");
    }
    CHECK(eco::readTerrain(chm).data() == g.data());

    const std::string other = dir.file("other.h5");
    {
        auto f = eco::h5::File::create(other);
        f.writeGrid("/maps/slope", g, "degrees");
    }
    CHECK_THROWS_WITH(eco::readTerrain(other), Catch::Contains(other) && Catch::Contains("/terrain/elevation") &&
                                                  Catch::Contains("/chm/height"));
}

TEST_CASE("terrain: a missing file is named", "[terrain]") {
    TempDir dir("tio_missing");
    for (const char* name : {"none.asc", "none.png", "none.h5", "none.exr"}) {
        const std::string path = dir.file(name);
        eco::TerrainReadOptions ro;
        ro.cellSizeM = 1.0;
        CHECK_THROWS_AS(eco::readTerrain(path, ro), eco::IoError);
        CHECK_THROWS_WITH(eco::readTerrain(path, ro), Catch::Contains(path) && Catch::Contains("cannot open"));
    }
}

TEST_CASE("terrain: a corrupt image is named", "[terrain]") {
    TempDir dir("tio_corrupt");
    const std::string path = dir.file("garbage.png");
    std::string junk;
    for (int i = 0; i < 4000; ++i) junk.push_back(static_cast<char>((i * 7919 + 13) % 251));
    writeText(path, junk);
    eco::TerrainReadOptions ro;
    ro.cellSizeM = 1.0;
    CHECK_THROWS_AS(eco::readTerrain(path, ro), eco::IoError);
    CHECK_THROWS_WITH(eco::readTerrain(path, ro), Catch::Contains(path) && Catch::Contains("cannot read image"));
    // A real PNG cut short.
    Grid<float> g(64, 64, 1.0);
    for (std::size_t i = 0; i < g.size(); ++i) g.data()[i] = static_cast<float>(i % 97);
    eco::TerrainWriteOptions wo;
    wo.verticalScale = 100;
    const std::string good = dir.file("good.png");
    eco::writeTerrain(good, g, wo);
    std::ifstream in(good, std::ios::binary);
    std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    const std::string cut = dir.file("cut.png");
    writeText(cut, bytes.substr(0, bytes.size() / 2));
    CHECK_THROWS_WITH(eco::readTerrain(cut, ro), Catch::Contains(cut));
}

TEST_CASE("terrain: NaN, infinity and NODATA in an .asc name the cell", "[terrain]") {
    TempDir dir("tio_nan");
    const std::string head = "ncols 3\nnrows 2\nxllcorner 0\nyllcorner 0\ncellsize 1\n";
    const std::string nan = dir.file("nan.asc");
    writeText(nan, head + "1 2 3\n4 nan 6\n");
    CHECK_THROWS_AS(eco::readTerrain(nan), eco::IoError);
    CHECK_THROWS_WITH(eco::readTerrain(nan), Catch::Contains(nan) && Catch::Contains("NaN") &&
                                                 Catch::Contains("column 1, row 0 from the lower left"));
    const std::string inf = dir.file("inf.asc");
    writeText(inf, head + "1 2 inf\n4 5 6\n");
    CHECK_THROWS_WITH(eco::readTerrain(inf), Catch::Contains(inf) && Catch::Contains("infinite") &&
                                                 Catch::Contains("column 2, row 1 from the lower left"));
    const std::string nodata = dir.file("nodata.asc");
    writeText(nodata, "ncols 3\nnrows 2\nxllcorner 0\nyllcorner 0\ncellsize 1\nNODATA_value -9999\n1 2 3\n-9999 5 6\n");
    CHECK_THROWS_WITH(eco::readTerrain(nodata), Catch::Contains(nodata) && Catch::Contains("NODATA") &&
                                                    Catch::Contains("column 0, row 0 from the lower left"));
    const std::string word = dir.file("word.asc");
    writeText(word, head + "1 2 3\n4 five 6\n");
    CHECK_THROWS_WITH(eco::readTerrain(word), Catch::Contains(word) && Catch::Contains("'five'") &&
                                                  Catch::Contains("not a number"));
}

TEST_CASE("terrain: .asc data count must match the header", "[terrain]") {
    TempDir dir("tio_count");
    const std::string head = "ncols 3\nnrows 2\nxllcorner 0\nyllcorner 0\ncellsize 1\n";
    const std::string few = dir.file("few.asc");
    writeText(few, head + "1 2 3\n4 5\n");
    CHECK_THROWS_AS(eco::readTerrain(few), eco::IoError);
    CHECK_THROWS_WITH(eco::readTerrain(few), Catch::Contains(few) && Catch::Contains("6 values") &&
                                                 Catch::Contains("has 5"));
    const std::string many = dir.file("many.asc");
    writeText(many, head + "1 2 3\n4 5 6\n7\n");
    CHECK_THROWS_WITH(eco::readTerrain(many), Catch::Contains("6 values") && Catch::Contains("has 7"));
}

TEST_CASE("terrain: .asc header errors", "[terrain]") {
    TempDir dir("tio_header");
    const std::string noCell = dir.file("nocell.asc");
    writeText(noCell, "ncols 2\nnrows 1\nxllcorner 0\nyllcorner 0\n1 2\n");
    CHECK_THROWS_WITH(eco::readTerrain(noCell), Catch::Contains(noCell) && Catch::Contains("missing 'cellsize'"));
    const std::string noY = dir.file("noy.asc");
    writeText(noY, "ncols 2\nnrows 1\nxllcorner 0\ncellsize 1\n1 2\n");
    CHECK_THROWS_WITH(eco::readTerrain(noY), Catch::Contains("yllcorner"));
    const std::string zero = dir.file("zero.asc");
    writeText(zero, "ncols 2\nnrows 1\nxllcorner 0\nyllcorner 0\ncellsize 0\n1 2\n");
    CHECK_THROWS_WITH(eco::readTerrain(zero), Catch::Contains("must lie in [0.001, 10000] m"));
    const std::string neg = dir.file("neg.asc");
    writeText(neg, "ncols 2\nnrows 1\nxllcorner 0\nyllcorner 0\ncellsize -3\n1 2\n");
    CHECK_THROWS_WITH(eco::readTerrain(neg), Catch::Contains("must lie in [0.001, 10000] m"));
    const std::string badCols = dir.file("badcols.asc");
    writeText(badCols, "ncols 2.5\nnrows 1\nxllcorner 0\nyllcorner 0\ncellsize 1\n1 2\n");
    CHECK_THROWS_WITH(eco::readTerrain(badCols), Catch::Contains("ncols"));
}

TEST_CASE("terrain: an image needs a cell size", "[terrain]") {
    TempDir dir("tio_nocell");
    Grid<float> g(5, 4, 1.0);
    g.fill(3.f);
    const std::string path = dir.file("t.exr");
    eco::writeTerrain(path, g);
    CHECK_THROWS_AS(eco::readTerrain(path), eco::ValidationError);
    CHECK_THROWS_WITH(eco::readTerrain(path), Catch::Contains(path) && Catch::Contains("--cell-size") &&
                                                  !Catch::Contains("cellSizeM"));  // no internal name
}

TEST_CASE("terrain: an .asc with a conflicting --cell-size is refused", "[terrain]") {
    TempDir dir("tio_conflict");
    const Grid<float> g = sampleTerrain();
    const std::string path = dir.file("t.asc");
    eco::writeTerrain(path, g);
    eco::TerrainReadOptions ro;
    ro.cellSizeM = 2.0;
    CHECK_THROWS_AS(eco::readTerrain(path, ro), eco::ValidationError);
    CHECK_THROWS_WITH(eco::readTerrain(path, ro), Catch::Contains(path) && Catch::Contains("wrong cell size") &&
                                                      Catch::Contains("0.914") && Catch::Contains("2"));
    // Same for HDF5.
    const std::string h5 = dir.file("t.h5");
    eco::writeTerrain(h5, g);
    CHECK_THROWS_WITH(eco::readTerrain(h5, ro), Catch::Contains("wrong cell size"));
    // A vertical scale on a metric format would silently change it.
    eco::TerrainReadOptions scaled;
    scaled.verticalScale = 2.0;
    CHECK_THROWS_WITH(eco::readTerrain(path, scaled), Catch::Contains("--vertical-scale"));
}

TEST_CASE("terrain: unknown extensions list the supported ones", "[terrain]") {
    TempDir dir("tio_ext");
    const std::string path = dir.file("t.xyz");
    writeText(path, "1 2 3");
    CHECK_THROWS_WITH(eco::readTerrain(path), Catch::Contains(path) && Catch::Contains(".asc") &&
                                                  Catch::Contains(".png") && Catch::Contains(".h5"));
    Grid<float> g(2, 2, 1.0);
    CHECK_THROWS_WITH(eco::writeTerrain(dir.file("out.jpg"), g), Catch::Contains(".tif"));
    CHECK_FALSE(std::filesystem::exists(dir.file("out.jpg")));
}

TEST_CASE("terrain: writers refuse non-finite values and leave no file", "[terrain]") {
    TempDir dir("tio_writenan");
    Grid<float> g(3, 3, 1.0);
    g(1, 2) = std::nanf("");
    for (const char* name : {"w.asc", "w.png", "w.h5", "w.exr"}) {
        const std::string path = dir.file(name);
        CHECK_THROWS_AS(eco::writeTerrain(path, g), eco::ValidationError);
        CHECK_FALSE(std::filesystem::exists(path));
    }
    CHECK_FALSE(leftovers(dir));
}

TEST_CASE("terrain: TIFF and EXR files carry no time stamp, so the same terrain gives the same bytes", "[terrain]") {
    // OpenImageIO writes the current time into a TIFF's DateTime tag unless told otherwise;
    // a "YYYY:MM:DD HH:MM:SS" anywhere in the file would make two runs differ.
    TempDir dir("tio_stamp");
    const Grid<float> g = sampleTerrain();
    const std::regex stamp(R"([12][0-9]{3}:[01][0-9]:[0-3][0-9] [0-2][0-9]:[0-5][0-9]:[0-5][0-9])");
    for (const char* name : {"t.tif", "t.exr"}) {
        INFO(name);
        eco::writeTerrain(dir.file(name), g);
        CHECK_FALSE(std::regex_search(eco::test::readAll(dir.file(name)), stamp));
    }
    eco::Grid<std::int32_t> sketch(4, 3, 1.0);
    sketch.fill(eco::Empty);
    eco::writeDensitySketch(dir.file("s.tif"), sketch);
    CHECK_FALSE(std::regex_search(eco::test::readAll(dir.file("s.tif")), stamp));
}
