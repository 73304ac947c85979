// The simulator engine's private header: the data layout shared by the phases of the
// monthly step (simulator_*.cpp) and the inline helpers their hot loops call. Included by
// the simulator's own files only; callers see simulator.h.
//
// The phases, one file each:
//   simulator_setup.cpp        inputs, species constants, grid, canopy shade and seedbank, initial plants
//   simulator_layout.cpp       footprints, band lists and their height order (radix sort)
//   simulator_sweep.cpp        the resource sweep of one band: count, prepare, paint, finish
//   simulator_plants.cpp       vigour, pool, growth, mortality; Deussen competition; removal of the dead
//   simulator_germination.cpp yearly germination from the seedbank
//   simulator_state.cpp        fingerprint, checkpoint save and load
//   simulator.cpp              the public front and the monthly step that runs the phases
// docs/simulator.md describes the model and how the sweep is parallelised without races.
#pragma once

#include <omp.h>
#ifdef __SSE2__
#include <emmintrin.h>
#endif

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <numeric>
#include <vector>

#include "batch_math.h"
#include "error.h"
#include "footprint.h"
#include "paint.h"
#include "processes.h"
#include "rng.h"
#include "simulator.h"

namespace eco::sim {

// Rows per band of the sweep. Fixed (never derived from the thread count), so that the
// per-band partial sums, and hence every result, are the same for any number of threads.
constexpr int kBandRows = 16;
// At most this many growth periods (named, and species' own months): germination keeps
// sets of them in 32-bit masks.
constexpr std::size_t kMaxGrowthPeriods = 32;
constexpr double kPi = 3.14159265358979323846;
// Below these sizes a loop runs on one thread: a fork and join costs more than the work, and
// far more on a loaded machine. Results never depend on it (see kBandRows). 5000 and 50000:
// on 2 threads the benchmark hectare's 150 years took 6.3-6.4 s against 6.6-8.7 s with
// 20000 and 200000, whose late decades (11 000 - 20 000 big crowns) ran on one thread.
inline std::size_t kParallelPlants = kDefaultParallelPlants;
inline std::size_t kParallelCells = kDefaultParallelCells;
// The O(n) scatters (band lists, compaction) have little work per plant: they go parallel
// only for this many times more plants (2: on the benchmark hectare, 40 000 plants and
// more, 2 threads cut band lists and compaction by 10-25 %; 16 kept them serial).
constexpr std::size_t kParallelSortFactor = 2;
// The dead are removed from the plant store once they are more than 1 / kCompactShare of it
// (compactIfDue). Results never depend on it.
constexpr std::size_t kCompactShare = 8;
// The paint pass prefetches the band entry this many places ahead in height order.
constexpr std::size_t kPaintPrefetch = 8;
constexpr std::size_t kFinishPrefetch = 32;
constexpr std::ptrdiff_t kScatterPrefetch = 16;

// Per-thread scratch of the band being swept: what the occupants of its cells share, one
// array per field (BandCells, paint.h), and the band's occupied cells.
struct BandScratch {
    std::vector<double> base, avail, rest;
    std::vector<float> transmission;
    std::vector<std::int32_t> painted;
    std::vector<std::uint32_t> occupied;
    std::vector<std::int32_t> diff;  // scatterBand: difference array of the occupancy (n + 1 cells, kept zero)
    std::vector<float> sunRow, moistRow;  // the month's abiotics of one row, per column (sweepBand)
    std::vector<std::uint32_t> remap;     // filterBand: each entry's new index
    void resize(std::size_t n) {
        if (diff.size() < n + 1) diff.resize(n + 1, 0);
        base.resize(n + kPaintPad);  // the paint kernel's padding (paint.h)
        avail.resize(n + kPaintPad);
        rest.resize(n + kPaintPad);
        transmission.resize(n + kPaintPad);
        painted.resize(n + kPaintPad);
        occupied.resize(n + 3);  // room for the vector prepare's packed stores
    }
    BandCells cells() { return BandCells{base.data(), avail.data(), rest.data(), transmission.data(), painted.data()}; }
};

// One plant in one band's list: everything the sweep needs, read sequentially. The plant's
// first row in the band is inline, so that a plant covering one row (most plants) needs no
// read of the footprint array, which the height-ordered lists visit at random.
struct BandEntry {
    std::uint32_t start;   // first cell of the plant's first row in the band
    std::uint32_t packed;  // that row's length (bits 0-15), rows in the band (16-20), species (21-31)
    std::uint32_t span;    // footprint span of that first row (the plant's further rows follow it)
    std::uint32_t slot;    // partial-sum slot of (plant, band)

    static constexpr std::uint32_t kMaxLen = 0xFFFF, kMaxSpecies = 0x7FF;
    static BandEntry make(Span first, std::uint32_t span, std::uint32_t rows, std::uint32_t slot, std::uint32_t species) {
        return BandEntry{first.start, first.len | rows << 16 | species << 21, span, slot};
    }
    std::uint32_t len() const { return packed & 0xFFFFu; }
    std::uint32_t rows() const { return (packed >> 16) & 0x1Fu; }
    std::uint32_t species() const { return packed >> 21; }
    // fn(first cell, cells) for each row of the entry, top to bottom.
    template <typename F>
    void forEachRow(const Span* footprint, F&& fn) const {
        fn(static_cast<std::size_t>(start), len());
        for (const Span *sp = footprint + span + 1, *se = footprint + span + rows(); sp < se; ++sp)
            fn(static_cast<std::size_t>(sp->start), sp->len);
    }
};
static_assert(sizeof(BandEntry) == 16);

struct SpeciesConst {
    double alpha = 0, maxAgeYears = 1, maxHeightM = 1;
    double capacity = 0;       // carbon pool capacity
    double backgroundMu = 0;   // monthly background mortality
    double growthPerOverflow = 0;  // months of growth age per unit overflow (growthMonthsPerUnitOverflow)
    double rouletteDenominator = 1;  // maxAge^beta
    // alpha, the optima c and reciprocal ranges 1 / r of Eq. 1 per factor (core/vigour.h's batch form).
    VigourCoeffs vigour;
    bool growthMonth[12] = {};
    int period = 0;            // index into biome.growthPeriods
    std::uint32_t memberMask = 0;      // sub-biomes the species belongs to (bit b = sub-biome b + 1)
    std::uint32_t canopySeedMask = 0;  // packages a canopy tree of this species spreads
    Allometry allometry;
};

// Plants as a structure of arrays (the order is the plant index; compaction keeps it stable).
struct PlantStore {
    std::vector<std::uint64_t> id;
    std::vector<std::int32_t> species;
    std::vector<double> x, y, groundZ, height, radius, growthAge, pool;
    // birthMonth: the months done at which the plant's age was 0 (its age is month - birthMonth,
    // so the monthly update need not touch it; negative for initial plants older than the run).
    std::vector<std::int32_t> birthMonth, rootIx, rootIy;
    std::vector<std::uint32_t> coarse;  // abiotics cell of the root
    std::vector<float> vigour, sun, water, canopyLimit;

    std::size_t size() const { return id.size(); }
    template <typename F>
    void forEachArray(F&& f) {
        f(id); f(species); f(x); f(y); f(groundZ); f(height); f(radius); f(growthAge); f(pool);
        f(birthMonth); f(rootIx); f(rootIy); f(coarse); f(vigour); f(sun); f(water); f(canopyLimit);
    }
    void resize(std::size_t n) {
        forEachArray([n](auto& v) { v.resize(n); });
    }
    std::size_t bytesPerPlant() {
        std::size_t b = 0;
        forEachArray([&](auto& v) { b += sizeof(typename std::decay_t<decltype(v)>::value_type); });
        return b;
    }
};

struct Simulation::Impl : CellGrid {
    // ---- fixed inputs
    Biome biome;
    SimParams params;
    std::uint64_t seed = 0;
    Abiotics abio;
    Grid<float> chm;
    std::vector<Plant> canopy;  // relevant trees only
    SimArea area;
    std::vector<SpeciesConst> spc;
    std::vector<std::uint32_t> periodMonthMask;       // per growth period: bit m set when month m belongs to it
    std::array<std::vector<int>, 12> periodsOfMonth;  // periods containing month m
    double vigA = 0.2, vigLnQ = std::log(0.01), vigP = 4.5;
    bool vigPIsFourAndHalf = true;  // x^4.5 as x^4 sqrt(x): exact to an ulp and 5x faster than pow

    // ---- simulation grid (W, H, cell, ox, oy and the footprint geometry: the CellGrid base)
    std::vector<int> coarseCol;        // per sim column: abiotics column
    std::vector<std::size_t> coarseRowOffset;  // per sim row: abiotics row * abiotics width
    // Static state of the cells (5 bytes a cell; the abiotics cell of cell (ix, iy) is
    // coarseRowOffset[iy] + coarseCol[ix]). The sweep counts a band's occupants and keeps what
    // they share during a month in its band scratch (BandScratch); germination keeps its
    // count in occupants.
    Grid<float> canopyTrans;           // per cell: product of (1 - alpha) of the covering canopy trees
    std::vector<std::uint8_t> canopyTrees;  // per cell: canopy trees covering it (saturates at 255)
    Grid<float> seedProb;              // also the grid geometry
    std::size_t cellCount() const { return canopyTrees.size(); }
    std::vector<std::uint16_t> seedPkg;
    std::vector<std::uint16_t> occupants;  // per cell: undergrowth plants covering it (germination)
    // Exploited sun and water per cell and growth period since the last germination,
    // interleaved (cell, period, {sun, water}) so that the last occupant of a cell updates
    // one cache line: see deficitAt.
    std::vector<float> deficit;
    std::size_t periods() const { return periodMonthMask.size(); }
    float* deficitAt(std::size_t c, std::size_t g) { return &deficit[(c * periods() + g) * 2]; }
    const float* deficitAt(std::size_t c, std::size_t g) const { return &deficit[(c * periods() + g) * 2]; }
    std::uint32_t windowMask = 0;      // months accumulated since the last germination
    // [model] germination_vigour = "mean_vigour" only (empty otherwise): exploited sun and
    // water per cell and month of the window, (cell, month, {sun, water}), for Eq. 1 on each
    // month's leftovers.
    std::vector<float> monthDeficit;
    float* monthDeficitAt(std::size_t c, int m) { return &monthDeficit[(c * 12 + static_cast<std::size_t>(m)) * 2]; }
    const float* monthDeficitAt(std::size_t c, int m) const { return &monthDeficit[(c * 12 + static_cast<std::size_t>(m)) * 2]; }

    // ---- plants and per-month scratch
    PlantStore pl;
    // Per plant: footprint rows and first span of its footprint in the pool `footprint`, or
    // kNoSpan when the footprint must be computed. The band-list passes read these 12 bytes
    // only; the radius range (fpRange) is read by the plants that grew.
    struct PlantBounds {
        std::int32_t rowLo, rowHi;
        std::uint32_t span;
    };
    static constexpr std::uint32_t kNoSpan = 0xFFFFFFFFu;
    static constexpr PlantBounds kNoBounds{0, 0, kNoSpan};
    static bool hasFootprint(const PlantBounds& b) { return b.span != kNoSpan; }
    // Footprints persist across months (buildBands): a plant's footprint depends only on
    // its root, position and radius, and its radius changes only in growth months with
    // overflow. fpRange[p] holds the radii for which plant p's footprint (rows in bounds[p],
    // spans in the pool from bounds[p].span) is valid (footprintRange); bounds[p].span is
    // kNoSpan when it must be computed (new plant, or a radius outside the range). A plant that grows
    // within its range keeps its spans (most growth months of most plants); the spans of a
    // recomputed or dead plant are left in the pool, which is repacked in plant order when
    // such garbage outgrows the live spans. bounds and fpRange are compacted with the
    // plants; both are empty (all footprints to compute) after addPlant or loadState.
    // The ranges are kept in floats, narrowed to the floats inside the exact range (8 bytes a
    // plant instead of 16, read by every plant that grows): a radius outside the narrowed
    // range but inside the exact one only recomputes the same footprint, so no result
    // depends on it.
    struct RadiusRangeF {
        float lo, hi;
        static RadiusRangeF narrowed(const RadiusRange& r) {
            float lo = static_cast<float>(r.lo), hi = static_cast<float>(r.hi);
            if (static_cast<double>(lo) < r.lo) lo = std::nextafter(lo, HUGE_VALF);
            if (static_cast<double>(hi) > r.hi) hi = std::nextafter(hi, -HUGE_VALF);
            return RadiusRangeF{lo, hi};
        }
        bool contains(double r) const { return r >= static_cast<double>(lo) && r <= static_cast<double>(hi); }
    };
    static constexpr RadiusRangeF kNoFootprint{HUGE_VALF, -HUGE_VALF};
    std::vector<PlantBounds> bounds;
    std::vector<RadiusRangeF> fpRange;
    std::vector<Span> footprint, repackScratch;
    std::vector<std::uint32_t> slotStart;
    std::vector<std::uint32_t> chunkSlots, chunkNew, chunkKept;  // buildBands: prefix over chunks
    std::vector<double> partSun, partWater;
    std::vector<std::int32_t> partCells;
    std::vector<std::uint32_t> bandStart;
    std::vector<BandEntry> bandEntries;
    std::vector<float> speciesKeep;  // 1 - alpha per species (the sweep's attenuation)
    // Per plant: 0 alive, 1 died (background / stress), 2 reached the canopy, 3 dominated.
    // The dead stay in the store, skipped by every pass, until compact() removes them
    // (deadPending of them; see settleDead): the same results as removing them at once.
    std::vector<std::uint8_t> fate;
    std::size_t deadPending = 0;
    // The month's layout (band lists, their paint order, slots) can serve the next month
    // too when no plant grew and none was added or moved: only the entries of the plants
    // that died meanwhile (their slots marked in slotDead) are dropped (filterBand).
    bool layoutReusable = false;
    std::vector<std::uint8_t> slotDead;
    // Marks the slots of plant p, which has just died (slotOf: slotStart, dead: slotDead).
    static void markSlotsDead(const std::uint32_t* slotOf, std::uint8_t* dead, std::size_t p) {
        std::fill(dead + slotOf[p], dead + slotOf[p + 1], std::uint8_t{1});
    }
    std::vector<std::uint32_t> bandEnd;  // each band's list ends here (bandStart[b + 1] until entries are dropped)
    // Deussen competition scratch: abilities and the plant lists of the pair-finding bins.
    std::vector<double> ability;
    std::vector<std::int32_t> binX0, binX1, binY0, binY1;
    // One plant in one bin: what the pair test reads, stored sequentially.
    struct BinEntry {
        double x, y, radius, ability;
        std::int32_t binX0, binY0;  // first bin of the plant's range (pair deduplication)
        std::uint32_t plant;
    };
    std::vector<std::uint32_t> binStart, binFill;
    std::vector<BinEntry> binEntries;
    std::vector<std::uint8_t> dominated;
    // The band sorts' records, one per band entry: height key (high 32 bits) and the entry's
    // index in its band's list (low 32 bits); after the sort, each band's paint order.
    std::vector<std::uint64_t> bandOrder;
    std::vector<BandScratch> bandScratch;  // per thread (sweepBand)

    // ---- disturbance (sim/disturbance.h): settings, the events so far, per species tolerance
    DisturbanceSettings disturbance;
    bool disturbanceOn = false;
    std::vector<DisturbanceRecord> disturbanceEvents;
    void disturb(int m);  // simulator.cpp: the events of this month, after the plants' update

    std::int64_t month = 0;
    std::uint64_t nextId = 1;
    SimCounters counters;
    SimPhaseSeconds phaseSeconds;
    std::size_t droppedInitial = 0;
    mutable std::uint64_t fingerprintCache = 0;
    mutable bool fingerprintReady = false;

    int bands() const { return (H + kBandRows - 1) / kBandRows; }

    // ------------------------------------------------------------------ vigour and allometry
    // Vigour (Eq. 1) in core/vigour.h's batch form, so that the monthly update can take the
    // exp of a whole block of plants at once (batch_math.h): the exponent, then the vigour
    // from its exp.
    BatchVigourShape vigourShape() const { return BatchVigourShape{vigPIsFourAndHalf, vigP, vigLnQ, vigA}; }
    // A plant's features (factors.h order): its sun and water shares (the resources the sweep
    // shares out), the month's temperature (germination: its season mean) and the static
    // factors of the abiotics cell of its root, read from the static maps of kAbioticMaps
    // (core/abiotics.h) held here, one plane per static map. A new static factor needs no
    // line here (docs/factors.md); a new monthly one does (the static_assert says so).
    // Held by value, so that the monthly update and germination keep it in locals; the
    // loop over the planes has a length and factor indices known at compile time, so it
    // unrolls into the loads of the named planes before.
    struct SitePlanes {
        std::array<const float*, kStaticMapCount> plane;
        Features features(double sun, double water, double temp, std::size_t coarseCell) const {
            static_assert(kStaticMapCount + 3 == kFactorCount && eco::detail::isMonthlyFactor(Factor::Sun) &&
                              eco::detail::isMonthlyFactor(Factor::Moisture) && eco::detail::isMonthlyFactor(Factor::Temperature),
                          "a new monthly factor: give the plant's value here (docs/factors.md)");
            Features x{};
            x[factorIndex(Factor::Sun)] = sun;
            x[factorIndex(Factor::Moisture)] = water;
            x[factorIndex(Factor::Temperature)] = temp;
            for (std::size_t i = 0; i < kStaticMapCount; ++i) x[factorIndex(kStaticMaps[i].factor)] = plane[i][coarseCell];
            return x;
        }
    };
    SitePlanes sitePlanes() const {
        SitePlanes site{};
        for (std::size_t i = 0; i < kStaticMapCount; ++i) site.plane[i] = (abio.*(kStaticMaps[i].single)).data().data();
        return site;
    }

    // Crown radius of species s at height h: the allometry of Table 3 (core/biome.h), r = f h
    // or r = exp(a + b ln h), with batch_math.h's log and exp. Every radius of the simulator
    // comes from here or from its block form in updatePlants (the same operations).
    double crownRadius(int s, double h) const {
        const Allometry& al = spc[static_cast<std::size_t>(s)].allometry;
        if (!(h > 0)) return 0.0;
        return al.linear ? al.linearFactor * h : batchExpOne(al.a + al.b * batchLogOne(h));
    }

    // ------------------------------------------------------------------ setup (simulator_setup.cpp)
    void setup(SimInputs&& in, const SimParams& p, std::uint64_t s);
    void validateAbiotics();
    void setupSpecies();
    void setupGrid(const std::optional<SimArea>& requested);
    // Canopy shade and water per cell, and the seedbank (germination probability and packages).
    void setupCanopy(const std::vector<Plant>& trees);
    float canopyLimitAt(double x, double y) const;
    void addPlant(std::uint64_t id, int s, double x, double y, int rootIx, int rootIy, double growthAgeYears,
                  double ageYears, double pool, double vig);
    void setPlant(std::size_t p, std::uint64_t id, int s, double x, double y, int rootIx, int rootIy, double growthAgeYears,
                  double ageYears, std::int64_t monthsDone, double pool, double vig);
    void addInitial(const std::vector<UndergrowthPlant>& initial);

    // ------------------------------------------------------------------ layout (simulator_layout.cpp)
    std::vector<std::uint32_t> chunkCounts;
    // Per-thread scratch of the band sorts (reused: no allocation in the steady state).
    std::vector<std::vector<std::uint64_t>> sortScratch;
    void buildBands(bool sorted);
    void repackFootprints(std::size_t chunk, std::size_t kept, std::size_t fresh);
    void scatterEntries(std::size_t chunk, std::size_t base, bool sorted);
    void sortBands();
    void filterBand(int b, std::vector<std::uint32_t>& remap);

    // ------------------------------------------------------------------ sweep (simulator_sweep.cpp)
    std::pair<std::size_t, std::size_t> scatterBand(int b, BandScratch& scr) const;
    template <typename Lanes>
    void paintEntries(const BandEntry* e0, std::size_t ne, const std::uint64_t* order, std::size_t c0, const BandCells& bc,
                      double demand, bool unshared);
    void paintDefault(const BandEntry* e0, std::size_t ne, const std::uint64_t* order, std::size_t c0, const BandCells& bc,
                      double demand, bool unshared);
#ifdef ECO_HAVE_AVX2_KERNELS
    ECO_TARGET_AVX2 void paintAvx2(const BandEntry* e0, std::size_t ne, const std::uint64_t* order, std::size_t c0,
                                   const BandCells& bc, double demand, bool unshared);
#endif
    void sweepBand(int b, int m, bool reuse);
    void finishBand(std::size_t c0, int m, const BandCells& bc, const std::uint32_t* occList, std::size_t nOcc);

    // ------------------------------------------------------------------ plants (simulator_plants.cpp)
    std::size_t updatePlants(int m);
    void compete();
    // Runs of surviving plants (first plant, count), in plant order (compact()).
    struct Run {
        std::uint32_t from, len;
    };
    std::vector<Run> keptRuns;
    void compact();
    void compactIfDue();
    void settleDead() { compact(); }
    void stepMonth();  // simulator.cpp

    // ------------------------------------------------------------------ germination (simulator_germination.cpp)
    void seasonMeans(std::size_t c, int ix, int iy, std::uint32_t wanted, double* sun, double* water, double* temp, bool* ok) const;
    void weightsAt(int ix, int iy, double* w, double* arg, int* cand) const;
    void monthlyMeanWeights(std::size_t c, std::size_t cc, const int* cand, std::size_t nc, double* w) const;
    void countOccupancy();
    void germinate(std::uint64_t year);

    // ------------------------------------------------------------------ outputs and state
    UndergrowthPlant plantAt(std::size_t p) const;  // simulator.cpp
    std::uint64_t computeFingerprint() const;       // simulator_state.cpp
};

}  // namespace eco::sim
