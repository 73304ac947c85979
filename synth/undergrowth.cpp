#include "undergrowth.h"

#include <omp.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <numeric>
#include <sstream>

#include "error.h"
#include "memory.h"
#include "sampling_detail.h"
#include "rng.h"
#include "text_format.h"

namespace eco::synth {

namespace {

using namespace detail;

// Stream families of the counter-based generator (rng.h); each is mixed with the pass or
// sweep and the cell or plant, so no two draws share a counter.
constexpr std::uint64_t kDartStream = 0x53594e5448445254ull;    // "SYNTHDRT"
constexpr std::uint64_t kRefineStream = 0x53594e5452464e45ull;  // "SYNTRFNE"
constexpr std::uint64_t kSourceStream = 0x5359534f55524345ull;  // "SYSOURCE"
constexpr std::uint64_t kCountStream = 0x5359434f554e5453ull;   // "SYCOUNTS"

using Clock = std::chrono::steady_clock;
double secondsSince(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

std::string num(double v) { return formatNumber(v, 10); }

/// Species roulette of every (region, combination) pair that occurs: cumulative weights of
/// the region's proportions restricted to the species the combination admits.
class SpeciesRoulette {
public:
    SpeciesRoulette(const BiomeDatabase& db, const std::vector<int>& subMask, std::vector<std::int32_t> masks)
        : masks_(std::move(masks)), nSpecies_(db.speciesCount()), nMasks_(static_cast<int>(masks_.size())) {
        cumulative_.assign(db.regions.size() * masks_.size() * static_cast<std::size_t>(nSpecies_), 0.0);
        for (std::size_t r = 0; r < db.regions.size(); ++r)
            for (std::size_t m = 0; m < masks_.size(); ++m) {
                double* c = &cumulative_[(r * masks_.size() + m) * static_cast<std::size_t>(nSpecies_)];
                double acc = 0;
                for (int s = 0; s < nSpecies_; ++s) {
                    const double p = db.regions[r].speciesProportion[static_cast<std::size_t>(s)];
                    if (p > 0 && (subMask[static_cast<std::size_t>(s)] & masks_[m]) != 0) acc += p;
                    c[s] = acc;
                }
            }
    }
    int maskIndex(std::int32_t mask) const {
        const auto it = std::lower_bound(masks_.begin(), masks_.end(), mask);
        return (it != masks_.end() && *it == mask) ? static_cast<int>(it - masks_.begin()) : -1;
    }
    double total(int region, int maskIdx) const {
        if (maskIdx < 0) return 0;
        return row(region, maskIdx)[nSpecies_ - 1];
    }
    /// Species for u in [0, 1), or -1 when the combination admits none of the region's species.
    int pick(int region, int maskIdx, double u) const {
        if (maskIdx < 0) return -1;
        const double* c = row(region, maskIdx);
        const double t = c[nSpecies_ - 1];
        if (!(t > 0)) return -1;
        const double x = u * t;
        int s = static_cast<int>(std::upper_bound(c, c + nSpecies_, x) - c);
        if (s >= nSpecies_) s = nSpecies_ - 1;
        // Skip species of zero weight that upper_bound may land on at the very top.
        while (s > 0 && c[s] == c[s - 1]) --s;
        return s;
    }

private:
    const double* row(int region, int maskIdx) const {
        return &cumulative_[(static_cast<std::size_t>(region) * static_cast<std::size_t>(nMasks_) +
                             static_cast<std::size_t>(maskIdx)) *
                            static_cast<std::size_t>(nSpecies_)];
    }
    std::vector<std::int32_t> masks_;
    int nSpecies_, nMasks_;
    std::vector<double> cumulative_;
};

/// Nearest region of a cell: BiomeDatabase::nearestRegion with the stand-in combination
/// looked up once per mask.
struct RegionLookup {
    const BiomeDatabase& db;
    std::vector<std::int32_t> masks;    ///< distinct masks, ascending
    std::vector<int> combinationIndex;  ///< per mask: index into db.combinations, -1 none

    RegionLookup(const BiomeDatabase& d, std::vector<std::int32_t> m) : db(d), masks(std::move(m)) {
        for (std::int32_t mask : masks) {
            const int stand = db.standInCombination(mask);
            combinationIndex.push_back(stand < 0 ? -1 : db.combinationIndex(stand));
        }
    }
    /// Index of mask in masks, -1 when absent.
    int maskIndex(std::int32_t mask) const {
        const auto it = std::lower_bound(masks.begin(), masks.end(), mask);
        return (it == masks.end() || *it != mask) ? -1 : static_cast<int>(it - masks.begin());
    }
    /// The region of a cell with mask index m (>= 0) and features x.
    int region(int m, const Features& x) const {
        const int ci = combinationIndex[static_cast<std::size_t>(m)];
        if (ci < 0) return -1;
        const DbCombination& c = db.combinations[static_cast<std::size_t>(ci)];
        if (c.k == 1) return c.firstRegion;  // nearestRegionOf's answer without the features
        return db.nearestRegionOf(static_cast<std::size_t>(ci), x);
    }
};

}  // namespace

// ======================================================================== inputs

Biome databaseBiome(const BiomeDatabase& db) {
    if (db.biomeToml.empty()) throw ValidationError("biome database: no biome recorded (biome_toml is empty)");
    Biome b = parseBiome(db.biomeToml, "biome database (biome_toml)");
    if (b.species.size() != db.speciesNames.size())
        throw ValidationError("biome database: its biome '" + b.name + "' has " + std::to_string(b.species.size()) +
                              " species but the database lists " + std::to_string(db.speciesNames.size()));
    for (std::size_t s = 0; s < b.species.size(); ++s)
        if (b.species[s].name != db.speciesNames[s])
            throw ValidationError("biome database: species " + std::to_string(s) + " is '" + db.speciesNames[s] +
                                  "' in the database but '" + b.species[s].name + "' in its biome");
    if (db.canopySubBiomeMask.size() != b.species.size())
        throw ValidationError("biome database: canopy sub-biome masks (" + std::to_string(db.canopySubBiomeMask.size()) +
                              ") do not match the species (" + std::to_string(b.species.size()) + ")");
    return b;
}

void validateCanopy(const std::vector<Plant>& canopy, const Grid<float>& terrainM, const Biome& biome,
                    const std::string& canopySource) {
    const double x0 = terrainM.originX(), y0 = terrainM.originY();
    const double x1 = x0 + terrainM.extentX(), y1 = y0 + terrainM.extentY();
    for (std::size_t i = 0; i < canopy.size(); ++i) {
        const Plant& p = canopy[i];
        const std::string which = canopySource + ": canopy tree " + std::to_string(i);
        if (p.speciesId < 0 || static_cast<std::size_t>(p.speciesId) >= biome.species.size())
            throw ValidationError(which + " has species id " + std::to_string(p.speciesId) + ", not a species of biome '" +
                                  biome.name + "'");
        if (!std::isfinite(p.xM) || !std::isfinite(p.yM) || !std::isfinite(p.heightM) || !std::isfinite(p.crownRadiusM) ||
            p.heightM < 0 || p.crownRadiusM < 0)
            throw ValidationError(which + " has a non-finite or negative position or size");
        if (p.xM < x0 || p.xM > x1 || p.yM < y0 || p.yM > y1)
            throw ValidationError(which + " (" + biome.species[static_cast<std::size_t>(p.speciesId)].name + ") at (" +
                                  num(p.xM) + ", " + num(p.yM) + ") lies outside the terrain (x " + num(x0) + " .. " +
                                  num(x1) + ", y " + num(y0) + " .. " + num(y1) +
                                  " m); the canopy was placed on another terrain");
    }
}

// ======================================================================== cluster map


ClusterMap computeClusterMap(const BiomeDatabase& db, const Biome& biome, const std::vector<Plant>& canopy,
                             const FactorGrids& features, const SynthParams& params) {
    params.validate();
    const Grid<float>& g = features.geometry();
    for (const auto* other = features.maps.data() + 1; other != features.maps.data() + kFactorCount; ++other)
        if (!other->sameGeometry(g))
            throw ValidationError("cluster map: the annual abiotic maps differ in geometry (" + g.geometryText() + " vs " +
                                  other->geometryText() + ")");
    if (static_cast<std::size_t>(db.speciesCount()) != biome.species.size() ||
        db.canopySubBiomeMask.size() != biome.species.size())
        throw ValidationError("cluster map: the database has " + std::to_string(db.speciesCount()) +
                              " species, the biome '" + biome.name + "' " + std::to_string(biome.species.size()));
    ClusterMap map;
    map.combination = seedingLabels(g, canopy, db.canopySubBiomeMask, db.seedingRadiusFactor,
                                    params.seedInnerRadiusFactor, &map.seedWeight);
    const std::vector<std::int32_t> masks = distinctValues(map.combination);
    const RegionLookup lookup(db, masks);
    const SpeciesRoulette roulette(db, speciesSubBiomeMasks(biome), masks);
    map.region = Grid<std::int32_t>::like(g, -1);
    const int w = g.width(), h = g.height();
#pragma omp parallel for schedule(static)
    for (int iy = 0; iy < h; ++iy) {
        // Neighbouring cells mostly share a mask: its index looked up once per run of them.
        std::int32_t lastMask = 0;
        int m = -1;
        for (int ix = 0; ix < w; ++ix) {
            const std::int32_t mask = map.combination(ix, iy);
            if (mask != lastMask) {
                lastMask = mask;
                m = lookup.maskIndex(mask);
            }
            int r = -1;
            if (mask != 0 && m >= 0) r = lookup.region(m, features.at(ix, iy));
            map.region(ix, iy) = r;
            // No darts where no species of the region may grow (a stand-in combination).
            if (r < 0 || !(roulette.total(r, m) > 0)) map.seedWeight(ix, iy) = 0.0f;
        }
    }
    return map;
}

// ======================================================================== sampling

double histogramQuantile(const DbHistogram& h, double u) {
    std::size_t k = 0;
    double t = 0;
    const int found = histogramLocate(h, u, k, t);
    if (found < 0) return -1;
    if (found == 0) return h.edges.back();  // in the overflow: at the last edge
    return h.edges[k] + t * (h.edges[k + 1] - h.edges[k]);
}

namespace {

/// A dart: enough to regenerate it from its (pass, cell) stream.
struct Dart {
    std::uint64_t key;   ///< random priority: regions accept darts in ascending key order
    std::uint32_t cell;  ///< cell index
    std::uint16_t j;     ///< dart number within the cell and pass
    std::uint16_t pass;
};

/// The random numbers of dart j of a cell in a pass: position, key, species, size.
struct DartDraw {
    double ux, uy, uSpecies, uSize;
    std::uint64_t key;
};
inline DartDraw drawDart(std::uint64_t seed, std::uint64_t cellStream, int j) {
    // Dart j uses blocks 3j .. 3j + 2 of the cell's stream (its count has a stream of its own).
    RandomStream rs(seed, cellStream, 3 * static_cast<std::uint64_t>(j));
    DartDraw d{};
    d.ux = rs.uniform();
    d.uy = rs.uniform();
    const std::uint64_t hi = rs.nextU32(), lo = rs.nextU32();
    d.key = (hi << 32) | lo;
    d.uSpecies = rs.uniform();
    d.uSize = rs.uniform();
    return d;
}

}  // namespace

UndergrowthSample sampleUndergrowth(const BiomeDatabase& db, const Biome& biome, const std::vector<Plant>& canopy,
                                    const ClusterMap& map, const Grid<float>& terrainM, const SynthParams& params,
                                    const Grid<float>* densityImage, const XuExemplar* exemplar) {
    const auto t0 = Clock::now();
    params.validate();
    if (densityImage != nullptr && params.method != SynthMethod::Deussen)
        throw ValidationError(std::string("undergrowth sampling: a density image is read by the 'deussen' method only, not by '") +
                              toString(params.method) + "'");
    if (exemplar != nullptr && params.method != SynthMethod::Xu2015)
        throw ValidationError(std::string("undergrowth sampling: an exemplar is read by the 'xu2015' method only, not by '") +
                              toString(params.method) + "'");
    if (exemplar == nullptr && params.method == SynthMethod::Xu2015)
        throw ValidationError("undergrowth sampling: the 'xu2015' method needs an exemplar stand (--exemplar)");
    if (densityImage != nullptr && !densityImage->sameGeometry(terrainM))
        throw ValidationError("undergrowth sampling: the density image (" + densityImage->geometryText() +
                              ") and the terrain (" + terrainM.geometryText() + ") differ in geometry");
    if (!map.region.sameGeometry(terrainM) || !map.seedWeight.sameGeometry(terrainM) ||
        !map.combination.sameGeometry(terrainM))
        throw ValidationError("undergrowth sampling: the cluster map and the terrain (" + terrainM.geometryText() +
                              ") differ in geometry");
    if (static_cast<std::size_t>(db.speciesCount()) != biome.species.size())
        throw ValidationError("undergrowth sampling: the database and the biome '" + biome.name + "' differ in species");
    for (std::size_t r = 0; r < db.regions.size(); ++r) {
        const DbRegion& reg = db.regions[r];
        const std::size_t ns = biome.species.size();
        if (reg.speciesProportion.size() != ns || reg.height.size() != ns || reg.crownRadius.size() != ns)
            throw ValidationError("undergrowth sampling: database region " + std::to_string(r) +
                                  " lacks species proportions or size histograms for all " + std::to_string(ns) + " species");
    }
    const int w = terrainM.width(), h = terrainM.height();
    if (static_cast<std::uint64_t>(w) * static_cast<std::uint64_t>(h) >= (std::uint64_t{1} << 32))
        throw ValidationError("undergrowth sampling: terrain of " + std::to_string(w) + " x " + std::to_string(h) +
                              " cells is too large (at most 2^32 cells)");
    {  // The plants the database asks for here, before any allocation: a database density of
        // 1e12 per m2 must be a clear error, not an abort inside a parallel region.
        std::vector<double> cellsOf(db.regions.size(), 0.0);
        for (const std::int32_t r : map.region.data())
            if (r >= 0 && static_cast<std::size_t>(r) < cellsOf.size()) cellsOf[static_cast<std::size_t>(r)] += 1;
        double plants = 0;
        for (std::size_t r = 0; r < db.regions.size(); ++r)
            plants += cellsOf[r] * terrainM.cellSizeM() * terrainM.cellSizeM() * db.regions[r].densityPerM2;
        // A plant, its candidates (about 2.5 per plant) and the sort buffers: about 200 bytes.
        requireMemory(200.0 * plants, "undergrowth sampling of about " + formatNumber(plants, 3) +
                                          " plants (the database's densities over this terrain)",
                      "a smaller terrain, or check the database's densities with eco inspect");
    }
    if (params.method == SynthMethod::Structured) return sampleStructured(db, biome, canopy, map, terrainM, params);
    if (params.method == SynthMethod::Deussen) return sampleDeussen(db, biome, canopy, map, terrainM, params, densityImage);
    if (params.method == SynthMethod::Xu2015) return sampleXu2015(db, biome, canopy, map, terrainM, params, *exemplar);
    const double cs = terrainM.cellSizeM();
    const double cellArea = cs * cs;
    const int nRegions = static_cast<int>(db.regions.size());
    const std::size_t nR = static_cast<std::size_t>(nRegions);

    // Per region: cells and the sum of dart weights (rows in parallel, added in row order).
    std::vector<std::int64_t> rowCells(static_cast<std::size_t>(h) * nR, 0);
    std::vector<double> rowWeight(static_cast<std::size_t>(h) * nR, 0.0);
#pragma omp parallel for schedule(static)
    for (int iy = 0; iy < h; ++iy)
        for (int ix = 0; ix < w; ++ix) {
            const int r = map.region(ix, iy);
            if (r < 0 || r >= nRegions) continue;
            const std::size_t i = static_cast<std::size_t>(iy) * nR + static_cast<std::size_t>(r);
            ++rowCells[i];
            rowWeight[i] += map.seedWeight(ix, iy);
        }
    UndergrowthSample out;
    std::vector<double> weightSum(nR, 0.0);
    out.regions.resize(nR);
    for (std::size_t r = 0; r < nR; ++r) {
        RegionSampling& rs = out.regions[r];
        rs.region = static_cast<int>(r);
        for (int iy = 0; iy < h; ++iy) {
            rs.cells += rowCells[static_cast<std::size_t>(iy) * nR + r];
            weightSum[r] += rowWeight[static_cast<std::size_t>(iy) * nR + r];
        }
        rs.areaM2 = static_cast<double>(rs.cells) * cellArea;
        rs.targetDensityPerM2 = db.regions[r].densityPerM2;
        rs.targetCount = static_cast<std::int64_t>(std::llround(rs.targetDensityPerM2 * rs.areaM2));
        if (!(weightSum[r] > 0)) rs.targetCount = 0;  // no cell may hold a plant
    }

    const TrunkIndex trunks(canopy, params.trunkExclusionFactor);
    // Cells a trunk's exclusion disc may reach: only darts there need the trunk query.
    Grid<std::uint8_t> nearTrunk = Grid<std::uint8_t>::like(terrainM, 0);
    if (params.trunkExclusionFactor > 0)
        for (const Plant& t : canopy) {
            const double re = params.trunkExclusionFactor * t.crownRadiusM;
            const int x0 = std::max(0, terrainM.cellX(t.xM - re)), x1 = std::min(w - 1, terrainM.cellX(t.xM + re));
            const int y0 = std::max(0, terrainM.cellY(t.yM - re)), y1 = std::min(h - 1, terrainM.cellY(t.yM + re));
            for (int iy = y0; iy <= y1; ++iy)
                for (int ix = x0; ix <= x1; ++ix) nearTrunk(ix, iy) = 1;
        }
    const std::vector<std::int32_t> masks = distinctValues(map.combination);
    const SpeciesRoulette roulette(db, speciesSubBiomeMasks(biome), masks);

    auto cellPassOrder = [](const Dart& a, const Dart& b) {
        if (a.cell != b.cell) return a.cell < b.cell;
        if (a.pass != b.pass) return a.pass < b.pass;
        return a.j < b.j;
    };
    std::vector<Dart> accepted;  // kept in (cell, pass, dart) order
    std::vector<double> scale(nR, 0.0), expScale(nR, 0.0);
    for (int pass = 0; pass < params.maxPasses; ++pass) {
        bool any = false;
        for (std::size_t r = 0; r < nR; ++r) {
            const std::int64_t remaining = out.regions[r].targetCount - out.regions[r].placed;
            scale[r] = remaining > 0 ? static_cast<double>(remaining) * params.candidateOversample / weightSum[r] : 0.0;
            expScale[r] = std::exp(-std::min(scale[r], 100.0));
            any = any || remaining > 0;
        }
        if (!any) break;
        out.passes = pass + 1;
        const std::uint64_t passStream = mixStream(kDartStream, static_cast<std::uint64_t>(pass));

        // Throw darts, rows in parallel; each cell's darts come from its own stream.
        std::vector<std::vector<Dart>> rowDarts(static_cast<std::size_t>(h));
        std::vector<std::int64_t> rowThrown(static_cast<std::size_t>(h), 0), rowOnTrunk(static_cast<std::size_t>(h), 0);
#pragma omp parallel for schedule(dynamic, 8)
        for (int iy = 0; iy < h; ++iy) {
            auto& darts = rowDarts[static_cast<std::size_t>(iy)];
            for (int ix = 0; ix < w; ++ix) {
                const int r = map.region(ix, iy);
                if (r < 0) continue;
                const float wgt = map.seedWeight(ix, iy);
                const double lambda = static_cast<double>(wgt) * scale[static_cast<std::size_t>(r)];
                if (!(lambda > 0)) continue;
                const std::uint32_t cell = static_cast<std::uint32_t>(terrainM.index(ix, iy));
                const std::uint64_t stream = mixStream(passStream, cell);
                // A Poisson number of darts: with the uniform positions and the random-order
                // acceptance below, the plants of a region form a (thinned) Poisson process of
                // intensity proportional to w, neither clumped nor more regular than random.
                RandomStream counter(params.seed, mixStream(stream, kCountStream), 0);
                const int n = (wgt == 1.0f && lambda <= 100.0)
                                  ? poissonCount(counter, lambda, 65535, expScale[static_cast<std::size_t>(r)])
                                  : poissonCount(counter, lambda, 65535);
                const bool trunkNear = nearTrunk(ix, iy) != 0;
                for (int j = 0; j < n; ++j) {
                    RandomStream rs(params.seed, stream, 3 * static_cast<std::uint64_t>(j));
                    const double ux = rs.uniform(), uy = rs.uniform();
                    const std::uint64_t hi = rs.nextU32(), lo = rs.nextU32();
                    ++rowThrown[static_cast<std::size_t>(iy)];
                    if (trunkNear && trunks.onTrunk(terrainM.originX() + (ix + ux) * cs, terrainM.originY() + (iy + uy) * cs)) {
                        ++rowOnTrunk[static_cast<std::size_t>(iy)];
                        continue;
                    }
                    darts.push_back(Dart{(hi << 32) | lo, cell, static_cast<std::uint16_t>(j), static_cast<std::uint16_t>(pass)});
                }
            }
        }
        // Each region keeps the darts of the lowest keys it needs (random order of arrival):
        // find its key threshold, then filter the darts in cell order.
        std::vector<std::vector<std::uint64_t>> keys(nR);
        for (int iy = 0; iy < h; ++iy) {
            out.darts += rowThrown[static_cast<std::size_t>(iy)];
            out.dartsOnTrunks += rowOnTrunk[static_cast<std::size_t>(iy)];
            for (const Dart& d : rowDarts[static_cast<std::size_t>(iy)])
                keys[static_cast<std::size_t>(map.region.data()[d.cell])].push_back(d.key);
        }
        std::vector<std::uint64_t> threshold(nR, std::numeric_limits<std::uint64_t>::max());
        std::vector<std::int64_t> equalQuota(nR, std::numeric_limits<std::int64_t>::max());
        for (std::size_t r = 0; r < nR; ++r) {
            auto& k = keys[r];
            const std::int64_t remaining = out.regions[r].targetCount - out.regions[r].placed;
            if (remaining <= 0) {
                threshold[r] = 0;
                equalQuota[r] = 0;
                continue;
            }
            if (static_cast<std::int64_t>(k.size()) <= remaining) continue;  // all accepted
            std::nth_element(k.begin(), k.begin() + (remaining - 1), k.end());
            threshold[r] = k[static_cast<std::size_t>(remaining - 1)];
            std::int64_t less = 0;
            for (std::uint64_t v : k) less += v < threshold[r];
            equalQuota[r] = remaining - less;  // darts with the threshold key, taken in cell order
            std::vector<std::uint64_t>().swap(k);
        }
        std::vector<Dart> passAccepted;
        for (int iy = 0; iy < h; ++iy) {
            for (const Dart& d : rowDarts[static_cast<std::size_t>(iy)]) {
                const std::size_t r = static_cast<std::size_t>(map.region.data()[d.cell]);
                if (d.key < threshold[r] || (d.key == threshold[r] && equalQuota[r]-- > 0)) {
                    passAccepted.push_back(d);
                    ++out.regions[r].placed;
                }
            }
            std::vector<Dart>().swap(rowDarts[static_cast<std::size_t>(iy)]);
        }
        const std::size_t mid = accepted.size();
        accepted.insert(accepted.end(), passAccepted.begin(), passAccepted.end());
        std::inplace_merge(accepted.begin(), accepted.begin() + static_cast<std::ptrdiff_t>(mid), accepted.end(), cellPassOrder);
    }

    // Pooled histograms per species (all regions share the edges): the fallback of a region
    // without plants of a species.
    const std::vector<DbHistogram> pooledHeight = pooledSizeHistograms(db, false), pooledRadius = pooledSizeHistograms(db, true);

    out.plants.resize(accepted.size());
    out.plantRegion.resize(accepted.size());
    const std::int64_t nPlants = static_cast<std::int64_t>(accepted.size());
#pragma omp parallel for schedule(static)
    for (std::int64_t i = 0; i < nPlants; ++i) {
        const Dart& dart = accepted[static_cast<std::size_t>(i)];
        const int ix = static_cast<int>(dart.cell % static_cast<std::uint32_t>(w));
        const int iy = static_cast<int>(dart.cell / static_cast<std::uint32_t>(w));
        const std::uint64_t stream = mixStream(mixStream(kDartStream, dart.pass), dart.cell);
        const DartDraw d = drawDart(params.seed, stream, dart.j);
        const double uSize = d.uSize;  // the same stream and words as when the dart was thrown
        const int r = map.region(ix, iy);
        Plant p;
        p.xM = terrainM.originX() + (ix + d.ux) * cs;
        p.yM = terrainM.originY() + (iy + d.uy) * cs;
        p.groundZM = terrainM.sampleBilinear(p.xM, p.yM);
        int s = roulette.pick(r, roulette.maskIndex(map.combination(ix, iy)), d.uSpecies);
        if (s < 0) s = 0;  // unreachable: cells without a species have no darts
        p.speciesId = s;
        const DbRegion& reg = db.regions[static_cast<std::size_t>(r)];
        const std::size_t si = static_cast<std::size_t>(s);
        double height = histogramQuantile(reg.height[si], uSize);
        double radius = histogramQuantile(reg.crownRadius[si], uSize);
        if (height < 0) height = histogramQuantile(pooledHeight[si], uSize);
        if (radius < 0) radius = histogramQuantile(pooledRadius[si], uSize);
        if (height < 0) height = 0.5 * biome.species[si].maxHeightM;
        if (radius < 0) radius = biome.species[si].allometry.crownRadiusM(height);
        p.heightM = height;
        p.crownRadiusM = radius;
        out.plants[static_cast<std::size_t>(i)] = p;
        out.plantRegion[static_cast<std::size_t>(i)] = r;
    }
    out.seconds = secondsSince(t0);
    return out;
}

// ======================================================================== pair correlation

double ScenePairStats::Region::g(int i, int j, int k, const DistanceBins& b, int nCat) const {
    const double ni = static_cast<double>(count[static_cast<std::size_t>(i)]);
    const double nj = static_cast<double>(count[static_cast<std::size_t>(j)]);
    const double n = areaM2 > 0 ? pairNormalisation(ni, nj, i == j, areaM2) : 0.0;
    const std::size_t idx = (static_cast<std::size_t>(i) * static_cast<std::size_t>(nCat) + static_cast<std::size_t>(j)) *
                                static_cast<std::size_t>(b.count) +
                            static_cast<std::size_t>(k);
    return annulusPcf(weighted[idx], b.annulusAreaM2(k), n);
}

ScenePairStats scenePairStatistics(const std::vector<Plant>& canopy, const std::vector<Plant>& undergrowth,
                                   const Grid<std::int32_t>& regionMap, int nRegions, int nSpecies,
                                   const DistanceBins& bins, const RectWindow* window, std::size_t maxSourcesPerRegion,
                                   std::uint64_t seed) {
    bins.validate("pair correlation bins");
    ScenePairStats st;
    st.bins = bins;
    st.nCategories = 2 * nSpecies;
    const int nCat = st.nCategories;
    const std::size_t nB = static_cast<std::size_t>(bins.count);
    const std::size_t C = static_cast<std::size_t>(nCat);
    st.regions.resize(static_cast<std::size_t>(std::max(0, nRegions)));
    if (nRegions <= 0) return st;
    const std::vector<CellWindow> windows = CellWindow::fromLabels(regionMap, nRegions, bins.rMaxM);
    for (int r = 0; r < nRegions; ++r) {
        auto& R = st.regions[static_cast<std::size_t>(r)];
        R.areaM2 = windows[static_cast<std::size_t>(r)].areaM2();
        R.count.assign(C, 0);
        R.weighted.assign(C * C * nB, 0.0);
    }
    // Points in a region (and the window), both layers.
    struct Pt {
        double x, y;
        int cat, region;
        std::uint32_t index;  ///< in its plant list
    };
    std::vector<Pt> pts;
    pts.reserve(canopy.size() + undergrowth.size());
    auto add = [&](const std::vector<Plant>& plants, int layer) {
        for (std::size_t i = 0; i < plants.size(); ++i) {
            const Plant& p = plants[i];
            if (window && !window->contains(p.xM, p.yM)) continue;
            const int ix = regionMap.cellX(p.xM), iy = regionMap.cellY(p.yM);
            if (!regionMap.inside(ix, iy)) continue;
            const int r = regionMap(ix, iy);
            if (r < 0 || r >= nRegions) continue;
            if (p.speciesId < 0 || p.speciesId >= nSpecies) continue;
            pts.push_back(Pt{p.xM, p.yM, layer * nSpecies + p.speciesId, r, static_cast<std::uint32_t>(i)});
        }
    };
    add(undergrowth, 0);
    add(canopy, 1);
    if (pts.empty()) return st;
    std::vector<double> xs(pts.size()), ys(pts.size());
    for (std::size_t i = 0; i < pts.size(); ++i) {
        xs[i] = pts[i].x;
        ys[i] = pts[i].y;
        ++st.regions[static_cast<std::size_t>(pts[i].region)].count[static_cast<std::size_t>(pts[i].cat)];
    }
    const PointGrid grid(xs, ys, std::max(bins.rMaxM / 2.0, 1e-3));
    std::vector<int> sCat(pts.size()), sRegion(pts.size());
    std::vector<std::uint32_t> sortedOf(pts.size());
    for (std::size_t s = 0; s < pts.size(); ++s) {
        const std::uint32_t o = grid.order()[s];
        sCat[s] = pts[o].cat;
        sRegion[s] = pts[o].region;
        sortedOf[o] = static_cast<std::uint32_t>(s);
    }
    // Sources: every canopy tree; undergrowth plants with probability f of their region.
    std::vector<std::int64_t> undergrowthIn(static_cast<std::size_t>(nRegions), 0);
    for (const Pt& p : pts)
        if (p.cat < nSpecies) ++undergrowthIn[static_cast<std::size_t>(p.region)];
    for (int r = 0; r < nRegions; ++r) {
        const auto n = undergrowthIn[static_cast<std::size_t>(r)];
        if (maxSourcesPerRegion > 0 && n > static_cast<std::int64_t>(maxSourcesPerRegion))
            st.regions[static_cast<std::size_t>(r)].sourceFraction = static_cast<double>(maxSourcesPerRegion) / static_cast<double>(n);
    }
    std::vector<std::uint32_t> src;
    src.reserve(pts.size());
    for (std::size_t i = 0; i < pts.size(); ++i) {
        const Pt& p = pts[i];
        const double f = st.regions[static_cast<std::size_t>(p.region)].sourceFraction;
        if (p.cat >= nSpecies || f >= 1.0) {
            src.push_back(static_cast<std::uint32_t>(i));
            continue;
        }
        const auto bits = randomBits(seed, mixStream(kSourceStream, p.index), 0);
        if (bitsToUnit(bits[0], bits[1]) < f) src.push_back(static_cast<std::uint32_t>(i));
    }
    // Work items: blocks of at most 4096 sources of one (region, category), in a fixed order;
    // each fills its own [target][bin] sums, added in item order afterwards.
    std::stable_sort(src.begin(), src.end(), [&](std::uint32_t a, std::uint32_t b) {
        if (pts[a].region != pts[b].region) return pts[a].region < pts[b].region;
        return pts[a].cat < pts[b].cat;
    });
    struct Item {
        std::size_t begin, end;
    };
    std::vector<Item> items;
    constexpr std::size_t kBlock = 4096;
    for (std::size_t i = 0; i < src.size();) {
        std::size_t j = i;
        while (j < src.size() && j - i < kBlock && pts[src[j]].region == pts[src[i]].region && pts[src[j]].cat == pts[src[i]].cat) ++j;
        items.push_back(Item{i, j});
        i = j;
    }
    std::vector<std::vector<double>> itemSums(items.size());
    const double rMax = bins.rMaxM;
#pragma omp parallel for schedule(dynamic, 1)
    for (std::size_t it = 0; it < items.size(); ++it) {
        std::vector<double> acc(C * nB, 0.0);
        for (std::size_t q = items[it].begin; q < items[it].end; ++q) {
            const std::uint32_t o = src[q];
            const Pt& p = pts[o];
            const std::size_t self = sortedOf[o];
            const CellWindow& win = windows[static_cast<std::size_t>(p.region)];
            grid.forEachWithin(p.x, p.y, rMax, [&](std::size_t s, double dx, double dy, double d2) {
                if (s == self || sRegion[s] != p.region) return;
                const int k = bins.binOf(std::sqrt(d2));
                if (k < 0) return;
                const double wgt = win.translationWeight(dx, dy);
                acc[static_cast<std::size_t>(sCat[s]) * nB + static_cast<std::size_t>(k)] += wgt;
            });
        }
        itemSums[it] = std::move(acc);
    }
    for (std::size_t it = 0; it < items.size(); ++it) {
        const Pt& p = pts[src[items[it].begin]];
        auto& R = st.regions[static_cast<std::size_t>(p.region)];
        double* dst = &R.weighted[static_cast<std::size_t>(p.cat) * C * nB];
        const auto& a = itemSums[it];
        const double scale = p.cat < nSpecies ? 1.0 / R.sourceFraction : 1.0;
        for (std::size_t i = 0; i < a.size(); ++i) dst[i] += a[i] * scale;
    }
    return st;
}

namespace {

/// The database's g of the pair {i, j} (either direction), or nullptr.
const std::vector<double>* databaseG(const DbRegion& r, int i, int j) {
    if (const DbPairStats* p = r.pair(i, j); p && !p->g.empty()) return &p->g;
    if (const DbPairStats* p = r.pair(j, i); p && !p->g.empty()) return &p->g;
    return nullptr;
}

/// Ordered point pairs of types i and j in a region (n_i n_j both ways, or n_i (n_i - 1)).
double pairsOf(const ScenePairStats::Region& R, int i, int j) {
    const double ni = static_cast<double>(R.count[static_cast<std::size_t>(i)]);
    const double nj = static_cast<double>(R.count[static_cast<std::size_t>(j)]);
    return i == j ? ni * (ni - 1) : 2 * ni * nj;
}

}  // namespace

PcfDistance pcfDistance(const ScenePairStats& scene, const BiomeDatabase& db) {
    if (scene.bins.count != db.pcfBins.count || std::abs(scene.bins.rMaxM - db.pcfBins.rMaxM) > 1e-9)
        throw ValidationError("pair-correlation distance: the scene's bins (" + std::to_string(scene.bins.count) + " to " +
                              num(scene.bins.rMaxM) + " m) differ from the database's (" +
                              std::to_string(db.pcfBins.count) + " to " + num(db.pcfBins.rMaxM) + " m)");
    if (scene.regions.size() != db.regions.size())
        throw ValidationError("pair-correlation distance: the scene has " + std::to_string(scene.regions.size()) +
                              " regions, the database " + std::to_string(db.regions.size()));
    const int nS = db.speciesCount(), nCat = scene.nCategories;
    PcfDistance out;
    out.perRegion.assign(scene.regions.size(), 0.0);
    out.pairWeight.assign(scene.regions.size(), 0.0);
    std::vector<double> regionSum(scene.regions.size(), 0.0);
    double total = 0;
    for (std::size_t r = 0; r < scene.regions.size(); ++r) {
        const auto& R = scene.regions[r];
        if (R.count.empty()) continue;
        for (int i = 0; i < nCat; ++i)
            for (int j = i; j < nCat; ++j) {
                if (i >= nS && j >= nS) continue;  // canopy with canopy: fixed, not synthesized
                const double pairs = pairsOf(R, i, j);
                if (!(pairs > 0)) continue;
                const std::vector<double>* gt = databaseG(db.regions[r], i, j);
                if (!gt || gt->size() != static_cast<std::size_t>(scene.bins.count)) continue;
                double mse = 0;
                for (int k = 0; k < scene.bins.count; ++k) {
                    const double d = R.g(i, j, k, scene.bins, nCat) - (*gt)[static_cast<std::size_t>(k)];
                    mse += d * d;
                }
                mse /= scene.bins.count;
                out.pairWeight[r] += pairs;
                regionSum[r] += pairs * mse;
                total += pairs;
            }
    }
    double sum = 0;
    for (std::size_t r = 0; r < scene.regions.size(); ++r) {
        if (out.pairWeight[r] > 0) out.perRegion[r] = std::sqrt(regionSum[r] / out.pairWeight[r]);
        sum += regionSum[r];
    }
    out.overall = total > 0 ? std::sqrt(sum / total) : 0.0;
    for (double& w : out.pairWeight) w = total > 0 ? w / total : 0.0;
    return out;
}

// ======================================================================== refinement

namespace {

/// Mutable uniform bucket grid of the undergrowth for the refinement.
struct Buckets {
    double ox = 0, oy = 0, side = 1, inv = 1;
    int nx = 0, ny = 0;
    std::vector<std::vector<std::uint32_t>> cells;
    int bx(double x) const { return std::clamp(static_cast<int>(std::floor((x - ox) * inv)), 0, nx - 1); }
    int by(double y) const { return std::clamp(static_cast<int>(std::floor((y - oy) * inv)), 0, ny - 1); }
    std::vector<std::uint32_t>& at(int x, int y) {
        return cells[static_cast<std::size_t>(y) * static_cast<std::size_t>(nx) + static_cast<std::size_t>(x)];
    }
    const std::vector<std::uint32_t>& at(int x, int y) const {
        return cells[static_cast<std::size_t>(y) * static_cast<std::size_t>(nx) + static_cast<std::size_t>(x)];
    }
};

/// Per-thread scratch: deltas of the objective's entries, with a list of touched entries.
struct Scratch {
    std::vector<double> value;
    std::vector<std::uint32_t> touched;
    void add(std::uint32_t e, double v) {
        if (value[e] == 0.0) touched.push_back(e);
        value[e] += v;
        if (value[e] == 0.0) value[e] = 1e-300;  // keep it listed (exact cancellation)
    }
    void clear() {
        for (std::uint32_t e : touched) value[e] = 0.0;
        touched.clear();
    }
};

}  // namespace

RefineResult refineUndergrowth(std::vector<Plant>& undergrowth, const std::vector<Plant>& canopy,
                               const ClusterMap& map, const Grid<float>& terrainM, const BiomeDatabase& db,
                               const SynthParams& synth, const RefineParams& params, const RefineProgress& progress) {
    const auto t0 = Clock::now();
    params.validate();
    synth.validate();
    if (!map.region.sameGeometry(terrainM))
        throw ValidationError("refinement: the cluster map and the terrain (" + terrainM.geometryText() + ") differ in geometry");
    const Biome biome = databaseBiome(db);
    const int nS = db.speciesCount();
    const int C = 2 * nS;
    const int nRegions = static_cast<int>(db.regions.size());
    RefineResult res;

    // The statistics' regions: the cluster map, inside the window when one is given.
    // With a window, the labels are cropped to its cells (world coordinates are kept), so
    // that the regions' windows cost what the refined area costs, not the whole terrain.
    Grid<std::int32_t> labels;
    if (params.useWindow) {
        params.window.validate("refinement window");
        const Grid<std::int32_t>& g = map.region;
        const int ix0 = std::clamp(g.cellX(params.window.x0), 0, g.width() - 1);
        const int ix1 = std::clamp(g.cellX(params.window.x1), 0, g.width() - 1);
        const int iy0 = std::clamp(g.cellY(params.window.y0), 0, g.height() - 1);
        const int iy1 = std::clamp(g.cellY(params.window.y1), 0, g.height() - 1);
        labels = Grid<std::int32_t>(ix1 - ix0 + 1, iy1 - iy0 + 1, g.cellSizeM(), g.originX() + ix0 * g.cellSizeM(),
                                    g.originY() + iy0 * g.cellSizeM(), -1);
        for (int iy = iy0; iy <= iy1; ++iy)
            for (int ix = ix0; ix <= ix1; ++ix)
                if (params.window.contains(g.cellCentreX(ix), g.cellCentreY(iy))) labels(ix - ix0, iy - iy0) = g(ix, iy);
    } else {
        labels = map.region;
    }

    // Range and bins matched: the database's first nb bins.
    const DistanceBins& dbBins = db.pcfBins;
    double rWanted = params.rMaxM;
    if (!(rWanted > 0)) {
        double densest = 0;
        for (const auto& r : db.regions) densest = std::max(densest, r.densityPerM2 + r.canopyCount / std::max(r.areaM2, 1e-9));
        rWanted = densest > 0 ? std::sqrt(params.autoNeighbours / (3.141592653589793 * densest)) : dbBins.rMaxM;
    }
    int nb = 0;
    while (nb < dbBins.count && dbBins.hiM(nb) <= rWanted + 1e-9) ++nb;
    nb = std::max(nb, 1);
    const double rRef = dbBins.hiM(nb - 1);
    const DistanceBins bins{rRef, nb};  // the same edges as the database's first nb bins
    res.rMaxM = rRef;

    const ScenePairStats sampledBefore =
        scenePairStatistics(canopy, undergrowth, labels, nRegions, nS, dbBins, nullptr, params.distanceSources, params.seed);
    res.distanceBefore = pcfDistance(sampledBefore, db).overall;
    if (params.sweeps == 0 || undergrowth.empty() || nRegions == 0) {
        res.distanceAfter = res.distanceBefore;
        res.seconds = secondsSince(t0);
        return res;
    }
    // Exact sums over the matched bins: the start of the incremental objective.
    const ScenePairStats before = scenePairStatistics(canopy, undergrowth, labels, nRegions, nS, bins);

    // Plants: positions, categories, regions (plants outside every region never move).
    const std::size_t n = undergrowth.size();
    std::vector<double> px(n), py(n);
    std::vector<int> pcat(n), preg(n);
    for (std::size_t i = 0; i < n; ++i) {
        px[i] = undergrowth[i].xM;
        py[i] = undergrowth[i].yM;
        pcat[i] = undergrowth[i].speciesId;
        const int ix = labels.cellX(px[i]), iy = labels.cellY(py[i]);
        preg[i] = labels.inside(ix, iy) ? labels(ix, iy) : -1;
        if (preg[i] >= 0) ++res.movable;
    }
    // Canopy trees of a region: fixed neighbours.
    std::vector<double> cx, cy;
    std::vector<int> ccat, creg;
    for (const Plant& t : canopy) {
        const int ix = labels.cellX(t.xM), iy = labels.cellY(t.yM);
        if (!labels.inside(ix, iy) || labels(ix, iy) < 0) continue;
        cx.push_back(t.xM);
        cy.push_back(t.yM);
        ccat.push_back(nS + t.speciesId);
        creg.push_back(labels(ix, iy));
    }
    const PointGrid canopyGrid(cx, cy, std::max(rRef / 2.0, 1e-3));
    const std::vector<int> gCat = canopyGrid.permuted(ccat), gReg = canopyGrid.permuted(creg);
    const std::vector<CellWindow> windows = CellWindow::fromLabels(labels, nRegions, rRef);
    const TrunkIndex trunks(canopy, synth.trunkExclusionFactor);
    const std::vector<int> subMask = speciesSubBiomeMasks(biome);

    // The objective: E = sum over entries e = (region, i <= j, bin) of kappa_e (S_e - T_e)^2,
    // S = translation-weighted ordered-pair sums, T = the database's g times the annulus area
    // times the pair normalisation; kappa makes E the mean squared g difference weighted by
    // pairs (as pcfDistance, over the bins matched here).
    const std::size_t CC = static_cast<std::size_t>(C) * static_cast<std::size_t>(C);
    const std::size_t NB = static_cast<std::size_t>(nb);
    const std::size_t perRegion = CC * NB;
    const std::size_t nEntries = perRegion * static_cast<std::size_t>(nRegions);
    if (nEntries >= (std::size_t{1} << 32)) throw ValidationError("refinement: too many regions and species");
    auto entry = [&](int r, int i, int j, int b) -> std::uint32_t {
        if (i > j) std::swap(i, j);
        return static_cast<std::uint32_t>(static_cast<std::size_t>(r) * perRegion +
                                          (static_cast<std::size_t>(i) * static_cast<std::size_t>(C) + static_cast<std::size_t>(j)) * NB +
                                          static_cast<std::size_t>(b));
    };
    std::vector<double> S(nEntries, 0.0), T(nEntries, 0.0), kappa(nEntries, 0.0);
    double totalPairs = 0;
    for (int r = 0; r < nRegions; ++r) {
        const auto& R = before.regions[static_cast<std::size_t>(r)];
        for (int i = 0; i < C; ++i)
            for (int j = i; j < C; ++j) {
                if (i >= nS && j >= nS) continue;
                if (pairsOf(R, i, j) > 0 && databaseG(db.regions[static_cast<std::size_t>(r)], i, j)) totalPairs += pairsOf(R, i, j);
            }
    }
    for (int r = 0; r < nRegions && totalPairs > 0; ++r) {
        const auto& R = before.regions[static_cast<std::size_t>(r)];
        for (int i = 0; i < C; ++i)
            for (int j = i; j < C; ++j) {
                if (i >= nS && j >= nS) continue;
                const double pairs = pairsOf(R, i, j);
                const std::vector<double>* gt = databaseG(db.regions[static_cast<std::size_t>(r)], i, j);
                if (!(pairs > 0) || !gt || gt->size() != static_cast<std::size_t>(dbBins.count)) continue;
                const double norm = pairNormalisation(static_cast<double>(R.count[static_cast<std::size_t>(i)]),
                                                      static_cast<double>(R.count[static_cast<std::size_t>(j)]), i == j, R.areaM2);
                for (int b = 0; b < nb; ++b) {
                    const std::uint32_t e = entry(r, i, j, b);
                    const double an = bins.annulusAreaM2(b) * norm;
                    S[e] = R.weighted[(static_cast<std::size_t>(i) * static_cast<std::size_t>(C) + static_cast<std::size_t>(j)) *
                                          NB +
                                      static_cast<std::size_t>(b)];
                    T[e] = (*gt)[static_cast<std::size_t>(b)] * an;
                    kappa[e] = (pairs / totalPairs) / (an * an * static_cast<double>(nb));
                }
            }
    }
    std::vector<std::uint32_t> active;
    for (std::uint32_t e = 0; e < nEntries; ++e)
        if (kappa[e] > 0) active.push_back(e);
    auto objective = [&] {
        double E = 0;
        for (std::uint32_t e : active) E += kappa[e] * (S[e] - T[e]) * (S[e] - T[e]);
        return std::sqrt(E);
    };
    res.objectivePerSweep.push_back(objective());

    // Buckets (a third of the range) and tiles of whole buckets, at least the range wide
    // (so that two tiles of one colour never see each other's plants) and twice the moves.
    Buckets bk;
    bk.ox = terrainM.originX();
    bk.oy = terrainM.originY();
    bk.side = std::max(rRef / 3.0, 0.25);
    bk.inv = 1.0 / bk.side;
    bk.nx = std::max(1, static_cast<int>(std::ceil(terrainM.extentX() * bk.inv)));
    bk.ny = std::max(1, static_cast<int>(std::ceil(terrainM.extentY() * bk.inv)));
    bk.cells.assign(static_cast<std::size_t>(bk.nx) * static_cast<std::size_t>(bk.ny), {});
    for (std::size_t i = 0; i < n; ++i)
        if (preg[i] >= 0) bk.at(bk.bx(px[i]), bk.by(py[i])).push_back(static_cast<std::uint32_t>(i));
    const double maxMove = std::max(params.moveRadiusM, params.swapRadiusM);
    const int tileB = std::max(1, static_cast<int>(std::ceil(std::max(rRef, 2.0 * maxMove) * bk.inv - 1e-9)));
    const int reach = static_cast<int>(std::ceil(rRef * bk.inv));  // buckets searched around a point

    const int nThreads = std::max(1, omp_get_max_threads());
    std::vector<Scratch> local(static_cast<std::size_t>(nThreads)), move(static_cast<std::size_t>(nThreads));
    for (int t = 0; t < nThreads; ++t) {
        local[static_cast<std::size_t>(t)].value.assign(nEntries, 0.0);
        move[static_cast<std::size_t>(t)].value.assign(nEntries, 0.0);
    }
    const double x0 = terrainM.originX(), y0 = terrainM.originY();
    const double x1 = x0 + terrainM.extentX(), y1 = y0 + terrainM.extentY();

    for (int sweep = 0; sweep < params.sweeps; ++sweep) {
        const int shift = (sweep % 2 == 1) ? tileB / 2 : 0;
        const int ntx = (bk.nx + shift + tileB - 1) / tileB, nty = (bk.ny + shift + tileB - 1) / tileB;
        auto tileOf = [&](double x, double y, int& tx, int& ty) {
            tx = (bk.bx(x) + shift) / tileB;
            ty = (bk.by(y) + shift) / tileB;
        };
        const std::uint64_t sweepStream = mixStream(kRefineStream, static_cast<std::uint64_t>(sweep));
        for (int phase = 0; phase < 4; ++phase) {
            std::vector<std::pair<int, int>> tiles;
            for (int ty = phase / 2; ty < nty; ty += 2)
                for (int tx = phase % 2; tx < ntx; tx += 2) tiles.emplace_back(tx, ty);
            // Each tile's share of the plants of each region moving in this phase: a tile aims
            // at that share of the region's residual, so that the tiles together aim at all of it.
            std::vector<std::vector<std::uint32_t>> tilePlants(tiles.size());
            std::vector<double> phaseCount(static_cast<std::size_t>(nRegions), 0.0);
            for (std::size_t t = 0; t < tiles.size(); ++t) {
                const int bxa = std::max(0, tiles[t].first * tileB - shift), bxb = std::min(bk.nx, (tiles[t].first + 1) * tileB - shift);
                const int bya = std::max(0, tiles[t].second * tileB - shift), byb = std::min(bk.ny, (tiles[t].second + 1) * tileB - shift);
                auto& list = tilePlants[t];
                for (int by = bya; by < byb; ++by)
                    for (int bx = bxa; bx < bxb; ++bx) {
                        const auto& c = bk.at(bx, by);
                        list.insert(list.end(), c.begin(), c.end());
                    }
                std::sort(list.begin(), list.end());
                for (std::uint32_t p : list) phaseCount[static_cast<std::size_t>(preg[p])] += 1;
            }
            std::vector<std::vector<std::pair<std::uint32_t, double>>> tileDelta(tiles.size());
            std::vector<std::int64_t> tileProposals(tiles.size(), 0), tileAccepted(tiles.size(), 0);
#pragma omp parallel for schedule(dynamic, 1)
            for (std::size_t t = 0; t < tiles.size(); ++t) {
                const auto& list = tilePlants[t];
                if (list.empty()) continue;
                Scratch& L = local[static_cast<std::size_t>(omp_get_thread_num())];
                Scratch& M = move[static_cast<std::size_t>(omp_get_thread_num())];
                std::vector<double> share(static_cast<std::size_t>(nRegions), 0.0);
                for (std::uint32_t p : list) share[static_cast<std::size_t>(preg[p])] += 1;
                for (int r = 0; r < nRegions; ++r)
                    if (phaseCount[static_cast<std::size_t>(r)] > 0) share[static_cast<std::size_t>(r)] /= phaseCount[static_cast<std::size_t>(r)];
                const int ttx = tiles[t].first, tty = tiles[t].second;

                // Pairs of a plant of category cat (region r) placed at (x, y) with every other
                // plant of region r within range, except `skipA` and `skipB`: sign x weight
                // into M.
                auto visit = [&](int r, int cat, double x, double y, std::uint32_t skipA, std::uint32_t skipB, double sign) {
                    const CellWindow& win = windows[static_cast<std::size_t>(r)];
                    const int cbx = bk.bx(x), cby = bk.by(y);
                    const double r2 = rRef * rRef;
                    for (int by = std::max(0, cby - reach); by <= std::min(bk.ny - 1, cby + reach); ++by)
                        for (int bx = std::max(0, cbx - reach); bx <= std::min(bk.nx - 1, cbx + reach); ++bx)
                            for (std::uint32_t q : bk.at(bx, by)) {
                                if (q == skipA || q == skipB || preg[q] != r) continue;
                                const double dx = px[q] - x, dy = py[q] - y, d2 = dx * dx + dy * dy;
                                if (!(d2 < r2)) continue;
                                const int b = bins.binOf(std::sqrt(d2));
                                if (b < 0 || b >= nb) continue;
                                const int cq = pcat[q];
                                const std::uint32_t e = entry(r, cat, cq, b);
                                if (kappa[e] == 0) continue;
                                M.add(e, sign * (cat == cq ? 2.0 : 1.0) * win.translationWeight(dx, dy));
                            }
                    canopyGrid.forEachWithin(x, y, rRef, [&](std::size_t s, double dx, double dy, double d2) {
                        if (gReg[s] != r) return;
                        const int b = bins.binOf(std::sqrt(d2));
                        if (b < 0 || b >= nb) return;
                        const std::uint32_t e = entry(r, cat, gCat[s], b);
                        if (kappa[e] == 0) return;
                        M.add(e, sign * win.translationWeight(dx, dy));
                    });
                };
                auto deltaE = [&](int r) {
                    const double f = share[static_cast<std::size_t>(r)];
                    double dE = 0;
                    for (std::uint32_t e : M.touched) {
                        const double base = f * (S[e] - T[e]) + L.value[e];
                        const double d = M.value[e];
                        dE += kappa[e] * ((base + d) * (base + d) - base * base);
                    }
                    return dE;
                };
                auto commit = [&] {
                    for (std::uint32_t e : M.touched) L.add(e, M.value[e]);
                    M.clear();
                };
                auto inTile = [&](double x, double y) {
                    int tx, ty;
                    tileOf(x, y, tx, ty);
                    return tx == ttx && ty == tty;
                };
                auto eraseFrom = [](std::vector<std::uint32_t>& v, std::uint32_t p) {
                    const auto it = std::find(v.begin(), v.end(), p);
                    if (it != v.end()) v.erase(it);
                };

                for (std::uint32_t p : list) {
                    const int r = preg[p];
                    RandomStream rs(params.seed, mixStream(sweepStream, p));
                    ++tileProposals[t];
                    if (rs.uniform() < params.swapProbability) {
                        // Swap positions with a plant of another species nearby.
                        const double ang = 6.283185307179586 * rs.uniform();
                        const double rad = params.swapRadiusM * std::sqrt(rs.uniform());
                        const double qx = px[p] + rad * std::cos(ang), qy = py[p] + rad * std::sin(ang);
                        if (qx < x0 || qx >= x1 || qy < y0 || qy >= y1 || !inTile(qx, qy)) continue;
                        const auto& cand = bk.at(bk.bx(qx), bk.by(qy));
                        if (cand.empty()) continue;
                        const std::uint32_t q = cand[rs.below(static_cast<std::uint32_t>(cand.size()))];
                        if (q == p || preg[q] != r || pcat[q] == pcat[p]) continue;
                        // The swapped plants must grow at each other's places.
                        const int ipx = map.combination.cellX(px[p]), ipy = map.combination.cellY(py[p]);
                        const int iqx = map.combination.cellX(px[q]), iqy = map.combination.cellY(py[q]);
                        if ((subMask[static_cast<std::size_t>(pcat[p])] & map.combination(iqx, iqy)) == 0 ||
                            (subMask[static_cast<std::size_t>(pcat[q])] & map.combination(ipx, ipy)) == 0)
                            continue;
                        visit(r, pcat[p], px[p], py[p], p, q, -1.0);
                        visit(r, pcat[p], px[q], py[q], p, q, +1.0);
                        visit(r, pcat[q], px[q], py[q], p, q, -1.0);
                        visit(r, pcat[q], px[p], py[p], p, q, +1.0);
                        if (deltaE(r) < 0) {
                            commit();
                            std::swap(px[p], px[q]);
                            std::swap(py[p], py[q]);
                            auto& bp = bk.at(bk.bx(px[p]), bk.by(py[p]));  // now holds q's old slot
                            auto& bq = bk.at(bk.bx(px[q]), bk.by(py[q]));
                            if (&bp != &bq) {
                                *std::find(bp.begin(), bp.end(), q) = p;
                                *std::find(bq.begin(), bq.end(), p) = q;
                            }
                            ++tileAccepted[t];
                        } else {
                            M.clear();
                        }
                    } else {
                        // Displacement, uniform in a disc.
                        const double ang = 6.283185307179586 * rs.uniform();
                        const double rad = params.moveRadiusM * std::sqrt(rs.uniform());
                        const double nx = px[p] + rad * std::cos(ang), ny = py[p] + rad * std::sin(ang);
                        if (nx < x0 || nx >= x1 || ny < y0 || ny >= y1 || !inTile(nx, ny)) continue;
                        const int ix = labels.cellX(nx), iy = labels.cellY(ny);
                        if (!labels.inside(ix, iy) || labels(ix, iy) != r) continue;
                        if ((subMask[static_cast<std::size_t>(pcat[p])] & map.combination(ix, iy)) == 0) continue;
                        if (trunks.onTrunk(nx, ny)) continue;
                        visit(r, pcat[p], px[p], py[p], p, p, -1.0);
                        visit(r, pcat[p], nx, ny, p, p, +1.0);
                        if (deltaE(r) < 0) {
                            commit();
                            auto& from = bk.at(bk.bx(px[p]), bk.by(py[p]));
                            auto& to = bk.at(bk.bx(nx), bk.by(ny));
                            if (&from != &to) {
                                eraseFrom(from, p);
                                to.push_back(p);
                            }
                            px[p] = nx;
                            py[p] = ny;
                            ++tileAccepted[t];
                        } else {
                            M.clear();
                        }
                    }
                }
                auto& delta = tileDelta[t];
                for (std::uint32_t e : L.touched) delta.emplace_back(e, L.value[e]);
                L.clear();
            }
            for (std::size_t t = 0; t < tiles.size(); ++t) {
                for (const auto& [e, d] : tileDelta[t]) S[e] += d;
                res.proposals += tileProposals[t];
                res.accepted += tileAccepted[t];
            }
        }
        res.objectivePerSweep.push_back(objective());
        if (progress) progress(sweep + 1, params.sweeps);
    }

    for (std::size_t i = 0; i < n; ++i) {
        undergrowth[i].xM = px[i];
        undergrowth[i].yM = py[i];
        undergrowth[i].groundZM = terrainM.sampleBilinear(px[i], py[i]);
    }
    const ScenePairStats after =
        scenePairStatistics(canopy, undergrowth, labels, nRegions, nS, dbBins, nullptr, params.distanceSources, params.seed);
    res.distanceAfter = pcfDistance(after, db).overall;
    res.seconds = secondsSince(t0);
    return res;
}

}  // namespace eco::synth
