// Command-line tests of `eco` for the canopy_placer module (split from canopy_placer_test.cpp, issue 23):
// they run the eco binary (ECO_BINARY) and live in eco_cli_tests, apart from the unit tests.
#include <catch2/catch.hpp>
#include <omp.h>

#include <cmath>
#include <fstream>
#include <limits>
#include <sstream>

#include "biome.h"
#include "canopy_placer.h"
#include "error.h"
#include "generate.h"
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
    {  // negative heights
        Grid<float> c(48, 40, 1.0, 0, 0, 5.f);
        c(7, 3) = -0.5f;
        writeTerrain(f.dir.file("negative.asc"), c);
        const auto r = test::runEco(base + " --chm " + f.dir.file("negative.asc"));
        CHECK(r.exitCode != 0);
        CHECK_THAT(r.output, Catch::Contains("negative.asc") && Catch::Contains("(7, 3)"));
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
