// Command-line tests of `eco` for the canopy_placer module (split from canopy_placer_test.cpp, issue 23):
// they run the eco binary (ECO_BINARY) and live in eco_cli_tests, apart from the unit tests.
#include <catch2/catch.hpp>
#include <omp.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <sstream>

#include "biome.h"
#include "canopy_file.h"
#include "canopy_placer.h"
#include "error.h"
#include "generate.h"
#include "geo_raster.h"
#include "geotiff_fixture.h"
#include <ogrsf_frmts.h>
#include "h5io.h"
#include "rng.h"
#include "species_map.h"
#include "terrain_io.h"
#include "test_util.h"

using namespace eco;

namespace {

std::string slurp(const std::string& path) {
    std::ifstream in(path);
    std::stringstream s;
    s << in.rdbuf();
    return s.str();
}

double nearestDistance(const std::vector<Plant>& plants, double x, double y) {
    double best = std::numeric_limits<double>::infinity();
    for (const Plant& p : plants) best = std::min(best, std::hypot(p.xM - x, p.yM - y));
    return best;
}

/// A small terrain and CHM pair on disk.
struct CliFiles {
    test::TempDir dir{"canopy_cli"};
    std::string terrain = dir.file("terrain.h5");
    std::string chm = dir.file("chm.h5");
    CliFiles() {
        Grid<float> t(48, 40, 1.0, 0, 0);
        for (int iy = 0; iy < t.height(); ++iy)
            for (int ix = 0; ix < t.width(); ++ix) t(ix, iy) = static_cast<float>(80 + 0.2 * ix + 0.1 * iy);
        writeTerrain(terrain, t);
        Grid<float> c = Grid<float>::like(t, 0.f);
        const Allometry a{"D", false, -0.72, 0.65, 0};
        rasterizeCrowns({{10.2, 10.7, 20, a.crownRadiusM(20)}, {30.5, 12.2, 25, a.crownRadiusM(25)},
                         {24.3, 28.9, 18, a.crownRadiusM(18)}, {28.1, 30.0, 19, a.crownRadiusM(19)}},
                        c);
        writeTerrain(chm, c);
    }
};

}  // namespace

TEST_CASE("eco canopy writes the trees, species map, iterations and pictures", "[canopy][cli]") {
    CliFiles f;
    const std::string out = f.dir.file("canopy.h5"), csv = f.dir.file("trees.csv"), png = f.dir.file("png");
    const auto r = test::runEco("canopy --terrain " + f.terrain + " --chm " + f.chm + " --out " + out + " --csv " + csv +
                                " --png " + png + " --target Redwood=0.5 --seed 5 --max-iterations 4");
    INFO(r.output);
    REQUIRE(r.exitCode == 0);
    CHECK_THAT(r.output, Catch::Contains("computing the abiotic maps"));
    CHECK_THAT(r.output, Catch::Contains("target Redwood = 0.5"));
    CHECK_THAT(r.output, Catch::Contains("final"));
    const Biome b = defaultBiome();
    const CanopyFileData d = readCanopyFile(out, b);
    CHECK(d.trees.size() >= 3);
    CHECK(d.trees.size() <= 5);
    CHECK(d.seed == 5u);
    const h5::File h = h5::File::openRead(out);
    CHECK(h.attrInt("/", "max_iterations") == 4);
    CHECK(h.attrString("/", "abiotics_source").find("computed") != std::string::npos);
    CHECK(h.readF64("/targets/requested") == std::vector<double>{0.5});
    CHECK_THAT(slurp(csv), Catch::StartsWith("layer,species_id,species,x_m,y_m,ground_z_m,height_m,crown_radius_m"));
    CHECK(std::ifstream(png + "/canopy.png").good());
    CHECK(std::ifstream(png + "/species_map.png").good());
}

TEST_CASE("eco canopy rejects bad input with a clear error and a non-zero exit", "[canopy][cli]") {
    CliFiles f;
    const std::string out = f.dir.file("c.h5");
    const std::string base = "canopy --terrain " + f.terrain + " --out " + out;
    {  // CHM of another size
        writeTerrain(f.dir.file("small.h5"), Grid<float>(40, 40, 1.0, 0, 0, 5.f));
        const auto r = test::runEco(base + " --chm " + f.dir.file("small.h5"));
        CHECK(r.exitCode != 0);
        CHECK_THAT(r.output, Catch::Contains("small.h5") && Catch::Contains("terrain.h5") && Catch::Contains("geometry"));
    }
    {  // CHM of another cell size
        writeTerrain(f.dir.file("coarse.h5"), Grid<float>(48, 40, 2.0, 0, 0, 5.f));
        const auto r = test::runEco(base + " --chm " + f.dir.file("coarse.h5"));
        CHECK(r.exitCode != 0);
        CHECK_THAT(r.output, Catch::Contains("coarse.h5") && Catch::Contains("2 m"));
    }
    {  // negative heights (lidar CHMs have them): clamped to 0 with a count, not refused
        Grid<float> c(48, 40, 1.0, 0, 0, 5.f);
        c(7, 3) = -0.5f;
        writeTerrain(f.dir.file("negative.asc"), c);
        const auto r = test::runEco("canopy --terrain " + f.terrain + " --chm " + f.dir.file("negative.asc") + " --out " +
                                    f.dir.file("negative.h5") + " --max-iterations 1");
        CHECK(r.exitCode == 0);
        CHECK_THAT(r.output, Catch::Contains("negative.asc: 1 cell(s) below 0 m (lowest -0.5 m) clamped to 0"));
        CHECK_THAT(r.output, !Catch::Contains("coarser"));  // 1 m cells resolve these crowns
    }
    {  // fraction outside [0, 1]
        const auto r = test::runEco(base + " --chm " + f.chm + " --target Redwood=1.5");
        CHECK(r.exitCode != 0);
        CHECK_THAT(r.output, Catch::Contains("[0, 1]"));
    }
    {  // unknown species
        const auto r = test::runEco(base + " --chm " + f.chm + " --target Sequoia=0.5");
        CHECK(r.exitCode != 0);
        CHECK_THAT(r.output, Catch::Contains("unknown species 'Sequoia'") && Catch::Contains("Redwood"));
    }
    {  // unknown config key
        std::ofstream(f.dir.file("bad.toml")) << "[canopy]\nmax_iteratons = 3\n";
        const auto r = test::runEco(base + " --chm " + f.chm + " --config " + f.dir.file("bad.toml"));
        CHECK(r.exitCode != 0);
        CHECK_THAT(r.output, Catch::Contains("max_iteratons"));
    }
    CHECK_FALSE(std::ifstream(out).good());  // nothing written by a failed run
}

TEST_CASE("eco canopy on GeoTIFFs in UTM: geometry from the files, CHM gaps filled, negatives clamped", "[canopy][cli][geo]") {
    CliFiles f;
    // The same terrain and CHM as GeoTIFFs with a UTM geotransform, the CHM with a nodata
    // hole inside a crown and a few slightly negative cells (as lidar CHMs come).
    const Grid<float> t = readTerrain(f.terrain), c = readTerrain(f.chm);
    auto spec = [&](const Grid<float>& g, bool chm) {
        test::GeoTiffSpec s;
        s.width = g.width();
        s.height = g.height();
        s.geotransform[0] = 545000.0;
        s.geotransform[1] = 1.0;
        s.geotransform[3] = 4260000.0 + g.height();
        s.geotransform[5] = -1.0;
        s.hasNodata = chm;
        s.nodata = -1.7e308;
        s.type = GDT_Float64;
        for (int row = 0; row < g.height(); ++row)
            for (int ix = 0; ix < g.width(); ++ix) s.northFirst.push_back(g(ix, g.height() - 1 - row));
        return s;
    };
    test::GeoTiffSpec cs = spec(c, true);
    const std::size_t hole = static_cast<std::size_t>(c.height() - 1 - 11) * static_cast<std::size_t>(c.width()) + 10;  // (10, 11)
    REQUIRE(cs.northFirst[hole] > 10);
    cs.northFirst[hole] = -1.7e308;
    cs.northFirst[0] = -0.2;
    cs.northFirst[1] = -0.05;
    const std::string dem = f.dir.file("dem.tif"), chm = f.dir.file("chm.tif"), out = f.dir.file("geo.h5");
    test::writeGeoTiff(dem, spec(t, false));
    test::writeGeoTiff(chm, cs);
    const std::string gpkg = f.dir.file("trees.gpkg");
    const std::string gis = f.dir.file("gis");
    const auto r = test::runEco("canopy --terrain " + dem + " --chm " + chm + " --out " + out +
                                " --seed 5 --max-iterations 4 --gpkg " + gpkg + " --geotiff " + gis);
    INFO(r.output);
    REQUIRE(r.exitCode == 0);
    CHECK_THAT(r.output, Catch::Contains("GeoPackage, the input's CRS"));
    CHECK_THAT(r.output, Catch::Contains("1 nodata cell(s): 1 filled") && Catch::Contains("2 cell(s) below 0 m (lowest -0.2 m) clamped to 0"));
    const CanopyFileData d = readCanopyFile(out, defaultBiome());
    REQUIRE(d.trees.size() >= 3);
    for (const Plant& p : d.trees) {
        CHECK(p.xM > 545000.0);
        CHECK(p.xM < 545048.0);
        CHECK(p.yM > 4260000.0);
        CHECK(p.yM < 4260040.0);
    }
    CHECK(d.chmM(10, 11) > 10.0f);  // the hole filled from the crown around it
    {  // the canopy file's grids as GeoTIFFs in place: the CHM as repaired, the species map as Int32
        CHECK_THAT(d.chmM.crsWkt(), Catch::Contains("UTM zone 10N"));
        const GeoRaster back = readGeoRaster(gis + "/geo_chm_height.tif");
        CHECK_THAT(back.crsName, Catch::Contains("UTM zone 10N"));
        CHECK(back.grid.sameGeometry(d.chmM));
        CHECK(back.grid.data() == d.chmM.data());
        CHECK(back.nodataCells == 0);
        const GeoRaster species = readGeoRaster(gis + "/geo_species_map.tif");
        CHECK(species.grid.sameGeometry(d.chmM));
        CHECK(species.driver == "GTiff");
        for (const char* name : {"geo_terrain_elevation.tif", "geo_species_map.tif"})
            CHECK(std::filesystem::exists(gis + "/" + name));
    }
    {  // eco abiotics --geotiff: each monthly map one 12-band GeoTIFF, months named, in the DEM's CRS
        const std::string ab = f.dir.file("ab.h5");
        const auto a = test::runEco("abiotics --terrain " + dem + " --out " + ab + " --geotiff " + gis + " --sun-step 60");
        INFO(a.output);
        REQUIRE(a.exitCode == 0);
        GDALDataset* g = GDALDataset::Open((gis + "/ab_sun.tif").c_str(), GDAL_OF_RASTER | GDAL_OF_READONLY);
        REQUIRE(g != nullptr);
        CHECK(g->GetRasterCount() == 12);
        CHECK(std::string(g->GetRasterBand(1)->GetDescription()) == "January");
        CHECK(std::string(g->GetRasterBand(12)->GetDescription()) == "December");
        REQUIRE(g->GetSpatialRef() != nullptr);
        CHECK_THAT(std::string(g->GetSpatialRef()->GetName()), Catch::Contains("UTM zone 10N"));
        double gt[6];
        g->GetGeoTransform(gt);
        CHECK(gt[0] == 545000.0);
        CHECK(gt[3] == 4260000.0 + t.height());
        GDALClose(GDALDataset::ToHandle(g));
        for (const char* name : {"ab_elevation.tif", "ab_slope.tif", "ab_moisture.tif", "ab_temperature.tif"})
            CHECK(std::filesystem::exists(gis + "/" + name));
    }
    {  // the GeoPackage: one point per tree, in UTM zone 10N, with its attributes
        GDALDataset* g = GDALDataset::Open(gpkg.c_str(), GDAL_OF_VECTOR | GDAL_OF_READONLY);
        REQUIRE(g != nullptr);
        OGRLayer* layer = g->GetLayerByName("plants");
        REQUIRE(layer != nullptr);
        CHECK(layer->GetFeatureCount() == static_cast<GIntBig>(d.trees.size()));
        REQUIRE(layer->GetSpatialRef() != nullptr);
        CHECK_THAT(std::string(layer->GetSpatialRef()->GetName()), Catch::Contains("UTM zone 10N"));
        OGRFeature* first = layer->GetNextFeature();
        REQUIRE(first != nullptr);
        const OGRPoint* pt = first->GetGeometryRef()->toPoint();
        CHECK(nearestDistance(d.trees, pt->getX(), pt->getY()) < 1e-9);
        CHECK(std::string(first->GetFieldAsString("layer")) == "canopy");
        CHECK(first->GetFieldAsDouble("height_m") > 3.0);
        OGRFeature::DestroyFeature(first);
        GDALClose(GDALDataset::ToHandle(g));
    }

    const auto fail = test::runEco("canopy --terrain " + dem + " --chm " + chm + " --out " + out + " --chm-gaps fail");
    CHECK(fail.exitCode != 0);
    CHECK_THAT(fail.output, Catch::Contains("column 10, row 11 from the lower left") && Catch::Contains("x = 545010.5 m, y = 4260011.5 m"));
    test::GeoTiffSpec zone11 = cs;
    zone11.epsg = 32611;
    const std::string chm11 = f.dir.file("chm11.tif");
    test::writeGeoTiff(chm11, zone11);
    const auto crs = test::runEco("canopy --terrain " + dem + " --chm " + chm11 + " --out " + f.dir.file("c11.h5"));
    CHECK(crs.exitCode != 0);
    CHECK_THAT(crs.output, Catch::Contains("UTM zone 10N") && Catch::Contains("UTM zone 11N") && Catch::Contains("one CRS"));
    {  // a DEM of 2 m cells under the 1 m CHM: refused with the way out, resampled when asked
        test::GeoTiffSpec coarse = spec(t, false);
        coarse.width = t.width() / 2;
        coarse.height = t.height() / 2;
        coarse.geotransform[1] = 2.0;
        coarse.geotransform[5] = -2.0;
        coarse.northFirst.clear();
        for (int row = 0; row < coarse.height; ++row)
            for (int ix = 0; ix < coarse.width; ++ix)
                coarse.northFirst.push_back(t.sampleBilinear(t.originX() + 2.0 * ix + 1.0, t.originY() + t.height() - 2.0 * row - 1.0));
        const std::string dem2 = f.dir.file("dem2m.tif"), out2 = f.dir.file("resampled.h5");
        test::writeGeoTiff(dem2, coarse);
        const auto refused = test::runEco("canopy --terrain " + dem2 + " --chm " + chm + " --out " + out2);
        CHECK(refused.exitCode != 0);
        CHECK_THAT(refused.output, Catch::Contains("differ in geometry") && Catch::Contains("--resample-terrain"));
        const auto resampled = test::runEco("canopy --terrain " + dem2 + " --chm " + chm + " --out " + out2 +
                                            " --max-iterations 2 --resample-terrain");
        INFO(resampled.output);
        REQUIRE(resampled.exitCode == 0);
        CHECK_THAT(resampled.output, Catch::Contains("resampled bilinearly onto the CHM's cells"));
        const CanopyFileData r2 = readCanopyFile(out2, defaultBiome());
        CHECK(r2.terrainM.sameGeometry(d.chmM));
        CHECK_THAT(r2.terrainM.crsWkt(), Catch::Contains("UTM zone 10N"));
        double worst = 0;
        for (int iy = 2; iy < t.height() - 2; ++iy)
            for (int ix = 2; ix < t.width() - 2; ++ix) worst = std::max(worst, std::abs(double(r2.terrainM(ix, iy)) - t(ix, iy)));
        CHECK(worst < 0.5);  // the 2 m DEM was sampled from this terrain
    }
    {  // an output that cannot be written is refused before any work: nothing else is left
        const std::string lone = f.dir.file("lone.h5");
        const auto bad = test::runEco("canopy --terrain " + dem + " --chm " + chm + " --out " + lone + " --gpkg /proc/eco_no/t.gpkg");
        CHECK(bad.exitCode != 0);
        CHECK_THAT(bad.output, Catch::Contains("/proc/eco_no"));
        CHECK_FALSE(std::ifstream(lone).good());
    }
    const auto coarse = test::runEco("canopy --terrain " + dem + " --chm " + chm + " --out " + f.dir.file("c.h5") + " --chm-gaps bad");
    CHECK(coarse.exitCode != 0);
    CHECK_THAT(coarse.output, Catch::Contains("--chm-gaps") && Catch::Contains("'bad'"));
}
