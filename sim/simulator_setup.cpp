// Simulator setup: the inputs checked, the species constants, the simulation grid, the canopy's
// shade and water per cell, the seedbank around the canopy trees, and the initial plants.
#include "simulator_impl.h"

#include <limits>

namespace eco::sim {

void Simulation::Impl::setup(SimInputs&& in, const SimParams& p, std::uint64_t s) {
    params = p;
    params.validate("simulation parameters");
    seed = s;
    biome = std::move(in.biome);
    abio = std::move(in.abiotics);
    chm = std::move(in.chmM);
    validateAbiotics();
    setupSpecies();
    setupGrid(in.area);
    setupCanopy(in.canopy);
}

void Simulation::Impl::validateAbiotics() {
    const Grid<float>& g = abio.slopeDeg;
    if (g.empty()) throw ValidationError("simulation: the abiotics have no slope map");
    // Every map of kAbioticMaps: the monthly ones first, then the static ones (the order of
    // the messages before the table).
    for (const bool monthly : {true, false})
        for (const AbioticMapInfo& m : kAbioticMaps) {
            if (m.isMonthly() != monthly) continue;
            if (monthly && (abio.*(m.monthly)).months.size() != 12)
                throw ValidationError(std::string("simulation: abiotic map '") + m.name +
                                      "' must have 12 monthly planes, has " +
                                      std::to_string((abio.*(m.monthly)).months.size()));
            if (!monthly && (abio.*(m.single)).empty())
                throw ValidationError(std::string("simulation: the abiotics have no ") + m.name + " map");
            forEachPlane(abio, m, [&](const Grid<float>& plane) {
                if (!plane.sameGeometry(g))
                    throw ValidationError(std::string("simulation: abiotic map '") + m.name +
                                          "' does not have the geometry of the slope map");
            });
        }
    if (abio.elevationM.empty()) abio.elevationM = Grid<float>::like(g, 0.f);
    if (!abio.elevationM.sameGeometry(g))
        throw ValidationError("simulation: the elevation map does not have the geometry of the slope map");
}

void Simulation::Impl::setupSpecies() {
    if (biome.species.empty()) throw ValidationError("simulation: the biome has no species");
    vigA = biome.vigour.a;
    vigLnQ = std::log(biome.vigour.q);
    vigP = biome.vigour.p;
    vigPIsFourAndHalf = vigP == 4.5;
    periodMonthMask.clear();
    for (const auto& [name, months] : biome.growthPeriods) {
        std::uint32_t mask = 0;
        for (int m : months) mask |= 1u << m;
        periodMonthMask.push_back(mask);
    }
    for (int m = 0; m < 12; ++m) {
        periodsOfMonth[m].clear();
        for (std::size_t g = 0; g < periodMonthMask.size(); ++g)
            if (periodMonthMask[g] & (1u << m)) periodsOfMonth[m].push_back(static_cast<int>(g));
    }
    if (biome.species.size() > BandEntry::kMaxSpecies + 1)
        throw ValidationError("simulation: the biome has " + std::to_string(biome.species.size()) + " species; at most " +
                              std::to_string(BandEntry::kMaxSpecies + 1) + " are supported");
    spc.assign(biome.species.size(), {});
    speciesKeep.assign(biome.species.size(), 1.f);
    for (std::size_t i = 0; i < biome.species.size(); ++i) {
        const Species& s = biome.species[i];
        SpeciesConst& c = spc[i];
        c.alpha = s.alpha;
        speciesKeep[i] = static_cast<float>(1.0 - s.alpha);
        c.maxAgeYears = s.maxAgeYears;
        c.maxHeightM = s.maxHeightM;
        if (!(s.maxAgeYears > 0) || !(s.maxHeightM > 0))
            throw ValidationError("simulation: species '" + s.name + "' needs a positive max age and max height");
        c.capacity = poolCapacity(params.poolCapacityStressMonths, s.alpha, vigA);
        c.backgroundMu = backgroundMortalityPerMonth(params.survivalAtMaxAge, s.maxAgeYears);
        c.rouletteDenominator = std::pow(s.maxAgeYears, params.rouletteAgeExponent);
        c.vigour = VigourCoeffs::from(s.alpha, s.responses);
        c.period = -1;
        for (std::size_t g = 0; g < biome.growthPeriods.size(); ++g)
            if (biome.growthPeriods[g].first == s.growthPeriod) c.period = static_cast<int>(g);
        std::vector<int> months = s.growthMonths;
        if (c.period >= 0 && months.empty()) months = biome.growthPeriods[static_cast<std::size_t>(c.period)].second;
        if (c.period < 0) {
            // A species whose months are not a named period gets a period of its own.
            std::uint32_t mask = 0;
            for (int m : months) mask |= 1u << m;
            periodMonthMask.push_back(mask);
            c.period = static_cast<int>(periodMonthMask.size() - 1);
            for (int m : months) periodsOfMonth[m].push_back(c.period);
        }
        for (int m : months) c.growthMonth[m] = true;
        int growthMonths = 0;
        for (bool g : c.growthMonth) growthMonths += g ? 1 : 0;
        // g's maximum is g(0) = 1, so the species' maximum vigour is alpha_s.
        c.growthPerOverflow =
            growthMonthsPerUnitOverflow(params.growthRule, params.growthMonthsPerOverflow, s.alpha, growthMonths);
        for (int b : s.subBiomes) c.memberMask |= 1u << (b - 1);
        c.allometry = s.allometry;
    }
    for (const SubBiome& sb : biome.subBiomes)
        for (const std::string& name : sb.canopySpecies)
            for (std::size_t i = 0; i < biome.species.size(); ++i)
                if (biome.species[i].name == name) spc[i].canopySeedMask |= 1u << (sb.number - 1);
    if (periodMonthMask.size() > kMaxGrowthPeriods)
        throw ValidationError("simulation: the biome has " + std::to_string(periodMonthMask.size()) +
                              " growth periods (named, and species' own growth months); at most " +
                              std::to_string(kMaxGrowthPeriods) + " are supported");
}

void Simulation::Impl::setupGrid(const std::optional<SimArea>& requested) {
    const Grid<float>& g = abio.slopeDeg;
    const double ex0 = g.originX(), ey0 = g.originY(), ex1 = ex0 + g.extentX(), ey1 = ey0 + g.extentY();
    area = requested ? *requested : SimArea{ex0, ey0, ex1, ey1};
    const double tol = 1e-6 * std::max(1.0, std::max(std::abs(ex1), std::abs(ey1)));
    if (area.x0 < ex0 - tol || area.y0 < ey0 - tol || area.x1 > ex1 + tol || area.y1 > ey1 + tol)
        throw ValidationError("simulation: area [" + std::to_string(area.x0) + ", " + std::to_string(area.y0) + ", " +
                              std::to_string(area.x1) + ", " + std::to_string(area.y1) +
                              "] (x0, y0, x1, y1 in metres) is not inside the abiotics extent [" +
                              std::to_string(ex0) + ", " + std::to_string(ey0) + ", " + std::to_string(ex1) + ", " +
                              std::to_string(ey1) + "]");
    cell = params.cellSizeM;
    W = static_cast<int>(std::floor((area.x1 - area.x0) / cell + 1e-9));
    H = static_cast<int>(std::floor((area.y1 - area.y0) / cell + 1e-9));
    if (W < 1 || H < 1) throw ValidationError("simulation: area is smaller than one cell of " + std::to_string(cell) + " m");
    // Footprint rows are at most W cells, stored in 16 bits (BandEntry).
    if (W > static_cast<int>(BandEntry::kMaxLen) || static_cast<double>(W) * H > 4.0e9)
        throw ValidationError("simulation: area of " + std::to_string(W) + " x " + std::to_string(H) + " cells of " +
                              std::to_string(cell) + " m is too large (at most " + std::to_string(BandEntry::kMaxLen) +
                              " cells wide and 4e9 cells): simulate it in parts or with larger cells");
    ox = area.x0;
    oy = area.y0;
    // The grid covers whole cells; the area's upper edges are trimmed to them.
    area.x1 = ox + W * cell;
    area.y1 = oy + H * cell;
    seedProb = Grid<float>(W, H, cell, ox, oy, 0.f);
    coarseCol.resize(static_cast<std::size_t>(W));
    for (int ix = 0; ix < W; ++ix) coarseCol[ix] = std::clamp(g.cellX(seedProb.cellCentreX(ix)), 0, g.width() - 1);
    coarseRowOffset.resize(static_cast<std::size_t>(H));
    for (int iy = 0; iy < H; ++iy)
        coarseRowOffset[iy] = static_cast<std::size_t>(std::clamp(g.cellY(seedProb.cellCentreY(iy)), 0, g.height() - 1)) *
                              static_cast<std::size_t>(g.width());
    const std::size_t n = static_cast<std::size_t>(W) * static_cast<std::size_t>(H);
    canopyTrans = Grid<float>(W, H, cell, ox, oy, 1.f);
    canopyTrees.assign(n, 0);
    seedPkg.assign(n, 0);
    occupants.assign(n, 0);
    deficit.assign(n * periodMonthMask.size() * 2, 0.f);
    if (params.germinationVigour == GerminationVigour::MeanVigour) monthDeficit.assign(n * 12 * 2, 0.f);
}

void Simulation::Impl::setupCanopy(const std::vector<Plant>& trees) {
    // Keep the trees whose crown or seeding disc reaches the area, in input order.
    canopy.clear();
    for (const Plant& t : trees) {
        if (t.speciesId < 0 || static_cast<std::size_t>(t.speciesId) >= spc.size())
            throw ValidationError("simulation: canopy tree with species id " + std::to_string(t.speciesId) +
                                  " outside the biome's " + std::to_string(spc.size()) + " species");
        if (!std::isfinite(t.xM) || !std::isfinite(t.yM) || !std::isfinite(t.crownRadiusM) || t.crownRadiusM < 0)
            throw ValidationError("simulation: canopy tree with a non-finite position or a bad crown radius");
        const double reach = std::max(1.0, params.seedOuterRadiusFactor) * t.crownRadiusM;
        const double dx = std::max({area.x0 - t.xM, 0.0, t.xM - area.x1});
        const double dy = std::max({area.y0 - t.yM, 0.0, t.yM - area.y1});
        if (dx * dx + dy * dy <= reach * reach) canopy.push_back(t);
    }
    if (chm.empty()) {
        // No CHM given: the tallest covering crown, at the abiotics resolution.
        chm = Grid<float>::like(abio.slopeDeg, 0.f);
        for (const Plant& t : trees) {
            const int x0 = std::max(0, chm.cellX(t.xM - t.crownRadiusM)), x1 = std::min(chm.width() - 1, chm.cellX(t.xM + t.crownRadiusM));
            const int y0 = std::max(0, chm.cellY(t.yM - t.crownRadiusM)), y1 = std::min(chm.height() - 1, chm.cellY(t.yM + t.crownRadiusM));
            for (int iy = y0; iy <= y1; ++iy)
                for (int ix = x0; ix <= x1; ++ix) {
                    const double dx = chm.cellCentreX(ix) - t.xM, dy = chm.cellCentreY(iy) - t.yM;
                    if (dx * dx + dy * dy <= t.crownRadiusM * t.crownRadiusM)
                        chm(ix, iy) = std::max(chm(ix, iy), static_cast<float>(t.heightM));
                }
        }
    }
    const double gamma = params.seedingProbability;
    const double inner = params.seedInnerRadiusFactor, outer = params.seedOuterRadiusFactor;
    std::vector<float>& prob = seedProb.data();
    // Each band of rows is owned by one thread and visits the trees in input order, so the
    // float products and sums per cell are the same for any thread count.
#pragma omp parallel for schedule(dynamic, 1)
    for (int b = 0; b < bands(); ++b) {
        const int r0 = b * kBandRows, r1 = std::min(H, r0 + kBandRows);
        for (const Plant& t : canopy) {
            const SpeciesConst& sc = spc[static_cast<std::size_t>(t.speciesId)];
            const float keep = static_cast<float>(1.0 - sc.alpha);
            int lo, hi;
            rowRange(t.yM, t.crownRadiusM, -1, lo, hi);
            if (t.crownRadiusM > 0 && lo <= hi)
                forEachSpan(t.xM, t.yM, t.crownRadiusM, -1, -1, std::max(lo, r0), std::min(hi + 1, r1),
                            [&](int iy, int a, int e) {
                                float* trans = &canopyTrans.data()[static_cast<std::size_t>(iy) * W];
                                std::uint8_t* count = &canopyTrees[static_cast<std::size_t>(iy) * W];
                                for (int ix = a; ix <= e; ++ix) {
                                    trans[ix] *= keep;
                                    if (count[ix] < 255) ++count[ix];
                                }
                            });
            if (sc.canopySeedMask == 0 || !(t.crownRadiusM > 0) || !(gamma > 0)) continue;
            const double reach = outer * t.crownRadiusM;
            rowRange(t.yM, reach, -1, lo, hi);
            if (lo > hi) continue;
            forEachSpan(t.xM, t.yM, reach, -1, -1, std::max(lo, r0), std::min(hi + 1, r1), [&](int iy, int a, int e) {
                const double dy = oy + (iy + 0.5) * cell - t.yM;
                const std::size_t rowOff = static_cast<std::size_t>(iy) * W;
                for (int ix = a; ix <= e; ++ix) {
                    const double dx = ox + (ix + 0.5) * cell - t.xM;
                    const double k = seedKernel(std::sqrt(dx * dx + dy * dy), t.crownRadiusM, inner, outer);
                    if (k <= 0) continue;
                    prob[rowOff + ix] += static_cast<float>(gamma * k);
                    seedPkg[rowOff + ix] |= static_cast<std::uint16_t>(sc.canopySeedMask);
                }
            });
        }
        for (int iy = r0; iy < r1; ++iy)
            for (int ix = 0; ix < W; ++ix) {
                float& v = prob[static_cast<std::size_t>(iy) * W + ix];
                v = std::min(v, 1.f);
            }
    }
}

float Simulation::Impl::canopyLimitAt(double x, double y) const {
    const int ix = std::clamp(chm.cellX(x), 0, chm.width() - 1), iy = std::clamp(chm.cellY(y), 0, chm.height() - 1);
    const double canopy = chm(ix, iy);
    if (params.canopyLimit == CanopyLimit::CanopyOnly)  // gaps: no limit below the species' own
        return canopy >= params.canopyThresholdM ? static_cast<float>(canopy) : std::numeric_limits<float>::infinity();
    return static_cast<float>(std::max(canopy, params.canopyThresholdM));
}

void Simulation::Impl::addPlant(std::uint64_t id, int s, double x, double y, int rootIx, int rootIy, double growthAgeYears,
              double ageYears, double pool, double vig) {
    pl.resize(pl.size() + 1);
    fpRange.clear();  // footprints are recomputed (buildBands)
    fate.resize(pl.size(), 0);
    layoutReusable = false;
    setPlant(pl.size() - 1, id, s, x, y, rootIx, rootIy, growthAgeYears, ageYears, month, pool, vig);
}

// Writes plant p of the store (already sized); plants are independent of each other. The
// plant is ageYears old when `monthsDone` months are done.
void Simulation::Impl::setPlant(std::size_t p, std::uint64_t id, int s, double x, double y, int rootIx, int rootIy, double growthAgeYears,
              double ageYears, std::int64_t monthsDone, double pool, double vig) {
    const SpeciesConst& c = spc[static_cast<std::size_t>(s)];
    const double h = idealHeightM(growthAgeYears, c.maxAgeYears, c.maxHeightM);
    const Grid<float>& g = abio.slopeDeg;
    const int cx = std::clamp(g.cellX(x), 0, g.width() - 1), cy = std::clamp(g.cellY(y), 0, g.height() - 1);
    pl.id[p] = id;
    pl.species[p] = s;
    pl.x[p] = x;
    pl.y[p] = y;
    pl.groundZ[p] = abio.elevationM.sampleBilinear(x, y);
    pl.height[p] = h;
    pl.radius[p] = crownRadius(s, h);
    pl.growthAge[p] = growthAgeYears;
    pl.pool[p] = pool;
    pl.birthMonth[p] = static_cast<std::int32_t>(monthsDone - std::lround(ageYears * 12.0));
    pl.rootIx[p] = rootIx;
    pl.rootIy[p] = rootIy;
    pl.coarse[p] = static_cast<std::uint32_t>(g.index(cx, cy));
    pl.vigour[p] = static_cast<float>(vig);
    pl.sun[p] = 0.f;
    pl.water[p] = 0.f;
    pl.canopyLimit[p] = canopyLimitAt(x, y);
}

void Simulation::Impl::addInitial(const std::vector<UndergrowthPlant>& initial) {
    for (const UndergrowthPlant& p : initial) {
        if (p.speciesId < 0 || static_cast<std::size_t>(p.speciesId) >= spc.size())
            throw ValidationError("simulation: initial plant with species id " + std::to_string(p.speciesId) +
                                  " outside the biome's " + std::to_string(spc.size()) + " species");
        if (!std::isfinite(p.xM) || !std::isfinite(p.yM) || !std::isfinite(p.heightM) || p.heightM < 0 ||
            !std::isfinite(p.pool) || !std::isfinite(p.ageYears) || p.ageYears < 0)
            throw ValidationError("simulation: initial plant " + std::to_string(p.id) + " has a non-finite or negative value");
        const int ix = seedProb.cellX(p.xM), iy = seedProb.cellY(p.yM);
        if (!seedProb.inside(ix, iy)) {
            ++droppedInitial;
            continue;
        }
        const SpeciesConst& c = spc[static_cast<std::size_t>(p.speciesId)];
        const double ga = p.growthAgeYears > 0 ? p.growthAgeYears : growthAgeForHeight(p.heightM, c.maxAgeYears, c.maxHeightM);
        const double pool = std::min(p.pool, c.capacity);
        addPlant(nextId++, p.speciesId, p.xM, p.yM, ix, iy, ga, p.ageYears, pool, p.vigour);
    }
}

}  // namespace eco::sim
