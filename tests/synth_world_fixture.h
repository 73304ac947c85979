// The test world of the synthesis tests (synth_test.cpp) and of `eco synth` / `eco compare`
// (synth_cli_test.cpp): a biome database built in memory (no analyser) on a flat 200 x 200 m
// terrain whose sun rises from west to east, Redwoods (sub-biome 1, Conifer) in its western
// half and Coast Live Oaks (sub-biome 2, California Oak) in its eastern half. The database
// holds combination 1 split into two regions by sun, and combination 2.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <map>
#include <string>
#include <vector>

#include "biome.h"
#include "biome_db.h"
#include "grid.h"
#include "plants.h"
#include "point_pattern.h"
#include "undergrowth.h"

namespace eco::test {

constexpr int kSide = 200;   // cells
constexpr double kCell = 1.0;

inline std::vector<int> canopyMasks(const Biome& b) {
    std::vector<int> m(b.species.size(), 0);
    for (const SubBiome& sb : b.subBiomes)
        for (const auto& name : sb.canopySpecies) m[static_cast<std::size_t>(b.speciesIndex(name))] |= 1 << (sb.number - 1);
    return m;
}

inline DbHistogram triangleHistogram(double maxValue, int bins, double peakFraction) {
    DbHistogram h;
    for (int k = 0; k <= bins; ++k) h.edges.push_back(maxValue * k / bins);
    for (int k = 0; k < bins; ++k) {
        const double mid = (k + 0.5) / bins;
        const double v = mid < peakFraction ? mid / peakFraction : (1 - mid) / (1 - peakFraction);
        h.counts.push_back(std::round(1000 * v) + 1);
    }
    return h;
}

/// g target: inhibition below `hardCoreM`, 1 beyond.
inline DbPairStats pairStats(int source, int target, const DistanceBins& bins, double hardCoreM) {
    DbPairStats p;
    p.source = source;
    p.target = target;
    p.normalisation = 1.0;
    for (int k = 0; k < bins.count; ++k) {
        const double g = bins.hiM(k) <= hardCoreM ? 0.0 : 1.0;
        p.g.push_back(g);
        p.translateWeighted.push_back(g * bins.annulusAreaM2(k));
        p.pairCount.push_back(g * bins.annulusAreaM2(k));
    }
    p.separationCount.assign(static_cast<std::size_t>(SeparationBins{}.count), 0.0);
    return p;
}

inline DbRegion makeRegion(const Biome& b, int combination, int cluster, double density, Features centroidRaw,
                           const std::map<std::string, double>& shares, const DistanceBins& bins, double hardCoreM) {
    DbRegion r;
    r.combination = combination;
    r.cluster = cluster;
    r.centroidRaw = centroidRaw;
    r.areaM2 = 10000;
    r.densityPerM2 = density;
    const std::size_t ns = b.species.size();
    r.speciesCount.assign(ns, 0.0);
    r.speciesProportion.assign(ns, 0.0);
    r.canopySpeciesCount.assign(ns, 0.0);
    r.height.resize(ns);
    r.crownRadius.resize(ns);
    for (std::size_t s = 0; s < ns; ++s) {
        const Species& sp = b.species[s];
        const double hMax = std::min(sp.maxHeightM, 3.0);
        // Absent species: the edges every region shares, no counts.
        r.height[s] = triangleHistogram(hMax, 20, 0.5);
        r.crownRadius[s] = triangleHistogram(sp.allometry.crownRadiusM(hMax), 20, 0.5);
        std::fill(r.height[s].counts.begin(), r.height[s].counts.end(), 0.0);
        std::fill(r.crownRadius[s].counts.begin(), r.crownRadius[s].counts.end(), 0.0);
    }
    double total = 0;
    for (const auto& [name, share] : shares) total += share;
    std::vector<int> present;
    for (const auto& [name, share] : shares) {
        const std::size_t s = static_cast<std::size_t>(b.speciesIndex(name));
        r.speciesProportion[s] = share / total;
        r.speciesCount[s] = std::round(density * r.areaM2 * share / total);
        const Species& sp = b.species[s];
        const double hMax = std::min(sp.maxHeightM, 3.0);
        r.height[s] = triangleHistogram(hMax, 20, 0.15 + 0.1 * static_cast<double>(s % 5));
        r.crownRadius[s] = triangleHistogram(sp.allometry.crownRadiusM(hMax), 20, 0.35);
        present.push_back(static_cast<int>(s));
    }
    r.undergrowthCount = density * r.areaM2;
    std::sort(present.begin(), present.end());
    for (int i : present)
        for (int j : present) r.pairs.push_back(pairStats(i, j, bins, hardCoreM));
    return r;
}

struct World {
    Biome biome = defaultBiome();
    BiomeDatabase db;
    Grid<float> terrain;
    FactorGrids features;
    std::vector<Plant> canopy;
};

inline World makeWorld(double hardCoreM = 0.8) {
    World w;
    const Biome& b = w.biome;
    BiomeDatabase& db = w.db;
    db.codeVersion = "test";
    db.createdUtc = "2000-01-01T00:00:00Z";
    db.biomeName = b.name;
    db.biomeToml = biomeToToml(b);
    for (const auto& s : b.species) db.speciesNames.push_back(s.name);
    for (const auto& sb : b.subBiomes) db.subBiomeNames.push_back(sb.name);
    db.canopySubBiomeMask = canopyMasks(b);
    db.seedingRadiusFactor = 12;
    db.pcfBins = DistanceBins{10.0, 40};
    // Combination 1 (Conifer): two regions by sun; combination 2 (California Oak): one.
    DbCombination c1;
    c1.mask = 1;
    c1.k = 2;
    c1.firstRegion = 0;
    c1.featureMean = {9.0, 100.0, 15.0, 0.0};
    c1.featureStd = {2.0, 1.0, 1.0, 1.0, 1.0};
    DbCombination c2;
    c2.mask = 2;
    c2.k = 1;
    c2.firstRegion = 2;
    c2.featureMean = {9.0, 100.0, 15.0, 0.0};
    c2.featureStd = {2.0, 1.0, 1.0, 1.0, 1.0};
    db.combinations = {c1, c2};
    db.regions.push_back(makeRegion(b, 1, 0, 1.2, {7.0, 100, 15, 0},
                                    {{"Western Swordfern", 0.4}, {"Redwood Sorrel", 0.3}, {"Tanoak", 0.2}, {"Toyon", 0.1}},
                                    db.pcfBins, hardCoreM));
    db.regions.push_back(makeRegion(b, 1, 1, 0.8, {11.0, 100, 15, 0},
                                    {{"Toyon", 0.5}, {"California Laurel", 0.3}, {"Western Swordfern", 0.2}}, db.pcfBins,
                                    hardCoreM));
    db.regions.push_back(makeRegion(b, 2, 0, 1.5, {9.0, 100, 15, 0},
                                    {{"Chamise", 0.35}, {"California Sagebrush", 0.35}, {"Toyon", 0.2}, {"Pacific Poison Oak", 0.1}},
                                    db.pcfBins, hardCoreM));
    for (auto& c : db.combinations)
        for (int r = c.firstRegion; r < c.firstRegion + c.k; ++r)
            for (std::size_t f = 0; f < kFactorCount; ++f)
                db.regions[static_cast<std::size_t>(r)].centroidNormalised[f] =
                    (db.regions[static_cast<std::size_t>(r)].centroidRaw[f] - c.featureMean[f]) / c.featureStd[f];

    // Terrain and annual abiotics: a gentle tilt, sun from 6 (west) to 12 h/day (east).
    w.terrain = Grid<float>(kSide, kSide, kCell, 0.0, 0.0);
    w.features = FactorGrids::uniform(w.terrain, {0, 100, 15, 0});
    for (int iy = 0; iy < kSide; ++iy)
        for (int ix = 0; ix < kSide; ++ix) {
            w.terrain(ix, iy) = static_cast<float>(100.0 + 0.02 * ix + 0.01 * iy);
            w.features[Factor::Sun](ix, iy) = static_cast<float>(6.0 + 6.0 * (ix + 0.5) / kSide);
        }
    // Canopy: Redwoods west, Coast Live Oaks east, on a jittered lattice.
    const int redwood = b.speciesIndex("Redwood"), oak = b.speciesIndex("Coast Live Oak");
    for (int j = 0; j < 10; ++j)
        for (int i = 0; i < 10; ++i) {
            Plant t;
            const bool west = i < 5;
            t.speciesId = west ? redwood : oak;
            t.xM = 10.0 + 20.0 * i + 3.0 * std::sin(1.7 * j + i);
            t.yM = 10.0 + 20.0 * j + 3.0 * std::cos(2.3 * i + j);
            t.heightM = west ? 40.0 : 15.0;
            t.crownRadiusM = west ? 3.0 : 2.5;
            t.groundZM = w.terrain.sampleBilinear(t.xM, t.yM);
            w.canopy.push_back(t);
        }
    return w;
}

}  // namespace eco::test
