// The resource sweep of one band of rows: occupancy count, per-cell resources, the paint
// of the plants in height order (paint.h kernels), and the month's leftovers into the
// germination deficit (docs/simulator.md, "Parallel sweep without races").
#include "simulator_impl.h"

namespace eco::sim {

namespace {

#ifdef ECO_HAVE_AVX2_KERNELS
// PSHUFB controls that pack the 32-bit lanes set in a 4-bit mask to the front (zeros after).
struct PackLanes {
    alignas(16) std::uint8_t control[16][16];
    constexpr PackLanes() : control() {
        for (int m = 0; m < 16; ++m) {
            int out = 0;
            for (int lane = 0; lane < 4; ++lane)
                if (m >> lane & 1) {
                    for (int b = 0; b < 4; ++b) control[m][out * 4 + b] = static_cast<std::uint8_t>(lane * 4 + b);
                    ++out;
                }
            for (; out < 4; ++out)
                for (int b = 0; b < 4; ++b) control[m][out * 4 + b] = 0x80;
        }
    }
};
constexpr PackLanes kPackLanes{};
#endif

// The prepare pass's view of one row of a band: its cells are the band-relative cells
// [i0, i0 + W), and the row's inputs are indexed by the cell's column j = i - i0.
struct PrepareRow {
    std::size_t i0;
    const float* trans;          // canopy transmission
    const std::uint8_t* trees;   // canopy trees
    const float* sun;            // the month's sun and moisture of each column (the row's
    const float* moist;          // abiotics row, expanded by sweepBand)
};
// The prepare pass's outputs (band scratch, band-relative) and its running state: the
// occupants n of the last cell done and the occupied cells listed so far.
struct PrepareOut {
    std::int32_t* diff;  // read, and left zero
    std::uint32_t* list;
    double *base, *avail, *rest;
    float* transmission;    // set to 1 (the paint's running product)
    std::int32_t* painted;  // set to 0
    std::int32_t n;
    std::size_t nOcc;
};

#ifdef ECO_HAVE_AVX2_KERNELS
// Cells [i, end) of a row of the prepare pass four at a time (AVX2, chosen at run time):
// the operations of its SSE2 loop, lane by lane (the same bits: every conversion to
// double is exact). Returns the first cell not done (fewer than 4 before end).
ECO_TARGET_AVX2 std::size_t prepareAvx2(std::size_t i, std::size_t end, const PrepareRow& r, double demand,
                                        PrepareOut& o) {
    const __m256d dem = _mm256_set1_pd(demand), zero = _mm256_setzero_pd(), one = _mm256_set1_pd(1.0);
    const __m128i step = _mm_setr_epi32(0, 1, 2, 3);
    // Pointers in locals: the stores through them could otherwise alias o.
    std::int32_t* diff = o.diff;
    std::uint32_t* list = o.list;
    double *base = o.base, *availOut = o.avail, *rest = o.rest;
    float* transmission = o.transmission;
    std::int32_t* painted = o.painted;
    __m128i n = _mm_set1_epi32(o.n);  // the last cell's occupants, in every lane
    std::size_t nOcc = o.nOcc;
    for (; i + 4 <= end; i += 4) {
        const std::size_t j = i - r.i0;
        // Occupants of the four cells: the running count plus the prefix sums of diff.
        __m128i d = _mm_loadu_si128(reinterpret_cast<const __m128i*>(diff + i));
        _mm_storeu_si128(reinterpret_cast<__m128i*>(diff + i), _mm_setzero_si128());
        _mm_storeu_ps(transmission + i, _mm_set1_ps(1.f));
        _mm_storeu_si128(reinterpret_cast<__m128i*>(painted + i), _mm_setzero_si128());
        d = _mm_add_epi32(d, _mm_slli_si128(d, 4));
        d = _mm_add_epi32(d, _mm_slli_si128(d, 8));
        const __m128i counts = _mm_add_epi32(n, d);
        n = _mm_shuffle_epi32(counts, 0xFF);
        // The occupied ones appended to the list: their indices packed to the front (the
        // list has room for 3 more entries past its end).
        const int occupied = ~_mm_movemask_ps(_mm_castsi128_ps(_mm_cmpeq_epi32(counts, _mm_setzero_si128()))) & 15;
        const __m128i idx = _mm_add_epi32(_mm_set1_epi32(static_cast<std::int32_t>(i)), step);
        _mm_storeu_si128(reinterpret_cast<__m128i*>(list + nOcc),
                         _mm_shuffle_epi8(idx, _mm_load_si128(reinterpret_cast<const __m128i*>(kPackLanes.control[occupied]))));
        nOcc += static_cast<std::size_t>(__builtin_popcount(static_cast<unsigned>(occupied)));
        std::int32_t treeBytes;
        std::memcpy(&treeBytes, r.trees + j, sizeof treeBytes);
        const __m256d trees = _mm256_cvtepi32_pd(_mm_cvtepu8_epi32(_mm_cvtsi32_si128(treeBytes)));
        const __m256d moist = _mm256_cvtps_pd(_mm_loadu_ps(r.moist + j));
        const __m256d avail = _mm256_max_pd(_mm256_sub_pd(moist, _mm256_mul_pd(trees, dem)), zero);
        const __m256d occ = _mm256_cvtepi32_pd(counts);
        const __m256d trans = _mm256_cvtps_pd(_mm_loadu_ps(r.trans + j));
        const __m256d sun = _mm256_cvtps_pd(_mm_loadu_ps(r.sun + j));
        _mm256_storeu_pd(base + i, _mm256_mul_pd(trans, sun));
        _mm256_storeu_pd(availOut + i, avail);
        const __m256d spare = _mm256_max_pd(_mm256_sub_pd(avail, _mm256_mul_pd(occ, dem)), zero);
        _mm256_storeu_pd(rest + i, _mm256_movemask_pd(_mm256_cmp_pd(spare, zero, _CMP_GT_OQ))
                                       ? _mm256_div_pd(spare, _mm256_add_pd(occ, one))
                                       : zero);
    }
    o.n = _mm_cvtsi128_si32(n);
    o.nOcc = nOcc;
    return i;
}
#endif

// Cells [i, end) of a row of the prepare pass: the prefix sum of the difference array
// gives the cell's occupants n; an occupied cell goes on the list of occupied cells
// (branch-free) and gets its shaded sun, its water after the canopy and the seeding
// share, once per cell instead of once per occupant (an empty cell's values are computed
// too, and never read).
void prepareRow(std::size_t i, std::size_t end, const PrepareRow& r, double demand, PrepareOut& o) {
#ifdef ECO_HAVE_AVX2_KERNELS
    if (avx2Kernels()) i = prepareAvx2(i, end, r, demand, o);
#endif
    std::int32_t n = o.n;
    std::size_t nOcc = o.nOcc;
    std::uint32_t* list = o.list;
#ifdef __SSE2__
    // Two cells at a time: the operations of the scalar loop below, lane by lane (the
    // same bits; MAXPD has maxZero's operand order, and n + 1 is exact in either form).
    const __m128d dem = _mm_set1_pd(demand), zero = _mm_setzero_pd(), one = _mm_set1_pd(1.0);
    for (; i + 2 <= end; i += 2) {
        const std::size_t j = i - r.i0;
        const std::int32_t n0 = n + o.diff[i], n1 = n0 + o.diff[i + 1];
        n = n1;
        o.diff[i] = o.diff[i + 1] = 0;
        o.transmission[i] = o.transmission[i + 1] = 1.f;
        o.painted[i] = o.painted[i + 1] = 0;
        list[nOcc] = static_cast<std::uint32_t>(i);
        nOcc += n0 != 0;
        list[nOcc] = static_cast<std::uint32_t>(i + 1);
        nOcc += n1 != 0;
        const __m128d trees = _mm_set_pd(r.trees[j + 1], r.trees[j]);
        const __m128d avail = _mm_max_pd(_mm_sub_pd(_mm_set_pd(r.moist[j + 1], r.moist[j]), _mm_mul_pd(trees, dem)), zero);
        const __m128d occ = _mm_set_pd(n1, n0);
        _mm_storeu_pd(o.base + i, _mm_mul_pd(_mm_set_pd(r.trans[j + 1], r.trans[j]), _mm_set_pd(r.sun[j + 1], r.sun[j])));
        _mm_storeu_pd(o.avail + i, avail);
        // The division only when a lane has water beyond the demands (0 / (n + 1) is 0).
        const __m128d spare = _mm_max_pd(_mm_sub_pd(avail, _mm_mul_pd(occ, dem)), zero);
        _mm_storeu_pd(o.rest + i, _mm_movemask_pd(_mm_cmpgt_pd(spare, zero)) ? _mm_div_pd(spare, _mm_add_pd(occ, one)) : zero);
    }
#endif
    for (; i < end; ++i) {
        const std::size_t j = i - r.i0;
        n += o.diff[i];
        o.diff[i] = 0;
        o.transmission[i] = 1.f;
        o.painted[i] = 0;
        list[nOcc] = static_cast<std::uint32_t>(i);
        nOcc += n != 0;
        const double avail = waterAfterCanopyMm(r.moist[j], r.trees[j], demand);
        o.base[i] = static_cast<double>(r.trans[j]) * r.sun[j];
        o.avail[i] = avail;
        o.rest[i] = waterLeftoverMm(avail, n, demand);
    }
    o.n = n;
    o.nOcc = nOcc;
}

}  // namespace

// The occupancy count of band b as a difference array (scr.diff, band-relative, kept zero
// between bands): each row span adds 1 at its first cell and -1 after its last, two
// writes whatever its length and no loop over its cells. A prefix sum over the band then
// gives every cell's occupants (the sweep's prepare pass, countOccupancy), and leaves
// scr.diff zero again. Exact: integer sums. The entries are read as the scatter left them,
// in plant order (the order does not matter to integer sums), so their footprint spans
// are read in address order. Returns the band's first cell and cell count.
std::pair<std::size_t, std::size_t> Simulation::Impl::scatterBand(int b, BandScratch& scr) const {
    const int r0 = b * kBandRows, r1 = std::min(H, r0 + kBandRows);
    const std::size_t c0 = static_cast<std::size_t>(r0) * W, nc = static_cast<std::size_t>(r1 - r0) * W;
    scr.resize(nc);
    std::int32_t* diff = scr.diff.data() - c0;  // indexed by cell
    const Span* fp = footprint.data();
    const BandEntry *e = bandEntries.data() + bandStart[b], *z = bandEntries.data() + bandEnd[b];
    for (; e != z; ++e) {
        // The footprint rows beyond the first are read from the span pool, where the band's
        // plants are spread among the others: fetched kScatterPrefetch entries ahead.
        if (z - e > kScatterPrefetch) __builtin_prefetch(fp + e[kScatterPrefetch].span + 1);
        e->forEachRow(fp, [diff](std::size_t start, std::uint32_t len) {
            ++diff[start];
            --diff[start + len];
        });
    }
    scr.diff[nc] = 0;  // the -1 after the band's last cell
    return {c0, nc};
}

// The paint pass of a band (sweepBand): its entries in height order (`order`), each taking
// its shares of its cells with the kernel Lanes (paint.h). Inlined into one function per
// kernel, so that the AVX2 one is compiled for AVX2 throughout.
template <typename Lanes>
__attribute__((always_inline)) inline void Simulation::Impl::paintEntries(const BandEntry* e0, std::size_t ne, const std::uint64_t* order,
                                                        std::size_t c0, const BandCells& bc, double demand, bool unshared) {
    const Span* fp = footprint.data();
    const float* keepOf = speciesKeep.data();
    double* sunOut = partSun.data();
    double* waterOut = partWater.data();
    std::int32_t* cellsOut = partCells.data();
    for (std::size_t k = 0; k < ne; ++k) {
        // The entries are in plant order and visited in height order: on a wide grid a
        // band's list outgrows the caches, so the entry kPaintPrefetch places ahead is
        // fetched early.
        if (k + kPaintPrefetch < ne) __builtin_prefetch(e0 + static_cast<std::uint32_t>(order[k + kPaintPrefetch]));
        const BandEntry* e = e0 + static_cast<std::uint32_t>(order[k]);
        const float keep = keepOf[e->species()];
        const std::size_t first = e->start - c0;
        const std::uint32_t len = e->len(), rows = e->rows();
        double sunSum, waterSum;
        std::int32_t count = static_cast<std::int32_t>(len);
        if (unshared) {
            sunSum = 0;
            waterSum = 0;
            count = 0;
            e->forEachRow(fp, [&](std::size_t start, std::uint32_t n) {
                for (std::size_t i = start - c0, z = i + n; i < z; ++i) {
                    sunSum += bc.base[i];
                    waterSum += bc.avail[i];
                    bc.transmission[i] *= keep;
                    ++bc.painted[i];
                }
                count += static_cast<std::int32_t>(n);
            });
        } else if (rows == 1 && len == 1) {
            // One cell (most plants): lane 0 alone, and (x + 0) + (0 + 0) = x for x >= 0.
            sunSum = bc.base[first] * static_cast<double>(bc.transmission[first]);
            waterSum = waterDemandShareMm(bc.avail[first], bc.painted[first], demand) + bc.rest[first];
            bc.transmission[first] *= keep;
            ++bc.painted[first];
        } else {
            Lanes lanes;
            lanes.span(bc, first, len, keep, demand);
            for (const Span *sp = fp + e->span + 1, *se = fp + e->span + rows; sp < se; ++sp) {
                lanes.span(bc, sp->start - c0, sp->len, keep, demand);
                count += static_cast<std::int32_t>(sp->len);
            }
            sunSum = lanes.sunTotal();
            waterSum = lanes.waterTotal();
        }
        sunOut[e->slot] = sunSum;
        waterOut[e->slot] = waterSum;
        cellsOut[e->slot] = count;
    }
}

void Simulation::Impl::paintDefault(const BandEntry* e0, std::size_t ne, const std::uint64_t* order, std::size_t c0,
                                    const BandCells& bc, double demand, bool unshared) {
    paintEntries<PaintLanes>(e0, ne, order, c0, bc, demand, unshared);
}

#ifdef ECO_HAVE_AVX2_KERNELS
ECO_TARGET_AVX2 void Simulation::Impl::paintAvx2(const BandEntry* e0, std::size_t ne, const std::uint64_t* order,
                                                 std::size_t c0, const BandCells& bc, double demand, bool unshared) {
    paintEntries<PaintLanesAvx2>(e0, ne, order, c0, bc, demand, unshared);
}
#endif

// One band: count, prepare, paint, finish. The band's rows belong to this call only.
//  * count: the band's difference array of occupants (scatterBand);
//  * prepare: every cell's occupants, resources and seeding share, and the occupied cells;
//  * paint: the entries in height order, each taking its shares of the cells it covers;
//  * finish: the occupied cells in address order: the leftovers of this month go to the
//    germination deficit (growth-period months).
//  When the layout is reused (`reuse`), the entries of plants that died since it was built
//  are dropped first (filterBand).
void Simulation::Impl::sweepBand(int b, int m, bool reuse) {
    const int r0 = b * kBandRows, r1 = std::min(H, r0 + kBandRows);
    const std::size_t c0 = static_cast<std::size_t>(r0) * W;
    BandScratch& scr = bandScratch[static_cast<std::size_t>(omp_get_thread_num())];
    if (reuse) filterBand(b, scr.remap);
    const BandEntry* e0 = bandEntries.data() + bandStart[b];
    const BandEntry* e1 = bandEntries.data() + bandEnd[b];
    const float* sunPlane = abio.sunHours[m].data().data();
    const float* moistPlane = abio.moistureMm[m].data().data();
    const double demand = params.minWaterDemandMm;
    scatterBand(b, scr);
    // Prepare, row by row over the band's cells in address order (prepareRow). The month's
    // sun and moisture of a row's columns are read once per abiotics row (several rows of
    // cells share one), instead of once per cell from the abiotics grid.
    const BandCells bc = scr.cells();
    PrepareOut po{scr.diff.data(), scr.occupied.data(), scr.base.data(), scr.avail.data(), scr.rest.data(),
                  bc.transmission, bc.painted, 0, 0};
    scr.sunRow.resize(static_cast<std::size_t>(W));
    scr.moistRow.resize(static_cast<std::size_t>(W));
    std::size_t expanded = SIZE_MAX;
    for (int iy = r0; iy < r1; ++iy) {
        if (coarseRowOffset[iy] != expanded) {
            expanded = coarseRowOffset[iy];
            const float *sun = sunPlane + expanded, *moist = moistPlane + expanded;
            for (int ix = 0; ix < W; ++ix) {
                scr.sunRow[ix] = sun[coarseCol[ix]];
                scr.moistRow[ix] = moist[coarseCol[ix]];
            }
        }
        const std::size_t i0 = static_cast<std::size_t>(iy - r0) * W;
        const PrepareRow row{i0, canopyTrans.data().data() + c0 + i0, canopyTrees.data() + c0 + i0, scr.sunRow.data(),
                             scr.moistRow.data()};
        prepareRow(i0, i0 + W, row, demand, po);
    }
    const std::size_t nOcc = po.nOcc;
    const std::uint32_t* occList = po.list;
    // Paint: every entry in height order takes its shares of its cells (paint.h). Deussen
    // mode: plants see the unshared (canopy-shaded, after canopy water) resources; the
    // leftovers for germination are the same as in the resources mode.
    const bool unshared = params.competition == CompetitionMode::Deussen;
    const std::uint64_t* order = bandOrder.data() + bandStart[b];
    const std::size_t ne = static_cast<std::size_t>(e1 - e0);
#ifdef ECO_HAVE_AVX2_KERNELS
    if (avx2Kernels()) paintAvx2(e0, ne, order, c0, bc, demand, unshared);
    else paintDefault(e0, ne, order, c0, bc, demand, unshared);
#else
    paintDefault(e0, ne, order, c0, bc, demand, unshared);
#endif
    finishBand(c0, m, bc, occList, nOcc);
}

// The finish pass of a band (sweepBand): the occupied cells (occList, band-relative, nOcc of
// them) in address order; this month's leftovers go to the germination deficit of the
// month's growth periods.
void Simulation::Impl::finishBand(std::size_t c0, int m, const BandCells& bc, const std::uint32_t* occList,
                                  std::size_t nOcc) {
    const std::vector<int>& periods = periodsOfMonth[m];
    if (periods.empty()) return;
    if (!monthDeficit.empty()) {  // germination_vigour = "mean_vigour": this month's own slot
        for (std::size_t k = 0; k < nOcc; ++k) {
            const std::size_t i = occList[k];
            const double sunLeft = bc.base[i] * bc.transmission[i];
            float* d = monthDeficitAt(c0 + i, m);
            d[0] += static_cast<float>(bc.base[i] - sunLeft);
            d[1] += static_cast<float>(bc.avail[i] - bc.rest[i]);
        }
    }
    // The month's periods are usually consecutive (all of them, in the default biome):
    // then a cell's deficits of these periods are one run of floats, updated by one
    // vector add (each float gets the same single addition as below).
    const int g0 = periods.front(), np = static_cast<int>(periods.size());
    const bool run = periods.back() - g0 + 1 == np;
    float* deficitRun = deficitAt(c0, static_cast<std::size_t>(g0));
    const std::size_t stride = this->periods() * 2;
    auto used = [&bc](std::size_t i, float& usedSun, float& usedWater) {
        const double sunLeft = bc.base[i] * bc.transmission[i];
        usedSun = static_cast<float>(bc.base[i] - sunLeft);
        usedWater = static_cast<float>(bc.avail[i] - bc.rest[i]);
    };
#ifdef __SSE2__
    if (run && np <= 2) {
        for (std::size_t k = 0; k < nOcc; ++k) {
            const std::size_t i = occList[k];
            if (k + kFinishPrefetch < nOcc) __builtin_prefetch(deficitRun + occList[k + kFinishPrefetch] * stride, 1);
            float usedSun, usedWater;
            used(i, usedSun, usedWater);
            float* d = deficitRun + i * stride;
            const __m128 add = _mm_setr_ps(usedSun, usedWater, usedSun, usedWater);
            if (np == 2) {
                _mm_storeu_ps(d, _mm_add_ps(_mm_loadu_ps(d), add));
            } else {
                const __m128d pair = _mm_load_sd(reinterpret_cast<const double*>(d));
                _mm_store_sd(reinterpret_cast<double*>(d), _mm_castps_pd(_mm_add_ps(_mm_castpd_ps(pair), add)));
            }
        }
        return;
    }
#endif
    for (std::size_t k = 0; k < nOcc; ++k) {
        const std::size_t i = occList[k];
        float usedSun, usedWater;
        used(i, usedSun, usedWater);
        for (int g : periods) {
            float* d = deficitAt(c0 + i, static_cast<std::size_t>(g));
            d[0] += usedSun;
            d[1] += usedWater;
        }
    }
}

}  // namespace eco::sim
