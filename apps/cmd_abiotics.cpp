// eco abiotics: parsing, progress and pictures only; the models are in core/abiotics.
#include <algorithm>
#include <array>
#include <cstdio>
#include <iostream>
#include <memory>
#include <sstream>
#include <string>

#include "abiotics.h"
#include "atomic_file.h"
#include "biome.h"
#include "canopy_placer.h"
#include "cli_common.h"
#include "error.h"
#include "image_out.h"
#include "terrain_io.h"
#include "text_format.h"

namespace eco::cli {

namespace {

constexpr std::array<const char*, 12> kMonthShort = {"jan", "feb", "mar", "apr", "may", "jun",
                                                     "jul", "aug", "sep", "oct", "nov", "dec"};
constexpr std::array<const char*, 12> kMonthLong = {"January", "February", "March",     "April",
                                                    "May",     "June",     "July",      "August",
                                                    "September", "October", "November", "December"};

/// Fixed colour ranges so that months can be compared picture to picture.
constexpr double kSunPngMaxHours = 15.0;

struct AbioticsArgs {
    std::string terrain;
    std::string biome;
    std::string out;
    std::string pngDir;
    std::string canopy;
    double cellSizeM = 0;
    double verticalScale = 1;
    double verticalOffsetM = 0;
    double sunStepMinutes = 10;
};

std::string num(double v) { return formatNumber(v, 6); }

/// "sun_01_jan.png" in dir.
std::string monthlyName(const std::string& dir, const std::string& map, int m) {
    char buf[64];
    std::snprintf(buf, sizeof buf, "%s_%02d_%s.png", map.c_str(), m + 1, kMonthShort[static_cast<std::size_t>(m)]);
    return dir + "/" + buf;
}

void writePictures(const std::string& dir, const Abiotics& a, const Biome& biome) {
    ensureDirectory(dir);
    double tMin = a.temperatureC[0].minValue(), tMax = a.temperatureC[0].maxValue();
    for (const auto& g : a.temperatureC.months) {
        tMin = std::min<double>(tMin, g.minValue());
        tMax = std::max<double>(tMax, g.maxValue());
    }
    Progress bar("abiotics pictures", 2 + 3 * 12);
    long done = 0;
    writeMapPng(dir + "/elevation.png", a.elevationM, "Elevation", "m", Colormap::Terrain);
    bar.update(++done);
    writeMapPng(dir + "/slope.png", a.slopeDeg, "Slope", "degrees", Colormap::Viridis);
    bar.update(++done);
    for (int m = 0; m < 12; ++m) {
        const std::string month = kMonthLong[static_cast<std::size_t>(m)];
        writeMapPng(monthlyName(dir, "sun", m), a.sunHours[m], "Sunlight, " + month, "hours/day", Colormap::Heat, 0.0,
                    kSunPngMaxHours);
        writeMapPng(monthlyName(dir, "moisture", m), a.moistureMm[m], "Soil moisture, " + month, "mm/month",
                    Colormap::Blues, 0.0, biome.soil.saturationMm);
        writeMapPng(monthlyName(dir, "temperature", m), a.temperatureC[m], "Temperature, " + month, "degC",
                    Colormap::Viridis, tMin, tMax);
        done += 3;
        bar.update(done);
    }
    bar.finish();
    std::cout << "wrote pictures: " << dir << "/ (elevation.png, slope.png, sun_MM_mon.png, moisture_MM_mon.png, "
              << "temperature_MM_mon.png for 12 months)\n";
}

void runAbiotics(const AbioticsArgs& args) {
    TerrainReadOptions readOptions;
    readOptions.cellSizeM = args.cellSizeM;
    readOptions.verticalScale = args.verticalScale;
    readOptions.verticalOffsetM = args.verticalOffsetM;
    const Grid<float> terrain = readTerrain(args.terrain, readOptions);
    validateElevation(terrain, args.terrain);
    const Biome biome = args.biome.empty() ? defaultBiome() : loadBiome(args.biome);

    AbioticParams params;
    params.sun.stepMinutes = args.sunStepMinutes;
    info("terrain: " + args.terrain + ": " + std::to_string(terrain.width()) + " x " + std::to_string(terrain.height()) +
         " cells of " + num(terrain.cellSizeM()) + " m, elevation " + num(terrain.minValue()) + " .. " +
         num(terrain.maxValue()) + " m");
    info("biome: " + biome.name + (args.biome.empty() ? " (embedded)" : " (" + args.biome + ")") + ", latitude " +
         num(biome.climate.latitudeDeg) + " deg");

    // Read the canopy first: a bad file fails before the long computation.
    std::vector<Plant> canopy;
    if (!args.canopy.empty()) {
        const CanopyFileData c = readCanopyFile(args.canopy, biome);
        if (!c.terrainM.sameGeometry(terrain))
            throw ValidationError("canopy '" + args.canopy + "' was placed on a terrain of " + c.terrainM.geometryText() +
                                  " but --terrain '" + args.terrain + "' is " + terrain.geometryText());
        canopy = c.trees;
        info("canopy: " + args.canopy + ": " + std::to_string(canopy.size()) + " trees shade the sun maps");
    }

    AbioticsProgress progress;
    Abiotics maps = computeAbiotics(terrain, biome, params, [&](const std::string& s, double f) { progress(s, f); });
    progress.finish();
    if (!args.canopy.empty()) {
        maps.sunHours = applyCanopyShade(maps.sunHours, shadingTrees(canopy, biome));
        maps.canopyShadeSource = args.canopy;
    }

    writeAbiotics(args.out, maps, biome, params);
    std::cout << "wrote abiotics: " << args.out << " (/elevation, /slope, /sun [12][" << terrain.height() << "]["
              << terrain.width() << "] hours/day" << (args.canopy.empty() ? "" : " under the canopy")
              << ", /moisture mm, /temperature degC)\n";
    if (!args.pngDir.empty()) writePictures(args.pngDir, maps, biome);
}

}  // namespace

void registerAbioticsCommand(CLI::App& app) {
    auto args = std::make_shared<AbioticsArgs>();
    CLI::App* cmd = app.add_subcommand(
        "abiotics",
        "Monthly abiotic maps of a terrain: sunlight (hours/day, terrain shadows and sky view), soil moisture "
        "(mm), temperature (degC), and slope (degrees); written to one HDF5 file");
    cmd->add_option("--terrain", args->terrain, "Terrain (.asc, .h5, .png, .tif, .exr), elevations in metres")
        ->required();
    cmd->add_option("--biome", args->biome, "Biome TOML (default: the embedded Sonoma biome)");
    cmd->add_option("--out", args->out, "Output HDF5 file, e.g. abiotics.h5 (written atomically)")->required();
    cmd->add_option("--png", args->pngDir, "Also write one PNG per map and month into this directory");
    cmd->add_option("--canopy", args->canopy,
                    "Canopy file from 'eco canopy' on this terrain: shade the sun maps under its crowns (each crown "
                    "x (1 - alpha)); for looking at the light under the canopy. eco simulate, analyse and synth "
                    "shade with their canopy themselves and want the unshaded file");
    cmd->add_option("--cell-size", args->cellSizeM,
                    "Metres per cell (required for image terrains; checked against .asc / .h5)")
        ->check(positiveNumber());
    cmd->add_option("--vertical-scale", args->verticalScale, "Image terrains only: metres per stored unit")
        ->capture_default_str();
    cmd->add_option("--vertical-offset", args->verticalOffsetM, "Image terrains only: metres added after scaling")
        ->capture_default_str();
    cmd->add_option("--sun-step", args->sunStepMinutes, "Sampling interval of the sun path, minutes")
        ->check(CLI::Range(0.1, 720.0))
        ->capture_default_str();
    cmd->callback([args] { runAbiotics(*args); });
}

}  // namespace eco::cli
