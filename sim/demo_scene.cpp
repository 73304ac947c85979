#include "demo_scene.h"

#include <algorithm>
#include <cmath>

#include "generate.h"

namespace eco::sim {

SimInputs makeDemoScene(const DemoSceneParams& p, const Biome& biome) {
    TerrainGenParams tp;
    tp.width = tp.height = p.cells;
    tp.cellSizeM = p.cellSizeM;
    tp.seed = p.seed;
    // Keep the relief proportionate on small scenes.
    const double extent = p.cells * p.cellSizeM;
    tp.reliefM = std::min(120.0, 0.25 * extent);
    tp.valleyDepthM = std::min(40.0, 0.1 * extent);
    tp.valleyHalfWidthM = std::min(70.0, 0.3 * extent);
    Grid<float> elevation = generateTerrain(tp);

    SimInputs in;
    in.biome = biome;
    if (p.uniformAbiotics) {
        // Every map of kAbioticMaps first takes its model's value on open flat ground at 100 m
        // (3 x 3 cells, the biome's climate), uniform: the wind is the biome's full strength.
        // A map added later thus needs no line here. Then the demo's own constant climate
        // replaces the sun, moisture and temperature, and its slope the flat ground's.
        AbioticParams flatParams;
        flatParams.sun.stepMinutes = 60;
        flatParams.moistureSpinUpYears = 0;
        const Abiotics flat =
            computeAbiotics(Grid<float>(3, 3, elevation.cellSizeM(), 0.0, 0.0, 100.f), biome, flatParams);
        in.abiotics.elevationM = Grid<float>::like(elevation, 100.f);
        for (const AbioticMapInfo& map : kAbioticMaps) {
            if (map.isMonthly())
                for (const Grid<float>& plane : (flat.*(map.monthly)).months)
                    (in.abiotics.*(map.monthly)).months.push_back(Grid<float>::like(elevation, plane(1, 1)));
            else
                in.abiotics.*(map.single) = Grid<float>::like(elevation, (flat.*(map.single))(1, 1));
        }
        in.abiotics.slopeDeg = Grid<float>::like(elevation, 5.f);
        for (int m = 0; m < 12; ++m) {
            // Day length at the biome's latitude; soil water following the rain, lagged.
            const double day = 12.0 + 2.4 * std::cos((m - 5.5) / 12.0 * 2.0 * M_PI);
            in.abiotics.sunHours[m] = Grid<float>::like(elevation, static_cast<float>(day));
            const double water = std::min(180.0, 0.8 * biome.climate.rainfallMm[static_cast<std::size_t>(m)] + 30.0);
            in.abiotics.moistureMm[m] = Grid<float>::like(elevation, static_cast<float>(water));
            const double t = biome.climate.temperatureC[static_cast<std::size_t>(m)] - 100.0 * biome.climate.lapseRateCPerKm / 1000.0;
            in.abiotics.temperatureC[m] = Grid<float>::like(elevation, static_cast<float>(t));
        }
    } else {
        AbioticParams ap;
        ap.sun.stepMinutes = 30;
        ap.sun.skyAzimuths = 8;
        ap.sun.skyElevations = 3;
        in.abiotics = computeAbiotics(elevation, biome, ap);
    }

    SketchParams sp;
    sp.seed = p.seed + 1;
    sp.emptyFraction = p.emptyFraction;
    sp.denseFraction = p.denseFraction;
    sp.featureSizeM = std::min(80.0, 0.4 * extent);
    const Grid<std::int32_t> sketch = generateDensitySketch(elevation, sp);
    ChmGenParams cp;
    cp.seed = p.seed + 2;
    std::vector<GeneratedTree> trees;
    in.chmM = generateChm(sketch, cp, trees);

    // Stand-in species map: the canopy-capable species of highest annual-mean vigour that
    // can reach the tree's height (else the tallest canopy species).
    const FactorGrids annual = annualFactors(in.abiotics);
    int tallest = -1;
    for (const Species& s : biome.species)
        if (s.canopy && (tallest < 0 || s.maxHeightM > biome.species[static_cast<std::size_t>(tallest)].maxHeightM)) tallest = s.id;
    for (const GeneratedTree& t : trees) {
        const int ix = std::clamp(elevation.cellX(t.x), 0, elevation.width() - 1);
        const int iy = std::clamp(elevation.cellY(t.y), 0, elevation.height() - 1);
        int best = -1;
        double bestV = -1e300;
        for (const Species& s : biome.species) {
            if (!s.canopy || s.maxHeightM < t.heightM) continue;
            const double v = biome.vigourOf(s.id, annual.at(ix, iy));
            if (v > bestV) {
                bestV = v;
                best = s.id;
            }
        }
        if (best < 0) best = tallest;
        if (best < 0) break;  // a biome without canopy species: no canopy
        in.canopy.push_back(Plant{best, t.x, t.y, in.abiotics.elevationM.sampleBilinear(t.x, t.y), t.heightM, t.crownRadiusM});
    }
    return in;
}

}  // namespace eco::sim
