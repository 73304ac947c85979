// The monthly plant processes (processes.h): vigour from the resource shares, carbon pool,
// growth, background and stress mortality; Deussen competition; removal of the dead.
#include "simulator_impl.h"

namespace eco::sim {

namespace {

// Plants per block of the monthly update: the vigour exponents of a block are gathered,
// their exps taken in one vectorised loop (batchExp), then each plant is updated. A plant's
// result depends on its own data only, so the blocking changes no result.
constexpr std::size_t kPlantBlock = kMortalityBatch;

// Bins of the pair search: a uniform grid of this edge over the area (crowns reaching
// beyond it go into the edge bins). Not a model constant: results do not depend on it.
constexpr double kCompetitionBinM = 1.0;

}  // namespace

// Plants that died in an earlier month (still in the store) are skipped; those dying now
// get their fate, and their slots are marked in slotDead. Returns the plants that grew.
std::size_t Simulation::Impl::updatePlants(int m) {
    const std::size_t n = pl.size();
    const float* tempPlane = abio.temperatureC[m].data().data();
    const SitePlanes site = sitePlanes();
    const std::size_t blocks = (n + kPlantBlock - 1) / kPlantBlock;
    std::int64_t cellsVisited = 0;  // an integer sum: the same for any thread count
    // Every array in a local: the stores into them (fate's bytes may alias anything) would
    // otherwise make the compiler reload each vector's pointer after every store.
    const BatchVigourShape vig = vigourShape();
    const SpeciesConst* species = spc.data();
    const std::uint32_t* slotOf = slotStart.data();
    const double *sunPart = partSun.data(), *waterPart = partWater.data();
    const std::int32_t* cellsPart = partCells.data();
    const std::int32_t* speciesOf = pl.species.data();
    const std::uint32_t* coarseOf = pl.coarse.data();
    const std::uint64_t* idOf = pl.id.data();
    const float* canopyLimitOf = pl.canopyLimit.data();
    float *sunOf = pl.sun.data(), *waterOf = pl.water.data(), *vigourOf = pl.vigour.data();
    double *poolOf = pl.pool.data(), *growthAgeOf = pl.growthAge.data(), *heightOf = pl.height.data();
    double* radiusOf = pl.radius.data();
    const RadiusRangeF* rangeOf = fpRange.data();
    PlantBounds* boundsOf = bounds.data();
    std::uint8_t* fateOf = fate.data();
    std::uint8_t* slotDeadOf = slotDead.data();
    const std::uint64_t month0 = static_cast<std::uint64_t>(month), seed0 = seed;
    std::int64_t died[3] = {};
    std::size_t grewCount = 0;
#pragma omp parallel for schedule(dynamic, 8) if (n > kParallelPlants) reduction(+ : cellsVisited, grewCount, died[:3])
    for (std::size_t blk = 0; blk < blocks; ++blk) {
        const std::size_t p0 = blk * kPlantBlock, p1 = std::min(n, p0 + kPlantBlock);
        double arg[kPlantBlock], ex[kPlantBlock];
        for (std::size_t p = p0; p < p1; ++p) {
            // The dead of earlier months (a few per cent, none in most months: see
            // compactIfDue) are skipped; their exponent is a placeholder.
            if (fateOf[p]) {
                arg[p - p0] = 0;
                continue;
            }
            // Every living plant has a slot in at least one band (its root's); most in one only.
            const std::uint32_t s0 = slotOf[p], s1 = slotOf[p + 1];
            double sunSum = 0.0 + sunPart[s0], waterSum = 0.0 + waterPart[s0];
            std::int64_t count = cellsPart[s0];
            for (std::uint32_t s = s0 + 1; s < s1; ++s) {
                sunSum += sunPart[s];
                waterSum += waterPart[s];
                count += cellsPart[s];
            }
            cellsVisited += count;
            // Always the division (1 / 1 is exact): a test for the many one-cell plants
            // would be a branch mispredicted about every other plant.
            const double inv = count > 0 ? 1.0 / static_cast<double>(count) : 0.0;
            const double sun = sunSum * inv, water = waterSum * inv;
            sunOf[p] = static_cast<float>(sun);
            waterOf[p] = static_cast<float>(water);
            arg[p - p0] = vig.exponent(species[speciesOf[p]].vigour,
                                       site.features(sun, water, tempPlane[coarseOf[p]], coarseOf[p]));
        }
        batchExp(arg, ex, p1 - p0);
        double draw[kPlantBlock];  // mortality uniforms (drawn for every plant, used unless it reached the canopy)
        mortalityUniforms(seed0, idOf + p0, month0, p1 - p0, draw);
        std::uint32_t grown[kPlantBlock];  // plants whose radius is exp(a + b ln h), computed after the loop
        double lnArg[kPlantBlock];
        std::size_t nGrown = 0;
        // A grown plant's new radius; its footprint is recomputed unless the radius stays
        // within the range of its last footprint (footprintRange).
        auto setGrownRadius = [radiusOf, rangeOf, boundsOf](std::size_t p, double r) {
            radiusOf[p] = r;
            if (!rangeOf[p].contains(r)) boundsOf[p].span = kNoSpan;
        };
        for (std::size_t p = p0; p < p1; ++p) {
            if (fateOf[p]) continue;
            const int s = speciesOf[p];
            const SpeciesConst& c = species[s];
            const double v = vig.fromExp(c.alpha, ex[p - p0]);
            vigourOf[p] = static_cast<float>(v);
            const PoolStep ps = updatePool(poolOf[p], v, c.capacity);
            poolOf[p] = ps.pool;
            if (c.growthMonth[m] && ps.overflow > 0) {
                ++grewCount;
                growthAgeOf[p] = advanceGrowthAgeYears(growthAgeOf[p], ps.overflow, true, c.growthPerOverflow);
                const double h = idealHeightM(growthAgeOf[p], c.maxAgeYears, c.maxHeightM);
                heightOf[p] = h;
                if (c.allometry.linear || !(h > 0)) {
                    setGrownRadius(p, crownRadius(s, h));
                } else {  // exp(a + b ln h) for the block at once, below
                    grown[nGrown] = static_cast<std::uint32_t>(p);
                    lnArg[nGrown] = h;
                    ++nGrown;
                }
            }
            std::uint8_t f = 0;
            if (heightOf[p] >= canopyLimitOf[p]) {
                f = 2;
            } else {
                const double mu = mortalityProbability(c.backgroundMu, poolOf[p]);
                if (draw[p - p0] < mu) f = 1;
            }
            if (f) {
                fateOf[p] = f;
                ++died[f];
                markSlotsDead(slotOf, slotDeadOf, p);
            }
        }
        // The grown plants' crown radii, crownRadius in blocks: log, a + b ln h, exp.
        batchLog(lnArg, lnArg, nGrown);
        for (std::size_t k = 0; k < nGrown; ++k) {
            const Allometry& al = species[speciesOf[grown[k]]].allometry;
            lnArg[k] = al.a + al.b * lnArg[k];
        }
        batchExp(lnArg, lnArg, nGrown);
        for (std::size_t k = 0; k < nGrown; ++k) setGrownRadius(grown[k], lnArg[k]);
    }
    counters.plantCellMonths += cellsVisited;
    counters.diedBackgroundOrStress += died[1];
    counters.diedAtCanopy += died[2];
    deadPending += static_cast<std::size_t>(died[1] + died[2]);
    return grewCount;
}

// Deussen et al. 1998 (docs/simulator.md): every pair of living undergrowth plants whose
// crown circles intersect is compared by competitive ability; the weaker is dominated.
// Decided from a snapshot of this month's state (after growth and mortality), with one
// draw per dominated plant keyed by (seed, plant id, month); no plant's fate depends on
// another's fate this month, so the order of evaluation is irrelevant.
void Simulation::Impl::compete() {
    const std::size_t n = pl.size();
    ability.resize(n);
    binX0.resize(n);
    binX1.resize(n);
    binY0.resize(n);
    binY1.resize(n);
    const double bin = kCompetitionBinM;
    const int nbx = std::max(1, static_cast<int>(std::ceil(W * cell / bin)));
    const int nby = std::max(1, static_cast<int>(std::ceil(H * cell / bin)));
    auto binOf = [](double v, int nb) {
        return static_cast<std::int32_t>(std::clamp(std::floor(v), 0.0, static_cast<double>(nb - 1)));
    };
#pragma omp parallel for schedule(static) if (n > kParallelPlants)
    for (std::size_t p = 0; p < n; ++p) {
        const SpeciesConst& c = spc[static_cast<std::size_t>(pl.species[p])];
        ability[p] = competitiveAbility(pl.vigour[p], pl.height[p], c.maxHeightM);
        const double r = pl.radius[p];
        binX0[p] = binOf((pl.x[p] - r - ox) / bin, nbx);
        binX1[p] = binOf((pl.x[p] + r - ox) / bin, nbx);
        binY0[p] = binOf((pl.y[p] - r - oy) / bin, nby);
        binY1[p] = binOf((pl.y[p] + r - oy) / bin, nby);
    }
    // Counting sort of (plant, bin) pairs into bins, in plant order. Plants that died this
    // month take no part.
    const std::size_t nbins = static_cast<std::size_t>(nbx) * static_cast<std::size_t>(nby);
    binStart.assign(nbins + 1, 0);
    for (std::size_t p = 0; p < n; ++p) {
        if (fate[p] != 0) continue;
        for (int by = binY0[p]; by <= binY1[p]; ++by)
            for (int bx = binX0[p]; bx <= binX1[p]; ++bx) ++binStart[static_cast<std::size_t>(by) * nbx + bx + 1];
    }
    for (std::size_t b = 0; b < nbins; ++b) binStart[b + 1] += binStart[b];
    binEntries.resize(binStart[nbins]);
    binFill.assign(binStart.begin(), binStart.end() - 1);
    for (std::size_t p = 0; p < n; ++p) {
        if (fate[p] != 0) continue;
        const BinEntry e{pl.x[p], pl.y[p], pl.radius[p], ability[p], binX0[p], binY0[p], static_cast<std::uint32_t>(p)};
        for (int by = binY0[p]; by <= binY1[p]; ++by)
            for (int bx = binX0[p]; bx <= binX1[p]; ++bx) binEntries[binFill[static_cast<std::size_t>(by) * nbx + bx]++] = e;
    }
    const double survivalPerYear = params.deussenDominatedSurvival;
    dominated.assign(n, 0);
#pragma omp parallel for schedule(dynamic, 2048) if (n > kParallelPlants)
    for (std::size_t p = 0; p < n; ++p) {
        if (fate[p] != 0) continue;
        int dominators = 0;
        const double ap = ability[p], xp = pl.x[p], yp = pl.y[p], rp = pl.radius[p];
        const std::int32_t bx0 = binX0[p], by0 = binY0[p];
        for (int by = by0; by <= binY1[p]; ++by)
            for (int bx = bx0; bx <= binX1[p]; ++bx) {
                const std::size_t b = static_cast<std::size_t>(by) * nbx + bx;
                for (std::uint32_t i = binStart[b]; i < binStart[b + 1]; ++i) {
                    const BinEntry& q = binEntries[i];
                    // Only stronger plants matter (p itself is not stronger than itself).
                    // Each pair once: in the first bin both plants share (lowest row and
                    // column of the overlap of their bin ranges).
                    if (!(q.ability > ap)) continue;
                    if (bx != std::max(bx0, q.binX0) || by != std::max(by0, q.binY0)) continue;
                    if (crownsIntersect(xp, yp, rp, q.x, q.y, q.radius)) ++dominators;
                }
            }
        if (dominators == 0) continue;
        const double survive = dominatedSurvivalPerMonth(survivalPerYear, dominators);
        if (dominationUniform(seed, pl.id[p], static_cast<std::uint64_t>(month)) >= survive) dominated[p] = 1;
    }
    for (std::size_t p = 0; p < n; ++p)
        if (dominated[p]) {
            fate[p] = 3;
            ++counters.diedDominated;
            ++deadPending;
            markSlotsDead(slotStart.data(), slotDead.data(), p);
        }
}

// Removes the dead (fate != 0) from the store, keeping the order of the living.
void Simulation::Impl::compact() {
    const std::size_t n = pl.size();
    if (deadPending == 0) return;
    deadPending = 0;
    layoutReusable = false;  // the plants move: their slots and entries are rebuilt
    // The survivors as runs of consecutive plants: every array is then compacted with one
    // memmove per run (few plants die in a month) instead of a test per plant and array.
    keptRuns.clear();
    std::size_t keep = 0, runStart = 0;
    for (std::size_t p = 0; p < n; ++p) {
        if (fate[p] == 0) continue;
        if (p > runStart) keptRuns.push_back(Run{static_cast<std::uint32_t>(runStart), static_cast<std::uint32_t>(p - runStart)});
        keep += p - runStart;
        runStart = p + 1;
    }
    if (n > runStart) keptRuns.push_back(Run{static_cast<std::uint32_t>(runStart), static_cast<std::uint32_t>(n - runStart)});
    keep += n - runStart;
    auto compactArray = [this, keep](auto& v) {
        using T = typename std::decay_t<decltype(v)>::value_type;
        std::size_t out = 0;
        for (const Run& r : keptRuns) {
            if (r.from != out) std::memmove(v.data() + out, v.data() + r.from, r.len * sizeof(T));
            out += r.len;
        }
        v.resize(keep);
    };
    // Arrays are compacted independently of each other: one task per array.
    const bool footprints = fpRange.size() == n;
    if (!footprints) fpRange.clear();
#pragma omp parallel if (n > kParallelSortFactor * kParallelPlants)
#pragma omp single
    {
        pl.forEachArray([&](auto& v) {
            auto* vp = &v;
#pragma omp task firstprivate(vp)
            compactArray(*vp);
        });
        if (footprints) {
#pragma omp task
            compactArray(fpRange);
#pragma omp task
            compactArray(bounds);
        }
    }
    fate.assign(keep, 0);
}

// The dead leave the store at once when they are many, or before anything outside the
// monthly step reads it (settleDead). Between, the passes skip them: a compaction moves
// every array of the plants behind the first dead one, so doing it every few months
// instead of every month saves most of that traffic. A layout the next month can reuse
// is kept until a quarter of the plants are dead.
void Simulation::Impl::compactIfDue() {
    const std::size_t n = pl.size();
    if (deadPending == n || deadPending * (layoutReusable ? 4 : kCompactShare) >= n) compact();
}

}  // namespace eco::sim
