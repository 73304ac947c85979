// Command-line tests of `eco` for the synth module (split from synth_test.cpp, issue 23):
// they run the eco binary (ECO_BINARY) and live in eco_cli_tests, apart from the unit tests.
#include <hdf5.h>
#include <omp.h>

#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <functional>
#include <fstream>
#include <map>
#include <set>

#include "abiotics.h"
#include "biome.h"
#include "biome_db.h"
#include "canopy_placer.h"
#include "error.h"
#include "factors.h"
#include "forest_floor.h"
#include "geo_raster.h"
#include "geotiff_fixture.h"
#include <ogrsf_frmts.h>
#include "h5io.h"
#include "scene.h"
#include "synth_world_fixture.h"
#include "synth_world_files.h"
#include "terrain_io.h"
#include "atomic_file.h"
#include "test_util.h"
#include "undergrowth.h"

using namespace eco;

namespace {

// ------------------------------------------------------------------ the test world (synth_world_fixture.h)

using test::kCell;
using test::kSide;
using test::makeWorld;
using test::World;

using test::WorldFiles;
using test::writeWorld;

}  // namespace

// ======================================================================== cluster map

TEST_CASE("eco synth and eco compare write a scene and report it", "[synth][cli]") {
    const World w = makeWorld();
    test::TempDir dir("synth_cli");
    const WorldFiles f = writeWorld(w, dir);
    const auto r = test::runEco("synth --terrain " + f.terrain + " --canopy " + f.canopy + " --database " + f.db +
                                " --abiotics " + f.abiotics + " --out " + dir.file("out/scene.h5") + " --png " +
                                dir.file("png") + " --csv " + dir.file("plants.csv") + " --pdb " + dir.file("plants.pdb") +
                                " --pdb-canopy " + dir.file("canopy.pdb") + " --pdb-undergrowth " + dir.file("undergrowth.pdb") +
                                " --refine --refine-sweeps 1 --refine-window 80,80,120,120");
    INFO(r.output);
    REQUIRE(r.exitCode == 0);
    {
        // The split lists (EcoLearn's viewer reads canopy and undergrowth as two files) hold
        // one layer each and together every plant of the joint list.
        const auto count = [](const std::vector<synth::PdbSpecies>& list) {
            std::size_t n = 0;
            for (const auto& s : list) n += s.plants.size();
            return n;
        };
        const std::size_t all = count(synth::readPdb(dir.file("plants.pdb")));
        const std::size_t canopyTrees = count(synth::readPdb(dir.file("canopy.pdb")));
        const std::size_t undergrowth = count(synth::readPdb(dir.file("undergrowth.pdb")));
        CHECK(canopyTrees == w.canopy.size());
        CHECK(undergrowth > 0);
        CHECK(canopyTrees + undergrowth == all);
        // One path for both: refused before any work, naming both flags.
        const auto same = test::runEco("synth --terrain " + f.terrain + " --canopy " + f.canopy + " --database " + f.db +
                                       " --out " + dir.file("same/scene.h5") + " --pdb-canopy " + dir.file("same/p.pdb") +
                                       " --pdb-undergrowth " + dir.file("same/p.pdb"));
        INFO(same.output);
        CHECK(same.exitCode == 1);
        CHECK_THAT(same.output, Catch::Contains("--pdb-canopy") && Catch::Contains("--pdb-undergrowth") &&
                                    Catch::Contains("are the same file"));
        CHECK_FALSE(std::filesystem::exists(dir.file("same/scene.h5")));
    }
    CHECK_THAT(r.output, Catch::Contains("refinement: pair-correlation distance"));
    for (const char* name : {"out/scene.h5", "plants.csv", "plants.pdb", "png/scene.png", "png/scene_zoom.png",
                             "png/grass.png", "png/litter.png", "png/cluster_map.png"})
        CHECK(std::filesystem::exists(dir.file(name)));
    const auto c = test::runEco("compare " + dir.file("out/scene.h5") + " " + f.db + " --png " + dir.file("cmp"));
    INFO(c.output);
    REQUIRE(c.exitCode == 0);
    CHECK_THAT(c.output, Catch::Contains("| region |") && Catch::Contains("pair-correlation distance"));
    CHECK(std::filesystem::exists(dir.file("cmp/compare.png")));
    // --png is a directory in every command: the old form (a file name) is a usage error that says so.
    const auto old = test::runEco("compare " + dir.file("out/scene.h5") + " " + f.db + " --png " + dir.file("old.png"));
    INFO(old.output);
    CHECK(old.exitCode == 2);
    CHECK_THAT(old.output, Catch::Contains("--png") && Catch::Contains("is a directory now") && Catch::Contains("old.png"));
    CHECK_FALSE(std::filesystem::exists(dir.file("old.png")));

    // Approximate instancing of the scene: every plant an instance, at most K prototypes per
    // species, the same bytes with 1 and 2 threads.
    for (const char* threads : {"1", "2"}) {
        const auto inst = test::runEco(std::string("--threads ") + threads + " instance " + dir.file("out/scene.h5") +
                                       " --prototypes 3 --curve-max 4 --out " + dir.file(std::string("inst") + threads));
        INFO(inst.output);
        REQUIRE(inst.exitCode == 0);
        CHECK_THAT(inst.output, Catch::Contains("prototypes: size error"));
        // Progress on stderr (a large scene took a minute without a word).
        CHECK_THAT(inst.output, Catch::Contains("instance: done in"));
    }
    const auto prototypes = test::readCsvRows(dir.file("inst1/prototypes.csv"));
    std::map<std::string, int> perSpecies;
    for (const auto& row : prototypes) ++perSpecies[row.at("species")];
    REQUIRE(!perSpecies.empty());
    for (const auto& [species, n] : perSpecies) CHECK(n <= 3);
    CHECK(test::readCsvRows(dir.file("inst1/instances.csv")).size() == test::readCsvRows(dir.file("plants.csv")).size());
    for (const char* name : {"instances.csv", "prototypes.csv", "instancing.md", "error_vs_k.png", "instances.ply", "grass.exr",
                             "litter.exr", "terrain.exr", "grass.tif", "litter.tif"}) {
        INFO(name);
        CHECK(!readTextFile(dir.file(std::string("inst1/") + name)).empty());
        CHECK(readTextFile(dir.file(std::string("inst1/") + name)) == readTextFile(dir.file(std::string("inst2/") + name)));
    }
    // The forest floor as GeoTIFF for GIS (docs/export.md): the scene's grids, in place.
    // (tests/python reads the PLY and the EXR images back with the Blender recipe's readers.)
    {
        const synth::SceneData scene = synth::readSceneFile(dir.file("out/scene.h5"), defaultBiome());
        for (const auto& [name, grid] : {std::pair<std::string, const Grid<float>*>{"grass", &scene.grass}, {"litter", &scene.litter}}) {
            INFO(name);
            const GeoRaster tif = readGeoRaster(dir.file("inst1/" + name + ".tif"));
            REQUIRE(tif.grid.width() == grid->width());
            REQUIRE(tif.grid.height() == grid->height());
            CHECK(tif.grid.originX() == Approx(grid->originX()));
            CHECK(tif.grid.originY() == Approx(grid->originY()));
            CHECK(tif.grid.cellSizeM() == Approx(grid->cellSizeM()));
            double maxDiff = 0;
            for (int iy = 0; iy < grid->height(); ++iy)
                for (int ix = 0; ix < grid->width(); ++ix) maxDiff = std::max(maxDiff, std::abs(double(tif.grid(ix, iy)) - (*grid)(ix, iy)));
            CHECK(maxDiff == 0.0);
        }
    }
    const auto notScene = test::runEco("instance " + dir.file("plants.csv") + " --out " + dir.file("inst3"));
    CHECK(notScene.exitCode == 1);
    CHECK_THAT(notScene.output, Catch::Contains("plants.csv"));
    CHECK_FALSE(std::filesystem::exists(dir.file("inst3/instances.csv")));
}

TEST_CASE("eco synth refuses bad inputs with one clear line and no output", "[synth][cli]") {
    const World w = makeWorld();
    test::TempDir dir("synth_bad");
    const WorldFiles f = writeWorld(w, dir);
    const std::string out = dir.file("scene.h5");
    auto synth = [&](const std::string& terrain, const std::string& canopy, const std::string& db) {
        return test::runEco("synth --terrain " + terrain + " --canopy " + canopy + " --database " + db + " --abiotics " +
                            f.abiotics + " --out " + out);
    };

    SECTION("a database of another schema version") {
        const std::string bad = dir.file("db_old.h5");
        std::filesystem::copy_file(f.db, bad);
        const hid_t file = H5Fopen(bad.c_str(), H5F_ACC_RDWR, H5P_DEFAULT);
        REQUIRE(file >= 0);
        REQUIRE(H5Adelete(file, "schema_version") >= 0);
        const hid_t space = H5Screate(H5S_SCALAR);
        const hid_t attr = H5Acreate2(file, "schema_version", H5T_STD_I64LE, space, H5P_DEFAULT, H5P_DEFAULT);
        const long long older = kBiomeDbOldestReadableVersion - 1;
        H5Awrite(attr, H5T_NATIVE_LLONG, &older);
        H5Aclose(attr);
        H5Sclose(space);
        H5Fclose(file);
        const auto r = synth(f.terrain, f.canopy, bad);
        INFO(r.output);
        CHECK(r.exitCode != 0);
        CHECK_THAT(r.output, Catch::Contains("db_old.h5") && Catch::Contains("schema_version") && Catch::Contains("eco: error"));
    }
    SECTION("a canopy tree outside the terrain") {
        std::vector<Plant> trees = w.canopy;
        trees[3].xM = kSide * kCell + 25.0;
        synth::CanopyRecord rec;
        rec.result.trees = trees;
        rec.speciesMap = Grid<std::int32_t>::like(w.terrain, -1);
        rec.chmM = Grid<float>::like(w.terrain, 0.0f);
        rec.terrainM = w.terrain;
        synth::writeCanopyFile(dir.file("outside.h5"), rec, w.biome);
        const auto r = synth(f.terrain, dir.file("outside.h5"), f.db);
        INFO(r.output);
        CHECK(r.exitCode != 0);
        CHECK_THAT(r.output, Catch::Contains("outside.h5") && Catch::Contains("canopy tree 3") &&
                                 Catch::Contains("outside the terrain"));
    }
    SECTION("a canopy placed on another terrain") {
        Grid<float> other(kSide / 2, kSide, kCell, 0, 0, 50.0f);
        writeTerrainH5(dir.file("other.h5"), other);
        const auto r = synth(dir.file("other.h5"), f.canopy, f.db);
        INFO(r.output);
        CHECK(r.exitCode != 0);
        CHECK_THAT(r.output, Catch::Contains("canopy.h5") && Catch::Contains("other.h5") &&
                                 Catch::Contains("was placed on a terrain of"));
    }
    SECTION("a missing file") {
        const auto r = synth(f.terrain, f.canopy, dir.file("nothing.h5"));
        INFO(r.output);
        CHECK(r.exitCode != 0);
        CHECK_THAT(r.output, Catch::Contains("nothing.h5"));
    }
    CHECK_FALSE(std::filesystem::exists(out));
    // No temporary files left beside the output either.
    for (const auto& e : std::filesystem::directory_iterator(dir.path()))
        CHECK(e.path().filename().string().find("scene") == std::string::npos);
}

TEST_CASE("eco compare refuses a scene from another database", "[synth][cli]") {
    const World w = makeWorld();
    test::TempDir dir("synth_cmp");
    const WorldFiles f = writeWorld(w, dir);
    REQUIRE(test::runEco("synth --terrain " + f.terrain + " --canopy " + f.canopy + " --database " + f.db +
                         " --abiotics " + f.abiotics + " --out " + dir.file("scene.h5"))
                .exitCode == 0);
    BiomeDatabase small = w.db;
    small.regions.resize(1);
    small.combinations.resize(1);
    small.combinations[0].k = 1;
    writeBiomeDatabase(dir.file("small.h5"), small);
    const auto r = test::runEco("compare " + dir.file("scene.h5") + " " + dir.file("small.h5"));
    INFO(r.output);
    CHECK(r.exitCode != 0);
    CHECK_THAT(r.output, Catch::Contains("another database"));
}

namespace {

Grid<float> shifted(const Grid<float>& g, double dx, double dy) {
    Grid<float> s(g.width(), g.height(), g.cellSizeM(), g.originX() + dx, g.originY() + dy);
    s.data() = g.data();
    return s;
}

/// A GeoTIFF read back through GDAL: geotransform, CRS name, band count, band 1 north first.
struct TiffBack {
    double gt[6] = {};
    std::string crsName;
    int bands = 0;
    std::string type, firstBandName;
    std::vector<double> northFirst;
    bool hasNodata = false;
    double nodata = 0;
};
TiffBack readTiffBack(const std::string& path) {
    GDALAllRegister();
    GDALDataset* ds = GDALDataset::Open(path.c_str(), GDAL_OF_RASTER | GDAL_OF_READONLY);
    if (ds == nullptr) throw std::runtime_error("cannot open " + path);
    TiffBack t;
    ds->GetGeoTransform(t.gt);
    if (const OGRSpatialReference* srs = ds->GetSpatialRef()) t.crsName = srs->GetName();
    t.bands = ds->GetRasterCount();
    GDALRasterBand* b = ds->GetRasterBand(1);
    t.type = GDALGetDataTypeName(b->GetRasterDataType());
    t.firstBandName = b->GetDescription();
    int has = 0;
    t.nodata = b->GetNoDataValue(&has);
    t.hasNodata = has != 0;
    const int w = ds->GetRasterXSize(), h = ds->GetRasterYSize();
    t.northFirst.resize(static_cast<std::size_t>(w) * static_cast<std::size_t>(h));
    if (b->RasterIO(GF_Read, 0, 0, w, h, t.northFirst.data(), w, h, GDT_Float64, 0, 0) != CE_None)
        throw std::runtime_error("cannot read " + path);
    GDALClose(GDALDataset::ToHandle(ds));
    return t;
}

}  // namespace

TEST_CASE("a georeferenced round trip: GeoTIFF in, scene out as GeoPackage and GeoTIFFs in the same CRS and place",
          "[synth][cli][geo]") {
    // The test world moved to UTM zone 10N coordinates, its terrain given as a GeoTIFF.
    constexpr double kX0 = 545000.0, kY0 = 4260000.0;
    World w = makeWorld();
    w.terrain = shifted(w.terrain, kX0, kY0);
    for (std::size_t f = 0; f < kFactorCount; ++f) w.features.maps[f] = shifted(w.features.maps[f], kX0, kY0);
    for (Plant& p : w.canopy) {
        p.xM += kX0;
        p.yM += kY0;
    }
    test::TempDir dir("synth_geo");
    const WorldFiles f = writeWorld(w, dir);  // canopy and abiotics files without a CRS
    test::GeoTiffSpec spec;
    spec.width = w.terrain.width();
    spec.height = w.terrain.height();
    spec.geotransform[0] = kX0;
    spec.geotransform[1] = kCell;
    spec.geotransform[3] = kY0 + kSide * kCell;
    spec.geotransform[5] = -kCell;
    for (int row = 0; row < spec.height; ++row)
        for (int ix = 0; ix < spec.width; ++ix) spec.northFirst.push_back(w.terrain(ix, spec.height - 1 - row));
    const std::string dem = dir.file("dem.tif");
    test::writeGeoTiff(dem, spec);

    const std::string scene = dir.file("scene.h5"), gpkg = dir.file("scene.gpkg"), gis = dir.file("gis");
    const auto r = test::runEco("synth --terrain " + dem + " --canopy " + f.canopy + " --database " + f.db + " --abiotics " +
                                f.abiotics + " --out " + scene + " --gpkg " + gpkg + " --geotiff " + gis);
    INFO(r.output);
    REQUIRE(r.exitCode == 0);
    CHECK_THAT(r.output, Catch::Contains("the terrain's CRS") && Catch::Contains("wrote GeoTIFFs"));

    // The scene file keeps the CRS on its grids.
    const Grid<float> sceneTerrain = h5::File::openRead(scene).readGrid("/terrain/elevation");
    CHECK_THAT(sceneTerrain.crsWkt(), Catch::Contains("UTM zone 10N"));

    // Plants: every one in the GeoPackage, in UTM zone 10N, at the scene's coordinates.
    const synth::SceneData s = synth::readSceneFile(scene, w.biome);
    REQUIRE(s.undergrowth.size() > 1000);
    {
        GDALDataset* g = GDALDataset::Open(gpkg.c_str(), GDAL_OF_VECTOR | GDAL_OF_READONLY);
        REQUIRE(g != nullptr);
        OGRLayer* layer = g->GetLayerByName("plants");
        REQUIRE(layer != nullptr);
        CHECK(layer->GetFeatureCount() == static_cast<GIntBig>(s.canopy.size() + s.undergrowth.size()));
        REQUIRE(layer->GetSpatialRef() != nullptr);
        CHECK_THAT(std::string(layer->GetSpatialRef()->GetName()), Catch::Contains("UTM zone 10N"));
        layer->SetAttributeFilter("layer = 'undergrowth'");
        OGRFeature* ft = layer->GetNextFeature();
        REQUIRE(ft != nullptr);
        const OGRPoint* pt = ft->GetGeometryRef()->toPoint();
        const auto same = std::find_if(s.undergrowth.begin(), s.undergrowth.end(), [&](const Plant& p) {
            return std::abs(p.xM - pt->getX()) < 1e-6 && std::abs(p.yM - pt->getY()) < 1e-6;
        });
        REQUIRE(same != s.undergrowth.end());
        CHECK(ft->GetFieldAsDouble("height_m") == Approx(same->heightM).epsilon(1e-6));
        CHECK(pt->getX() > kX0);
        CHECK(pt->getY() > kY0);
        OGRFeature::DestroyFeature(ft);
        GDALClose(GDALDataset::ToHandle(g));
    }

    // Grids: the terrain back as the same cells, geotransform and CRS; maps as typed rasters.
    const TiffBack t = readTiffBack(gis + "/scene_terrain_elevation.tif");
    for (int i = 0; i < 6; ++i) CHECK(t.gt[i] == spec.geotransform[i]);
    CHECK_THAT(t.crsName, Catch::Contains("UTM zone 10N"));
    REQUIRE(t.northFirst.size() == spec.northFirst.size());
    CHECK(std::equal(t.northFirst.begin(), t.northFirst.end(), spec.northFirst.begin(),
                     [](double a, double b) { return static_cast<float>(a) == static_cast<float>(b); }));
    const TiffBack cluster = readTiffBack(gis + "/scene_cluster_map.tif");
    CHECK(cluster.type == "Int32");
    CHECK(cluster.hasNodata);
    CHECK(cluster.nodata == -1);
    CHECK_THAT(cluster.crsName, Catch::Contains("UTM zone 10N"));
    {  // the cluster map's cells are the scene's, north row first
        const Grid<std::int32_t> cm = h5::File::openRead(scene).readGridI32("/cluster_map");
        int mismatches = 0;
        for (int row = 0; row < cm.height(); ++row)
            for (int ix = 0; ix < cm.width(); ++ix)
                mismatches += cluster.northFirst[static_cast<std::size_t>(row * cm.width() + ix)] != cm(ix, cm.height() - 1 - row);
        CHECK(mismatches == 0);
    }
    for (const char* name : {"scene_forest_floor_grass.tif", "scene_forest_floor_litter.tif", "scene_combination_map.tif"})
        CHECK(readTiffBack(gis + "/" + name).crsName.find("UTM zone 10N") != std::string::npos);

    // The CRS travels through our HDF5: the terrain converted to .h5 and back to .tif, and a
    // synthesis on the .h5 terrain, keep it.
    const std::string demH5 = dir.file("dem.h5"), back = dir.file("back.tif");
    REQUIRE(test::runEco("terrain convert " + dem + " " + demH5).exitCode == 0);
    const auto conv = test::runEco("terrain convert " + demH5 + " " + back);
    INFO(conv.output);
    REQUIRE(conv.exitCode == 0);
    const TiffBack b = readTiffBack(back);
    for (int i = 0; i < 6; ++i) CHECK(b.gt[i] == spec.geotransform[i]);
    CHECK_THAT(b.crsName, Catch::Contains("UTM zone 10N"));
    const std::string gpkg2 = dir.file("scene2.gpkg");
    const auto r2 = test::runEco("synth --terrain " + demH5 + " --canopy " + f.canopy + " --database " + f.db + " --abiotics " +
                                 f.abiotics + " --out " + dir.file("scene2.h5") + " --gpkg " + gpkg2);
    INFO(r2.output);
    REQUIRE(r2.exitCode == 0);
    CHECK_THAT(r2.output, Catch::Contains("the terrain's CRS"));
}

TEST_CASE("eco synth: a database asking for more plants than fit in memory is refused before sampling", "[synth][cli][errors]") {
    World w = makeWorld();
    w.db.regions[0].densityPerM2 = 1e12;  // issue 26: grew past 5 GB and aborted inside an OpenMP region
    test::TempDir dir("synth_memory");
    const WorldFiles f = writeWorld(w, dir);
    const auto r = test::runEco("synth --terrain " + f.terrain + " --canopy " + f.canopy + " --database " + f.db +
                                    " --abiotics " + f.abiotics + " --out " + dir.file("scene.h5"),
                                3L * 1024 * 1024);
    INFO(r.output);
    CHECK(r.exitCode == 1);
    CHECK_THAT(r.output, Catch::Contains("undergrowth sampling of about") && Catch::Contains("needs about") &&
                             Catch::Contains("eco inspect"));
    CHECK_FALSE(std::filesystem::exists(dir.file("scene.h5")));
}

// ======================================================================== --method deussen

namespace {

/// A greyscale 8-bit PNG of the world's size: value(ix, iy) in [0, 1], row 0 = north.
void writeGreyPng(const std::string& path, int width, int height, const std::function<double(int, int)>& value) {
    std::vector<std::uint8_t> px(static_cast<std::size_t>(width) * static_cast<std::size_t>(height));
    for (int row = 0; row < height; ++row)
        for (int ix = 0; ix < width; ++ix)
            px[static_cast<std::size_t>(row) * static_cast<std::size_t>(width) + static_cast<std::size_t>(ix)] =
                static_cast<std::uint8_t>(std::lround(255.0 * value(ix, height - 1 - row)));
    REQUIRE(eco::test::writeImage(path, width, height, 1, eco::SampleType::UInt8, eco::SampleType::UInt8, px.data()));
}

}  // namespace

TEST_CASE("eco synth --method deussen: a scene from a density image, and bad input refused with one clear line",
          "[synth][cli][deussen]") {
    const World w = makeWorld();
    test::TempDir dir("synth_deussen");
    const WorldFiles f = writeWorld(w, dir);
    const std::string base = "synth --terrain " + f.terrain + " --canopy " + f.canopy + " --database " + f.db +
                             " --abiotics " + f.abiotics + " --out " + dir.file("scene.h5");
    // Western half dark grey (0.25), eastern half white (1).
    const std::string image = dir.file("density.png");
    writeGreyPng(image, kSide, kSide, [](int ix, int) { return ix < kSide / 2 ? 0.25 : 1.0; });

    SECTION("a scene with every output; the image decides where, the canopy stays as given") {
        const auto r = test::runEco(base + " --method deussen --density-image " + image + " --lloyd-iterations 4 --csv " +
                                    dir.file("plants.csv") + " --pdb " + dir.file("plants.pdb") + " --png " + dir.file("png"));
        INFO(r.output);
        REQUIRE(r.exitCode == 0);
        CHECK_THAT(r.output, Catch::Contains("deussen: ") && Catch::Contains("Clark-Evans R") &&
                                 Catch::Contains("density image: " + image));
        for (const char* name : {"scene.h5", "plants.csv", "plants.pdb", "png/scene.png", "png/cluster_map.png"})
            CHECK(std::filesystem::exists(dir.file(name)));
        const synth::SceneData scene = synth::readSceneFile(dir.file("scene.h5"), w.biome);
        REQUIRE(scene.canopy.size() == w.canopy.size());
        for (std::size_t i = 0; i < w.canopy.size(); ++i) {
            CHECK(scene.canopy[i].xM == w.canopy[i].xM);
            CHECK(scene.canopy[i].yM == w.canopy[i].yM);
            CHECK(scene.canopy[i].heightM == w.canopy[i].heightM);
        }
        std::size_t west = 0, east = 0;
        for (const Plant& p : scene.undergrowth) (p.xM < kSide * kCell / 2 ? west : east) += 1;
        INFO("west " << west << ", east " << east);
        // Four times the relative density in the east: well over twice the plants there.
        CHECK(east > 2 * west);
        CHECK(west > 0);
        h5::File file = h5::File::openRead(dir.file("scene.h5"));
        CHECK(file.attrString("/", "method") == "deussen");
        CHECK(file.attrInt("/", "deussen_lloyd_iterations") == 4);  // an integer attribute, not text
        CHECK(file.attrString("/", "deussen_density_image") == image);
    }
    SECTION("an unknown method") {
        const auto r = test::runEco(base + " --method halftone");
        INFO(r.output);
        CHECK(r.exitCode == 2);
        CHECK_THAT(r.output, Catch::Contains("--method") && Catch::Contains("halftone") && Catch::Contains("deussen"));
    }
    SECTION("a missing density image") {
        const auto r = test::runEco(base + " --method deussen --density-image " + dir.file("none.png"));
        INFO(r.output);
        CHECK(r.exitCode == 1);
        CHECK_THAT(r.output, Catch::Contains("none.png") && Catch::Contains("eco: error"));
    }
    SECTION("a density image of another size") {
        writeGreyPng(dir.file("small.png"), 50, 40, [](int, int) { return 1.0; });
        const auto r = test::runEco(base + " --method deussen --density-image " + dir.file("small.png"));
        INFO(r.output);
        CHECK(r.exitCode == 1);
        CHECK_THAT(r.output, Catch::Contains("small.png") && Catch::Contains("50 x 40") && Catch::Contains("200 x 200"));
    }
    SECTION("a black density image") {
        writeGreyPng(dir.file("black.png"), kSide, kSide, [](int, int) { return 0.0; });
        const auto r = test::runEco(base + " --method deussen --density-image " + dir.file("black.png"));
        INFO(r.output);
        CHECK(r.exitCode == 1);
        CHECK_THAT(r.output, Catch::Contains("black.png") && Catch::Contains("0 everywhere"));
    }
    SECTION("a density image with another method") {
        const auto r = test::runEco(base + " --density-image " + image);
        INFO(r.output);
        CHECK(r.exitCode == 1);
        CHECK_THAT(r.output, Catch::Contains("--density-image") && Catch::Contains("--method deussen only"));
    }
    SECTION("a negative number of Lloyd iterations") {
        const auto r = test::runEco(base + " --method deussen --lloyd-iterations -1");
        INFO(r.output);
        CHECK(r.exitCode == 2);
        CHECK_THAT(r.output, Catch::Contains("--lloyd-iterations"));
    }
    if (!std::filesystem::exists(dir.file("plants.csv"))) CHECK_FALSE(std::filesystem::exists(dir.file("scene.h5")));
}

// ======================================================================== --method xu2015

namespace {

/// A plant CSV in eco synth's layout (layer first): a 14 x 14 jittered grid of Western
/// Swordferns on 20 m x 20 m, plus one canopy row that the exemplar reader must skip.
void writeExemplarCsv(const std::string& path) {
    std::ofstream out(path);
    out << "layer,species_id,species,x_m,y_m,ground_z_m,height_m,crown_radius_m\n";
    out << "canopy,0,\"Redwood\",5,5,100,40,3\n";
    for (int j = 0; j < 14; ++j)
        for (int i = 0; i < 14; ++i)
            out << "undergrowth,1,\"Western Swordfern\"," << (i + 0.5) * 20.0 / 14 + 0.2 * std::sin(i * 7.0 + j) << ","
                << (j + 0.5) * 20.0 / 14 + 0.2 * std::cos(j * 5.0 + i) << ",100,0.6,0.4\n";
}

}  // namespace

TEST_CASE("eco synth --method xu2015: a scene from an exemplar CSV, and bad exemplars refused with one clear line",
          "[synth][cli][xu2015]") {
    const World w = makeWorld();
    test::TempDir dir("synth_xu2015");
    const WorldFiles f = writeWorld(w, dir);
    const std::string base = "synth --terrain " + f.terrain + " --canopy " + f.canopy + " --database " + f.db +
                             " --abiotics " + f.abiotics + " --out " + dir.file("scene.h5");
    const std::string exemplar = dir.file("stand.csv");
    writeExemplarCsv(exemplar);

    SECTION("a scene with every output; the exemplar's density over the seeded cells") {
        const auto r = test::runEco(base + " --method xu2015 --exemplar " + exemplar + " --csv " + dir.file("plants.csv") +
                                    " --pdb " + dir.file("plants.pdb") + " --png " + dir.file("png"));
        INFO(r.output);
        REQUIRE(r.exitCode == 0);
        CHECK_THAT(r.output, Catch::Contains("exemplar '" + exemplar + "': 196 undergrowth plants") &&
                                 Catch::Contains("xu2015: neighbourhood radius"));
        for (const char* name : {"scene.h5", "plants.csv", "plants.pdb", "png/scene.png", "png/cluster_map.png"})
            CHECK(std::filesystem::exists(dir.file(name)));
        const synth::SceneData scene = synth::readSceneFile(dir.file("scene.h5"), w.biome);
        // 0.49 per m^2 on the world's 200 m x 200 m, less trunks and cells without a region.
        INFO(scene.undergrowth.size() << " plants");
        CHECK(scene.undergrowth.size() > 0.8 * 0.49 * 200 * 200 * 0.5);
        CHECK(scene.undergrowth.size() < 1.1 * 0.49 * 200 * 200);
        h5::File file = h5::File::openRead(dir.file("scene.h5"));
        CHECK(file.attrString("/", "method") == "xu2015");
        CHECK(file.attrDouble("/", "xu_sigma") == 5.0);  // a typed attribute (docs/hdf5.md)
        CHECK_THAT(file.attrString("/", "xu_exemplar"), Catch::Contains("stand.csv"));
        // Our own CSV output is an exemplar in turn.
        const auto again = test::runEco("synth --terrain " + f.terrain + " --canopy " + f.canopy + " --database " + f.db +
                                        " --abiotics " + f.abiotics + " --out " + dir.file("scene2.h5") +
                                        " --method xu2015 --exemplar " + dir.file("plants.csv") +
                                        " --exemplar-window 60,60,140,140");
        INFO(again.output);
        CHECK(again.exitCode == 0);
    }
    SECTION("a missing exemplar file") {
        const auto r = test::runEco(base + " --method xu2015 --exemplar " + dir.file("none.csv"));
        INFO(r.output);
        CHECK(r.exitCode == 1);
        CHECK_THAT(r.output, Catch::Contains("none.csv") && Catch::Contains("cannot open"));
    }
    SECTION("an empty exemplar: a header and no undergrowth") {
        std::ofstream(dir.file("empty.csv")) << "x,y,species,height,crown_radius\n";
        const auto r = test::runEco(base + " --method xu2015 --exemplar " + dir.file("empty.csv"));
        INFO(r.output);
        CHECK(r.exitCode == 1);
        CHECK_THAT(r.output, Catch::Contains("empty.csv") && Catch::Contains("no undergrowth plants"));
    }
    SECTION("an exemplar without a crown radius column") {
        std::ofstream(dir.file("nocrown.csv")) << "x,y,species,height\n1,2,Toyon,1\n";
        const auto r = test::runEco(base + " --method xu2015 --exemplar " + dir.file("nocrown.csv"));
        INFO(r.output);
        CHECK(r.exitCode == 1);
        CHECK_THAT(r.output, Catch::Contains("nocrown.csv:1") && Catch::Contains("crown_radius"));
    }
    SECTION("an exemplar with a species outside the biome, and a bad number") {
        std::ofstream(dir.file("bad.csv")) << "x,y,species,height,crown_radius\n1,2,Toyon,1,0.5\n3,4,Baobab,1,0.5\n";
        auto r = test::runEco(base + " --method xu2015 --exemplar " + dir.file("bad.csv"));
        INFO(r.output);
        CHECK(r.exitCode == 1);
        CHECK_THAT(r.output, Catch::Contains("bad.csv:3") && Catch::Contains("Baobab"));
        std::ofstream(dir.file("nan.csv")) << "x,y,species,height,crown_radius\n1,2,Toyon,tall,0.5\n";
        r = test::runEco(base + " --method xu2015 --exemplar " + dir.file("nan.csv"));
        CHECK(r.exitCode == 1);
        CHECK_THAT(r.output, Catch::Contains("nan.csv:2") && Catch::Contains("height") && Catch::Contains("'tall'"));
    }
    SECTION("an exemplar too small for its neighbourhood") {
        std::ofstream(dir.file("tiny.csv")) << "x,y,species,height,crown_radius\n1,1,Toyon,1,0.5\n2,1,Toyon,1,0.5\n1,2,Toyon,1,0.5\n";
        const auto r = test::runEco(base + " --method xu2015 --exemplar " + dir.file("tiny.csv"));
        INFO(r.output);
        CHECK(r.exitCode == 1);
        CHECK_THAT(r.output, Catch::Contains("tiny.csv") && Catch::Contains("too small"));
    }
    SECTION("xu2015 without an exemplar, and its options with another method: usage errors") {
        auto r = test::runEco(base + " --method xu2015");
        INFO(r.output);
        CHECK(r.exitCode == 2);
        CHECK_THAT(r.output, Catch::Contains("--exemplar"));
        for (const std::string& opt : std::vector<std::string>{"--exemplar " + exemplar, "--xu-candidates 64", "--xu-sigma 2", "--exemplar-window 0,0,20,20"}) {
            r = test::runEco(base + " --method structured " + opt);
            INFO(opt << ": " << r.output);
            CHECK(r.exitCode == 2);
            CHECK_THAT(r.output, Catch::Contains("--method xu2015 only"));
        }
        r = test::runEco(base + " --exemplar " + exemplar);  // the default method
        CHECK(r.exitCode == 2);
    }
    if (!std::filesystem::exists(dir.file("plants.csv"))) CHECK_FALSE(std::filesystem::exists(dir.file("scene.h5")));
}
