#include "sim_input.h"

#include <algorithm>
#include <cstdlib>
#include <filesystem>

#include "abiotics.h"
#include "error.h"
#include "sim_file.h"

namespace eco::analysis {

namespace {

std::string resolveBeside(const std::string& target, const std::string& besideFile) {
    std::error_code ec;
    if (target.empty() || std::filesystem::exists(target, ec)) return target;
    const std::filesystem::path p(target);
    if (p.is_absolute()) return target;
    const std::filesystem::path alt = std::filesystem::path(besideFile).parent_path() / p;
    return std::filesystem::exists(alt, ec) ? alt.string() : target;
}

}  // namespace

LoadedSimulation readSimulation(const std::string& path, const SimulationReadOptions& options) {
    SimulationFileData file = readSimulationFile(path, options.year);  // the format's reader (core/sim_file.h)
    LoadedSimulation out;
    auto biome = std::make_shared<Biome>(std::move(file.biome));
    out.biome = biome;
    out.years = file.years;
    AnalysisInput& in = out.input;
    in.biome = out.biome.get();
    in.undergrowth = std::move(file.undergrowth);
    in.canopy = std::move(file.canopy);

    // Abiotics: annual means.
    const std::string& recorded = file.abioticsPath;
    std::string abioticsPath = options.abioticsPath;
    if (abioticsPath.empty()) {
        if (recorded.empty())
            throw IoError(path + ": root attribute 'abiotics_path' is missing; give the abiotics file with --abiotics");
        abioticsPath = resolveBeside(recorded, path);
    }
    Abiotics ab;
    try {
        ab = readAbiotics(abioticsPath);
    } catch (const IoError& e) {
        throw IoError(std::string(e.what()) + " (abiotics of simulation " + path +
                      (options.abioticsPath.empty() ? "; override with --abiotics" : "") + ")");
    }
    if (!ab.canopyShadeSource.empty())
        throw ValidationError(abioticsPath + ": its sun is already shaded by the canopy of " + ab.canopyShadeSource +
                              "; the analyser shades with the simulation's canopy itself: give the terrain's own "
                              "abiotics (eco abiotics without --canopy)");
    // Region features: the sun under the simulation's canopy, so that clearings, forest edges
    // and deep shade can fall into different regions (the synthesizer shades its target alike).
    const Grid<float> shadedSun = applyCanopyShade(ab.sunHours, shadingTrees(in.canopy, *biome)).annualMean();
    in.features = annualFactors(ab, &shadedSun);

    // Area.
    if (file.area) {
        in.window = RectWindow{(*file.area)[0], (*file.area)[1], (*file.area)[2], (*file.area)[3]};
    } else {
        const Grid<float>& g = in.features.geometry();
        in.window = RectWindow{g.originX(), g.originY(), g.originX() + g.extentX(), g.originY() + g.extentY()};
    }
    try {
        in.window.validate(path + ": area x0, y0, x1, y1");
    } catch (const ValidationError& e) {
        throw IoError(e.what());
    }

    // Provenance.
    DbInput& p = in.provenance;
    p.path = path;
    p.abioticsPath = abioticsPath;
    p.terrainPath = file.terrainPath;
    p.canopyPath = file.canopyPath;
    p.seed = file.seed;
    p.year = file.year;
    p.parameters = file.modelToml;
    out.seedOuterRadiusFactor = file.seedOuterRadiusFactor;
    return out;
}

}  // namespace eco::analysis
