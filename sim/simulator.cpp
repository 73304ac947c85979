// The undergrowth simulator engine. The model is in processes.h; this file is the data
// layout and the parallel sweep (docs/simulator.md, "Parallel sweep without races").
#include "simulator.h"

#include <omp.h>
#ifdef __SSE2__
#include <emmintrin.h>
#endif

#include <algorithm>
#include <cmath>
#include <cstring>
#include <numeric>

#include "error.h"
#include "batch_math.h"
#include "footprint.h"
#include "paint.h"
#include "processes.h"
#include "rng.h"

namespace eco::sim {

namespace {

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
std::size_t kParallelPlants = kDefaultParallelPlants;
std::size_t kParallelCells = kDefaultParallelCells;
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

struct SpeciesConst {
    double alpha = 0, maxAgeYears = 1, maxHeightM = 1;
    double capacity = 0;       // carbon pool capacity
    double backgroundMu = 0;   // monthly background mortality
    double growthPerOverflow = 0;  // months of growth age per unit overflow (growthMonthsPerUnitOverflow)
    double rouletteDenominator = 1;  // maxAge^beta
    // Optima c and reciprocal ranges 1 / r of Eq. 1 (multiplications instead of divisions).
    double sunC = 0, sunInvR = 1, moistC = 0, moistInvR = 1, tempC = 0, tempInvR = 1, slopeC = 0, slopeInvR = 1;
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

std::uint64_t hashBytes(std::uint64_t h, const void* data, std::size_t n) {
    const auto* p = static_cast<const unsigned char*>(data);
    std::size_t i = 0;
    for (; i + 8 <= n; i += 8) {
        std::uint64_t w;
        std::memcpy(&w, p + i, 8);
        h = mixStream(h, w);
    }
    std::uint64_t tail = n;
    for (; i < n; ++i) tail = (tail << 8) ^ p[i];
    return mixStream(h, tail);
}
template <typename T>
std::uint64_t hashVector(std::uint64_t h, const std::vector<T>& v) {
    return hashBytes(h, v.data(), v.size() * sizeof(T));
}

}  // namespace

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

    std::int64_t month = 0;
    std::uint64_t nextId = 1;
    SimCounters counters;
    SimPhaseSeconds phaseSeconds;
    std::size_t droppedInitial = 0;
    mutable std::uint64_t fingerprintCache = 0;
    mutable bool fingerprintReady = false;

    int bands() const { return (H + kBandRows - 1) / kBandRows; }

    // ------------------------------------------------------------------ setup
    void setup(SimInputs&& in, const SimParams& p, std::uint64_t s) {
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

    void validateAbiotics() {
        const Grid<float>& g = abio.slopeDeg;
        if (g.empty()) throw ValidationError("simulation: the abiotics have no slope map");
        auto check = [&](const MonthlyGrids<float>& m, const char* what) {
            if (m.months.size() != 12)
                throw ValidationError(std::string("simulation: abiotic map '") + what + "' must have 12 monthly planes, has " +
                                      std::to_string(m.months.size()));
            for (const auto& plane : m.months)
                if (!plane.sameGeometry(g))
                    throw ValidationError(std::string("simulation: abiotic map '") + what +
                                          "' does not have the geometry of the slope map");
        };
        check(abio.sunHours, "sun");
        check(abio.moistureMm, "moisture");
        check(abio.temperatureC, "temperature");
        if (abio.elevationM.empty()) abio.elevationM = Grid<float>::like(g, 0.f);
        if (!abio.elevationM.sameGeometry(g))
            throw ValidationError("simulation: the elevation map does not have the geometry of the slope map");
    }

    void setupSpecies() {
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
            c.sunC = s.sun.c; c.sunInvR = 1.0 / s.sun.r;
            c.moistC = s.moisture.c; c.moistInvR = 1.0 / s.moisture.r;
            c.tempC = s.temperature.c; c.tempInvR = 1.0 / s.temperature.r;
            c.slopeC = s.slope.c; c.slopeInvR = 1.0 / s.slope.r;
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

    void setupGrid(const std::optional<SimArea>& requested) {
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
    }

    void setupCanopy(const std::vector<Plant>& trees) {
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

    // ------------------------------------------------------------------ plants
    // Vigour (Eq. 1) in two steps, so that the monthly update can take the exp of a whole
    // block of plants at once (batch_math.h): the exponent, then the vigour from its exp.
    // g is decreasing in |d| / r, so min(g(.)) = g(max |d| / r): one exp and one pow.
    // VigourShape holds Eq. 1's shape (p, ln q, a) by value, so that the monthly update and
    // germination keep it in locals.
    struct VigourShape {
        bool fourAndHalf;  // p = 4.5: x^4 sqrt(x) instead of pow
        double p, lnQ, a;
        double exponent(const SpeciesConst& c, double sun, double water, double temp, double slope) const {
            const double x = std::max(std::max(std::abs(temp - c.tempC) * c.tempInvR, std::abs(water - c.moistC) * c.moistInvR),
                                      std::max(std::abs(sun - c.sunC) * c.sunInvR, std::abs(slope - c.slopeC) * c.slopeInvR));
            const double xp = fourAndHalf ? (x * x) * (x * x) * std::sqrt(x) : std::pow(x, p);
            return xp * lnQ;
        }
        double fromExp(const SpeciesConst& c, double e) const { return c.alpha * ((1.0 + a) * e - a); }
    };
    VigourShape vigourShape() const { return VigourShape{vigPIsFourAndHalf, vigP, vigLnQ, vigA}; }

    // Crown radius of species s at height h: the allometry of Table 3 (core/biome.h), r = f h
    // or r = exp(a + b ln h), with batch_math.h's log and exp. Every radius of the simulator
    // comes from here or from its block form in updatePlants (the same operations).
    double crownRadius(int s, double h) const {
        const Allometry& al = spc[static_cast<std::size_t>(s)].allometry;
        if (!(h > 0)) return 0.0;
        return al.linear ? al.linearFactor * h : batchExpOne(al.a + al.b * batchLogOne(h));
    }

    float canopyLimitAt(double x, double y) const {
        const int ix = std::clamp(chm.cellX(x), 0, chm.width() - 1), iy = std::clamp(chm.cellY(y), 0, chm.height() - 1);
        return static_cast<float>(std::max(static_cast<double>(chm(ix, iy)), params.canopyThresholdM));
    }

    void addPlant(std::uint64_t id, int s, double x, double y, int rootIx, int rootIy, double growthAgeYears,
                  double ageYears, double pool, double vig) {
        pl.resize(pl.size() + 1);
        fpRange.clear();  // footprints are recomputed (buildBands)
        fate.resize(pl.size(), 0);
        layoutReusable = false;
        setPlant(pl.size() - 1, id, s, x, y, rootIx, rootIy, growthAgeYears, ageYears, month, pool, vig);
    }
    // Writes plant p of the store (already sized); plants are independent of each other. The
    // plant is ageYears old when `monthsDone` months are done.
    void setPlant(std::size_t p, std::uint64_t id, int s, double x, double y, int rootIx, int rootIy, double growthAgeYears,
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

    void addInitial(const std::vector<UndergrowthPlant>& initial) {
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

    // ------------------------------------------------------------------ the monthly sweep
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
    void buildBands(bool sorted) {
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
        if (footprint.size() > 2 * kept + 4096) {
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
        const std::size_t base = footprint.size();
        if (base + fresh > 0xFFFFFFFFu) throw ValidationError("simulation: over 2^32 footprint spans; use a smaller area");
        footprint.resize(base + fresh);
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

    // Chunks of the parallel counting scatters: sized from the plant count, never from the
    // thread count, and a scatter is stable whatever the chunking, so results do not depend
    // on it. Plants per chunk: n / 16 within [4096, 32768], so that a hectare's 10 000 - 70 000
    // plants make enough chunks for the threads to share evenly, and a km2's millions not
    // too many per-chunk histograms (chunks x bands counters).
    static std::size_t scatterChunk(std::size_t n) { return std::clamp<std::size_t>(n / 16, 4096, 32768); }
    std::vector<std::uint32_t> chunkCounts;

    // Sort key of a plant: descending height as an unsigned integer (heights are >= 0, so
    // the bits of the float order like the values).
    static std::uint32_t heightKeyOf(double height) {
        const float h = static_cast<float>(height);
        std::uint32_t bits;
        std::memcpy(&bits, &h, sizeof bits);
        return ~bits;
    }

    // Per-thread scratch of the band sorts (reused: no allocation in the steady state).
    std::vector<std::vector<std::uint64_t>> sortScratch;

    // LSD radix passes over the records' keys (bits 32-63) in digits of Bits bits, from in
    // to out and back; a pass in which every key has the same digit is skipped. The counts
    // of every digit are taken in one read of the records, before the first pass. Returns
    // the array holding the sorted records.
    template <int Bits>
    static std::uint64_t* radixPasses(std::uint64_t* in, std::uint64_t* out, std::size_t n) {
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
    static void sortBand(std::uint64_t* rec, std::size_t n, std::vector<std::uint64_t>& scratch) {
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

    // Each band's records into paint order: height order (tallest first, ties by plant
    // index, which is id order because plants are appended with increasing ids and
    // compaction is stable); an independent sort of each band's records, parallel over
    // bands, in the cache.
    void sortBands() {
        const int nb = bands();
        const std::size_t run = bandOrder.size();
        sortScratch.resize(static_cast<std::size_t>(omp_get_max_threads()));
#pragma omp parallel for schedule(dynamic, 1) if (run > kParallelPlants)
        for (int b = 0; b < nb; ++b)
            sortBand(bandOrder.data() + bandStart[b], bandEnd[b] - bandStart[b],
                     sortScratch[static_cast<std::size_t>(omp_get_thread_num())]);
    }

    // The occupancy count of band b as a difference array (scr.diff, band-relative, kept zero
    // between bands): each row span adds 1 at its first cell and -1 after its last, two
    // writes whatever its length and no loop over its cells. A prefix sum over the band then
    // gives every cell's occupants (the sweep's prepare pass, countOccupancy), and leaves
    // scr.diff zero again. Exact: integer sums. The entries are read as the scatter left them,
    // in plant order (the order does not matter to integer sums), so their footprint spans
    // are read in address order. Returns the band's first cell and cell count.
    std::pair<std::size_t, std::size_t> scatterBand(int b, BandScratch& scr) const {
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

    // Band b's list and paint order without the entries whose slots are marked dead: both
    // filtered in place, stably, so the survivors keep their order (that of a fresh
    // buildBands and sortBands: the same plants, heights, footprints and slots) and the
    // order records are renumbered to the entries' new places.
    void filterBand(int b, std::vector<std::uint32_t>& remap) {
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

    // The paint pass of a band (sweepBand): its entries in height order (`order`), each taking
    // its shares of its cells with the kernel Lanes (paint.h). Inlined into one function per
    // kernel, so that the AVX2 one is compiled for AVX2 throughout.
    template <typename Lanes>
    __attribute__((always_inline)) inline void paintEntries(const BandEntry* e0, std::size_t ne, const std::uint64_t* order,
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
    void paintDefault(const BandEntry* e0, std::size_t ne, const std::uint64_t* order, std::size_t c0, const BandCells& bc,
                      double demand, bool unshared) {
        paintEntries<PaintLanes>(e0, ne, order, c0, bc, demand, unshared);
    }
#ifdef ECO_HAVE_AVX2_KERNELS
    ECO_TARGET_AVX2 void paintAvx2(const BandEntry* e0, std::size_t ne, const std::uint64_t* order, std::size_t c0,
                                   const BandCells& bc, double demand, bool unshared) {
        paintEntries<PaintLanesAvx2>(e0, ne, order, c0, bc, demand, unshared);
    }
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
    static ECO_TARGET_AVX2 std::size_t prepareAvx2(std::size_t i, std::size_t end, const PrepareRow& r, double demand,
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
    static void prepareRow(std::size_t i, std::size_t end, const PrepareRow& r, double demand, PrepareOut& o) {
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

    // One band: count, prepare, paint, finish. The band's rows belong to this call only.
    //  * count: the band's difference array of occupants (scatterBand);
    //  * prepare: every cell's occupants, resources and seeding share, and the occupied cells;
    //  * paint: the entries in height order, each taking its shares of the cells it covers;
    //  * finish: the occupied cells in address order: the leftovers of this month go to the
    //    germination deficit (growth-period months).
    //  When the layout is reused (`reuse`), the entries of plants that died since it was built
    //  are dropped first (filterBand).
    void sweepBand(int b, int m, bool reuse) {
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
        // Finish: this month's leftovers go to the germination deficit.
        const std::vector<int>& periods = periodsOfMonth[m];
        if (periods.empty()) return;
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

    // Plants per block of the monthly update: the vigour exponents of a block are gathered,
    // their exps taken in one vectorised loop (batchExp), then each plant is updated. A plant's
    // result depends on its own data only, so the blocking changes no result.
    static constexpr std::size_t kPlantBlock = kMortalityBatch;

    // Plants that died in an earlier month (still in the store) are skipped; those dying now
    // get their fate, and their slots are marked in slotDead. Returns the plants that grew.
    std::size_t updatePlants(int m) {
        const std::size_t n = pl.size();
        const float* tempPlane = abio.temperatureC[m].data().data();
        const float* slopePlane = abio.slopeDeg.data().data();
        const std::size_t blocks = (n + kPlantBlock - 1) / kPlantBlock;
        std::int64_t cellsVisited = 0;  // an integer sum: the same for any thread count
        // Every array in a local: the stores into them (fate's bytes may alias anything) would
        // otherwise make the compiler reload each vector's pointer after every store.
        const VigourShape vig = vigourShape();
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
                arg[p - p0] = vig.exponent(species[speciesOf[p]], sun, water, tempPlane[coarseOf[p]], slopePlane[coarseOf[p]]);
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
                const double v = vig.fromExp(c, ex[p - p0]);
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

    // ------------------------------------------------------------------ Deussen competition
    // Bins of the pair search: a uniform grid of this edge over the area (crowns reaching
    // beyond it go into the edge bins). Not a model constant: results do not depend on it.
    static constexpr double kCompetitionBinM = 1.0;

    // Deussen et al. 1998 (docs/simulator.md): every pair of living undergrowth plants whose
    // crown circles intersect is compared by competitive ability; the weaker is dominated.
    // Decided from a snapshot of this month's state (after growth and mortality), with one
    // draw per dominated plant keyed by (seed, plant id, month); no plant's fate depends on
    // another's fate this month, so the order of evaluation is irrelevant.
    void compete() {
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

    // Runs of surviving plants (first plant, count), in plant order (compact()).
    struct Run {
        std::uint32_t from, len;
    };
    std::vector<Run> keptRuns;

    // Removes the dead (fate != 0) from the store, keeping the order of the living.
    void compact() {
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
    void compactIfDue() {
        const std::size_t n = pl.size();
        if (deadPending == n || deadPending * (layoutReusable ? 4 : kCompactShare) >= n) compact();
    }
    void settleDead() { compact(); }

    void stepMonth() {
        const int m = static_cast<int>(month % 12);
        double t = omp_get_wtime();
        auto lap = [&t](double& phase) {
            const double now = omp_get_wtime();
            phase += now - t;
            t = now;
        };
        fate.resize(pl.size(), 0);
        compactIfDue();  // all dead, or many (a checkpoint or census may also have settled them)
        const std::size_t n = pl.size(), alive = n - deadPending;
        if (n > 0) {
            // The layout: reused from last month when no plant grew and none was added since
            // (only the dead's entries are dropped, in sweepBand), built and sorted otherwise.
            const bool reuse = layoutReusable;
            if (!reuse) {
                buildBands(true);
                lap(phaseSeconds.footprints);
                sortBands();
                lap(phaseSeconds.ordering);
                slotDead.assign(slotStart[n], 0);
                layoutReusable = true;
            }
            const std::size_t slots = slotStart[n];
            partSun.resize(slots);
            partWater.resize(slots);
            partCells.resize(slots);
            bandScratch.resize(static_cast<std::size_t>(omp_get_max_threads()));
            // The sweep's prepare pass visits every cell whatever the number of plants: it goes
            // parallel for many cells as well as for many plants (big crowns, few plants).
#pragma omp parallel for schedule(dynamic, 1) if (slots > kParallelPlants || cellCount() > kParallelCells)
            for (int b = 0; b < bands(); ++b) sweepBand(b, m, reuse);
            lap(phaseSeconds.sweep);
            if (updatePlants(m) > 0) layoutReusable = false;  // heights and crowns changed
            lap(phaseSeconds.plants);
            if (params.competition == CompetitionMode::Deussen) {
                compete();
                lap(phaseSeconds.competition);
            }
            compactIfDue();
            lap(phaseSeconds.compaction);
        }
        windowMask |= 1u << m;
        counters.plantMonths += static_cast<std::int64_t>(alive);
        if (m == params.seedingMonth) {
            germinate(static_cast<std::uint64_t>(month / 12));
            lap(phaseSeconds.germination);
        }
        ++month;
    }

    // ------------------------------------------------------------------ germination
    // Mean leftover sun, water and temperature of cell c over the months in the window of
    // each growth period g in `wanted` (bit g): into sun[g], water[g], temp[g], with ok[g]
    // false when the window holds none of g's months. One pass over the months: each month's
    // abiotics are read once and added to every wanted period containing it, each period's
    // sums in month order (the same sums as a pass per period).
    void seasonMeans(std::size_t c, int ix, int iy, std::uint32_t wanted, double* sun, double* water, double* temp, bool* ok) const {
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
    void weightsAt(int ix, int iy, double* w, double* arg, int* cand) const {
        const std::size_t c = static_cast<std::size_t>(iy) * W + ix;
        const std::uint32_t pkg = seedPkg[c];
        const std::size_t cc = coarseRowOffset[iy] + static_cast<std::size_t>(coarseCol[ix]);
        const double slope = abio.slopeDeg.data()[cc];
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
        double sunG[kMaxGrowthPeriods], waterG[kMaxGrowthPeriods], tempG[kMaxGrowthPeriods];
        bool okG[kMaxGrowthPeriods];
        seasonMeans(c, ix, iy, wanted, sunG, waterG, tempG, okG);
        const VigourShape vig = vigourShape();
        std::size_t na = 0;
        for (std::size_t k = 0; k < nc; ++k) {
            const int s = cand[k];
            const SpeciesConst& sc = spc[static_cast<std::size_t>(s)];
            const int g = sc.period;
            if (!okG[g]) continue;
            cand[na] = s;
            arg[na] = vig.exponent(sc, sunG[g], waterG[g], tempG[g], slope);
            ++na;
        }
        batchExp(arg, arg, na);
        for (std::size_t k = 0; k < na; ++k) {  // rouletteWeight, with maxAge^beta precomputed
            const SpeciesConst& sc = spc[static_cast<std::size_t>(cand[k])];
            const double vbar = vig.fromExp(sc, arg[k]);
            w[cand[k]] = std::max(0.0, vbar / sc.rouletteDenominator);
        }
    }

    // Occupancy count of the current plants into occupants[] (band-parallel), saturating.
    void countOccupancy() {
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

    struct Candidate {
        int ix, iy, species;
        double x, y;
    };

    void germinate(std::uint64_t year) {
        countOccupancy();
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
                        if (!(seedProb.data()[c] > 0) || occupants[c] > 0 || seedPkg[c] == 0) continue;
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
        windowMask = 0;
    }

    // ------------------------------------------------------------------ outputs
    UndergrowthPlant plantAt(std::size_t p) const {
        UndergrowthPlant u;
        u.id = pl.id[p];
        u.speciesId = pl.species[p];
        u.xM = pl.x[p];
        u.yM = pl.y[p];
        u.groundZM = pl.groundZ[p];
        u.heightM = pl.height[p];
        u.crownRadiusM = pl.radius[p];
        u.ageYears = static_cast<double>(month - pl.birthMonth[p]) / 12.0;
        u.growthAgeYears = pl.growthAge[p];
        u.vigour = pl.vigour[p];
        u.pool = pl.pool[p];
        u.sunShare = pl.sun[p];
        u.waterShare = pl.water[p];
        return u;
    }

    std::uint64_t computeFingerprint() const {
        std::uint64_t h = 0x65636F73696D3031ull;
        for (const auto& [k, v] : params.namedValues()) {
            h = hashBytes(h, k.data(), k.size());
            h = hashBytes(h, &v, sizeof v);
        }
        h = mixStream(h, seed);
        const std::string toml = biomeToToml(biome);
        h = hashBytes(h, toml.data(), toml.size());
        const double a[4] = {area.x0, area.y0, area.x1, area.y1};
        h = hashBytes(h, a, sizeof a);
        for (const Plant& t : canopy) {  // field by field: the struct has padding
            const double v[5] = {t.xM, t.yM, t.groundZM, t.heightM, t.crownRadiusM};
            h = mixStream(h, static_cast<std::uint64_t>(t.speciesId));
            h = hashBytes(h, v, sizeof v);
        }
        for (const auto* mg : {&abio.sunHours, &abio.moistureMm, &abio.temperatureC})
            for (const auto& g : mg->months) h = hashVector(h, g.data());
        h = hashVector(h, abio.slopeDeg.data());
        h = hashVector(h, abio.elevationM.data());
        h = hashVector(h, chm.data());
        return h;
    }
};

// ====================================================================== public API

void setParallelThresholds(std::size_t plants, std::size_t cells) {
    kParallelPlants = plants;
    kParallelCells = cells;
}

Simulation::Simulation(SimInputs inputs, SimParams params, std::uint64_t seed,
                       const std::vector<UndergrowthPlant>& initial)
    : impl_(std::make_unique<Impl>()) {
    impl_->setup(std::move(inputs), params, seed);
    impl_->addInitial(initial);
}

Simulation::~Simulation() = default;

void Simulation::stepMonth() { impl_->stepMonth(); }
void Simulation::stepYear() {
    for (int i = 0; i < 12; ++i) impl_->stepMonth();
}
std::int64_t Simulation::monthsDone() const { return impl_->month; }
// The observers below see the living plants only: those that take the store's order settle
// the dead first (settleDead: the state the monthly step would reach anyway), which changes
// nothing observable. Like the rest of the class, not for concurrent use.
std::size_t Simulation::plantCount() const { return impl_->pl.size() - impl_->deadPending; }

std::vector<UndergrowthPlant> Simulation::plants() const {
    impl_->settleDead();
    std::vector<UndergrowthPlant> out(impl_->pl.size());
    for (std::size_t p = 0; p < out.size(); ++p) out[p] = impl_->plantAt(p);
    return out;
}

YearRecord Simulation::census() const {
    impl_->settleDead();
    const Impl& s = *impl_;
    const std::size_t ns = s.spc.size();
    YearRecord r;
    r.year = yearsDone();
    r.count.assign(ns, 0);
    r.meanHeightM.assign(ns, 0);
    r.meanVigour.assign(ns, 0);
    r.crownAreaM2.assign(ns, 0);
    for (std::size_t p = 0; p < s.pl.size(); ++p) {
        const std::size_t sp = static_cast<std::size_t>(s.pl.species[p]);
        ++r.count[sp];
        r.meanHeightM[sp] += s.pl.height[p];
        r.meanVigour[sp] += s.pl.vigour[p];
        r.crownAreaM2[sp] += kPi * s.pl.radius[p] * s.pl.radius[p];
    }
    for (std::size_t sp = 0; sp < ns; ++sp)
        if (r.count[sp] > 0) {
            r.meanHeightM[sp] /= r.count[sp];
            r.meanVigour[sp] /= r.count[sp];
        }
    return r;
}

const SimCounters& Simulation::counters() const { return impl_->counters; }
const SimPhaseSeconds& Simulation::phaseSeconds() const { return impl_->phaseSeconds; }
std::size_t Simulation::droppedInitialPlants() const { return impl_->droppedInitial; }
const SimParams& Simulation::params() const { return impl_->params; }
const Biome& Simulation::biome() const { return impl_->biome; }
std::uint64_t Simulation::seed() const { return impl_->seed; }
SimArea Simulation::area() const { return impl_->area; }
const Grid<float>& Simulation::gridGeometry() const { return impl_->seedProb; }
const std::vector<Plant>& Simulation::relevantCanopy() const { return impl_->canopy; }
const Grid<float>& Simulation::seedProbability() const { return impl_->seedProb; }
const Grid<float>& Simulation::canopyTransmission() const { return impl_->canopyTrans; }

Grid<std::int32_t> Simulation::seedPackages() const {
    Grid<std::int32_t> g(impl_->W, impl_->H, impl_->cell, impl_->ox, impl_->oy, 0);
    for (std::size_t i = 0; i < g.size(); ++i) g.data()[i] = impl_->seedPkg[i];
    return g;
}

bool Simulation::leftoverMeans(int ix, int iy, int period, double& sunHours, double& waterMm) const {
    const Impl& s = *impl_;
    if (ix < 0 || iy < 0 || ix >= s.W || iy >= s.H || period < 0 ||
        static_cast<std::size_t>(period) >= s.periodMonthMask.size())
        throw ValidationError("leftoverMeans: cell or period out of range");
    double sun[kMaxGrowthPeriods], water[kMaxGrowthPeriods], temp[kMaxGrowthPeriods];
    bool ok[kMaxGrowthPeriods];
    s.seasonMeans(static_cast<std::size_t>(iy) * s.W + ix, ix, iy, 1u << period, sun, water, temp, ok);
    sunHours = sun[period];
    waterMm = water[period];
    return ok[period];
}

std::vector<double> Simulation::germinationWeights(int ix, int iy) const {
    const Impl& s = *impl_;
    if (ix < 0 || iy < 0 || ix >= s.W || iy >= s.H) throw ValidationError("germinationWeights: cell out of range");
    std::vector<double> w(s.spc.size()), arg(s.spc.size());
    std::vector<int> cand(s.spc.size());
    s.weightsAt(ix, iy, w.data(), arg.data(), cand.data());
    return w;
}

std::uint64_t Simulation::fingerprint() const {
    if (!impl_->fingerprintReady) {
        impl_->fingerprintCache = impl_->computeFingerprint();
        impl_->fingerprintReady = true;
    }
    return impl_->fingerprintCache;
}

namespace {
std::string hex64(std::uint64_t v) {
    char buf[32];
    std::snprintf(buf, sizeof buf, "%016llx", static_cast<unsigned long long>(v));
    return buf;
}
}  // namespace

void Simulation::saveState(h5::File& f, const std::string& group) const {
    impl_->settleDead();
    const Impl& s = *impl_;
    const PlantStore& pl = s.pl;
    const hsize_t n = pl.size();
    f.ensureGroup(group);
    f.setAttr(group, "fingerprint", hex64(fingerprint()));
    f.setAttr(group, "months_done", static_cast<std::int64_t>(s.month));
    f.setAttr(group, "next_id", hex64(s.nextId));
    f.setAttr(group, "window_mask", static_cast<std::int64_t>(s.windowMask));
    f.setAttr(group, "plant_months", static_cast<std::int64_t>(s.counters.plantMonths));
    f.setAttr(group, "plant_cell_months", static_cast<std::int64_t>(s.counters.plantCellMonths));
    f.setAttr(group, "germinated", static_cast<std::int64_t>(s.counters.germinated));
    f.setAttr(group, "died_background_or_stress", static_cast<std::int64_t>(s.counters.diedBackgroundOrStress));
    f.setAttr(group, "died_at_canopy", static_cast<std::int64_t>(s.counters.diedAtCanopy));
    f.setAttr(group, "died_dominated", static_cast<std::int64_t>(s.counters.diedDominated));
    f.setAttr(group, "dropped_initial", static_cast<std::int64_t>(s.droppedInitial));
    // Ids split in two exact 32-bit halves.
    std::vector<std::int32_t> idLo(n), idHi(n);
    for (std::size_t p = 0; p < n; ++p) {
        idLo[p] = static_cast<std::int32_t>(static_cast<std::uint32_t>(pl.id[p]));
        idHi[p] = static_cast<std::int32_t>(static_cast<std::uint32_t>(pl.id[p] >> 32));
    }
    f.writeI32(group + "/id_lo", idLo, {n});
    f.writeI32(group + "/id_hi", idHi, {n});
    f.writeI32(group + "/species", pl.species, {n});
    f.writeF64(group + "/x", pl.x, {n});
    f.writeF64(group + "/y", pl.y, {n});
    f.writeF64(group + "/growth_age", pl.growthAge, {n});
    f.writeF64(group + "/pool", pl.pool, {n});
    std::vector<std::int32_t> ageMonths(n);
    for (std::size_t p = 0; p < n; ++p) ageMonths[p] = static_cast<std::int32_t>(s.month - pl.birthMonth[p]);
    f.writeI32(group + "/age_months", ageMonths, {n});
    f.writeI32(group + "/root_ix", pl.rootIx, {n});
    f.writeI32(group + "/root_iy", pl.rootIy, {n});
    f.writeF32(group + "/vigour", pl.vigour, {n});
    f.writeF32(group + "/sun", pl.sun, {n});
    f.writeF32(group + "/water", pl.water, {n});
    // Height and radius are kept bit-exactly (they follow growth age, but only in growth
    // months, so they cannot be recomputed from it for every plant).
    f.writeF64(group + "/height", pl.height, {n});
    f.writeF64(group + "/radius", pl.radius, {n});
    for (std::size_t g = 0; g < s.periods(); ++g) {
        const hsize_t dims[2] = {static_cast<hsize_t>(s.H), static_cast<hsize_t>(s.W)};
        std::vector<float> sun(s.cellCount()), water(s.cellCount());
        for (std::size_t c = 0; c < s.cellCount(); ++c) {
            sun[c] = s.deficitAt(c, g)[0];
            water[c] = s.deficitAt(c, g)[1];
        }
        f.writeF32(group + "/deficit_sun_" + std::to_string(g), sun, {dims[0], dims[1]});
        f.writeF32(group + "/deficit_water_" + std::to_string(g), water, {dims[0], dims[1]});
    }
}

void Simulation::loadState(const h5::File& f, const std::string& group) {
    Impl& s = *impl_;
    const std::string where = f.path() + ": " + group;
    if (!f.exists(group)) throw IoError(where + ": no simulation state");
    const std::string fp = f.attrString(group, "fingerprint");
    if (fp != hex64(fingerprint()))
        throw IoError(where + ": the checkpoint belongs to another run (different inputs, biome, area, seed or model "
                              "parameters; fingerprint " + fp + ", this run " + hex64(fingerprint()) + ")");
    PlantStore pl;
    const auto idLo = f.readI32(group + "/id_lo");
    const auto idHi = f.readI32(group + "/id_hi");
    pl.species = f.readI32(group + "/species");
    pl.x = f.readF64(group + "/x");
    pl.y = f.readF64(group + "/y");
    pl.growthAge = f.readF64(group + "/growth_age");
    pl.pool = f.readF64(group + "/pool");
    pl.birthMonth = f.readI32(group + "/age_months");  // ages here; birth months once the month is read, below
    pl.rootIx = f.readI32(group + "/root_ix");
    pl.rootIy = f.readI32(group + "/root_iy");
    pl.vigour = f.readF32(group + "/vigour");
    pl.sun = f.readF32(group + "/sun");
    pl.water = f.readF32(group + "/water");
    pl.height = f.readF64(group + "/height");
    pl.radius = f.readF64(group + "/radius");
    const std::size_t n = pl.species.size();
    for (std::size_t len : {idLo.size(), idHi.size(), pl.x.size(), pl.y.size(), pl.growthAge.size(), pl.pool.size(),
                            pl.birthMonth.size(), pl.rootIx.size(), pl.rootIy.size(), pl.vigour.size(), pl.sun.size(),
                            pl.water.size(), pl.height.size(), pl.radius.size()})
        if (len != n) throw IoError(where + ": plant arrays differ in length");
    // Rebuild the derived arrays exactly as addPlant does.
    const Grid<float>& g = s.abio.slopeDeg;
    for (std::size_t p = 0; p < n; ++p) {
        if (pl.species[p] < 0 || static_cast<std::size_t>(pl.species[p]) >= s.spc.size() || !s.seedProb.inside(pl.rootIx[p], pl.rootIy[p]))
            throw IoError(where + ": plant " + std::to_string(p) + " has a bad species or root cell");
        pl.id.push_back((static_cast<std::uint64_t>(static_cast<std::uint32_t>(idHi[p])) << 32) |
                        static_cast<std::uint32_t>(idLo[p]));
        pl.groundZ.push_back(s.abio.elevationM.sampleBilinear(pl.x[p], pl.y[p]));
        const int cx = std::clamp(g.cellX(pl.x[p]), 0, g.width() - 1), cy = std::clamp(g.cellY(pl.y[p]), 0, g.height() - 1);
        pl.coarse.push_back(static_cast<std::uint32_t>(g.index(cx, cy)));
        pl.canopyLimit.push_back(s.canopyLimitAt(pl.x[p], pl.y[p]));
    }
    std::vector<float> deficit(s.deficit.size());
    for (std::size_t gi = 0; gi < s.periods(); ++gi) {
        auto ds = f.readF32(group + "/deficit_sun_" + std::to_string(gi));
        auto dw = f.readF32(group + "/deficit_water_" + std::to_string(gi));
        if (ds.size() != s.cellCount() || dw.size() != s.cellCount()) throw IoError(where + ": accumulator size mismatch");
        for (std::size_t c = 0; c < s.cellCount(); ++c) {
            deficit[(c * s.periods() + gi) * 2] = ds[c];
            deficit[(c * s.periods() + gi) * 2 + 1] = dw[c];
        }
    }
    s.deficit = std::move(deficit);
    s.pl = std::move(pl);
    s.fpRange.clear();  // footprints are recomputed (buildBands)
    s.fate.assign(s.pl.size(), 0);
    s.deadPending = 0;
    s.layoutReusable = false;
    s.month = f.attrInt(group, "months_done");
    for (std::int32_t& b : s.pl.birthMonth) b = static_cast<std::int32_t>(s.month - b);
    s.nextId = std::stoull(f.attrString(group, "next_id"), nullptr, 16);
    s.windowMask = static_cast<std::uint32_t>(f.attrInt(group, "window_mask"));
    s.counters.plantMonths = f.attrInt(group, "plant_months");
    s.counters.plantCellMonths = f.hasAttr(group, "plant_cell_months") ? f.attrInt(group, "plant_cell_months") : 0;
    s.counters.germinated = f.attrInt(group, "germinated");
    s.counters.diedBackgroundOrStress = f.attrInt(group, "died_background_or_stress");
    s.counters.diedAtCanopy = f.attrInt(group, "died_at_canopy");
    s.counters.diedDominated = f.hasAttr(group, "died_dominated") ? f.attrInt(group, "died_dominated") : 0;
    s.droppedInitial = static_cast<std::size_t>(f.attrInt(group, "dropped_initial"));
}

std::size_t Simulation::bytesPerCell() const {
    return sizeof(float) /*canopy transmission*/ + sizeof(std::uint8_t) /*canopy trees*/ + sizeof(std::uint16_t) /*occupants*/ +
           sizeof(float) /*seed probability*/ + sizeof(std::uint16_t) /*package*/ + impl_->periods() * 2 * sizeof(float);
}

std::size_t Simulation::bytesPerPlant() const {
    // State arrays plus the per-plant scratch: row and band bounds, the footprint's radius
    // range, slot starts, about 1.1 band slots of partials and band entries, the span pool
    // (live and dead spans; a repack briefly holds a second, live-only copy), order and
    // radix scratch, fate and the slots' dead marks. Per living plant: the dead still in the
    // store (at most an eighth of it, compactIfDue) are counted in.
    const Impl& s = *impl_;
    const std::size_t n = s.pl.size(), alive = n - s.deadPending;
    if (alive == 0) return 0;
    const double spans = s.fpRange.size() == n ? static_cast<double>(s.footprint.size()) : static_cast<double>(alive);
    const std::size_t perStored = impl_->pl.bytesPerPlant() + sizeof(Impl::PlantBounds) + sizeof(Impl::RadiusRangeF) + sizeof(std::uint32_t) +
                                  static_cast<std::size_t>(1.1 * (2 * sizeof(double) + sizeof(std::int32_t) + sizeof(BandEntry) + 1)) +
                                  4 * sizeof(std::uint32_t) + 1;
    return static_cast<std::size_t>((static_cast<double>(perStored) * n + spans * sizeof(Span)) / alive + 0.5);
}

}  // namespace eco::sim
