// Yearly germination: free seeded cells draw whether they germinate, a species by roulette on
// the vigour of the season's leftover resources, and a position; seedlings in cell order.
#include "simulator_impl.h"

namespace eco::sim {

namespace {

struct Candidate {
    int ix, iy, species;
    double x, y;
};

}  // namespace

// Mean leftover sun, water and temperature of cell c over the months in the window of
// each growth period g in `wanted` (bit g): into sun[g], water[g], temp[g], with ok[g]
// false when the window holds none of g's months. One pass over the months: each month's
// abiotics are read once and added to every wanted period containing it, each period's
// sums in month order (the same sums as a pass per period).
void Simulation::Impl::seasonMeans(std::size_t c, int ix, int iy, std::uint32_t wanted, double* sun, double* water, double* temp, bool* ok) const {
    const std::size_t cc = coarseRowOffset[iy] + static_cast<std::size_t>(coarseCol[ix]);
    const double transmission = canopyTrans.data()[c];
    const int trees = canopyTrees[c];
    double sunBase[kMaxGrowthPeriods], waterBase[kMaxGrowthPeriods], tempSum[kMaxGrowthPeriods];
    int count[kMaxGrowthPeriods];
    std::uint32_t months = 0;
    for (std::uint32_t rest = wanted; rest; rest &= rest - 1) {
        const int g = __builtin_ctz(rest);
        sunBase[g] = waterBase[g] = tempSum[g] = 0;
        count[g] = 0;
        months |= windowMask & periodMonthMask[static_cast<std::size_t>(g)];
    }
    for (; months; months &= months - 1) {
        const int m = __builtin_ctz(months);
        const double s = transmission * abio.sunHours[m].data()[cc];
        const double w = waterAfterCanopyMm(abio.moistureMm[m].data()[cc], trees, params.minWaterDemandMm);
        const double t = abio.temperatureC[m].data()[cc];
        for (std::uint32_t rest = wanted; rest; rest &= rest - 1) {
            const int g = __builtin_ctz(rest);
            if (!(periodMonthMask[static_cast<std::size_t>(g)] & (1u << m))) continue;
            sunBase[g] += s;
            waterBase[g] += w;
            tempSum[g] += t;
            ++count[g];
        }
    }
    for (std::uint32_t rest = wanted; rest; rest &= rest - 1) {
        const int g = __builtin_ctz(rest);
        ok[g] = count[g] > 0;
        if (!ok[g]) continue;
        const float* d = deficitAt(c, static_cast<std::size_t>(g));
        sun[g] = std::max(0.0, sunBase[g] - d[0]) / count[g];
        water[g] = std::max(0.0, waterBase[g] - d[1]) / count[g];
        temp[g] = tempSum[g] / count[g];
    }
}

// Germination weights of every species at cell (ix, iy) into w; `arg` and `cand` are
// scratch of the same size. The candidates (species of the cell's seed packages whose
// growth period has months in the window) are listed first, and only their vigour
// exponents computed, their exps taken in one batch (batchExp gives every element the same
// bits wherever it stands), and their weights set; the others are 0, as rouletteSelect
// expects (adding 0 changes none of its sums).
void Simulation::Impl::weightsAt(int ix, int iy, double* w, double* arg, int* cand) const {
    const std::size_t c = static_cast<std::size_t>(iy) * W + ix;
    const std::uint32_t pkg = seedPkg[c];
    const std::size_t cc = coarseRowOffset[iy] + static_cast<std::size_t>(coarseCol[ix]);
    const SitePlanes site = sitePlanes();
    const int periods = static_cast<int>(periodMonthMask.size());
    const std::size_t ns = spc.size();
    // The growth periods of the candidate species, whose means are computed once.
    std::uint32_t wanted = 0;
    std::size_t nc = 0;
    for (std::size_t s = 0; s < ns; ++s) {
        w[s] = 0;
        if ((spc[s].memberMask & pkg) && spc[s].period < periods) {
            wanted |= 1u << spc[s].period;
            cand[nc++] = static_cast<int>(s);
        }
    }
    const BatchVigourShape vig = vigourShape();
    if (!monthDeficit.empty()) {  // germination_vigour = "mean_vigour"
        monthlyMeanWeights(c, cc, cand, nc, w);
        return;
    }
    double sunG[kMaxGrowthPeriods], waterG[kMaxGrowthPeriods], tempG[kMaxGrowthPeriods];
    bool okG[kMaxGrowthPeriods];
    seasonMeans(c, ix, iy, wanted, sunG, waterG, tempG, okG);
    std::size_t na = 0;
    for (std::size_t k = 0; k < nc; ++k) {
        const int s = cand[k];
        const SpeciesConst& sc = spc[static_cast<std::size_t>(s)];
        const int g = sc.period;
        if (!okG[g]) continue;
        cand[na] = s;
        arg[na] = vig.exponent(sc.vigour, site.features(sunG[g], waterG[g], tempG[g], cc));
        ++na;
    }
    batchExp(arg, arg, na);
    for (std::size_t k = 0; k < na; ++k) {  // rouletteWeight, with maxAge^beta precomputed
        const SpeciesConst& sc = spc[static_cast<std::size_t>(cand[k])];
        const double vbar = vig.fromExp(sc.alpha, arg[k]);
        w[cand[k]] = std::max(0.0, vbar / sc.rouletteDenominator);
    }
}

// germination_vigour = "mean_vigour": the weight of each of the nc candidates (cand) of cell c
// (abiotic cell cc) is max(0, vbar / maxAge^beta) with vbar the mean, over the window's months
// of the species' growth period, of Eq. 1 on that month's leftover sun and water and its
// temperature; a species with no such month keeps weight 0.
void Simulation::Impl::monthlyMeanWeights(std::size_t c, std::size_t cc, const int* cand, std::size_t nc, double* w) const {
    const double transmission = canopyTrans.data()[c];
    const int trees = canopyTrees[c];
    const SitePlanes site = sitePlanes();
    const BatchVigourShape vig = vigourShape();
    double arg[12];
    for (std::size_t k = 0; k < nc; ++k) {
        const SpeciesConst& sc = spc[static_cast<std::size_t>(cand[k])];
        std::size_t n = 0;
        for (std::uint32_t months = windowMask & periodMonthMask[static_cast<std::size_t>(sc.period)]; months;
             months &= months - 1) {
            const int m = __builtin_ctz(months);
            const float* d = monthDeficitAt(c, m);
            const double sun = std::max(0.0, transmission * abio.sunHours[m].data()[cc] - d[0]);
            const double water =
                std::max(0.0, waterAfterCanopyMm(abio.moistureMm[m].data()[cc], trees, params.minWaterDemandMm) - d[1]);
            arg[n++] = vig.exponent(sc.vigour, site.features(sun, water, abio.temperatureC[m].data()[cc], cc));
        }
        if (n == 0) continue;
        batchExp(arg, arg, n);
        double sum = 0;
        for (std::size_t i = 0; i < n; ++i) sum += vig.fromExp(sc.alpha, arg[i]);
        w[cand[k]] = std::max(0.0, sum / static_cast<double>(n) / sc.rouletteDenominator);
    }
}

// Occupancy count of the current plants into occupants[] (band-parallel), saturating.
void Simulation::Impl::countOccupancy() {
    buildBands(false);
    bandScratch.resize(static_cast<std::size_t>(omp_get_max_threads()));
#pragma omp parallel for schedule(dynamic, 1) if (bandEntries.size() > kParallelPlants)
    for (int b = 0; b < bands(); ++b) {
        BandScratch& scr = bandScratch[static_cast<std::size_t>(omp_get_thread_num())];
        const auto [c0, nc] = scatterBand(b, scr);
        std::int32_t n = 0;
        for (std::size_t i = 0; i < nc; ++i) {
            n += scr.diff[i];
            scr.diff[i] = 0;
            occupants[c0 + i] = static_cast<std::uint16_t>(std::min<std::int32_t>(n, 0xFFFF));
        }
    }
}

void Simulation::Impl::germinate(std::uint64_t year) {
    // Our reading tests only the cells no undergrowth crown covers; the paper's wording,
    // every seeded cell ([model] germination_cells).
    const bool uncoveredOnly = params.germinationCells == GerminationCells::Uncovered;
    countOccupancy();  // also when every cell draws: it builds the band layout the rest relies on
    const std::size_t ns = spc.size();
    std::vector<std::vector<Candidate>> perBand(static_cast<std::size_t>(bands()));
#pragma omp parallel if (cellCount() > kParallelCells)
    {
        std::vector<double> w(ns), arg(ns);
        std::vector<int> cand(ns);
        // A row's free seeded cells, their streams and the first two words of their draws.
        std::vector<int> rowCells(static_cast<std::size_t>(W));
        std::vector<std::uint64_t> rowStreams(static_cast<std::size_t>(W));
        std::vector<std::uint32_t> word0(static_cast<std::size_t>(W)), word1(static_cast<std::size_t>(W));
#pragma omp for schedule(dynamic, 1)
        for (int b = 0; b < bands(); ++b) {
            const int r0 = b * kBandRows, r1 = std::min(H, r0 + kBandRows);
            for (int iy = r0; iy < r1; ++iy) {
                const std::size_t rowStart = static_cast<std::size_t>(iy) * W;
                std::size_t free = 0;
                for (int ix = 0; ix < W; ++ix) {
                    const std::size_t c = rowStart + static_cast<std::size_t>(ix);
                    if (!(seedProb.data()[c] > 0) || (uncoveredOnly && occupants[c] > 0) || seedPkg[c] == 0) continue;
                    rowCells[free] = ix;
                    rowStreams[free] = mixStream(c, kGerminationStreamTag);
                    ++free;
                }
                // Word 0 decides whether the cell germinates (most do not): drawn for the
                // row at once (randomBitsBatch: the same bits as randomBits), the other
                // words only for the cells that germinate.
                randomBitsBatch(seed, rowStreams.data(), year, free, word0.data(), word1.data());
                // The germinating cells, whose state (read at random, mostly from memory)
                // is fetched for all of them before the first is evaluated.
                std::size_t sprouting = 0;
                for (std::size_t k = 0; k < free; ++k) {
                    const std::size_t c = rowStart + static_cast<std::size_t>(rowCells[k]);
                    if (word0[k] * 0x1.0p-32 >= seedProb.data()[c]) continue;
                    __builtin_prefetch(&canopyTrans.data()[c]);
                    __builtin_prefetch(&canopyTrees[c]);
                    __builtin_prefetch(deficitAt(c, 0));
                    rowCells[sprouting] = rowCells[k];
                    rowStreams[sprouting] = rowStreams[k];
                    ++sprouting;
                }
                for (std::size_t k = 0; k < sprouting; ++k) {
                    const int ix = rowCells[k];
                    const auto bits = randomBits(seed, rowStreams[k], year);
                    weightsAt(ix, iy, w.data(), arg.data(), cand.data());
                    const int s = rouletteSelect(w.data(), static_cast<int>(ns), bits[1] * 0x1.0p-32);
                    if (s < 0) continue;
                    perBand[static_cast<std::size_t>(b)].push_back(
                        {ix, iy, s, ox + (ix + bits[2] * 0x1.0p-32) * cell, oy + (iy + bits[3] * 0x1.0p-32) * cell});
                }
            }
        }
    }
    // In cell order: a seedling occupies its cells at once, so a later candidate whose
    // cell an earlier seedling of this year already covers does not germinate. The
    // decisions are serial (and cheap); the new plants are then written in parallel, with
    // ids in cell order.
    const double ga = params.seedlingGrowthAgeMonths / 12.0;
    std::vector<double> seedlingRadius(ns);
    for (std::size_t s = 0; s < ns; ++s)
        seedlingRadius[s] = crownRadius(static_cast<int>(s), idealHeightM(ga, spc[s].maxAgeYears, spc[s].maxHeightM));
    std::vector<const Candidate*> accepted;
    for (const auto& list : perBand)
        for (const Candidate& cd : list) {
            if (!uncoveredOnly) {  // every cell draws once: no cover blocks a seedling
                accepted.push_back(&cd);
                continue;
            }
            const std::size_t c = static_cast<std::size_t>(cd.iy) * W + cd.ix;
            if (occupants[c] > 0) continue;
            accepted.push_back(&cd);
            const double r = seedlingRadius[static_cast<std::size_t>(cd.species)];
            int lo, hi;
            rowRange(cd.y, r, cd.iy, lo, hi);
            forEachSpan(cd.x, cd.y, r, cd.ix, cd.iy, lo, hi + 1, [&](int iy, int a, int z) {
                std::uint16_t* row = &occupants[static_cast<std::size_t>(iy) * W];
                for (int ix = a; ix <= z; ++ix)
                    if (row[ix] < 65535) ++row[ix];
            });
        }
    const std::size_t first = pl.size(), k = accepted.size();
    pl.resize(first + k);
    fate.resize(first + k, 0);
    if (fpRange.size() == first) {
        fpRange.resize(first + k, kNoFootprint);
        bounds.resize(first + k, kNoBounds);
    } else {
        fpRange.clear();
    }
#pragma omp parallel for schedule(dynamic, 4096) if (k > kParallelPlants)
    for (std::size_t i = 0; i < k; ++i) {
        const Candidate& cd = *accepted[i];
        // Age 0 once this month is done (germination ends the month's step).
        setPlant(first + i, nextId + i, cd.species, cd.x, cd.y, cd.ix, cd.iy, ga, 0.0, month + 1, 0.0, 0.0);
    }
    nextId += k;
    counters.germinated += static_cast<std::int64_t>(k);
    // A new season of leftovers starts. (The occupancy needs no clearing: countOccupancy
    // writes every cell.)
    const std::size_t perChunk = 65536 * periods() * 2, chunks = (deficit.size() + perChunk - 1) / perChunk;
#pragma omp parallel for schedule(dynamic, 1) if (cellCount() > kParallelCells)
    for (std::size_t k = 0; k < chunks; ++k)
        std::fill(deficit.data() + k * perChunk, deficit.data() + std::min(deficit.size(), (k + 1) * perChunk), 0.f);
    std::fill(monthDeficit.begin(), monthDeficit.end(), 0.f);
    windowMask = 0;
}

}  // namespace eco::sim
