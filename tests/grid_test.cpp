// The (x, y) convention of Grid<T> on a NON-SQUARE grid, so that an x/y transposition or a
// north/south flip in any reader or writer shows up.

#include <catch2/catch.hpp>

#include <fstream>
#include <vector>

#include "grid.h"
#include "h5io.h"
#include "terrain_io.h"
#include "test_util.h"

using eco::Grid;

namespace {

constexpr int kW = 7;  // columns, along x (east)
constexpr int kH = 4;  // rows, along y (north)

/// Asymmetric pattern: value = 10 * ix + iy + 1 (all distinct, no symmetry under
/// transposition or flips). The NE corner (6, 3) holds 64, the SW corner (0, 0) holds 1.
float pattern(int ix, int iy) { return static_cast<float>(10 * ix + iy + 1); }

Grid<float> patternGrid(double cell = 2.0, double ox = 100.0, double oy = 200.0) {
    Grid<float> g(kW, kH, cell, ox, oy);
    for (int iy = 0; iy < kH; ++iy)
        for (int ix = 0; ix < kW; ++ix) g(ix, iy) = pattern(ix, iy);
    return g;
}

void requirePattern(const Grid<float>& g, double tol = 0.0) {
    REQUIRE(g.width() == kW);
    REQUIRE(g.height() == kH);
    for (int iy = 0; iy < kH; ++iy)
        for (int ix = 0; ix < kW; ++ix) {
            INFO("cell (" << ix << ", " << iy << ")");
            REQUIRE(g(ix, iy) == Approx(pattern(ix, iy)).margin(tol));
        }
    // The north-east corner is the last column of the last (northern) row.
    CHECK(g(kW - 1, kH - 1) == Approx(64.0f).margin(tol));
    CHECK(g(0, 0) == Approx(1.0f).margin(tol));
}

}  // namespace

TEST_CASE("grid: cell centres and their inverse on a non-square grid", "[grid]") {
    const Grid<float> g = patternGrid(2.0, 100.0, 200.0);
    CHECK(g.width() == 7);
    CHECK(g.height() == 4);
    CHECK(g.size() == 28u);
    CHECK(g.extentX() == Approx(14.0));
    CHECK(g.extentY() == Approx(8.0));
    // Cell (ix, iy): x from ix, y from iy, measured from the lower-left corner.
    CHECK(g.cellCentreX(0) == Approx(101.0));
    CHECK(g.cellCentreY(0) == Approx(201.0));
    CHECK(g.cellCentreX(6) == Approx(113.0));
    CHECK(g.cellCentreY(3) == Approx(207.0));
    for (int iy = 0; iy < kH; ++iy)
        for (int ix = 0; ix < kW; ++ix) {
            CHECK(g.cellX(g.cellCentreX(ix)) == ix);
            CHECK(g.cellY(g.cellCentreY(iy)) == iy);
        }
    // Storage is row-major with rows along y.
    CHECK(g.index(6, 0) == 6u);
    CHECK(g.index(0, 1) == 7u);
    CHECK(g.data()[g.index(6, 3)] == 64.0f);
    // Points outside.
    CHECK_FALSE(g.inside(g.cellX(99.9), 0));
    CHECK_FALSE(g.inside(0, g.cellY(208.1)));
    CHECK(g.inside(g.cellX(113.9), g.cellY(207.9)));
    CHECK(g.clamped(10, -3) == g(6, 0));
}

TEST_CASE("grid: sampleBilinear is exact on a linear ramp", "[grid]") {
    Grid<float> g(kW, kH, 0.5, -3.0, 4.0);
    auto ramp = [](double x, double y) { return 2.0 + 0.75 * x - 1.25 * y; };
    for (int iy = 0; iy < kH; ++iy)
        for (int ix = 0; ix < kW; ++ix) g(ix, iy) = static_cast<float>(ramp(g.cellCentreX(ix), g.cellCentreY(iy)));
    // Anywhere between the first and last cell centres.
    for (double fx : {0.0, 0.13, 0.5, 0.77, 1.0})
        for (double fy : {0.0, 0.31, 0.5, 0.9, 1.0}) {
            const double x = g.cellCentreX(0) + fx * (g.cellCentreX(kW - 1) - g.cellCentreX(0));
            const double y = g.cellCentreY(0) + fy * (g.cellCentreY(kH - 1) - g.cellCentreY(0));
            CHECK(g.sampleBilinear(x, y) == Approx(ramp(x, y)).margin(1e-5));
        }
    // At a cell centre it returns the cell.
    CHECK(g.sampleBilinear(g.cellCentreX(5), g.cellCentreY(2)) == g(5, 2));
}

TEST_CASE("grid: an ESRI ASCII grid's first row is the north edge", "[grid]") {
    eco::test::TempDir dir("grid_asc");
    const std::string path = dir.file("pattern.asc");
    {
        // Written by hand (not by our writer): first data row = northern row iy = 3.
        std::ofstream f(path);
        f << "ncols 7\nnrows 4\nxllcorner 100\nyllcorner 200\ncellsize 2\n";
        for (int iy = kH - 1; iy >= 0; --iy) {
            for (int ix = 0; ix < kW; ++ix) f << pattern(ix, iy) << (ix + 1 < kW ? " " : "\n");
        }
    }
    const Grid<float> g = eco::readTerrain(path);
    requirePattern(g);
    CHECK(g.originX() == 100.0);
    CHECK(g.originY() == 200.0);
    CHECK(g.cellSizeM() == 2.0);
    // The value at the world position of the NE corner cell.
    CHECK(g(g.cellX(113.5), g.cellY(207.5)) == 64.0f);

    // And our own writer puts the northern row first.
    const std::string out = dir.file("ours.asc");
    eco::writeTerrain(out, g);
    std::ifstream in(out);
    std::string line;
    for (int i = 0; i < 5; ++i) std::getline(in, line);  // header
    std::getline(in, line);
    CHECK(line == "4 14 24 34 44 54 64");
    CHECK(eco::readTerrain(out).data() == g.data());
}

TEST_CASE("grid: image row 0 is the north edge (PNG)", "[grid]") {
    eco::test::TempDir dir("grid_png");
    const std::string path = dir.file("pattern.png");
    eco::TerrainWriteOptions wo;
    wo.verticalScale = 100.0;
    eco::writeTerrain(path, patternGrid(), wo);

    // Look at the pixels directly, independently of our reader.
    std::string error;
    auto in = eco::openImageFile(path, error);
    REQUIRE(in);
    REQUIRE(in->width() == kW);
    REQUIRE(in->height() == kH);
    CHECK(in->stored() == eco::SampleType::UInt16);
    std::vector<float> px(kW * kH);
    REQUIRE(in->readFloat(1, px.data()));
    in.reset();
    CHECK(px[kW - 1] * 100.0 == Approx(64.0).margin(0.01));                  // top-right pixel = NE
    CHECK(px[(kH - 1) * kW] * 100.0 == Approx(1.0).margin(0.01));            // bottom-left pixel = SW
    CHECK(px[0] * 100.0 == Approx(pattern(0, kH - 1)).margin(0.01));         // top-left = NW

    eco::TerrainReadOptions ro;
    ro.cellSizeM = 2.0;
    ro.verticalScale = 100.0;
    ro.originX = 100.0;
    ro.originY = 200.0;
    const Grid<float> g = eco::readTerrain(path, ro);
    requirePattern(g, 100.0 / 65535.0);
    CHECK(g.originX() == 100.0);
    CHECK(g.originY() == 200.0);
}

TEST_CASE("grid: HDF5 stores rows south first as [height][width]", "[grid]") {
    eco::test::TempDir dir("grid_h5");
    const std::string path = dir.file("pattern.h5");
    eco::writeTerrain(path, patternGrid());
    {
        const auto f = eco::h5::File::openRead(path);
        std::vector<hsize_t> dims;
        const std::vector<float> raw = f.readF32("/terrain/elevation", &dims);
        REQUIRE(dims == std::vector<hsize_t>{kH, kW});
        CHECK(raw[0] == 1.0f);                      // first stored value = SW corner
        CHECK(raw[(kH - 1) * kW + (kW - 1)] == 64.0f);  // last = NE corner
        CHECK(f.attrString("/terrain/elevation", "row_order") == "south_to_north");
        CHECK(f.attrString("/terrain/elevation", "units") == "m");
    }
    const Grid<float> g = eco::readTerrain(path);
    requirePattern(g);
    CHECK(g.originX() == 100.0);
    CHECK(g.originY() == 200.0);
    CHECK(g.cellSizeM() == 2.0);
}

TEST_CASE("grid: like, sameGeometry and MonthlyGrids", "[grid]") {
    const Grid<float> g = patternGrid();
    const auto i = Grid<int>::like(g, 3);
    CHECK(i.sameGeometry(g));
    CHECK(i(6, 3) == 3);
    CHECK_FALSE(Grid<float>(kH, kW, 2.0, 100.0, 200.0).sameGeometry(g));
    CHECK_THROWS_AS(Grid<float>(2, 2, 0.0), eco::ValidationError);
    CHECK_THROWS_AS(Grid<float>(-1, 2, 1.0), eco::ValidationError);

    eco::MonthlyGrids<float> m;
    for (int k = 0; k < 12; ++k) m.months.push_back(Grid<float>::like(g, static_cast<float>(k)));
    const auto mean = m.annualMean();
    CHECK(mean(4, 2) == Approx(5.5f));
    CHECK(g.minValue() == 1.0f);
    CHECK(g.maxValue() == 64.0f);
}

TEST_CASE("grid: resampledOnto a finer grid is exact on a linear ramp and refuses what it does not cover", "[grid]") {
    // A 10 m DEM of a plane, resampled onto 1 m cells inside it (not at its outer half-cells,
    // where bilinear sampling clamps).
    Grid<float> coarse(8, 6, 10.0, 1000.0, 2000.0);
    coarse.setCrsWkt("LOCAL_CS[\"test\"]");
    for (int iy = 0; iy < 6; ++iy)
        for (int ix = 0; ix < 8; ++ix) coarse(ix, iy) = static_cast<float>(0.5 * coarse.cellCentreX(ix) - 0.25 * coarse.cellCentreY(iy));
    const Grid<std::uint8_t> fine(40, 30, 1.0, 1010.0, 2010.0);
    const Grid<float> r = resampledOnto(coarse, fine, "dem");
    CHECK(r.sameGeometry(fine));
    CHECK(r.crsWkt() == coarse.crsWkt());
    for (int iy = 0; iy < r.height(); ++iy)
        for (int ix = 0; ix < r.width(); ++ix)
            REQUIRE(r(ix, iy) == Approx(0.5 * r.cellCentreX(ix) - 0.25 * r.cellCentreY(iy)).margin(1e-3));
    const Grid<std::uint8_t> outside(40, 30, 1.0, 1050.0, 2010.0);  // reaches 1090 m > 1080 m + 5 m
    CHECK_THROWS_WITH(resampledOnto(coarse, outside, "dem"), Catch::Contains("dem") && Catch::Contains("does not cover"));
}
