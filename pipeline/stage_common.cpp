#include "stage_common.h"

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <sstream>
#include <string>

#include "atomic_file.h"
#include "error.h"
#include "geo_raster.h"
#include "text_format.h"

namespace eco::pipeline {

TerrainReadOptions TerrainReadFlags::options() const {
    TerrainReadOptions o;
    if (cellSizeM) o.cellSizeM = *cellSizeM;
    if (verticalScale) o.verticalScale = *verticalScale;
    if (verticalOffsetM) o.verticalOffsetM = *verticalOffsetM;
    return o;
}

void TerrainReadFlags::appendArgs(std::vector<std::string>& args) const {
    if (cellSizeM) args.insert(args.end(), {"--cell-size", argNumber(*cellSizeM)});
    if (verticalScale) args.insert(args.end(), {"--vertical-scale", argNumber(*verticalScale)});
    if (verticalOffsetM) args.insert(args.end(), {"--vertical-offset", argNumber(*verticalOffsetM)});
}

std::string argNumber(double v) {
    char buf[64];
    std::snprintf(buf, sizeof buf, "%.10g", v);
    return buf;
}

// CLI11 reads a floating-point option with strtold and narrows it to double; so does this.
double asOnCommandLine(double v) { return static_cast<double>(std::strtold(argNumber(v).c_str(), nullptr)); }

std::string quotedCommand(const std::vector<std::string>& args) {
    std::string s = "eco";
    for (const auto& a : args) s += " " + (a.find(' ') == std::string::npos ? a : "'" + a + "'");
    return s;
}

void prepareOutput(const std::string& path) {
    const std::filesystem::path p(path);
    if (p.has_parent_path()) ensureDirectory(p.parent_path().string());
    cleanUpAfterDeadWriters(path);
}

void requireOutputsNotInputs(const std::vector<std::pair<std::string, std::string>>& outputs,
                             const std::vector<std::string>& inputs) {
    for (const auto& [flag, out] : outputs) {
        if (out.empty()) continue;
        for (const std::string& in : inputs) {
            if (in.empty()) continue;
            std::error_code ec;
            if (std::filesystem::equivalent(out, in, ec) && !ec)
                throw ValidationError(flag + " '" + out + "' is the input '" + in +
                                      "': writing it would destroy the input; choose another output path");
        }
    }
}

void requireDistinctOutputs(const std::vector<std::pair<std::string, std::string>>& outputs) {
    for (std::size_t i = 0; i < outputs.size(); ++i)
        for (std::size_t j = i + 1; j < outputs.size(); ++j) {
            const auto& [flagA, a] = outputs[i];
            const auto& [flagB, b] = outputs[j];
            if (a.empty() || b.empty()) continue;
            std::error_code ea, eb;
            const auto ca = std::filesystem::weakly_canonical(a, ea), cb = std::filesystem::weakly_canonical(b, eb);
            if (ea || eb ? a == b : ca == cb)
                throw ValidationError(flagA + " '" + a + "' and " + flagB + " '" + b +
                                      "' are the same file: one output would replace the other; give two paths");
        }
}

void prepareOutputDirectory(const std::string& dir) {
    ensureDirectory(dir);
    cleanUpDirectoryAfterDeadWriters(dir);
}

void writeGeoTiffs(const std::string& h5Path, const AtomicOutputSet& outputs, const std::string& dir, Reporter& reporter,
                   std::vector<std::string>& written) {
    ensureDirectory(dir);
    const std::vector<std::string> files =
        exportGridsAsGeoTiff(outputs.readablePath(h5Path), dir, std::filesystem::path(h5Path).stem().string() + "_");
    std::string names;
    for (const std::string& f : files) names += (names.empty() ? "" : ", ") + std::filesystem::path(f).filename().string();
    reporter.out() << "wrote GeoTIFFs: " << dir << "/ (" << names << ")\n";
    written.insert(written.end(), files.begin(), files.end());
}

namespace {

void setCrs(Abiotics& a, const std::string& wkt) {
    for (const AbioticMapInfo& m : kAbioticMaps) forEachPlane(a, m, [&](Grid<float>& g) { g.setCrsWkt(wkt); });
    a.elevationM.setCrsWkt(wkt);
}

}  // namespace

void warnLatitudeMismatch(const Grid<float>& terrain, const std::string& terrainPath, const Biome& biome,
                          const std::string& biomePath, Reporter& reporter) {
    double lat = 0, lon = 0;
    if (!gridCentreLatLon(terrain, lat, lon)) return;
    if (!(std::abs(lat - biome.climate.latitudeDeg) > kLatitudeWarningDeg)) return;
    reporter.info("warning: terrain '" + terrainPath + "' lies at latitude " + formatNumber(lat, 4) +
                  " deg (its centre, from its CRS) but the sun's path is computed for the biome's latitude_deg " +
                  formatNumber(biome.climate.latitudeDeg, 4) + " (biome " + biome.name +
                  (biomePath.empty() ? std::string() : ", " + biomePath) + "); for the site's sunlight set [climate] latitude_deg in a biome file (eco biome show > biome.toml) "
                  "and give it with --biome");
}

Abiotics abioticsForTerrain(const std::string& abioticsPath, const Grid<float>& terrain,
                            const std::string& terrainPath, const Biome& biome, const std::string& note,
                            Reporter& reporter) {
    if (!abioticsPath.empty()) {
        Abiotics abiotics = readAbiotics(abioticsPath);
        if (!abiotics.slopeDeg.sameGeometry(terrain))
            throw ValidationError("abiotics '" + abioticsPath + "' (" + abiotics.slopeDeg.geometryText() +
                                  ") and terrain '" + terrainPath + "' (" + terrain.geometryText() +
                                  ") differ in geometry");
        reporter.info("abiotics: " + abioticsPath);
        // One CRS for the terrain and its abiotics (a file made before the terrain was
        // georeferenced takes the terrain's): the maps derived from them keep it.
        setCrs(abiotics, sharedCrs(terrain.crsWkt(), "terrain '" + terrainPath + "'", abiotics.slopeDeg.crsWkt(),
                                   "abiotics '" + abioticsPath + "'"));
        return abiotics;
    }
    reporter.info("no --abiotics: computing the abiotic maps from the terrain with default parameters (" + note + ")");
    validateElevation(terrain, terrainPath);
    warnLatitudeMismatch(terrain, terrainPath, biome, "", reporter);
    AbioticsProgress progress(reporter);
    Abiotics abiotics = computeAbiotics(terrain, biome, AbioticParams{},
                                        [&](const std::string& s, double f) { progress(s, f); });
    progress.finish();
    setCrs(abiotics, terrain.crsWkt());
    return abiotics;
}

RectWindow parseWindow(const std::string& text, const std::string& option, bool allowSquare) {
    std::vector<double> v;
    std::stringstream ss(text);
    std::string item;
    while (std::getline(ss, item, ',')) {
        std::size_t used = 0;
        double d = 0;
        try {
            d = std::stod(item, &used);
        } catch (const std::exception&) {
            used = 0;
        }
        if (used == 0 || item.find_first_not_of(" \t", used) != std::string::npos || !std::isfinite(d))
            throw ValidationError(option + " '" + text + "': '" + item + "' is not a number");
        v.push_back(d);
    }
    RectWindow w;
    if (allowSquare && v.size() == 3) {
        if (!(v[2] > 0)) throw ValidationError(option + " '" + text + "': the side must be positive");
        w = RectWindow{v[0] - 0.5 * v[2], v[1] - 0.5 * v[2], v[0] + 0.5 * v[2], v[1] + 0.5 * v[2]};
    } else if (v.size() == 4) {
        w = RectWindow{v[0], v[1], v[2], v[3]};
    } else {
        throw ValidationError(option + " '" + text + "': expected " +
                              (allowSquare ? std::string("x_centre,y_centre,side or ") : std::string()) + "x0,y0,x1,y1 in metres");
    }
    w.validate(option);
    return w;
}

}  // namespace eco::pipeline
