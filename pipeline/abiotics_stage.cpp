#include "abiotics_stage.h"

#include <algorithm>
#include <array>
#include <cctype>
#include <cstdio>
#include <limits>
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

/// A picture's title, colour map and colour range (vmin >= vmax: the data's own).
struct PictureStyle {
    std::string title;
    Colormap cmap;
    double vmin = 0, vmax = 0;
};

/// The picture of map m of kAbioticMaps. The sun, moisture and wind have ranges of their own
/// (fixed, so that months and biomes compare); every other map, a map added later too, is
/// drawn in Viridis with its factor's label as the title over the range of its values (for
/// a monthly map, over all its months, so that months compare), with no line here.
PictureStyle pictureStyle(const AbioticMapInfo& m, const Abiotics& a, const Biome& biome) {
    const std::string name = m.name;
    if (name == "sun") return {"Sunlight", Colormap::Heat, 0.0, kSunPngMaxHours};
    if (name == "moisture") return {"Soil moisture", Colormap::Blues, 0.0, biome.soil.saturationMm};
    // Wind: 0 (sheltered) .. the biome's strength (open ground), so that biomes compare.
    if (name == "wind") return {"Wind exposure", Colormap::Blues, 0.0, std::max(biome.wind.strengthMS, 1e-3)};
    std::string title = kFactors[factorIndex(m.factor)].label;
    if (!title.empty()) title[0] = static_cast<char>(std::toupper(static_cast<unsigned char>(title[0])));
    if (!m.isMonthly()) return {title, Colormap::Viridis};
    double lo = std::numeric_limits<double>::infinity(), hi = -lo;
    forEachPlane(a, m, [&](const Grid<float>& g) {
        lo = std::min<double>(lo, g.minValue());
        hi = std::max<double>(hi, g.maxValue());
    });
    return {title, Colormap::Viridis, lo, hi};
}

/// The elevation, then each static map, then each month's monthly maps, in kAbioticMaps order.
void writePictures(const std::string& dir, const Abiotics& a, const Biome& biome, Reporter& reporter,
                   std::vector<std::string>& written) {
    ensureDirectory(dir);
    std::size_t monthlyMaps = 0;
    for (const AbioticMapInfo& m : kAbioticMaps) monthlyMaps += m.isMonthly() ? 1 : 0;
    auto bar = reporter.progress("abiotics pictures",
                                 static_cast<long>(1 + kStaticMapCount + monthlyMaps * 12));
    long done = 0;
    std::string listed = "elevation.png";
    writeMapPng(dir + "/elevation.png", a.elevationM, "Elevation", "m", Colormap::Terrain);
    written.push_back(dir + "/elevation.png");
    bar->update(++done);
    for (const AbioticMapInfo& m : kStaticMaps) {
        const PictureStyle style = pictureStyle(m, a, biome);
        const std::string path = dir + "/" + m.name + ".png";
        writeMapPng(path, a.*(m.single), style.title, m.unit, style.cmap, style.vmin, style.vmax);
        written.push_back(path);
        listed += std::string(", ") + m.name + ".png";
        bar->update(++done);
    }
    std::vector<PictureStyle> styles(kAbioticMaps.size());
    for (std::size_t i = 0; i < kAbioticMaps.size(); ++i)
        if (kAbioticMaps[i].isMonthly()) {
            styles[i] = pictureStyle(kAbioticMaps[i], a, biome);
            listed += std::string(", ") + kAbioticMaps[i].name + "_MM_mon.png";
        }
    for (int month = 0; month < 12; ++month) {
        const std::string monthName = kMonthLong[static_cast<std::size_t>(month)];
        for (std::size_t i = 0; i < kAbioticMaps.size(); ++i) {
            const AbioticMapInfo& m = kAbioticMaps[i];
            if (!m.isMonthly()) continue;
            const std::string path = monthlyName(dir, m.name, month);
            writeMapPng(path, (a.*(m.monthly))[month], styles[i].title + ", " + monthName, m.unit, styles[i].cmap,
                        styles[i].vmin, styles[i].vmax);
            written.push_back(path);
            ++done;
        }
        bar->update(done);
    }
    bar->finish();
    reporter.out() << "wrote pictures: " << dir << "/ (" << listed << " for 12 months)\n";
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
    warnLatitudeMismatch(terrain, args.terrain, biome, args.biome.empty() ? "embedded" : args.biome, reporter);

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
    // "/elevation m, /slope degrees, /sun [12][H][W] hours/day, ...": every map of the file.
    std::string listed = "/elevation m";
    for (const AbioticMapInfo& m : kAbioticMaps) {
        listed += std::string(", ") + m.dataset;
        if (m.isMonthly())
            listed += " [12][" + std::to_string(terrain.height()) + "][" + std::to_string(terrain.width()) + "]";
        listed += std::string(" ") + m.unit;
        if (m.factor == Factor::Sun && !args.canopy.empty()) listed += " under the canopy";
    }
    reporter.out() << "wrote abiotics: " << args.out << " (" << listed << ")\n";
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
