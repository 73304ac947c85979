// The month's layout: every plant's footprint rows and spans, its partial-sum slots, the band
// lists of the plants overlapping each band of rows, and each band's paint order (tallest
// first) by an LSD radix sort; a reused layout drops the entries of the dead (filterBand).
#include "simulator_impl.h"

namespace eco::sim {

namespace {

// Chunks of the parallel counting scatters: sized from the plant count, never from the
// thread count, and a scatter is stable whatever the chunking, so results do not depend
// on it. Plants per chunk: n / 16 within [4096, 32768], so that a hectare's 10 000 - 70 000
// plants make enough chunks for the threads to share evenly, and a km2's millions not
// too many per-chunk histograms (chunks x bands counters).
std::size_t scatterChunk(std::size_t n) { return std::clamp<std::size_t>(n / 16, 4096, 32768); }

// Sort key of a plant: descending height as an unsigned integer (heights are >= 0, so
// the bits of the float order like the values).
std::uint32_t heightKeyOf(double height) {
    const float h = static_cast<float>(height);
    std::uint32_t bits;
    std::memcpy(&bits, &h, sizeof bits);
    return ~bits;
}

// LSD radix passes over the records' keys (bits 32-63) in digits of Bits bits, from in
// to out and back; a pass in which every key has the same digit is skipped. The counts
// of every digit are taken in one read of the records, before the first pass. Returns
// the array holding the sorted records.
template <int Bits>
std::uint64_t* radixPasses(std::uint64_t* in, std::uint64_t* out, std::size_t n) {
    constexpr std::uint64_t mask = (std::uint64_t{1} << Bits) - 1;
    constexpr int passes = (32 + Bits - 1) / Bits;
    std::uint32_t count[passes][mask + 1] = {};
    for (std::size_t i = 0; i < n; ++i) {
        const std::uint64_t key = in[i] >> 32;
        for (int d = 0; d < passes; ++d) ++count[d][(key >> (d * Bits)) & mask];
    }
    for (int d = 0; d < passes; ++d) {
        const int shift = 32 + d * Bits;
        std::uint32_t* c = count[d];
        if (c[(in[0] >> shift) & mask] == n) continue;
        std::uint32_t run = 0;
        for (std::uint64_t v = 0; v <= mask; ++v) {
            const std::uint32_t k = c[v];
            c[v] = run;
            run += k;
        }
        for (std::size_t i = 0; i < n; ++i) out[c[(in[i] >> shift) & mask]++] = in[i];
        std::swap(in, out);
    }
    return in;
}

// Sort of one band's records (height key << 32 | entry index) into ascending order, i.e.
// by key, ties in entry order (plant-index order): LSD radix on the key (the records
// enter in index order, so a stable sort by key is the full order), in three passes of
// 11-bit digits (four 8-bit passes took 5 % longer on the benchmark hectare's lists of
// about 1 800), or four of 8 bits for lists too short to fill 2048 counters; short lists
// by insertion. The entries themselves stay where the scatter put them: 8-byte records
// move instead of 16-byte entries and their keys, and the sweep reads the entries
// through the order.
void sortBand(std::uint64_t* rec, std::size_t n, std::vector<std::uint64_t>& scratch) {
    if (n < 2) return;
    if (n <= 32) {
        for (std::size_t i = 1; i < n; ++i) {
            const std::uint64_t r = rec[i];
            std::size_t j = i;
            for (; j > 0 && rec[j - 1] > r; --j) rec[j] = rec[j - 1];
            rec[j] = r;
        }
        return;
    }
    scratch.resize(n);
    const std::uint64_t* sorted = n < 512 ? radixPasses<8>(rec, scratch.data(), n) : radixPasses<11>(rec, scratch.data(), n);
    if (sorted != rec) std::copy(sorted, sorted + n, rec);
}

}  // namespace

// The month's layout: footprint rows and spans of the plants without one, every plant's
// partial-sum slots, and the band lists: the plants overlapping each band, in plant
// order, with (when `sorted`) each band's sort records in bandOrder (sortBands puts them
// in paint order). Two passes over the plants, parallel over fixed chunks of plants
// (scatterChunk: never derived from the thread count):
//  1. rows, and the chunk's totals: slots, new spans, kept spans and plants per band;
//  2. after the prefixes over chunks (and over bands), each plant's slots, its new spans
//     when its footprint was recomputed, and its entries in the bands' lists: a stable
//     counting scatter of the (plant, band) pairs by band (sequential reads of the plant
//     arrays).
// Integer sums and a pool layout that are the same for any chunking and thread count
// (and results never depend on the layout).
void Simulation::Impl::buildBands(bool sorted) {
    const std::size_t n = pl.size();
    layoutReusable = false;  // stepMonth sets it again after its sort
    const std::uint8_t* deadOf = fate.data();  // fate.size() == n
    if (fpRange.size() != n) {
        fpRange.assign(n, kNoFootprint);
        bounds.assign(n, kNoBounds);
    }
    slotStart.resize(n + 1);
    const int nb = bands();
    const std::size_t chunk = scatterChunk(n);
    const std::size_t chunks = (n + chunk - 1) / chunk;
    chunkSlots.assign(chunks + 1, 0);
    chunkNew.assign(chunks + 1, 0);
    chunkKept.assign(chunks + 1, 0);
    chunkCounts.assign(chunks * static_cast<std::size_t>(nb), 0u);
    const bool parallel = n > kParallelPlants;
#pragma omp parallel for schedule(dynamic, 1) if (parallel)
    for (std::size_t c = 0; c < chunks; ++c) {
        std::uint32_t slots = 0, fresh = 0, kept = 0;
        std::uint32_t* h = &chunkCounts[c * nb];
        for (std::size_t p = c * chunk, e = std::min(n, p + chunk); p < e; ++p) {
            if (deadOf[p]) continue;  // no slots, no entries
            PlantBounds& pb = bounds[p];
            if (hasFootprint(pb)) {
                kept += static_cast<std::uint32_t>(pb.rowHi - pb.rowLo + 1);
            } else {
                int lo = pl.rootIy[p], hi = lo;
                // No other cell centre is closer than half a cell to a point inside its
                // own cell: below that radius the footprint is the root cell (most
                // plants, most months).
                if (!(pl.radius[p] < 0.5 * cell)) rowRange(pl.y[p], pl.radius[p], pl.rootIy[p], lo, hi);
                pb.rowLo = lo;
                pb.rowHi = hi;
                fresh += static_cast<std::uint32_t>(hi - lo + 1);
            }
            const int b0 = pb.rowLo / kBandRows, b1 = pb.rowHi / kBandRows;
            slots += static_cast<std::uint32_t>(b1 - b0 + 1);
            for (int b = b0; b <= b1; ++b) ++h[b];
        }
        chunkSlots[c + 1] = slots;
        chunkNew[c + 1] = fresh;
        chunkKept[c + 1] = kept;
    }
    for (std::size_t c = 0; c < chunks; ++c) {
        chunkSlots[c + 1] += chunkSlots[c];
        chunkNew[c + 1] += chunkNew[c];
        chunkKept[c + 1] += chunkKept[c];
    }
    slotStart[n] = chunkSlots[chunks];
    // Each (chunk, band)'s first position in the band lists: bands in order, chunks in
    // order within a band.
    bandStart.assign(static_cast<std::size_t>(nb) + 1, 0);
    std::uint32_t run = 0;
    for (int b = 0; b < nb; ++b) {
        bandStart[b] = run;
        for (std::size_t c = 0; c < chunks; ++c) {
            const std::uint32_t k = chunkCounts[c * nb + b];
            chunkCounts[c * nb + b] = run;
            run += k;
        }
    }
    bandStart[nb] = run;
    bandEnd.assign(bandStart.begin() + 1, bandStart.end());
    bandEntries.resize(run);
    if (sorted) bandOrder.resize(run);
    const std::size_t kept = chunkKept[chunks], fresh = chunkNew[chunks];
    // Repack when the dead spans (of dead plants and of recomputed footprints) outnumber
    // the live ones: the kept footprints in plant order, then the new ones after them.
    if (footprint.size() > 2 * kept + 4096) repackFootprints(chunk, kept, fresh);
    const std::size_t base = footprint.size();
    if (base + fresh > 0xFFFFFFFFu) throw ValidationError("simulation: over 2^32 footprint spans; use a smaller area");
    footprint.resize(base + fresh);
    scatterEntries(chunk, base, sorted);
}

// buildBands: the kept footprints (those of living plants not to recompute) copied in
// plant order to the front of a new span pool, with room for `fresh` new spans after the
// `kept` ones (chunkKept: each chunk's first kept span).
void Simulation::Impl::repackFootprints(std::size_t chunk, std::size_t kept, std::size_t fresh) {
    const std::size_t n = pl.size(), chunks = chunkKept.size() - 1;
    const bool parallel = n > kParallelPlants;
    const std::uint8_t* deadOf = fate.data();
    repackScratch.resize(kept + fresh);
#pragma omp parallel for schedule(dynamic, 1) if (parallel)
    for (std::size_t c = 0; c < chunks; ++c) {
        std::uint32_t at = chunkKept[c];
        for (std::size_t p = c * chunk, e = std::min(n, p + chunk); p < e; ++p) {
            PlantBounds& pb = bounds[p];
            if (deadOf[p]) pb = kNoBounds;  // its spans are not copied (pass 1 did not count them)
            if (!hasFootprint(pb)) continue;
            const std::uint32_t rows = static_cast<std::uint32_t>(pb.rowHi - pb.rowLo + 1);
            std::copy_n(footprint.data() + pb.span, rows, repackScratch.data() + at);
            pb.span = at;
            at += rows;
        }
    }
    std::swap(footprint, repackScratch);
    footprint.resize(kept);
    std::vector<Span>().swap(repackScratch);  // the old pool's memory back (a repack is rare)
}

// Pass 2 of buildBands, after the prefixes over chunks and bands: each plant's slots, its new
// spans (after the pool's first `base`) when its footprint is to be recomputed, and its
// entries in the bands' lists (with sort records when `sorted`).
void Simulation::Impl::scatterEntries(std::size_t chunk, std::size_t base, bool sorted) {
    const std::size_t n = pl.size(), chunks = chunkSlots.size() - 1;
    const int nb = bands();
    const bool parallel = n > kParallelPlants;
    const std::uint8_t* deadOf = fate.data();
    // The arrays in locals: the stores into the entries and spans could otherwise alias the
    // vectors' pointers, which the compiler would then reload for every plant.
    PlantBounds* boundsOf = bounds.data();
    std::uint32_t* slotOf = slotStart.data();
    RadiusRangeF* rangeOf = fpRange.data();
    Span* spans = footprint.data();
    const double* heights = pl.height.data();
    const std::int32_t* speciesOf = pl.species.data();
    const std::uint32_t* bandFirst = bandStart.data();
    BandEntry* entries = bandEntries.data();
    std::uint64_t* records = sorted ? bandOrder.data() : nullptr;
#pragma omp parallel for schedule(dynamic, 1) if (parallel)
    for (std::size_t c = 0; c < chunks; ++c) {
        std::uint32_t slot = chunkSlots[c], span = static_cast<std::uint32_t>(base + chunkNew[c]);
        std::uint32_t* pos = &chunkCounts[c * nb];
        for (std::size_t p = c * chunk, e = std::min(n, p + chunk); p < e; ++p) {
            PlantBounds& pb = boundsOf[p];
            const std::uint32_t firstSlot = slotOf[p] = slot;
            if (deadOf[p]) continue;
            const int lo = pb.rowLo, hi = pb.rowHi;
            const int b0 = lo / kBandRows, b1 = hi / kBandRows;
            slot += static_cast<std::uint32_t>(b1 - b0 + 1);
            if (__builtin_expect(!hasFootprint(pb), 0)) {
                pb.span = span;
                span += static_cast<std::uint32_t>(hi - lo + 1);
                Span* sp = spans + pb.span;
                if (pl.radius[p] < 0.5 * cell) {
                    sp[0] = Span{static_cast<std::uint32_t>(static_cast<std::size_t>(pl.rootIy[p]) * W + pl.rootIx[p]), 1};
                    rangeOf[p] = RadiusRangeF::narrowed(RadiusRange{-HUGE_VAL, std::nextafter(0.5 * cell, 0.0)});
                } else {
                    const double x = pl.x[p], y = pl.y[p], r = pl.radius[p];
                    footprintSpans(x, y, r, pl.rootIx[p], pl.rootIy[p], lo, hi, sp);
                    rangeOf[p] = RadiusRangeF::narrowed(footprintRange(x, y, r, pl.rootIx[p], pl.rootIy[p], lo, hi, sp));
                }
            }
            const std::uint32_t key = records ? heightKeyOf(heights[p]) : 0;
            const std::uint32_t species = static_cast<std::uint32_t>(speciesOf[p]);
            if (b0 == b1) {  // one band (most plants): all its rows, from its first span
                const std::uint32_t at = pos[b0]++;
                entries[at] = BandEntry::make(spans[pb.span], pb.span, static_cast<std::uint32_t>(hi - lo + 1), firstSlot, species);
                if (records) records[at] = static_cast<std::uint64_t>(key) << 32 | (at - bandFirst[b0]);
                continue;
            }
            for (int b = b0; b <= b1; ++b) {
                // Rows of the plant within band b.
                const int first = std::max(lo, b * kBandRows), last = std::min(hi, (b + 1) * kBandRows - 1);
                const std::uint32_t at = pos[b]++;
                const std::uint32_t sp = pb.span + static_cast<std::uint32_t>(first - lo);
                entries[at] = BandEntry::make(spans[sp], sp, static_cast<std::uint32_t>(last - first + 1),
                                              firstSlot + static_cast<std::uint32_t>(b - b0), species);
                if (records) records[at] = static_cast<std::uint64_t>(key) << 32 | (at - bandFirst[b]);
            }
        }
    }
}

// Each band's records into paint order: height order (tallest first, ties by plant
// index, which is id order because plants are appended with increasing ids and
// compaction is stable); an independent sort of each band's records, parallel over
// bands, in the cache.
void Simulation::Impl::sortBands() {
    const int nb = bands();
    const std::size_t run = bandOrder.size();
    sortScratch.resize(static_cast<std::size_t>(omp_get_max_threads()));
#pragma omp parallel for schedule(dynamic, 1) if (run > kParallelPlants)
    for (int b = 0; b < nb; ++b)
        sortBand(bandOrder.data() + bandStart[b], bandEnd[b] - bandStart[b],
                 sortScratch[static_cast<std::size_t>(omp_get_thread_num())]);
}

// Band b's list and paint order without the entries whose slots are marked dead: both
// filtered in place, stably, so the survivors keep their order (that of a fresh
// buildBands and sortBands: the same plants, heights, footprints and slots) and the
// order records are renumbered to the entries' new places.
void Simulation::Impl::filterBand(int b, std::vector<std::uint32_t>& remap) {
    constexpr std::uint32_t kDropped = 0xFFFFFFFFu;
    BandEntry* e = bandEntries.data() + bandStart[b];
    const std::size_t n = bandEnd[b] - bandStart[b];
    const std::uint8_t* dead = slotDead.data();
    remap.resize(n);
    std::uint32_t* to = remap.data();
    std::size_t out = 0;
    for (std::size_t i = 0; i < n; ++i) {
        const BandEntry x = e[i];
        const bool drop = dead[x.slot] != 0;
        to[i] = drop ? kDropped : static_cast<std::uint32_t>(out);
        e[out] = x;
        out += !drop;
    }
    if (out == n) return;
    bandEnd[b] = bandStart[b] + static_cast<std::uint32_t>(out);
    std::uint64_t* rec = bandOrder.data() + bandStart[b];
    std::size_t kept = 0;
    for (std::size_t i = 0; i < n; ++i) {
        const std::uint64_t r = rec[i];
        const std::uint32_t at = to[static_cast<std::uint32_t>(r)];
        rec[kept] = (r & ~std::uint64_t{0xFFFFFFFFu}) | at;
        kept += at != kDropped;
    }
}

}  // namespace eco::sim
