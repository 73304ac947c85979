#include "abiotics_stage.h"

#include <algorithm>
#include <array>
#include <cstdio>
#include <ostream>

#include "atomic_file.h"
#include "biome.h"
#include "canopy_placer.h"
#include "error.h"
#include "image_out.h"
#include "terrain_io.h"
#include "text_format.h"

namespace eco::pipeline {

namespace {

constexpr std::array<const char*, 12> kMonthShort = {"jan", "feb", "mar", "apr", "may", "jun",
                                                     "jul", "aug", "sep", "oct", "nov", "dec"};
constexpr std::array<const char*, 12> kMonthLong = {"January", "February", "March",     "April",
                                                    "May",     "June",     "July",      "August",
                                                    "September", "October", "November", "December"};

/// Fixed colour ranges so that months can be compared picture to picture.
constexpr double kSunPngMaxHours = 15.0;

std::string num(double v) { return formatNumber(v, 6); }

/// "sun_01_jan.png" in dir.
std::string monthlyName(const std::string& dir, const std::string& map, int m) {
    char buf[64];
    std::snprintf(buf, sizeof buf, "%s_%02d_%s.png", map.c_str(), m + 1, kMonthShort[static_cast<std::size_t>(m)]);
    return dir + "/" + buf;
}

void writePictures(const std::string& dir, const Abiotics& a, const Biome& biome, Reporter& reporter,
                   std::vector<std::string>& written) {
    ensureDirectory(dir);
    double tMin = a.temperatureC[0].minValue(), tMax = a.temperatureC[0].maxValue();
    for (const auto& g : a.temperatureC.months) {
        tMin = std::min<double>(tMin, g.minValue());
        tMax = std::max<double>(tMax, g.maxValue());
    }
    auto bar = reporter.progress("abiotics pictures", 3 + 3 * 12);
    long done = 0;
    writeMapPng(dir + "/elevation.png", a.elevationM, "Elevation", "m", Colormap::Terrain);
    bar->update(++done);
    writeMapPng(dir + "/slope.png", a.slopeDeg, "Slope", "degrees", Colormap::Viridis);
    bar->update(++done);
    // Wind: 0 (sheltered) .. the biome's strength (open ground), so that biomes compare.
    writeMapPng(dir + "/wind.png", a.windMS, "Wind exposure", "m/s", Colormap::Blues, 0.0,
                std::max(biome.wind.strengthMS, 1e-3));
    bar->update(++done);
    written.insert(written.end(), {dir + "/elevation.png", dir + "/slope.png", dir + "/wind.png"});
    for (int m = 0; m < 12; ++m) {
        const std::string month = kMonthLong[static_cast<std::size_t>(m)];
        writeMapPng(monthlyName(dir, "sun", m), a.sunHours[m], "Sunlight, " + month, "hours/day", Colormap::Heat, 0.0,
                    kSunPngMaxHours);
        writeMapPng(monthlyName(dir, "moisture", m), a.moistureMm[m], "Soil moisture, " + month, "mm/month",
                    Colormap::Blues, 0.0, biome.soil.saturationMm);
        writeMapPng(monthlyName(dir, "temperature", m), a.temperatureC[m], "Temperature, " + month, "degC",
                    Colormap::Viridis, tMin, tMax);
        written.insert(written.end(), {monthlyName(dir, "sun", m), monthlyName(dir, "moisture", m),
                                       monthlyName(dir, "temperature", m)});
        done += 3;
        bar->update(done);
    }
    bar->finish();
    reporter.out() << "wrote pictures: " << dir << "/ (elevation.png, slope.png, wind.png, sun_MM_mon.png, moisture_MM_mon.png, "
                   << "temperature_MM_mon.png for 12 months)\n";
}

}  // namespace

AbioticsResult abioticsStage(const AbioticsOptions& args, Reporter& reporter) {
    requireOutputsNotInputs({{"--out", args.out}}, {args.terrain, args.biome, args.canopy});
    const Grid<float> terrain = readTerrain(args.terrain, args.terrainRead.options());
    validateElevation(terrain, args.terrain);
    const Biome biome = args.biome.empty() ? defaultBiome() : loadBiome(args.biome);

    AbioticParams params;
    params.sun.stepMinutes = args.sunStepMinutes;
    reporter.info("terrain: " + args.terrain + ": " + std::to_string(terrain.width()) + " x " +
                  std::to_string(terrain.height()) + " cells of " + num(terrain.cellSizeM()) + " m, elevation " +
                  num(terrain.minValue()) + " .. " + num(terrain.maxValue()) + " m");
    reporter.info("biome: " + biome.name + (args.biome.empty() ? " (embedded)" : " (" + args.biome + ")") +
                  ", latitude " + num(biome.climate.latitudeDeg) + " deg");

    cleanUpAfterDeadWriters(args.out);  // what killed runs left
    if (!args.geotiffDir.empty()) prepareOutputDirectory(args.geotiffDir);
    if (!args.pngDir.empty()) cleanUpDirectoryAfterDeadWriters(args.pngDir);
    // Read the canopy first: a bad file fails before the long computation.
    std::vector<Plant> canopy;
    if (!args.canopy.empty()) {
        const CanopyFileData c = readCanopyFile(args.canopy, biome);
        if (!c.terrainM.sameGeometry(terrain))
            throw ValidationError("canopy '" + args.canopy + "' was placed on a terrain of " + c.terrainM.geometryText() +
                                  " but --terrain '" + args.terrain + "' is " + terrain.geometryText());
        canopy = c.trees;
        reporter.info("canopy: " + args.canopy + ": " + std::to_string(canopy.size()) + " trees shade the sun maps");
    }

    AbioticsResult result;
    AbioticsProgress progress(reporter);
    result.maps = computeAbiotics(terrain, biome, params, [&](const std::string& s, double f) { progress(s, f); });
    progress.finish();
    Abiotics& maps = result.maps;
    if (!args.canopy.empty()) {
        maps.sunHours = applyCanopyShade(maps.sunHours, shadingTrees(canopy, biome));
        maps.canopyShadeSource = args.canopy;
    }

    AtomicOutputSet outputs;  // the abiotics file, GeoTIFFs and pictures together
    writeAbiotics(args.out, maps, biome, params);
    result.written.push_back(args.out);
    reporter.out() << "wrote abiotics: " << args.out << " (/elevation, /slope, /sun [12][" << terrain.height() << "]["
                   << terrain.width() << "] hours/day" << (args.canopy.empty() ? "" : " under the canopy")
                   << ", /moisture mm, /temperature degC, /wind m/s)\n";
    if (!args.geotiffDir.empty()) writeGeoTiffs(args.out, outputs, args.geotiffDir, reporter, result.written);
    if (!args.pngDir.empty()) writePictures(args.pngDir, maps, biome, reporter, result.written);
    outputs.commit();
    return result;
}

std::vector<std::string> commandLine(const AbioticsOptions& a) {
    std::vector<std::string> args = {"abiotics", "--terrain", a.terrain, "--out", a.out};
    if (!a.pngDir.empty()) args.insert(args.end(), {"--png", a.pngDir});
    if (!a.geotiffDir.empty()) args.insert(args.end(), {"--geotiff", a.geotiffDir});
    args.insert(args.end(), {"--sun-step", argNumber(a.sunStepMinutes)});
    a.terrainRead.appendArgs(args);
    if (!a.canopy.empty()) args.insert(args.end(), {"--canopy", a.canopy});
    if (!a.biome.empty()) args.insert(args.end(), {"--biome", a.biome});
    return args;
}

}  // namespace eco::pipeline
