// The EcoMod model (Zamuda & Brest): species parameters with their defaults, the suitability
// maps, and the yearly step (seeding, growth with domination, elimination). See ecomod.h and
// docs/ecomod.md.
#include "ecomod.h"
#include "state_hash.h"

#include <omp.h>

#ifdef __x86_64__
#include <immintrin.h>
#endif

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>

#include "abiotics.h"
#include "cpu.h"
#include "error.h"
#include "factors.h"
#include "rng.h"
#include "text_format.h"
#include "simulator.h"
#include "simulator_impl.h"  // kParallelPlants (setParallelThresholds)

namespace eco::sim {
namespace {

constexpr double kInfinity = std::numeric_limits<double>::infinity();

// Stream tags of the model's random draws (mixed with seed-independent identifiers).
constexpr std::uint64_t kStreamSeeding = 0x65636F2D73656564ull;   // per (year, species)
constexpr std::uint64_t kStreamDeathAge = 0x65636F2D64656174ull;  // per plant id
constexpr std::uint64_t kStreamLives = 0x65636F2D6C697665ull;      // per plant id: its dominated years survived

std::string num(double v) { return formatNumber(v, 6); }

// A uniform double in [0, 1) for (seed, stream, counter): SplitMix64's finaliser over the
// three, a counter-based draw as Philox but a few times cheaper, for the per-tree draws of
// the yearly step (its cost is a large share of a tree-year).
inline double unitDraw(std::uint64_t seed, std::uint64_t stream, std::uint64_t counter) {
    return static_cast<double>(mixStream(mixStream(seed, stream), counter) >> 11) * 0x1.0p-53;
}

// Sequential draws of one (seed, stream) by unitDraw.
class CounterDraws {
public:
    CounterDraws(std::uint64_t seed, std::uint64_t stream) : key_(mixStream(seed, stream)) {}
    double uniform() { return static_cast<double>(mixStream(key_, counter_++) >> 11) * 0x1.0p-53; }
    double uniform(double lo, double hi) { return lo + (hi - lo) * uniform(); }
    std::uint32_t below(std::uint32_t n) {
        return static_cast<std::uint32_t>((static_cast<std::uint64_t>(mixStream(key_, counter_++) >> 32) * n) >> 32);
    }

private:
    std::uint64_t key_, counter_ = 0;
};

// The yearly step's loops have little work per tree (tens of nanoseconds): a parallel region
// pays off only on large scenes, and on a loaded machine each fork and join may wait for a
// descheduled thread (milliseconds). They go parallel above this many times the simulator's
// plant threshold (setParallelThresholds; 0 in the tests, to exercise the parallel paths).
constexpr std::size_t kEcoModParallelFactor = 64;
bool parallelLoop(std::size_t items) { return items > kParallelPlants * kEcoModParallelFactor; }

double given(double v, double fallback) { return std::isnan(v) ? fallback : v; }

}  // namespace

EcoModSpeciesParams resolveEcoModSpecies(const Species& s, const std::string& source) {
    const EcoModSpecies& e = s.ecomod;
    EcoModSpeciesParams p;
    p.maxAgeYears = given(e.maxAgeYears, s.maxAgeYears);
    p.maturityAgeYears = given(e.maturityAgeYears, 0.1 * p.maxAgeYears);
    p.fullGrownAgeYears = given(e.fullGrownAgeYears, 0.5 * p.maxAgeYears);
    p.fullHeightM = given(e.fullHeightM, s.maxHeightM);
    p.matureHeightM = given(e.matureHeightM, 0.6 * p.fullHeightM);
    p.persistence = given(e.persistence, p.maxAgeYears / (p.maxAgeYears + 50.0));
    p.seedsPerYear = given(e.seedsPerYear, 2.0);
    p.germination = given(e.germination, 0.5);
    p.nearProbability = given(e.nearProbability, 0.9);
    p.dispersalRadiusM = given(e.dispersalRadiusM, std::max(1.0, 2.0 * s.allometry.crownRadiusM(p.fullHeightM)));
    p.immigrantsPerHaYear = given(e.immigrantsPerHaYear, 0.1);
    p.dominatedSurvival = given(e.dominatedSurvival, p.persistence);
    p.dominatedGrowth = given(e.dominatedGrowth, 0.0);
    p.elevationOpt = given(e.elevationOpt, 0.5);
    p.elevationTol = given(e.elevationTol, 0.5);
    p.elevationHarm = given(e.elevationHarm, 1.0);
    // From the species' responses of Eq. 1: optimum c, full suitability within r / 4, none from r on.
    auto fromResponse = [&](Factor f, double eOpt, double eTol, double eHarm, double& opt, double& tol, double& harm) {
        const Response& r = s.response(f);
        if (r.isIndifferent()) {  // an optional factor the species does not respond to
            opt = given(eOpt, 0.0);
            tol = given(eTol, kInfinity);
            harm = given(eHarm, 0.0);
            return;
        }
        opt = given(eOpt, r.c);
        tol = given(eTol, r.r / 4.0);
        harm = given(eHarm, 1.0 / r.r);
    };
    fromResponse(Factor::Moisture, e.moistureOpt, e.moistureTol, e.moistureHarm, p.moistureOpt, p.moistureTol, p.moistureHarm);
    fromResponse(Factor::Sun, e.sunOpt, e.sunTol, e.sunHarm, p.sunOpt, p.sunTol, p.sunHarm);
    fromResponse(Factor::Wind, e.windOpt, e.windTol, e.windHarm, p.windOpt, p.windTol, p.windHarm);
    {
        // Zero suitability at the steepest slope the species' response tolerates (c + r, at most 90 degrees).
        const Response& r = s.response(Factor::Slope);
        double limitDeg = r.isIndifferent() ? 90.0 : std::min(90.0, r.c + r.r);
        if (!(limitDeg > 0)) limitDeg = 90.0;
        p.slopeHarm = given(e.slopeHarm, 1.0 / (1.0 - std::cos(limitDeg * kPi / 180.0)));
    }
    const std::string where = source + ": species '" + s.name + "': ecomod: ";
    if (!(p.maturityAgeYears < p.fullGrownAgeYears))
        throw ValidationError(where + "maturity_age_years " + num(p.maturityAgeYears) + " must be less than full_grown_age_years " +
                              num(p.fullGrownAgeYears));
    if (!(p.fullGrownAgeYears <= p.maxAgeYears))
        throw ValidationError(where + "full_grown_age_years " + num(p.fullGrownAgeYears) + " must not exceed max_age_years " +
                              num(p.maxAgeYears));
    if (!(p.matureHeightM <= p.fullHeightM))
        throw ValidationError(where + "mature_height_m " + num(p.matureHeightM) + " must not exceed full_height_m " +
                              num(p.fullHeightM));
    return p;
}

double ecomodPolylineHeightM(const EcoModSpeciesParams& p, double ageYears) {
    if (ageYears <= 0) return 0.0;
    if (ageYears < p.maturityAgeYears) return p.matureHeightM * ageYears / p.maturityAgeYears;
    if (ageYears < p.fullGrownAgeYears)
        return p.matureHeightM + (p.fullHeightM - p.matureHeightM) * (ageYears - p.maturityAgeYears) /
                                     (p.fullGrownAgeYears - p.maturityAgeYears);
    return p.fullHeightM;
}

double ecomodPolylineAgeYears(const EcoModSpeciesParams& p, double heightM) {
    if (heightM <= 0) return 0.0;
    if (heightM >= p.fullHeightM) return p.fullGrownAgeYears;
    if (heightM < p.matureHeightM) return p.maturityAgeYears * heightM / p.matureHeightM;
    if (p.fullHeightM <= p.matureHeightM) return p.maturityAgeYears;
    return p.maturityAgeYears +
           (p.fullGrownAgeYears - p.maturityAgeYears) * (heightM - p.matureHeightM) / (p.fullHeightM - p.matureHeightM);
}

double ecomodDeviationSuitability(double x, double opt, double tol, double harm) {
    const double d = std::fabs(x - opt);
    if (d <= tol) return 1.0;
    return 1.0 - std::min(1.0, d * harm);
}

double ecomodSlopeSuitability(double slopeDeg, double harm) {
    const double s = harm * (1.0 - std::cos(slopeDeg * kPi / 180.0));
    return std::max(0.0, 1.0 - s * s);
}

// ====================================================================== the engine

struct EcoModel::Impl {
    SimParams params;
    std::uint64_t seed = 0;
    Biome biome;
    std::vector<EcoModSpeciesParams> sp;
    std::vector<double> logSurvival;  // per species: log(dominated_survival) (drawLives)
    SimArea area;
    Grid<float> geom;              // abiotics cells covering the area (values unused)
    std::vector<float> suit;       // [species][cell of geom]: v
    std::vector<float> cellSun, cellMoisture;  // annual, per cell of geom (plants' sunShare, waterShare)
    Grid<float> elevation;         // whole abiotics elevation (ground z)
    std::vector<Plant> canopy;     // relevant static canopy trees
    std::vector<float> canopyV;    // their suitability
    // Disturbance (sim/disturbance.h): the settings, the events so far, and the event ground:
    // the abiotics cells of geom (elevation, wind exposure, each month's moisture).
    DisturbanceSettings disturbance;
    bool disturbanceOn = false;
    std::vector<DisturbanceRecord> disturbanceEvents;
    Grid<float> siteElevation, siteWind;
    std::vector<Grid<float>> siteMoisture;  // 12 months
    std::vector<double> fireTolerance;      // per species
    double hRef = 1.0;             // tallest full height of the biome: h / hRef in [0, 1]
    double areaHa = 0;
    std::uint64_t fingerprintValue = 0;

    // The trees (structure of arrays; creation order).
    std::vector<std::uint64_t> id;
    std::vector<std::int32_t> species;
    std::vector<double> x, y, height, radius, growthAge, deathAge;  // ground z: from `elevation` when written
    std::vector<std::int32_t> age;
    std::vector<float> v;
    // The dominated years each tree survives from now on (kInfiniteLives: every one): drawn
    // once at its creation (drawLives), one spent in each year it is dominated; it dies in a
    // dominated year with none left. The same law as a survival draw of probability
    // dominated_survival in each dominated year (geometric), without a draw per year.
    static constexpr std::int32_t kInfiniteLives = 1 << 30;
    std::vector<std::int32_t> lives;

    int year = 0;
    std::uint64_t nextId = 1;
    SimCounters counters;
    std::size_t droppedInitial = 0;

    // The domination test's memory, a cache that never changes a result: per tree, the tree
    // (index) or canopy tree (kWitnessCanopy | its index) that dominated it last time, or
    // kNoWitness. Kept in step with the store by push and compact.
    static constexpr std::uint32_t kNoWitness = 0xFFFFFFFFu, kWitnessCanopy = 0x80000000u;
    // A dozer (see Dozer) as witness: kWitnessDozer | its index (store indices stay below it).
    static constexpr std::uint32_t kWitnessDozer = 0x40000000u, kDozerMask = kWitnessDozer - 1;
    static bool isStoreCode(std::uint32_t q) { return q < kWitnessDozer; }
    static bool isDozerCode(std::uint32_t q) { return q != kNoWitness && (q & (kWitnessCanopy | kWitnessDozer)) == kWitnessDozer; }
    std::vector<std::uint32_t> witness;
    // Per tree, also a cache: 1 when it was dominated last year without growing (its
    // position, crown and ability as before) and no tree shrank; while its witness lives
    // (witness[p] != kNoWitness: a dead witness is forgotten when the store is renumbered),
    // the witness still dominates it (abilities and crowns never fall, places never move),
    // so testAble takes it as dominated without testing. Kept in step with the store.
    std::vector<std::uint8_t> sure;
    // And a fourth: per tree, its level and bucket in the grids (kLevelShift: level in the top
    // bits) while the grids' base spacing (gridBase) and its crown are as when buildGrids
    // computed them, else kNoKey; per canopy tree the same (canopyKey). Kept in step with the store.
    static constexpr std::uint32_t kNoKey = 0xFFFFFFFFu;
    static constexpr int kLevelShift = 27;
    std::vector<std::uint32_t> gridKey, canopyKey;
    double gridBase = 0;  // the base of the keys (0: none yet)
    EcoModel::CacheCounts cacheCounts;  // how often the caches served (diagnostic)
    // A third cache, for the trees of ability 0 (the year's new seedlings, mostly): per cell of
    // kCoverCellM metres over the area, the last dominator a search found for such a tree
    // standing in it (its id, or kCoverCanopy | canopy index; 0: none), tried before a search
    // when the tree's own witness fails. Ids, not store indices: no renumbering between years;
    // a dead or shrunk guess fails its test (found by id, its entry re-checked), and no result
    // depends on it (the test's outcome is the existence of a dominator).
    static constexpr double kCoverCellM = 2.0;
    static constexpr std::uint64_t kCoverCanopy = 1ull << 63;
    std::vector<std::uint64_t> coverGuess;
    int coverW = 0, coverH = 0;
    std::size_t coverCell(double px, double py) const {
        const int cx = std::clamp(static_cast<int>((px - area.x0) * (1.0 / kCoverCellM)), 0, coverW - 1);
        const int cy = std::clamp(static_cast<int>((py - area.y0) * (1.0 / kCoverCellM)), 0, coverH - 1);
        return static_cast<std::size_t>(cy) * static_cast<std::size_t>(coverW) + static_cast<std::size_t>(cx);
    }

    // Scratch of the step, kept between years (no allocation per year once grown).
    struct Level {
        double bucketM = 1, inverseM = 1;
        double maxAbility = -1;  // of its trees (-1: none): a tree at least this able skips the level
        double maxRadius = 0;    // of its trees
        int bw = 1, bh = 1;
        std::size_t first = 0;  // its first bucket in `start`
    };
    // The buckets of level `lv` that a tree at offset (ox, oy) from the area's corner with crown
    // radius `r` may overlap (every tree of the level has a radius <= maxRadius). Bucket ranges by
    // truncation: exact for the non-negative offsets, and a negative one clamps to bucket 0 as
    // its floor would.
    struct BucketBox {
        int bx0, bx1, by0, by1;
    };
    static BucketBox bucketBox(const Level& lv, double ox, double oy, double r) {
        const double reach = r + lv.maxRadius;
        return {std::clamp(static_cast<int>((ox - reach) * lv.inverseM), 0, lv.bw - 1),
                std::clamp(static_cast<int>((ox + reach) * lv.inverseM), 0, lv.bw - 1),
                std::clamp(static_cast<int>((oy - reach) * lv.inverseM), 0, lv.bh - 1),
                std::clamp(static_cast<int>((oy + reach) * lv.inverseM), 0, lv.bh - 1)};
    }
    struct Entry {  // a tree or canopy tree in bucket order: position, crown radius, ability
        double x, y, r, a;
    };
    std::vector<double> ability;     // per tree, then per canopy tree (the store's order)
    std::vector<std::uint8_t> fate;  // 0 alive, 1 natural death, 3 disturbance (compact's input)
    std::vector<Level> levels;
    std::vector<Level> allLevels;  // every level's geometry at gridBase (maxAbility -1, maxRadius 0)
    bool keysUsable = false;       // the buckets fit below 2^kLevelShift (else no key is kept)
    std::vector<std::uint8_t> levelOf, dominated;  // buildGrids: each able tree's level
    // The able (ability > 0, the only possible dominators): their store indices (n + c for
    // canopy tree c), their buckets; `slot` maps a store index to its place in `packed`.
    // `able` holds ableN entries (a buffer that never shrinks: no refill of its tail each year).
    std::vector<std::uint32_t> able, bucket, start, packedItem, slot, newIndex, fixup;
    std::size_t ableN = 0;
    std::size_t rated = 0;  // trees whose ability seedYear computed (those before the year's new ones)
    std::vector<Entry> ableEntry;   // buildGrids: the able's entries in `able` order
    std::size_t searchN = 0;        // the store's size when the grids were built (store index < searchN, else canopy)
    int maxLevel = 0;               // the grids' top level
    bool anyShrunk = false;         // growStore: a tree whose crown or height fell (an initial plant above its polyline)
    std::vector<Entry> packed;      // the able in bucket order
    // The same in four arrays (x, y, r, a), for the AVX2 search's four entries at a time;
    // three entries of padding past the last (never read as a find: the runs are masked).
    std::vector<double> packedX, packedY, packedR, packedA;
    struct Parent {  // a parent's place, and itself as a witness (tree index or kWitnessCanopy | canopy index)
        double x, y;
        std::uint32_t self;
    };
    std::vector<std::vector<Parent>> parentsOf;  // per species (seedYear)
    struct Seed {  // a seed that reached the area: its place, its cell, its establishment draw, its parent
        double x, y, draw;
        std::uint32_t cell, parent;
    };
    struct Sapling {  // an established seed: its place, the suitability there, its parent (kNoWitness: none)
        double x, y;
        float v;
        std::uint32_t parent;
    };
    // Sleeping seedlings, set aside from the store's yearly passes (docs/ecomod.md "Speed"): a
    // tree of height and crown 0 whose species gains no growth age when dominated, found
    // dominated by its witness W, stays dominated while W lives with a crown at least as
    // large (its own ability and crown are 0; W's ability stays > 0), so the year of its
    // event (its death, dominated or of age, or its maturity) is known from its lives and
    // ages (planSleep, in closed form: no yearly work). It rejoins the store when it matures (a parent must be in
    // the store's pass of seedYear), when W dies or shrinks and no other tree dominates it
    // (it then grows), and before a disturbance, removeTrees or a checkpoint's arrays need
    // every tree; views that list the trees (plants, census, saveState) merge the two by id,
    // which is creation order, the store's order. Sorted by id; the dead stay as tombstones
    // (event year -1) until they are more than the living.
    enum class Wake : std::uint8_t { DiesDominated, DiesNatural, Matures };
    struct Sleeper {
        std::uint64_t id;
        double x, y, growthAge, deathAge;
        float v;
        std::int32_t species;
        std::int32_t ageBase;  // age = ageBase + years completed (between years), ageBase + Y at the start of year Y
        std::int32_t domDeathYear;  // the year it dies if dominated in every year until then (kNeverYear: never)
        Wake kind;                  // what happens in its event year
    };
    std::vector<Sleeper> sleepers;
    std::vector<std::int32_t> sleepEvent;     // per sleeper: the year of its event, -1 for a tombstone
    std::vector<std::uint32_t> sleepWitness;  // per sleeper: its witness (store index, canopy, or kNoWitness: test it)
    std::size_t sleepersLive = 0;
    struct Woken {  // a tree rejoining the store: its state at the end of a year, its witness (store index after compaction)
        std::uint64_t id;
        std::int32_t species, age;
        double x, y, height, radius, growthAge, deathAge;
        float v;
        std::uint32_t witness;
        std::int32_t lives;
    };
    std::vector<Woken> woken;
    // Dozers: trees of height > 0 set aside from the store's yearly passes, as the sleepers
    // are. A store tree found dominated in a species with dominated_growth 0 neither grows nor
    // changes its crown or ability while dominated, and it stays dominated while its witness
    // W lives (W's ability and crown never fall, places never move; a shrink anywhere drops
    // the witnesses of the store): its next event, its dominated death or its death of age,
    // is known in closed form. Unlike a sleeper it is able (ability > 0): it stays among the
    // dominators of the grids (rateYear lists it, able index n + canopy + d) and can be a
    // witness (kWitnessDozer | d), and a mature one is a parent (seedYear merges the dozers
    // into the store's parents by id). Stored in arrival order (indices stable; tombstones:
    // dozerEvent -1, dropped when they are more than half the living, every code renumbered), with
    // dozerOrder listing them by id. Each year (dozersYear) one pass looks at each dozer's
    // witness and event year; one without a witness is tested, and a free one grows and
    // rejoins the store (woken). Every dozer rejoins the store before a disturbance,
    // removeTrees or forgetCaches (wakeAll).
    struct Dozer {
        std::uint64_t id;
        double x, y, height, radius, growthAge, deathAge, ability;
        float v;
        std::int32_t species;
        std::int32_t ageBase;       // age at the start of year Y: ageBase + Y
        std::int32_t domDeathYear;  // the year it dies if dominated in every year until then (kNeverYear: never)
        bool diesDominated;         // its event: the dominated death (else its death of age)
    };
    std::vector<Dozer> dozers;
    std::vector<std::int32_t> dozerEvent;     // per dozer: the year of its event, -1 for a tombstone
    std::vector<std::uint32_t> dozerWitness;  // per dozer: its witness (a code, kNoWitness: test it)
    std::vector<std::uint32_t> dozerKey;      // per dozer: its grid key (as gridKey)
    std::vector<std::uint32_t> dozerOrder;    // the dozers' indices by id
    std::vector<double> dozerAbility;         // per dozer: its ability (0 for a tombstone), dense for rateYear
    std::vector<std::uint32_t> dozerDue;      // the dozers with work next year (no witness, or their event): dozersFollow, admitDozers
    std::size_t dozersLive = 0;
    bool dozing = true;  // test mode off: no tree dozes
    std::vector<Dozer> newDozers;
    std::vector<std::uint32_t> newDozerWitness, newDozerKey, dozerRemap;
    std::vector<Woken> dozerWoken;
    bool shrunkOutside = false;  // dozersYear: a woken dozer's crown or height fell (growStore's anyShrunk)
    bool dozerAlive(std::uint32_t q) const { return dozerEvent[q & kDozerMask] >= 0; }
    // The event of a dozer dominated from year y0 + 1 on: its dominated death or its death of
    // age, the earlier (the dominated first in a tie, as in growStore).
    std::int32_t planDoze(Dozer& d, int y0) const {
        const std::int64_t natural =
            std::max(static_cast<std::int64_t>(y0) + 1, static_cast<std::int64_t>(std::ceil(d.deathAge)) - 1 - d.ageBase);
        d.diesDominated = d.domDeathYear <= natural;
        return static_cast<std::int32_t>(d.diesDominated ? d.domDeathYear : natural);
    }
    void dozersYear();
    void dozersFollow();
    void admitDozers();
    void dropDozerTombstones();
    // The store's second copy, written by growStore and swapped in (its contents are scratch).
    struct Store {
        std::vector<std::uint64_t> id;
        std::vector<std::int32_t> species, age, lives;
        std::vector<double> x, y, height, radius, growthAge, deathAge;
        std::vector<float> v;
        std::vector<std::uint32_t> witness, gridKey;
        std::vector<std::uint8_t> sure;
        void resize(std::size_t k) {
            gridKey.resize(k);
            id.resize(k);
            for (auto* a : {&species, &age, &lives}) a->resize(k);
            for (auto* a : {&x, &y, &height, &radius, &growthAge, &deathAge}) a->resize(k);
            v.resize(k);
            witness.resize(k);
            sure.resize(k);
        }
    };
    Store spare;
    void swapStore(Store& o) {
        id.swap(o.id);
        species.swap(o.species);
        age.swap(o.age);
        lives.swap(o.lives);
        x.swap(o.x);
        y.swap(o.y);
        height.swap(o.height);
        radius.swap(o.radius);
        growthAge.swap(o.growthAge);
        deathAge.swap(o.deathAge);
        v.swap(o.v);
        witness.swap(o.witness);
        sure.swap(o.sure);
        gridKey.swap(o.gridKey);
    }
    std::vector<std::uint32_t> mergeAt, mergeShift;  // mergeWoken's insertion points, and the shift of each old index
    std::vector<Sleeper> newSleepers;
    std::vector<Sleeper> bornAsleep;  // seedYear: the year's new trees asleep at birth (their witnesses: bornAsleepWitness)
    std::vector<std::uint32_t> bornAsleepWitness;
    std::size_t bornOutside = 0;      // the year's new trees not in the store (asleep, or dead in their first year)
    std::vector<std::pair<std::uint32_t, std::uint32_t>> slowSleepers;  // sleepersYear: (sleeper, its witness before the year)
    // So that a year renumbers only the witnesses that need it: `watched` lists (a superset
    // of) the sleepers whose witness is a store tree or kNoWitness (the others have a canopy
    // witness, which never dies or moves: about three quarters on the demo scenes), in index
    // order, rebuilt when the sleepers' indices change.
    std::vector<std::uint32_t> watched;
    static bool needsWatch(std::uint32_t q) { return q == kNoWitness || !(q & kWitnessCanopy); }
    // And a calendar of the events: per year modulo kCalendarYears, the sleepers (indices)
    // whose event falls in it, so that a year looks only at its own (a stale index, of a
    // tombstone, is dropped when its year comes; one of a later turn stays). Rebuilt with
    // `watched`, cleared with the sleepers.
    static constexpr std::size_t kCalendarYears = 1024;
    bool checkCalendar = false;  // test mode: each year's calendar entry against a scan (cacheCounts.calendarMismatches)
    std::vector<std::vector<std::uint32_t>> calendar;
    void calendarAdd(std::uint32_t i, std::int32_t event) {
        if (calendar.empty()) calendar.resize(kCalendarYears);
        calendar[static_cast<std::size_t>(event) % kCalendarYears].push_back(i);
    }
    void clearCalendar() {
        for (auto& b : calendar) b.clear();
    }
    void rebuildWatched() {
        watched.clear();
        clearCalendar();
        for (std::size_t i = 0; i < sleepers.size(); ++i) {
            if (sleepEvent[i] >= 0 && needsWatch(sleepWitness[i])) watched.push_back(static_cast<std::uint32_t>(i));
            if (sleepEvent[i] >= 0) calendarAdd(static_cast<std::uint32_t>(i), sleepEvent[i]);
        }
    }
    std::vector<std::uint32_t> newSleeperWitness;
    static constexpr std::int32_t kTombstone = -1;  // a dead sleeper's event year (its witness: kWitnessCanopy)
    static constexpr std::int32_t kNeverYear = std::numeric_limits<std::int32_t>::max();
    // The event of a sleeper that lives through year y0 (its age after y0: ageBase + y0 + 1),
    // in closed form: the first later year in which it dies (its dominated years run out, or
    // its death age), or the year before it starts mature, the earliest of them; in a year
    // of several, maturity first, then domination, then age, as in the store's pass.
    void planSleep(Sleeper& s, std::int32_t& event, int y0) const {
        const EcoModSpeciesParams& ps = sp[static_cast<std::size_t>(s.species)];
        // ageBase + y is whole: ageBase + y >= t_m from y = ceil(t_m) - ageBase on, and
        // ageBase + y + 1 >= death age from y = ceil(death age) - 1 - ageBase on.
        const std::int64_t first = static_cast<std::int64_t>(y0) + 1;
        const std::int64_t mature = std::max(first, static_cast<std::int64_t>(std::ceil(ps.maturityAgeYears)) - s.ageBase);
        const std::int64_t natural = std::max(first, static_cast<std::int64_t>(std::ceil(s.deathAge)) - 1 - s.ageBase);
        const std::int64_t dominated = s.domDeathYear;
        if (mature <= dominated && mature <= natural) {
            s.kind = Wake::Matures;
            event = static_cast<std::int32_t>(mature - 1);
        } else if (dominated <= natural) {
            s.kind = Wake::DiesDominated;
            event = static_cast<std::int32_t>(dominated);
        } else {
            s.kind = Wake::DiesNatural;
            event = static_cast<std::int32_t>(natural);
        }
    }
    // A sleeper's dominated years left (lives) when it has been dominated through the year
    // before `yearsCompleted`.
    static std::int32_t livesAfter(const Sleeper& s, int yearsCompleted) {
        return s.domDeathYear == kNeverYear ? kInfiniteLives : s.domDeathYear - yearsCompleted;
    }
    static std::int32_t domDeathYearOf(std::int32_t livesLeft, int yearDone) {  // lives left after year `yearDone`
        return livesLeft >= kInfiniteLives ? kNeverYear : yearDone + livesLeft + 1;
    }
    Woken wake(const Sleeper& s, int yearsCompleted, std::uint32_t w) const {
        return Woken{s.id,        s.species, s.ageBase + yearsCompleted, s.x, s.y, 0.0, 0.0, s.growthAge, s.deathAge, s.v, w,
                     livesAfter(s, yearsCompleted)};
    }
    // Visits every tree in creation order (the store's trees and the sleepers, merged by id)
    // as f(id, species, x, y, height, radius, growthAge, age, deathAge, v, lives).
    template <class F>
    void forEachTree(F&& f) const {
        const std::size_t n = size(), k = sleepers.size(), nd = dozerOrder.size();
        constexpr std::uint64_t kNone = std::numeric_limits<std::uint64_t>::max();
        std::size_t a = 0, b = 0, c = 0;
        for (;;) {
            while (b < k && sleepEvent[b] < 0) ++b;
            while (c < nd && dozerEvent[dozerOrder[c]] < 0) ++c;
            const std::uint64_t ia = a < n ? id[a] : kNone, ib = b < k ? sleepers[b].id : kNone,
                                ic = c < nd ? dozers[dozerOrder[c]].id : kNone;
            if (ia == kNone && ib == kNone && ic == kNone) break;
            if (ia < ib && ia < ic) {
                f(id[a], species[a], x[a], y[a], height[a], radius[a], growthAge[a], age[a], deathAge[a], v[a], lives[a]);
                ++a;
            } else if (ib < ic) {
                const Sleeper& s = sleepers[b];
                f(s.id, s.species, s.x, s.y, 0.0, 0.0, s.growthAge, s.ageBase + year, s.deathAge, s.v, livesAfter(s, year));
                ++b;
            } else {
                const Dozer& z = dozers[dozerOrder[c]];
                f(z.id, z.species, z.x, z.y, z.height, z.radius, z.growthAge, z.ageBase + year, z.deathAge, z.v,
                  z.domDeathYear == kNeverYear ? kInfiniteLives : z.domDeathYear - year);
                ++c;
            }
        }
    }
    void mergeWoken();                    // woken (sorted by id) into the store
    void wakeAll(int yearsCompleted);     // every sleeper into the store
    std::vector<std::vector<Seed>> seedsOf;       // per species (seedYear)
    std::vector<std::vector<Sapling>> born;       // per species (seedYear)
    std::vector<std::int64_t> attempts;

    // geom's cell of (px, py), clamped to geom: Grid::cellX / cellY's quotient truncated
    // instead of floored (no floor call); the same cell, as the two differ only below 0,
    // where both clamp to 0.
    std::size_t cellOf(double px, double py) const {
        const int ix = std::clamp(static_cast<int>((px - geom.originX()) / geom.cellSizeM()), 0, geom.width() - 1);
        const int iy = std::clamp(static_cast<int>((py - geom.originY()) / geom.cellSizeM()), 0, geom.height() - 1);
        return geom.index(ix, iy);
    }
    float suitAt(int s, double px, double py) const {
        return suit[static_cast<std::size_t>(s) * geom.size() + cellOf(px, py)];
    }
    bool inArea(double px, double py) const { return px >= area.x0 && px < area.x1 && py >= area.y0 && py < area.y1; }
    double crown(int s, double h) const {
        return h > 0 ? biome.species[static_cast<std::size_t>(s)].allometry.crownRadiusM(h) : 0.0;
    }
    // Per species, height and crown at the whole growth ages 0, 1, ..., up to the first at or
    // past t_a (a tree born in the run has a whole growth age unless dominated_growth is
    // fractional): the polyline's and the allometry's values, computed once, so that a
    // growing tree's year needs no exp or log. growthShape gives the same numbers as the two
    // functions for any growth age.
    struct Shape {
        double h, r;
    };
    std::vector<std::vector<Shape>> shapeOf;
    void buildShapes() {
        shapeOf.assign(sp.size(), {});
        for (std::size_t s = 0; s < sp.size(); ++s) {
            const double last = std::min(std::ceil(sp[s].fullGrownAgeYears), 100000.0);
            for (double g = 0; g <= last; g += 1.0) {
                const double h = ecomodPolylineHeightM(sp[s], g);
                shapeOf[s].push_back({h, crown(static_cast<int>(s), h)});
            }
        }
    }
    Shape growthShape(int s, double g) const {
        const std::vector<Shape>& t = shapeOf[static_cast<std::size_t>(s)];
        if (g >= 0 && g < static_cast<double>(t.size())) {
            const std::size_t i = static_cast<std::size_t>(g);
            if (static_cast<double>(i) == g) return t[i];
        }
        const double h = ecomodPolylineHeightM(sp[static_cast<std::size_t>(s)], g);
        return {h, crown(s, h)};
    }
    double drawDeathAge(int s, std::uint64_t plantId, double minAge) const {
        const EcoModSpeciesParams& p = sp[static_cast<std::size_t>(s)];
        const double lo = std::max(p.fullGrownAgeYears, minAge), hi = std::max(p.maxAgeYears, lo);
        return lo + (hi - lo) * unitDraw(seed, kStreamDeathAge, plantId);
    }
    // K with P(K >= k) = dominated_survival^k: floor(log u / log survival) for u uniform in (0, 1].
    std::int32_t drawLives(int s, std::uint64_t plantId) const {
        const double survival = sp[static_cast<std::size_t>(s)].dominatedSurvival;
        if (!(survival < 1.0)) return kInfiniteLives;
        if (!(survival > 0.0)) return 0;
        const double u = 1.0 - unitDraw(seed, kStreamLives, plantId);  // (0, 1]
        const double k = std::floor(std::log(u) / logSurvival[static_cast<std::size_t>(s)]);
        return k >= static_cast<double>(kInfiniteLives) ? kInfiniteLives : static_cast<std::int32_t>(k);
    }
    void push(std::uint64_t pid, int s, double px, double py, double h, double gAge, int ageYears, double dAge) {
        push(pid, s, px, py, h, gAge, ageYears, dAge, suitAt(s, px, py));
    }
    // `guess`: a first candidate for the tree's witness (a cache: no result depends on it).
    void push(std::uint64_t pid, int s, double px, double py, double h, double gAge, int ageYears, double dAge, float vv,
              std::uint32_t guess = kNoWitness) {
        id.push_back(pid);
        species.push_back(s);
        x.push_back(px);
        y.push_back(py);
        height.push_back(h);
        radius.push_back(crown(s, h));
        growthAge.push_back(gAge);
        age.push_back(ageYears);
        deathAge.push_back(dAge);
        v.push_back(vv);
        witness.push_back(guess);
        sure.push_back(0);
        gridKey.push_back(kNoKey);
        lives.push_back(drawLives(s, pid));
    }
    // The same as push, into place t of a store already resized (truncate) to hold it.
    void setAt(std::size_t t, std::uint64_t pid, int s, double px, double py, double h, double gAge, int ageYears, double dAge,
               float vv, std::uint32_t guess) {
        id[t] = pid;
        species[t] = s;
        x[t] = px;
        y[t] = py;
        height[t] = h;
        radius[t] = crown(s, h);
        growthAge[t] = gAge;
        age[t] = ageYears;
        deathAge[t] = dAge;
        v[t] = vv;
        witness[t] = guess;
        sure[t] = 0;
        gridKey[t] = kNoKey;
        lives[t] = drawLives(s, pid);
    }
    std::size_t size() const { return id.size(); }
    void truncate(std::size_t w) {  // the store keeps its first w trees (or grows to w, for setAt)
        for (auto* a : {&x, &y, &height, &radius, &growthAge, &deathAge}) a->resize(w);
        id.resize(w);
        species.resize(w);
        age.resize(w);
        v.resize(w);
        witness.resize(w);
        sure.resize(w);
        lives.resize(w);
        gridKey.resize(w);
    }
    void compact();
    void seedYear();
    // growYear's phases, in order (see growYear).
    void growYear();
    void rateYear();
    void buildGrids();
    bool isDominated(const Entry& me, std::uint32_t& wit) const;
#ifdef ECO_HAVE_AVX2_KERNELS
    ECO_TARGET_AVX2 bool searchAvx2(const Entry& me, std::uint32_t& wit) const;
#endif
    void testAble();
    void testUnable();
    bool testPoint(const Entry& me, std::uint32_t& wit);
    void growStore();
    void sleepersYear();
    void sleepersFollow();
    void admitSleepers();
    void dropTombstones();
    // A witness's store index after growStore's compaction (kNoWitness if it died, or if any
    // tree shrank: then every witness is tested again).
    // A dozer witness: itself while it dozes (dozers never shrink), else kNoWitness.
    std::uint32_t follow(std::uint32_t q) const {
        if (q == kNoWitness || (q & kWitnessCanopy)) return q;
        if (!isStoreCode(q)) return dozerAlive(q) ? q : kNoWitness;
        return anyShrunk ? kNoWitness : newIndex[q];
    }
    // A witness code's index in `ability` and `slot` (store, then canopy, then dozers), and back.
    std::size_t codeIndex(std::uint32_t w) const {
        if (w & kWitnessCanopy) return searchN + (w & ~kWitnessCanopy);
        if (w & kWitnessDozer) return searchN + canopy.size() + (w & kDozerMask);
        return w;
    }
    std::uint32_t codeOf(std::size_t e) const {
        const std::size_t n = searchN, nc = canopy.size();
        if (e < n) return static_cast<std::uint32_t>(e);
        if (e < n + nc) return kWitnessCanopy | static_cast<std::uint32_t>(e - n);
        return kWitnessDozer | static_cast<std::uint32_t>(e - n - nc);
    }
    void disturbYear();
    std::uint64_t computeFingerprint() const;
};

void EcoModel::Impl::compact() {
    const std::size_t n = size();
    newIndex.resize(n);
    // Every new index first: a witness may stand later in the store than its tree (reading
    // growStore's stale newIndex there would give a wrong tree, or a dozer's code).
    for (std::size_t p = 0, k = 0; p < n; ++p) newIndex[p] = fate[p] != 0 ? kNoWitness : static_cast<std::uint32_t>(k++);
    std::size_t w = 0;
    for (std::size_t p = 0; p < n; ++p) {
        if (fate[p] != 0) continue;
        if (w != p) {
            id[w] = id[p];
            species[w] = species[p];
            x[w] = x[p];
            y[w] = y[p];
            height[w] = height[p];
            radius[w] = radius[p];
            growthAge[w] = growthAge[p];
            age[w] = age[p];
            deathAge[w] = deathAge[p];
            v[w] = v[p];
            lives[w] = lives[p];
            gridKey[w] = gridKey[p];
        }
        const std::uint32_t q = witness[p];  // follows its dominator to its new place (or forgets it)
        witness[w] = isStoreCode(q) ? newIndex[q] : q;  // no dozer codes here (compact follows wakeAll)
        sure[w] = sure[p];
        ++w;
    }
    truncate(w);
    fate.assign(w, 0);
}

// Algorithm 2: new trees of every species (species in parallel, each from its own stream;
// appended in species order, so ids do not depend on the schedule).
void EcoModel::Impl::seedYear() {
    const int ns = static_cast<int>(sp.size());
    // Scratch kept between years: cleared, not freed.
    born.resize(static_cast<std::size_t>(ns));
    parentsOf.resize(static_cast<std::size_t>(ns));
    attempts.assign(static_cast<std::size_t>(ns), 0);
    seedsOf.resize(static_cast<std::size_t>(ns));
    for (auto& b : born) b.clear();
    for (auto& pa : parentsOf) pa.clear();
    // Parents: mature trees of each species (the store's order), then its canopy trees. The
    // same pass rates every tree's competitive ability for growYear (heights do not change
    // in between; the year's new trees, appended below, are rated there).
    rated = size();
    if (ability.size() < rated) ability.resize(rated);  // never shrunk (no refill of its tail)
    if (able.size() < rated + 1) able.resize(rated + 1);  // written in place (no push_back per tree), then cut
    std::size_t na = 0;
    // The mature dozers among the store's parents, by id.
    constexpr std::uint64_t kNoId = std::numeric_limits<std::uint64_t>::max();
    std::size_t od = 0;
    std::uint64_t nextDozer = dozerOrder.empty() ? kNoId : dozers[dozerOrder[0]].id;
    auto dozerParents = [&](std::uint64_t upTo) {
        for (; od < dozerOrder.size() && dozers[dozerOrder[od]].id < upTo; ++od) {
            const std::uint32_t d = dozerOrder[od];
            if (dozerEvent[d] < 0) continue;
            const Dozer& z = dozers[d];
            const std::size_t s = static_cast<std::size_t>(z.species);
            if (z.ageBase + year >= sp[s].maturityAgeYears) parentsOf[s].push_back({z.x, z.y, kWitnessDozer | d});
        }
        nextDozer = od < dozerOrder.size() ? dozers[dozerOrder[od]].id : kNoId;
    };
    for (std::size_t t = 0; t < rated; ++t) {
        if (id[t] > nextDozer) dozerParents(id[t]);
        const std::size_t s = static_cast<std::size_t>(species[t]);
        const EcoModSpeciesParams& ps = sp[s];
        const double a = height[t] / hRef * ps.persistence * v[t];
        ability[t] = a;
        able[na] = static_cast<std::uint32_t>(t);
        na += a > 0 ? 1 : 0;
        if (age[t] >= ps.maturityAgeYears) parentsOf[s].push_back({x[t], y[t], static_cast<std::uint32_t>(t)});
    }
    dozerParents(kNoId);
    ableN = na;
    for (std::size_t c = 0; c < canopy.size(); ++c)
        parentsOf[static_cast<std::size_t>(canopy[c].speciesId)].push_back(
            {canopy[c].xM, canopy[c].yM, kWitnessCanopy | static_cast<std::uint32_t>(c)});
    // The canopy's abilities and the grids of the start of the year: the year's new trees
    // (height 0) are never among the able, so they are tested on these as they are born.
    rateYear();
    buildGrids();
#pragma omp parallel for schedule(dynamic, 1) if (parallelLoop(size()))
    for (int s = 0; s < ns; ++s) {
        const EcoModSpeciesParams& p = sp[static_cast<std::size_t>(s)];
        const std::vector<Parent>& parents = parentsOf[static_cast<std::size_t>(s)];
        CounterDraws r(seed, mixStream(mixStream(kStreamSeeding, static_cast<std::uint64_t>(year)), static_cast<std::uint64_t>(s)));
        auto stochasticRound = [&r](double expected) {
            const double whole = std::floor(expected);
            return static_cast<std::int64_t>(whole) + (r.uniform() < expected - whole ? 1 : 0);
        };
        const std::int64_t seeds = stochasticRound(static_cast<double>(parents.size()) * p.seedsPerYear * p.germination);
        const std::int64_t immigrants = stochasticRound(p.immigrantsPerHaYear * areaHa);
        // The draws first (their sequence does not depend on the suitabilities), then the
        // establishment test of each seed, with the suitability of its cell fetched ahead: the
        // map of a species over a large area is beyond the caches, and a seed lands anywhere.
        std::vector<Seed>& cand = seedsOf[static_cast<std::size_t>(s)];
        cand.clear();
        auto establish = [&](double px, double py, std::uint32_t parent) {
            if (!inArea(px, py)) return;  // the seed left the area
            cand.push_back({px, py, r.uniform(), static_cast<std::uint32_t>(cellOf(px, py)), parent});
        };
        auto anywhere = [&] {
            const double px = r.uniform(area.x0, area.x1), py = r.uniform(area.y0, area.y1);
            establish(px, py, kNoWitness);
        };
        for (std::int64_t n = 0; n < seeds; ++n) {
            if (r.uniform() < p.nearProbability) {  // under-dispersion: near a parent of the species
                const auto& parent = parents[r.below(static_cast<std::uint32_t>(parents.size()))];
                const double dist = p.dispersalRadiusM * std::sqrt(r.uniform()), angle = 2 * kPi * r.uniform();
                // The parent is the seedling's first guess of a dominator (it often stands over it).
                establish(parent.x + dist * std::cos(angle), parent.y + dist * std::sin(angle), parent.self);
            } else {
                anywhere();
            }
        }
        for (std::int64_t n = 0; n < immigrants; ++n) anywhere();
        attempts[static_cast<std::size_t>(s)] = seeds + immigrants;
        std::vector<Sapling>& out = born[static_cast<std::size_t>(s)];
        const float* sv = suit.data() + static_cast<std::size_t>(s) * geom.size();
        constexpr std::size_t kAhead = 16;
        for (std::size_t i = 0; i < std::min(kAhead, cand.size()); ++i) __builtin_prefetch(sv + cand[i].cell);
        for (std::size_t i = 0; i < cand.size(); ++i) {
            if (i + kAhead < cand.size()) __builtin_prefetch(sv + cand[i + kAhead].cell);
            const Seed& c = cand[i];
            const float vv = sv[c.cell];
            if (c.draw < vv) out.push_back({c.x, c.y, vv, c.parent});  // germinates only where suitable
        }
    }
    // The new trees in species order, each tested at once on the grids of the start of the
    // year (the new trees are not among the able: height 0). One found dominated that cannot
    // grow while dominated has its first year here, as growStore would give it (its
    // dominated death, its death of age, or its sleep: to bornAsleep, never in the store);
    // the others are appended to the store with their test's outcome (the arrays grown once,
    // not a push per field).
    std::size_t t = size(), added = 0;
    for (const auto& b : born) added += b.size();
    truncate(t + added);
    dominated.resize(t + added);
    bornAsleep.clear();
    bornAsleepWitness.clear();
    bornOutside = 0;
    for (int s = 0; s < ns; ++s) {
        const EcoModSpeciesParams& sps = sp[static_cast<std::size_t>(s)];
        const bool canSleep = sps.dominatedGrowth == 0.0 && 1.0 < sps.maturityAgeYears;
        for (const auto& b : born[static_cast<std::size_t>(s)]) {
            const std::uint64_t pid = nextId++;
            const double dAge = drawDeathAge(s, pid, 0.0);
            std::uint32_t wit = b.parent;
            const bool dom = testPoint(Entry{b.x, b.y, 0.0, 0.0}, wit);
            if (dom && canSleep) {
                ++bornOutside;
                std::int32_t lv = drawLives(s, pid);
                if (lv == 0) {
                    ++counters.diedDominated;  // suffocation in its first year
                    continue;
                }
                if (lv != kInfiniteLives) --lv;
                if (1 >= dAge) {
                    ++counters.diedBackgroundOrStress;
                    continue;
                }
                bornAsleep.push_back(Sleeper{pid, b.x, b.y, 0.0, dAge, b.v, s, -year, domDeathYearOf(lv, year), Wake::DiesDominated});
                bornAsleepWitness.push_back(wit);
                continue;
            }
            setAt(t, pid, s, b.x, b.y, 0.0, 0.0, 0, dAge, b.v, wit);
            dominated[t] = dom ? 1 : 0;
            ++t;
        }
        counters.germinated += static_cast<std::int64_t>(born[static_cast<std::size_t>(s)].size());
    }
    truncate(t);
    dominated.resize(t);
}

// Growth with domination (Algorithm 3) and the deaths of the year. A tree is dominated when
// a more able tree (or canopy tree) overlaps its neighbourhood. Only trees of ability > 0
// can dominate (abilities are >= 0 and domination needs a strictly higher one): in a closed
// stand most trees are seedlings of height 0, suppressed at birth and never growing, and
// they stay out of the search structure. First the tree that dominated a tree last year is
// tried (its witness: most dominated trees stay dominated by the same neighbour); otherwise
// a search over a hierarchy of bucket grids by crown radius: level L holds the able of
// radius at most base x 2^L in buckets of that size (base: about the spacing of the able,
// at least 1 m), so that a tree meets every possible dominator of level L in the 3 x 3 (or a
// few more) buckets round it, from the level of the largest crowns down (a seedling under a
// large crown finds it first), skipping levels and buckets with nobody more able. The outcome
// is the existence of a dominator, the same whichever is found first, whatever the buckets.
// The grids are built in seedYear (the year's new trees, of height 0, are never among the
// able) and each new tree is tested as it is born (testPoint). Here the able are tested
// first, in bucket order (their neighbours' buckets stay in cache; in parallel on large
// scenes), then the store's other trees of ability 0 (testUnable), the sleepers' year
// (sleepersYear), and one pass in the store's order grows every tree, spends the dominated
// trees' lives and compacts the store into its second copy (the dead out, the woken in).
void EcoModel::Impl::growYear() {
    counters.plantMonths += 12 * static_cast<std::int64_t>(size() + sleepersLive + dozersLive + bornOutside);
    testAble();
    testUnable();
    sleepersYear();
    dozersYear();
    growStore();
    dozersFollow();
    admitDozers();
    // The year's new trees that fell asleep at birth, after growStore's (their ids are larger).
    newSleepers.insert(newSleepers.end(), bornAsleep.begin(), bornAsleep.end());
    newSleeperWitness.insert(newSleeperWitness.end(), bornAsleepWitness.begin(), bornAsleepWitness.end());
    sleepersFollow();
    admitSleepers();
    dropTombstones();
    dropDozerTombstones();
}

// The abilities of the year's new trees and of the canopy trees (the others' are seedYear's),
// `able` completed with them.
void EcoModel::Impl::rateYear() {
    const std::size_t n = size(), nc = canopy.size(), nd = dozers.size();
    if (ability.size() < n + nc + nd) ability.resize(n + nc + nd);  // the first `rated` from seedYear, with `able` among them
    std::size_t na = ableN;
    if (able.size() < na + (n - rated) + nc + nd + 1) able.resize(na + (n - rated) + nc + nd + 1);  // written in place
    for (std::size_t p = rated; p < n; ++p) {
        const double a = height[p] / hRef * sp[static_cast<std::size_t>(species[p])].persistence * v[p];
        ability[p] = a;
        able[na] = static_cast<std::uint32_t>(p);
        na += a > 0 ? 1 : 0;
    }
    for (std::size_t c = 0; c < nc; ++c) {
        const Plant& t = canopy[c];
        const double a = t.heightM / hRef * sp[static_cast<std::size_t>(t.speciesId)].persistence * canopyV[c];
        ability[n + c] = a;
        able[na] = static_cast<std::uint32_t>(n + c);
        na += a > 0 ? 1 : 0;
    }
    const double* za = dozerAbility.data();
    for (std::size_t d = 0; d < nd; ++d) {  // a tombstone: 0
        const double a = za[d];
        ability[n + nc + d] = a;
        able[na] = static_cast<std::uint32_t>(n + nc + d);
        na += a > 0 ? 1 : 0;
    }
    ableN = na;
}

// The level of each able tree, the levels' grids, and the able sorted by bucket (packed).
// The base spacing follows the able's (about one per bucket of level 0, at least 1 m) with
// some slack: it is kept while within a factor kBaseSlack of that, so that a tree whose crown
// did not change keeps its level and bucket (gridKey) from one year to the next.
void EcoModel::Impl::buildGrids() {
    constexpr int kMaxLevels = 24;
    constexpr double kBaseSlack = 1.25;
    const std::size_t n = size(), nc = canopy.size(), total = n + nc + dozers.size();
    searchN = n;
    const std::size_t m = ableN;
    const double areaW = area.x1 - area.x0, areaH = area.y1 - area.y0;
    const double wanted = std::max(1.0, std::sqrt(areaW * areaH / static_cast<double>(std::max<std::size_t>(m, 1))));
    bool fresh = false;  // every key recomputed (a new base)
    if (!(gridBase > 0) || wanted > gridBase * kBaseSlack || wanted * kBaseSlack < gridBase) {
        gridBase = wanted;
        fresh = true;
        // Every level's geometry at this base (the keys' bucket numbers depend on nothing else).
        allLevels.clear();
        std::size_t buckets = 0;
        for (int L = 0; L < kMaxLevels; ++L) {
            Level lv;
            lv.bucketM = gridBase * static_cast<double>(1 << L);
            lv.inverseM = 1.0 / lv.bucketM;
            lv.bw = std::max(1, static_cast<int>(std::ceil(areaW / lv.bucketM)));
            lv.bh = std::max(1, static_cast<int>(std::ceil(areaH / lv.bucketM)));
            lv.first = buckets;
            buckets += static_cast<std::size_t>(lv.bw) * lv.bh;
            allLevels.push_back(lv);
        }
        keysUsable = buckets < (std::size_t{1} << kLevelShift);
        canopyKey.assign(canopy.size(), kNoKey);
        std::fill(gridKey.begin(), gridKey.end(), kNoKey);
        std::fill(dozerKey.begin(), dozerKey.end(), kNoKey);
    }
    const double base = gridBase;
    constexpr std::uint32_t kBucketMask = (1u << kLevelShift) - 1;
    ableEntry.resize(m);
    bucket.resize(m);
    levelOf.resize(m);
    int top = 0;
    std::uint32_t* const treeKey = gridKey.data();
    for (std::size_t i = 0; i < m; ++i) {
        const std::size_t e = able[i];
        Entry q;
        std::uint32_t* keyAt;
        if (e < n) {
            q = Entry{x[e], y[e], radius[e], ability[e]};
            keyAt = treeKey + e;
        } else if (e < n + nc) {
            const Plant& t = canopy[e - n];
            q = Entry{t.xM, t.yM, t.crownRadiusM, ability[e]};
            keyAt = canopyKey.data() + (e - n);
        } else {
            const Dozer& z = dozers[e - n - nc];
            q = Entry{z.x, z.y, z.radius, ability[e]};
            keyAt = dozerKey.data() + (e - n - nc);
        }
        ableEntry[i] = q;
        const std::uint32_t key = *keyAt;
        int L;
        std::uint32_t k;
        if (key == kNoKey || fresh || !keysUsable) {
            // Level: base x 2^L by doublings (exact, as the product was); then the bucket.
            L = 0;
            double limit = base;
            while (L < kMaxLevels - 1 && q.r > limit) {
                ++L;
                limit *= 2.0;
            }
            const Level& lv = allLevels[static_cast<std::size_t>(L)];
            const int bx = std::clamp(static_cast<int>((q.x - area.x0) * lv.inverseM), 0, lv.bw - 1);
            const int by = std::clamp(static_cast<int>((q.y - area.y0) * lv.inverseM), 0, lv.bh - 1);
            k = static_cast<std::uint32_t>(lv.first + static_cast<std::size_t>(by) * lv.bw + bx);
            *keyAt = keysUsable ? (static_cast<std::uint32_t>(L) << kLevelShift) | k : kNoKey;
        } else {
            L = static_cast<int>(key >> kLevelShift);
            k = key & kBucketMask;
            ++cacheCounts.keysKept;
        }
        bucket[i] = k;
        levelOf[i] = static_cast<std::uint8_t>(L);
        top = std::max(top, L);
    }
    maxLevel = top;
    levels.assign(allLevels.begin(), allLevels.begin() + maxLevel + 1);  // maxAbility -1, maxRadius 0
    const std::size_t buckets = levels.back().first + static_cast<std::size_t>(levels.back().bw) * levels.back().bh;
    // Counting sort of the able by bucket: start[k] counts, then ends, then (filled from the
    // back) the first entry of bucket k; start[buckets] = m.
    start.assign(buckets + 1, 0);
    packed.resize(m);
    packedItem.resize(m);
    slot.resize(total);
    for (std::size_t i = 0; i < m; ++i) {
        const Entry& q = ableEntry[i];
        Level& lv = levels[levelOf[i]];
        lv.maxAbility = std::max(lv.maxAbility, q.a);
        lv.maxRadius = std::max(lv.maxRadius, q.r);
        ++start[bucket[i]];
    }
    for (std::size_t k = 1; k <= buckets; ++k) start[k] += start[k - 1];
    for (std::size_t i = m; i-- > 0;) {
        const std::uint32_t k = --start[bucket[i]];
        packed[k] = ableEntry[i];
        packedItem[k] = able[i];
        slot[able[i]] = k;
    }
#ifdef ECO_HAVE_AVX2_KERNELS
    if (avx2Kernels()) {
        for (auto* col : {&packedX, &packedY, &packedR, &packedA}) col->resize(m + 3);
        for (std::size_t k = 0; k < m; ++k) {
            const Entry& q = packed[k];
            packedX[k] = q.x;
            packedY[k] = q.y;
            packedR[k] = q.r;
            packedA[k] = q.a;
        }
    }
#endif
}

// Is a tree (position, radius and ability `me` at the start of the year, witness `wit`)
// dominated? Reads only the start-of-year entries (buildGrids'); writes only its witness.
inline bool EcoModel::Impl::isDominated(const Entry& me, std::uint32_t& wit) const {
    const double px = me.x, py = me.y, pr = me.r, pa = me.a;
    // Eq. 8: the neighbourhoods intersect (the same expression for the witness and the search).
    auto overlaps = [px, py, pr](const Entry& q) {
        const double dx = px - q.x, dy = py - q.y, rr = pr + q.r;
        return dx * dx + dy * dy < rr * rr;
    };
    const std::uint32_t w = wit;
    if (w != kNoWitness) {
        const std::size_t e = codeIndex(w);
        if (ability[e] > 0) {  // always, as abilities never fall; a guard all the same
            const Entry& q = packed[slot[e]];
            if (pa < q.a && overlaps(q)) return true;
        }
    }
#ifdef ECO_HAVE_AVX2_KERNELS
    if (avx2Kernels()) return searchAvx2(me, wit);
#endif
    const double ox = px - area.x0, oy = py - area.y0;
    for (int L = maxLevel; L >= 0; --L) {
        const Level& lv = levels[static_cast<std::size_t>(L)];
        if (!(pa < lv.maxAbility)) continue;  // nobody there is more able
        const BucketBox b = bucketBox(lv, ox, oy, pr);
        // The buckets bx0..bx1 of a row are consecutive in `packed` (sorted by bucket, row by
        // row): one run of entries per row, in the order a bucket-by-bucket scan would meet them.
        for (int by = b.by0; by <= b.by1; ++by) {
            const std::size_t row = lv.first + static_cast<std::size_t>(by) * lv.bw;
            const std::uint32_t end = start[row + b.bx1 + 1];
            for (std::uint32_t k = start[row + b.bx0]; k < end; ++k) {
                const Entry& q = packed[k];
                if (pa < q.a && overlaps(q)) {  // only the more able dominate (p itself never)
                    wit = codeOf(packedItem[k]);
                    return true;
                }
            }
        }
    }
    wit = kNoWitness;
    return false;
}

#ifdef ECO_HAVE_AVX2_KERNELS
// isDominated's search (after the witness) four entries at a time: each lane performs the
// scalar test's operations (the same bits: no fused multiply-add), and a run's first lane
// that dominates is the entry the scalar loop would meet first, so the find is the same.
ECO_TARGET_AVX2 bool EcoModel::Impl::searchAvx2(const Entry& me, std::uint32_t& wit) const {
    const __m256d vx = _mm256_set1_pd(me.x), vy = _mm256_set1_pd(me.y), vr = _mm256_set1_pd(me.r),
                  va = _mm256_set1_pd(me.a);
    const double *qx = packedX.data(), *qy = packedY.data(), *qr = packedR.data(), *qa = packedA.data();
    const double ox = me.x - area.x0, oy = me.y - area.y0;
    for (int L = maxLevel; L >= 0; --L) {
        const Level& lv = levels[static_cast<std::size_t>(L)];
        if (!(me.a < lv.maxAbility)) continue;
        const BucketBox b = bucketBox(lv, ox, oy, me.r);
        for (int by = b.by0; by <= b.by1; ++by) {
            const std::size_t row = lv.first + static_cast<std::size_t>(by) * lv.bw;
            const std::uint32_t end = start[row + b.bx1 + 1];
            for (std::uint32_t k = start[row + b.bx0]; k < end; k += 4) {
                const __m256d dx = _mm256_sub_pd(vx, _mm256_loadu_pd(qx + k));
                const __m256d dy = _mm256_sub_pd(vy, _mm256_loadu_pd(qy + k));
                const __m256d rr = _mm256_add_pd(vr, _mm256_loadu_pd(qr + k));
                const __m256d d2 = _mm256_add_pd(_mm256_mul_pd(dx, dx), _mm256_mul_pd(dy, dy));
                const __m256d hit = _mm256_and_pd(_mm256_cmp_pd(va, _mm256_loadu_pd(qa + k), _CMP_LT_OQ),
                                                  _mm256_cmp_pd(d2, _mm256_mul_pd(rr, rr), _CMP_LT_OQ));
                unsigned bits = static_cast<unsigned>(_mm256_movemask_pd(hit));
                if (end - k < 4) bits &= (1u << (end - k)) - 1;  // lanes past the run
                if (bits != 0) {
                    wit = codeOf(packedItem[k + static_cast<std::uint32_t>(__builtin_ctz(bits))]);
                    return true;
                }
            }
        }
    }
    wit = kNoWitness;
    return false;
}
#endif

// The able trees' test, in bucket order; each writes only its own flag and witness.
void EcoModel::Impl::testAble() {
    const std::size_t n = searchN, m = ableN;  // dominated: sized by seedYear
#pragma omp parallel for schedule(dynamic, 1024) if (parallelLoop(m))
    for (std::int64_t ki = 0; ki < static_cast<std::int64_t>(m); ++ki) {
        const std::size_t k = static_cast<std::size_t>(ki);
        const std::size_t p = packedItem[k];
        if (p >= n) continue;  // canopy trees: static, never dominated
        dominated[p] = (sure[p] != 0 && witness[p] != kNoWitness) || isDominated(packed[k], witness[p]) ? 1 : 0;
    }
}

// The test of the store's trees of ability 0 (they cannot dominate: the year's new
// seedlings, and the woken before they grow), in the store's order: their witness (the new
// seedling's parent), then the cover cache's guess for their place, then the search; the
// search's find goes into the cache. Sequential (it writes the cache).
void EcoModel::Impl::testUnable() {
    const std::size_t n = searchN;
    for (std::size_t p = 0; p < n; ++p) {
        if (ability[p] > 0) continue;
        std::uint32_t w = witness[p];
        dominated[p] = testPoint(Entry{x[p], y[p], radius[p], ability[p]}, w) ? 1 : 0;
        witness[p] = w;
    }
}

// The test of a tree of ability 0 at `me` (start-of-year grids): its guess `wit` (a witness,
// or a new seedling's parent), then the cover cache's guess for its place, then the search,
// whose find goes into the cache; `wit` becomes the dominator found (kNoWitness: none).
bool EcoModel::Impl::testPoint(const Entry& me, std::uint32_t& wit) {
    const std::size_t n = searchN;
    if (coverGuess.empty()) {
        coverW = std::max(1, static_cast<int>(std::ceil((area.x1 - area.x0) / kCoverCellM)));
        coverH = std::max(1, static_cast<int>(std::ceil((area.y1 - area.y0) / kCoverCellM)));
        coverGuess.assign(static_cast<std::size_t>(coverW) * static_cast<std::size_t>(coverH), 0);
    }
    auto overlaps = [&me](const Entry& q) {  // isDominated's test, the same expression
        const double dx = me.x - q.x, dy = me.y - q.y, rr = me.r + q.r;
        return dx * dx + dy * dy < rr * rr;
    };
    const std::uint32_t w = wit;
    if (w != kNoWitness) {
        const std::size_t e = codeIndex(w);
        if (ability[e] > 0) {
            const Entry& q = packed[slot[e]];
            if (me.a < q.a && overlaps(q)) return true;
        }
    }
    const std::uint64_t* ids = id.data();  // the first n: the store's at the grids (sorted)
    const std::size_t cell = coverCell(me.x, me.y);
    const std::uint64_t guess = coverGuess[cell];
    if (guess != 0) {
        std::size_t e = n;
        std::uint32_t code = kNoWitness;
        if (guess & kCoverCanopy) {
            const std::size_t c = static_cast<std::size_t>(guess & ~kCoverCanopy);
            e = n + c;
            code = kWitnessCanopy | static_cast<std::uint32_t>(c);
        } else {
            e = static_cast<std::size_t>(std::lower_bound(ids, ids + n, guess) - ids);
            if (e < n && ids[e] == guess)
                code = static_cast<std::uint32_t>(e);
            else
                e = ability.size();  // died (or asleep): past every index
        }
        if (e < ability.size() && ability[e] > 0) {
            const Entry& q = packed[slot[e]];
            if (me.a < q.a && overlaps(q)) {
                wit = code;
                ++cacheCounts.coverHits;
                return true;
            }
        }
    }
    std::uint32_t found = kNoWitness;
    const bool dom = isDominated(me, found);
    wit = found;
    if (dom && !isDozerCode(found))
        coverGuess[cell] = (found & kWitnessCanopy) ? kCoverCanopy | (found & ~kWitnessCanopy) : ids[found];
    return dom;
}

// Every tree in the store's order: the others' test, growth, survival, natural death, and
// compaction in place (the dead out, the order kept; witnesses renumbered after). A
// dominated seedling of height 0 that cannot grow while dominated goes to sleep (leaves
// the store for the sleepers) with its witness.
void EcoModel::Impl::growStore() {
    const std::size_t n = size(), nw = woken.size(), cap = n + nw;
    newIndex.resize(n + 1);  // one more: the sleepers' pass reads entry 0 even for an empty store
    fixup.clear();
    newSleepers.clear();
    newSleeperWitness.clear();
    newDozers.clear();
    newDozerWitness.clear();
    newDozerKey.clear();
    anyShrunk = shrunkOutside;  // a woken dozer's shrink (dozersYear)
    shrunkOutside = false;
    // Written into the second copy of the arrays (swapped in at the end): the woken can go in
    // by id during the pass (no in-place compaction could make room for them), and nearly
    // every tree moves in a year anyway (a tree leaves the store early in the order).
    Store& o = spare;
    o.resize(cap);
    std::uint64_t* const oid = o.id.data();
    std::int32_t* const ospecies = o.species.data();
    std::int32_t* const oage = o.age.data();
    std::int32_t* const olives = o.lives.data();
    double* const ox = o.x.data();
    double* const oy = o.y.data();
    double* const oheight = o.height.data();
    double* const oradius = o.radius.data();
    double* const ogrowth = o.growthAge.data();
    double* const odeath = o.deathAge.data();
    float* const ov = o.v.data();
    std::uint32_t* const owitness = o.witness.data();
    std::uint8_t* const osure = o.sure.data();
    std::uint32_t* const okey = o.gridKey.data();
    std::size_t w = 0, j = 0;
    constexpr std::uint64_t kNone = std::numeric_limits<std::uint64_t>::max();
    std::uint64_t nextWoken = nw > 0 ? woken[0].id : kNone;  // the next woken's id (kNone: no more)
    // The woken before id `upTo`, at their places (their witnesses in start-of-year indices: after the pass).
    auto admitWoken = [&](std::uint64_t upTo) {
        for (; j < nw && woken[j].id < upTo; ++j, ++w) {
            const Woken& t = woken[j];
            oid[w] = t.id;
            ospecies[w] = t.species;
            oage[w] = t.age;
            olives[w] = t.lives;
            ox[w] = t.x;
            oy[w] = t.y;
            oheight[w] = t.height;
            oradius[w] = t.radius;
            ogrowth[w] = t.growthAge;
            odeath[w] = t.deathAge;
            ov[w] = t.v;
            owitness[w] = t.witness;
            osure[w] = 0;
            okey[w] = kNoKey;
            if (isStoreCode(t.witness))
                fixup.push_back(static_cast<std::uint32_t>(w));
            else if (isDozerCode(t.witness) && !dozerAlive(t.witness))
                owitness[w] = kNoWitness;
        }
        nextWoken = j < nw ? woken[j].id : kNone;
    };
    for (std::size_t p = 0; p < n; ++p) {
        if (id[p] > nextWoken) admitWoken(id[p]);
        const bool dom = dominated[p] != 0;  // testAble's or testUnable's
        const int s = species[p];
        const EcoModSpeciesParams& sps = sp[static_cast<std::size_t>(s)];
        const double before = growthAge[p];
        double g = before;
        std::int32_t lv = lives[p];
        if (dom) {
            g += sps.dominatedGrowth;
            if (lv == 0) {
                ++counters.diedDominated;  // suffocation
                newIndex[p] = kNoWitness;
                continue;
            }
            if (lv != kInfiniteLives) --lv;
        } else {
            g += 1.0;
        }
        const std::int32_t ageYears = age[p] + 1;
        if (ageYears >= deathAge[p]) {
            ++counters.diedBackgroundOrStress;  // natural death
            newIndex[p] = kNoWitness;
            continue;
        }
        double h = height[p], r = radius[p];
        bool moved = false;  // its height or crown changed (its grid place with it)
        // Height and crown only where the polyline moved (a full-grown or obstructed tree keeps
        // both): the allometry's exp and log are the costliest part of a growing tree's year.
        if (g != before && before < sps.fullGrownAgeYears) {
            const Shape sh = growthShape(s, g);
            h = sh.h;
            r = sh.r;
            if (h < height[p] || r < radius[p]) anyShrunk = true;
            moved = h != height[p] || r != radius[p];
        }
        if (dom && h == 0.0 && (r == 0.0 && sps.dominatedGrowth == 0.0 && ageYears < sps.maturityAgeYears &&
                                witness[p] != kNoWitness)) {
            // To sleep: dominated by its witness in the years to come (see Sleeper).
            newSleepers.push_back(Sleeper{id[p], x[p], y[p], g, deathAge[p], v[p], s, ageYears - year - 1, domDeathYearOf(lv, year),
                                          Wake::DiesDominated});
            newSleeperWitness.push_back(witness[p]);
            newIndex[p] = kNoWitness;  // nobody's witness: its ability is 0
            continue;
        }
        if (dom && dozing && g == before && sps.dominatedGrowth == 0.0 && h > 0.0 && witness[p] != kNoWitness &&
            dozers.size() + newDozers.size() < kDozerMask) {  // a dozer's index must fit its code (else it stays awake)
            // To doze: dominated by its witness in the years to come, unchanged (see Dozer).
            const std::uint32_t d = static_cast<std::uint32_t>(dozers.size() + newDozers.size());
            newDozers.push_back(Dozer{id[p], x[p], y[p], h, r, g, deathAge[p], h / hRef * sps.persistence * v[p], v[p], s,
                                      ageYears - year - 1, domDeathYearOf(lv, year), true});
            newDozerWitness.push_back(witness[p]);
            newDozerKey.push_back(gridKey[p]);
            newIndex[p] = kWitnessDozer | d;  // its watchers follow it
            continue;
        }
        newIndex[p] = static_cast<std::uint32_t>(w);
        // The witness follows its tree to its new place: now if it was before (its new index
        // is known), after the pass otherwise; a dozer witness stays while it dozes.
        const std::uint32_t q = witness[p];
        if (isStoreCode(q)) {
            if (q < p)
                owitness[w] = newIndex[q];
            else {
                owitness[w] = q;
                fixup.push_back(static_cast<std::uint32_t>(w));
            }
        } else if (isDozerCode(q) && !dozerAlive(q)) {
            owitness[w] = kNoWitness;
        } else {
            owitness[w] = q;
        }
        oid[w] = id[p];
        ospecies[w] = s;
        ox[w] = x[p];
        oy[w] = y[p];
        odeath[w] = deathAge[p];
        ov[w] = v[p];
        olives[w] = lv;
        osure[w] = dom && g == before ? 1 : 0;
        okey[w] = moved ? kNoKey : gridKey[p];  // its grid place holds while its crown does
        oheight[w] = h;
        oradius[w] = r;
        ogrowth[w] = g;
        oage[w] = ageYears;
        ++w;
    }
    admitWoken(kNone);
    cacheCounts.wokenInPass += nw;
    woken.clear();
    swapStore(o);
    truncate(w);
    for (std::uint32_t k : fixup) witness[k] = newIndex[witness[k]];
    if (anyShrunk) std::fill(sure.begin(), sure.end(), std::uint8_t{0});  // a witness may have shrunk
}

// The sleepers' year, before growStore (on the start-of-year grids): those whose witness
// died or shrank last year (kNoWitness) are tested (the others are dominated by theirs); a
// dominated one meets its planned event if this is its year; one that nobody dominates grows
// and rejoins the store (woken: growStore puts it in by id), as does one about to mature.
// Their witnesses stay in start-of-year indices until sleepersFollow.
void EcoModel::Impl::sleepersYear() {
    woken.clear();
    // First the few sleepers with work this year (their event, or no witness), from the
    // watched and the events' calendar (no pass over every witness).
    slowSleepers.clear();
    const std::int32_t* events = sleepEvent.data();
    const std::uint32_t* witnesses = sleepWitness.data();
    const std::int32_t now = year;
    for (const std::uint32_t i : watched) {
        const std::uint32_t q = witnesses[i];
        if (q == kNoWitness || (!(q & kWitnessCanopy) && events[i] == now)) slowSleepers.push_back({i, q});
    }
    // This year's events of the sleepers under a canopy tree (the others' are listed above):
    // the calendar's entry of the year (the tombstones' out, a later turn's kept), sorted.
    const std::size_t watchedSlow = slowSleepers.size();
    if (!calendar.empty()) {
        std::vector<std::uint32_t>& due = calendar[static_cast<std::size_t>(now) % kCalendarYears];
        std::size_t kept = 0;
        for (const std::uint32_t i : due) {
            const std::int32_t ev = events[i];
            if (ev > now) {
                due[kept++] = i;
                continue;
            }
            const std::uint32_t q = witnesses[i];
            if (ev == now && q != kNoWitness && (q & kWitnessCanopy)) slowSleepers.push_back({i, q});
        }
        due.resize(kept);  // in index order already: a year's entries are appended in index order, rebuilt in it
    }
    cacheCounts.calendarEvents += slowSleepers.size() - watchedSlow;
    if (checkCalendar) {  // test mode: the same sleepers as a scan of every event year would list
        std::vector<std::pair<std::uint32_t, std::uint32_t>> scan;
        for (std::size_t i = 0; i < sleepers.size(); ++i) {
            const std::uint32_t q = witnesses[i];
            if (events[i] == now && q != kNoWitness && (q & kWitnessCanopy)) scan.push_back({static_cast<std::uint32_t>(i), q});
        }
        if (!std::equal(scan.begin(), scan.end(), slowSleepers.begin() + static_cast<std::ptrdiff_t>(watchedSlow), slowSleepers.end()))
            ++cacheCounts.calendarMismatches;
    }
    // In index (id) order, as the woken must be (two sorted runs; disjoint).
    std::inplace_merge(slowSleepers.begin(), slowSleepers.begin() + static_cast<std::ptrdiff_t>(watchedSlow), slowSleepers.end());
    // Then their year, with the witness they had at its start.
    for (const auto& [slow, witnessBefore] : slowSleepers) {
        const std::size_t i = slow;
        const std::int32_t ev = sleepEvent[i];
        std::uint32_t q = witnessBefore;
        Sleeper& sl = sleepers[i];
        if (q == kNoWitness) {
            if (!isDominated(Entry{sl.x, sl.y, 0.0, 0.0}, q)) {
                // Free: it grows this year as a tree of the store would (no survival draw).
                const EcoModSpeciesParams& sps = sp[static_cast<std::size_t>(sl.species)];
                const std::int32_t ageYears = sl.ageBase + year + 1;
                sleepEvent[i] = kTombstone;
                sleepWitness[i] = kWitnessCanopy;
                --sleepersLive;
                if (ageYears >= sl.deathAge) {
                    ++counters.diedBackgroundOrStress;
                    continue;
                }
                const double g = sl.growthAge + 1.0;
                double h = 0.0, r = 0.0;
                if (sl.growthAge < sps.fullGrownAgeYears) {
                    const Shape sh = growthShape(sl.species, g);
                    h = sh.h;
                    r = sh.r;
                }
                woken.push_back(
                    Woken{sl.id, sl.species, ageYears, sl.x, sl.y, h, r, g, sl.deathAge, sl.v, kNoWitness, livesAfter(sl, year)});
                continue;
            }
        }
        if (ev == year) {
            switch (sl.kind) {
                case Wake::DiesDominated:
                    ++counters.diedDominated;
                    break;
                case Wake::DiesNatural:
                    ++counters.diedBackgroundOrStress;
                    break;
                case Wake::Matures:  // mature from next year on (its witness renumbered by growStore)
                    woken.push_back(wake(sl, year + 1, q));
                    break;
            }
            sleepEvent[i] = kTombstone;
            sleepWitness[i] = kWitnessCanopy;
            --sleepersLive;
            continue;
        }
        sleepWitness[i] = q;  // a start-of-year index (or canopy): sleepersFollow renumbers it
    }
}

// After growStore: the watched sleepers' witnesses to the store's new indices (kNoWitness for
// a witness that died, went to sleep or, after a shrink, any store witness: tested next year).
void EcoModel::Impl::sleepersFollow() {
    std::uint32_t* witnesses = sleepWitness.data();
    if (!anyShrunk) {
        const std::uint32_t* renumber = newIndex.data();
        for (const std::uint32_t i : watched) {
            const std::uint32_t q = witnesses[i];
            if (isStoreCode(q))
                witnesses[i] = renumber[q];
            else if (isDozerCode(q) && !dozerAlive(q))
                witnesses[i] = kNoWitness;
        }
    } else {
        for (const std::uint32_t i : watched) witnesses[i] = follow(witnesses[i]);
    }
}

// The year's new sleepers (growStore's), their events planned, after the others (their ids
// in order; usually beyond every sleeper's).
void EcoModel::Impl::admitSleepers() {
    if (!newSleepers.empty()) {
        std::vector<std::int32_t> events(newSleepers.size());
        for (std::size_t i = 0; i < newSleepers.size(); ++i) {
            planSleep(newSleepers[i], events[i], year);
            newSleeperWitness[i] = follow(newSleeperWitness[i]);
        }
        if (sleepers.empty() || sleepers.back().id < newSleepers.front().id) {
            for (std::size_t i = 0; i < newSleepers.size(); ++i) {
                if (needsWatch(newSleeperWitness[i])) watched.push_back(static_cast<std::uint32_t>(sleepers.size() + i));
                calendarAdd(static_cast<std::uint32_t>(sleepers.size() + i), events[i]);
            }
            sleepers.insert(sleepers.end(), newSleepers.begin(), newSleepers.end());
            sleepEvent.insert(sleepEvent.end(), events.begin(), events.end());
            sleepWitness.insert(sleepWitness.end(), newSleeperWitness.begin(), newSleeperWitness.end());
        } else {  // merge by id
            std::vector<Sleeper> ms;
            std::vector<std::int32_t> me;
            std::vector<std::uint32_t> mw;
            const std::size_t total2 = sleepers.size() + newSleepers.size();
            ms.reserve(total2);
            me.reserve(total2);
            mw.reserve(total2);
            std::size_t a = 0, b = 0;
            while (a < sleepers.size() || b < newSleepers.size()) {
                if (b == newSleepers.size() || (a < sleepers.size() && sleepers[a].id < newSleepers[b].id)) {
                    ms.push_back(sleepers[a]);
                    me.push_back(sleepEvent[a]);
                    mw.push_back(sleepWitness[a]);
                    ++a;
                } else {
                    ms.push_back(newSleepers[b]);
                    me.push_back(events[b]);
                    mw.push_back(newSleeperWitness[b]);
                    ++b;
                }
            }
            sleepers.swap(ms);
            sleepEvent.swap(me);
            sleepWitness.swap(mw);
            rebuildWatched();
        }
        sleepersLive += newSleepers.size();
    }
}

// Tombstones out once they outnumber the living (the order kept).
void EcoModel::Impl::dropTombstones() {
    const std::size_t dead = sleepers.size() - sleepersLive;
    if (dead > sleepersLive && dead > 64) {
        std::size_t o = 0;
        for (std::size_t i = 0; i < sleepers.size(); ++i)
            if (sleepEvent[i] >= 0) {
                sleepers[o] = sleepers[i];
                sleepEvent[o] = sleepEvent[i];
                sleepWitness[o] = sleepWitness[i];
                ++o;
            }
        sleepers.resize(o);
        sleepEvent.resize(o);
        sleepWitness.resize(o);
        rebuildWatched();
    }
}

// The dozers' year, before growStore (on the start-of-year grids; after sleepersYear, whose
// woken it completes by id): a dozer whose witness is gone (kNoWitness) is tested; one that
// nobody dominates grows and rejoins the store, as a store tree would (no life spent); the
// others are dominated this year, and one whose event falls in it dies.
void EcoModel::Impl::dozersYear() {
    dozerWoken.clear();
    const std::int32_t now = year;
    for (const std::uint32_t d : dozerDue) {  // the others are dominated by their witness, and live on
        const std::int32_t ev = dozerEvent[d];
        std::uint32_t q = dozerWitness[d];
        if (ev < 0 || (q != kNoWitness && ev != now)) continue;  // a guard: the list has only those with work
        const Dozer& z = dozers[d];
        if (q == kNoWitness) {
            if (!isDominated(Entry{z.x, z.y, z.radius, z.ability}, q)) {
                const EcoModSpeciesParams& sps = sp[static_cast<std::size_t>(z.species)];
                const std::int32_t ageYears = z.ageBase + now + 1;
                dozerEvent[d] = kTombstone;
                dozerAbility[d] = 0.0;
                --dozersLive;
                if (ageYears >= z.deathAge) {
                    ++counters.diedBackgroundOrStress;
                    continue;
                }
                const double g = z.growthAge + 1.0;
                double h = z.height, r = z.radius;
                if (z.growthAge < sps.fullGrownAgeYears) {
                    const Shape sh = growthShape(z.species, g);
                    h = sh.h;
                    r = sh.r;
                    if (h < z.height || r < z.radius) shrunkOutside = true;
                }
                dozerWoken.push_back(Woken{z.id, z.species, ageYears, z.x, z.y, h, r, g, z.deathAge, z.v, kNoWitness,
                                           z.domDeathYear == kNeverYear ? kInfiniteLives : z.domDeathYear - now});
                continue;
            }
            dozerWitness[d] = q;
        }
        if (ev == now) {
            if (z.diesDominated)
                ++counters.diedDominated;
            else
                ++counters.diedBackgroundOrStress;
            dozerEvent[d] = kTombstone;
            dozerAbility[d] = 0.0;
            --dozersLive;
        }
    }
    if (!dozerWoken.empty()) {
        auto byId = [](const Woken& a, const Woken& b) { return a.id < b.id; };
        std::sort(dozerWoken.begin(), dozerWoken.end(), byId);
        const std::size_t k = woken.size();
        woken.insert(woken.end(), dozerWoken.begin(), dozerWoken.end());
        std::inplace_merge(woken.begin(), woken.begin() + static_cast<std::ptrdiff_t>(k), woken.end(), byId);
    }
}

// After growStore: the dozers' witnesses to the store's new indices (kNoWitness for a witness
// that died or woke, or any store witness after a shrink).
// The same pass lists next year's dozers with work (dozerDue): no witness, or their event.
void EcoModel::Impl::dozersFollow() {
    const std::size_t nd = dozers.size();
    const std::int32_t next = year + 1;
    const std::int32_t* events = dozerEvent.data();
    std::uint32_t* witnesses = dozerWitness.data();
    const std::uint32_t* renumber = newIndex.data();
    const bool shrunk = anyShrunk;
    dozerDue.clear();
    for (std::size_t d = 0; d < nd; ++d) {
        const std::int32_t ev = events[d];
        if (ev < 0) continue;
        std::uint32_t q = witnesses[d];
        if (isStoreCode(q))
            witnesses[d] = q = shrunk ? kNoWitness : renumber[q];
        else if (isDozerCode(q) && events[q & kDozerMask] < 0)
            witnesses[d] = q = kNoWitness;
        if (q == kNoWitness || ev == next) dozerDue.push_back(static_cast<std::uint32_t>(d));
    }
}

// The year's new dozers (growStore's, in id order) after the others, their events planned;
// dozerOrder merged with them by id.
void EcoModel::Impl::admitDozers() {
    if (newDozers.empty()) return;
    const std::size_t first = dozers.size(), k = newDozers.size();
    for (std::size_t i = 0; i < k; ++i) {
        Dozer z = newDozers[i];
        const std::int32_t ev = planDoze(z, year);
        dozers.push_back(z);
        dozerEvent.push_back(ev);
        const std::uint32_t q = follow(newDozerWitness[i]);
        dozerWitness.push_back(q);
        dozerKey.push_back(newDozerKey[i]);
        dozerAbility.push_back(z.ability);
        if (q == kNoWitness || ev == year + 1) dozerDue.push_back(static_cast<std::uint32_t>(first + i));
    }
    // Into dozerOrder by id from the back (block moves), as mergeWoken spreads the store.
    std::size_t end = dozerOrder.size();
    dozerOrder.resize(end + k);
    const auto o = dozerOrder.begin();
    for (std::size_t j = k; j-- > 0;) {
        const std::uint64_t nid = dozers[first + j].id;
        const std::size_t at = static_cast<std::size_t>(
            std::upper_bound(o, o + static_cast<std::ptrdiff_t>(end), nid,
                             [this](std::uint64_t v, std::uint32_t d) { return v < dozers[d].id; }) -
            o);
        std::move_backward(o + static_cast<std::ptrdiff_t>(at), o + static_cast<std::ptrdiff_t>(end),
                           o + static_cast<std::ptrdiff_t>(end + j + 1));
        dozerOrder[at + j] = static_cast<std::uint32_t>(first + j);
        end = at;
    }
    dozersLive += k;
}

// The dozers' tombstones out once they are more than half the living (every yearly
// pass reads them); every dozer code renumbered.
void EcoModel::Impl::dropDozerTombstones() {
    const std::size_t nd = dozers.size(), dead = nd - dozersLive;
    if (!(2 * dead > dozersLive && dead > 64)) return;
    dozerRemap.assign(nd, kNoWitness);
    std::size_t o = 0;
    for (std::size_t d = 0; d < nd; ++d) {
        if (dozerEvent[d] < 0) continue;
        dozerRemap[d] = static_cast<std::uint32_t>(o);
        dozers[o] = dozers[d];
        dozerEvent[o] = dozerEvent[d];
        dozerWitness[o] = dozerWitness[d];
        dozerKey[o] = dozerKey[d];
        dozerAbility[o] = dozerAbility[d];
        ++o;
    }
    dozers.resize(o);
    dozerEvent.resize(o);
    dozerWitness.resize(o);
    dozerKey.resize(o);
    dozerAbility.resize(o);
    std::size_t kept = 0;
    for (const std::uint32_t d : dozerDue)
        if (dozerRemap[d] != kNoWitness) dozerDue[kept++] = dozerRemap[d];
    dozerDue.resize(kept);
    auto remap = [this](std::uint32_t& q) {
        if (!isDozerCode(q)) return;
        const std::uint32_t to = dozerRemap[q & kDozerMask];
        q = to == kNoWitness ? kNoWitness : kWitnessDozer | to;
    };
    for (auto& q : witness) remap(q);
    for (const std::uint32_t i : watched) remap(sleepWitness[i]);  // the others' witnesses: canopy trees
    for (auto& q : dozerWitness) remap(q);
    std::size_t w = 0;
    for (const std::uint32_t d : dozerOrder)
        if (dozerRemap[d] != kNoWitness) dozerOrder[w++] = dozerRemap[d];
    dozerOrder.resize(w);
}

// The woken (in id order; witnesses as store indices) into the store, by id, in place: each
// array grows by their number and its trees move back by the number of woken before them
// (a few per year: block moves); the store's and the sleepers' witnesses renumbered.
void EcoModel::Impl::mergeWoken() {
    const std::size_t n = size(), nw = woken.size(), total = n + nw;
    // at[j]: the store index before which woken j goes (ids ascending in both).
    mergeAt.resize(nw);
    for (std::size_t j = 0; j < nw; ++j)
        mergeAt[j] = static_cast<std::uint32_t>(std::lower_bound(id.begin(), id.end(), woken[j].id) - id.begin());
    auto spread = [&](auto& a, auto field) {
        a.resize(total);
        std::size_t end = n;  // trees [at[j], end) move back by j + 1
        for (std::size_t j = nw; j-- > 0;) {
            const std::size_t from = mergeAt[j];
            std::move_backward(a.begin() + static_cast<std::ptrdiff_t>(from), a.begin() + static_cast<std::ptrdiff_t>(end),
                               a.begin() + static_cast<std::ptrdiff_t>(end + j + 1));
            a[from + j] = field(woken[j]);
            end = from;
        }
    };
    spread(id, [](const Woken& t) { return t.id; });
    spread(species, [](const Woken& t) { return t.species; });
    spread(age, [](const Woken& t) { return t.age; });
    spread(x, [](const Woken& t) { return t.x; });
    spread(y, [](const Woken& t) { return t.y; });
    spread(height, [](const Woken& t) { return t.height; });
    spread(radius, [](const Woken& t) { return t.radius; });
    spread(growthAge, [](const Woken& t) { return t.growthAge; });
    spread(deathAge, [](const Woken& t) { return t.deathAge; });
    spread(v, [](const Woken& t) { return t.v; });
    spread(witness, [](const Woken& t) { return t.witness; });
    spread(sure, [](const Woken&) { return std::uint8_t{0}; });
    spread(lives, [](const Woken& t) { return t.lives; });
    spread(gridKey, [](const Woken&) { return kNoKey; });
    // Old store index q -> q + (woken placed before it), for the witnesses (all in old indices).
    mergeShift.resize(n + 1);
    for (std::size_t j = 0, q = 0; q <= n; ++q) {
        while (j < nw && mergeAt[j] <= q) ++j;
        mergeShift[q] = static_cast<std::uint32_t>(j);
    }
    auto remap = [&](std::uint32_t q) {
        return isStoreCode(q) ? q + mergeShift[q] : q;
    };
    for (auto& q : witness) q = remap(q);
    for (const std::uint32_t i : watched) sleepWitness[i] = remap(sleepWitness[i]);  // the others': canopy, kept
    woken.clear();
}

void EcoModel::Impl::wakeAll(int yearsCompleted) {
    woken.clear();
    for (std::size_t i = 0; i < sleepers.size(); ++i)
        if (sleepEvent[i] >= 0) woken.push_back(wake(sleepers[i], yearsCompleted, sleepWitness[i]));
    // The dozers too, by id (their codes forgotten: the dozers' indices end here).
    const std::size_t fromSleepers = woken.size();
    for (const std::uint32_t d : dozerOrder) {
        if (dozerEvent[d] < 0) continue;
        const Dozer& z = dozers[d];
        woken.push_back(Woken{z.id, z.species, z.ageBase + yearsCompleted, z.x, z.y, z.height, z.radius, z.growthAge, z.deathAge,
                              z.v, dozerWitness[d],
                              z.domDeathYear == kNeverYear ? kInfiniteLives : z.domDeathYear - yearsCompleted});
    }
    if (!dozerOrder.empty()) {
        std::inplace_merge(woken.begin(), woken.begin() + static_cast<std::ptrdiff_t>(fromSleepers), woken.end(),
                           [](const Woken& a, const Woken& b) { return a.id < b.id; });
        for (Woken& t : woken)
            if (isDozerCode(t.witness)) t.witness = kNoWitness;
        for (auto& q : witness)
            if (isDozerCode(q)) q = kNoWitness;
    }
    dozers.clear();
    dozerEvent.clear();
    dozerWitness.clear();
    dozerKey.clear();
    dozerOrder.clear();
    dozerAbility.clear();
    dozerDue.clear();
    dozersLive = 0;
    sleepers.clear();
    sleepEvent.clear();
    sleepWitness.clear();
    watched.clear();
    clearCalendar();
    sleepersLive = 0;
    if (!woken.empty()) mergeWoken();
}

std::uint64_t EcoModel::Impl::computeFingerprint() const {
    std::uint64_t h = 0x65636F6D6F643032ull;  // "ecomod02": the dominated trees' lives (checkpoints of 01 differ)
    for (const auto& [k, val] : params.namedValues()) {
        h = hashBytes(h, k.data(), k.size());
        h = hashBytes(h, &val, sizeof val);
    }
    h = mixStream(h, seed);
    const std::string toml = biomeToToml(biome);
    h = hashBytes(h, toml.data(), toml.size());
    const double a[4] = {area.x0, area.y0, area.x1, area.y1};
    h = hashBytes(h, a, sizeof a);
    for (const Plant& t : canopy) {
        const double vals[5] = {t.xM, t.yM, t.groundZM, t.heightM, t.crownRadiusM};
        h = mixStream(h, static_cast<std::uint64_t>(t.speciesId));
        h = hashBytes(h, vals, sizeof vals);
    }
    h = hashBytes(h, suit.data(), suit.size() * sizeof(float));
    h = hashBytes(h, elevation.data().data(), elevation.size() * sizeof(float));
    if (disturbanceOn) {  // only when on: checkpoints of runs without it keep their fingerprint
        const std::string d = disturbance.toToml();
        h = hashBytes(h, d.data(), d.size());
        h = hashBytes(h, siteWind.data().data(), siteWind.size() * sizeof(float));
        for (const Grid<float>& g : siteMoisture) h = hashBytes(h, g.data().data(), g.size() * sizeof(float));
    }
    return h;
}

// ---------------------------------------------------------------------- construction

EcoModel::EcoModel(SimInputs in, const SimParams& params, std::uint64_t seed, const std::vector<UndergrowthPlant>& initial)
    : impl_(std::make_unique<Impl>()) {
    Impl& m = *impl_;
    m.params = params;
    m.params.validate("simulation parameters");
    m.seed = seed;
    m.biome = std::move(in.biome);
    if (m.biome.species.empty()) throw ValidationError("simulation: the biome has no species");
    const std::string source = m.biome.sourcePath.empty() ? std::string("biome '") + m.biome.name + "'" : m.biome.sourcePath;
    for (const Species& s : m.biome.species) m.sp.push_back(resolveEcoModSpecies(s, source));
    for (const auto& p : m.sp) m.logSurvival.push_back(std::log(p.dominatedSurvival));
    m.hRef = 0;
    for (const auto& p : m.sp) m.hRef = std::max(m.hRef, p.fullHeightM);
    m.buildShapes();

    Abiotics& abio = in.abiotics;
    const Grid<float>& g = abio.slopeDeg;
    if (g.empty()) throw ValidationError("simulation: the abiotics have no slope map");
    if (abio.windMS.empty() || !abio.windMS.sameGeometry(g))
        throw ValidationError("simulation: the abiotics have no wind map of the slope map's geometry (run eco abiotics again)");
    for (const auto* mg : {&abio.sunHours, &abio.moistureMm})
        if (mg->months.size() != 12 || !mg->months[0].sameGeometry(g))
            throw ValidationError("simulation: the abiotics' sun and moisture need 12 monthly planes of the slope map's geometry");
    if (abio.elevationM.empty()) abio.elevationM = Grid<float>::like(g, 0.f);
    if (!abio.elevationM.sameGeometry(g))
        throw ValidationError("simulation: the elevation map does not have the geometry of the slope map");

    const double ex0 = g.originX(), ey0 = g.originY(), ex1 = ex0 + g.extentX(), ey1 = ey0 + g.extentY();
    m.area = in.area ? *in.area : SimArea{ex0, ey0, ex1, ey1};
    const double tol = 1e-6 * std::max(1.0, std::max(std::abs(ex1), std::abs(ey1)));
    if (m.area.x0 < ex0 - tol || m.area.y0 < ey0 - tol || m.area.x1 > ex1 + tol || m.area.y1 > ey1 + tol ||
        !(m.area.x1 > m.area.x0 && m.area.y1 > m.area.y0))
        throw ValidationError("simulation: area [" + num(m.area.x0) + ", " + num(m.area.y0) + ", " + num(m.area.x1) + ", " +
                              num(m.area.y1) + "] (x0, y0, x1, y1 in metres) is not inside the abiotics extent [" + num(ex0) +
                              ", " + num(ey0) + ", " + num(ex1) + ", " + num(ey1) + "]");
    m.areaHa = (m.area.x1 - m.area.x0) * (m.area.y1 - m.area.y0) / 10000.0;
    const double c = g.cellSizeM();
    const int ix0 = std::clamp(static_cast<int>(std::floor((m.area.x0 - ex0) / c + 1e-9)), 0, g.width() - 1);
    const int iy0 = std::clamp(static_cast<int>(std::floor((m.area.y0 - ey0) / c + 1e-9)), 0, g.height() - 1);
    const int ix1 = std::clamp(static_cast<int>(std::ceil((m.area.x1 - ex0) / c - 1e-9)), ix0 + 1, g.width());
    const int iy1 = std::clamp(static_cast<int>(std::ceil((m.area.y1 - ey0) / c - 1e-9)), iy0 + 1, g.height());
    m.geom = Grid<float>(ix1 - ix0, iy1 - iy0, c, ex0 + ix0 * c, ey0 + iy0 * c, 0.f);

    // Suitability per species and cell (Eq. 2) from the annual maps; elevation normalised
    // over the whole terrain (Eq. 11).
    const FactorGrids annual = annualFactors(abio);
    const float eMin = abio.elevationM.minValue(), eMax = abio.elevationM.maxValue();
    const std::size_t cells = m.geom.size(), ns = m.sp.size();
    m.suit.assign(ns * cells, 0.f);
    m.cellSun.assign(cells, 0.f);
    m.cellMoisture.assign(cells, 0.f);
    for (int iy = 0; iy < m.geom.height(); ++iy)
        for (int ix = 0; ix < m.geom.width(); ++ix) {
            const std::size_t cell = m.geom.index(ix, iy);
            const std::size_t src = g.index(ix0 + ix, iy0 + iy);
            const double sun = annual[Factor::Sun].data()[src], moist = annual[Factor::Moisture].data()[src];
            const double wind = annual[Factor::Wind].data()[src], slope = annual[Factor::Slope].data()[src];
            const double yNorm = eMax > eMin ? (abio.elevationM.data()[src] - eMin) / (eMax - eMin) : 0.0;
            m.cellSun[cell] = static_cast<float>(sun);
            m.cellMoisture[cell] = static_cast<float>(moist);
            for (std::size_t s = 0; s < ns; ++s) {
                const EcoModSpeciesParams& p = m.sp[s];
                const double vv = ecomodDeviationSuitability(yNorm, p.elevationOpt, p.elevationTol, p.elevationHarm) *
                                  ecomodDeviationSuitability(moist, p.moistureOpt, p.moistureTol, p.moistureHarm) *
                                  ecomodDeviationSuitability(sun, p.sunOpt, p.sunTol, p.sunHarm) *
                                  ecomodDeviationSuitability(wind, p.windOpt, p.windTol, p.windHarm) *
                                  ecomodSlopeSuitability(slope, p.slopeHarm);
                m.suit[s * cells + cell] = static_cast<float>(vv);
            }
        }
    // The disturbance events' ground: the same cells (sim/disturbance.h).
    auto crop = [&](const Grid<float>& src) {
        Grid<float> out = Grid<float>::like(m.geom, 0.f);
        if (src.sameGeometry(g))
            for (int iy = 0; iy < m.geom.height(); ++iy)
                for (int ix = 0; ix < m.geom.width(); ++ix) out(ix, iy) = src(ix0 + ix, iy0 + iy);
        return out;
    };
    m.siteElevation = crop(abio.elevationM);
    m.siteWind = crop(abio.windMS);
    for (const Grid<float>& month : abio.moistureMm.months) m.siteMoisture.push_back(crop(month));
    for (const Species& s : m.biome.species) m.fireTolerance.push_back(s.fireTolerance);
    m.elevation = std::move(abio.elevationM);

    // Static canopy trees that reach the area with their crown or their seeds.
    for (const Plant& t : in.canopy) {
        if (t.speciesId < 0 || static_cast<std::size_t>(t.speciesId) >= ns)
            throw ValidationError("simulation: a canopy tree has species id " + std::to_string(t.speciesId) + " outside the biome");
        const double reach = std::max(t.crownRadiusM, m.sp[static_cast<std::size_t>(t.speciesId)].dispersalRadiusM);
        if (t.xM + reach < m.area.x0 || t.xM - reach >= m.area.x1 || t.yM + reach < m.area.y0 || t.yM - reach >= m.area.y1)
            continue;
        m.canopy.push_back(t);
        m.canopyV.push_back(m.suitAt(t.speciesId, t.xM, t.yM));
    }

    for (const UndergrowthPlant& u : initial) {
        if (u.speciesId < 0 || static_cast<std::size_t>(u.speciesId) >= ns)
            throw ValidationError("simulation: an initial plant has species id " + std::to_string(u.speciesId) + " outside the biome");
        if (!m.inArea(u.xM, u.yM)) {
            ++m.droppedInitial;
            continue;
        }
        const EcoModSpeciesParams& p = m.sp[static_cast<std::size_t>(u.speciesId)];
        const double gAge = u.growthAgeYears > 0 ? u.growthAgeYears : ecomodPolylineAgeYears(p, u.heightM);
        const int ageYears = static_cast<int>(std::lround(u.ageYears > 0 ? u.ageYears : gAge));
        const std::uint64_t pid = m.nextId++;
        m.push(pid, u.speciesId, u.xM, u.yM, u.heightM, gAge, ageYears, m.drawDeathAge(u.speciesId, pid, ageYears + 1.0));
    }
    m.fate.assign(m.size(), 0);
    m.fingerprintValue = m.computeFingerprint();
}

EcoModel::~EcoModel() = default;

void EcoModel::stepYear() {
    // Store indices share the witness codes with the dozers' (kWitnessDozer | d): a store of
    // 2^30 trees (about 100 GB) would read as dozers, so it is refused rather than misread.
    if (impl_->id.size() >= Impl::kWitnessDozer)
        throw Error("simulation: EcoMod's store holds " + std::to_string(impl_->id.size()) + " trees, more than its limit of " +
                    std::to_string(Impl::kWitnessDozer - 1));
    impl_->seedYear();
    impl_->growYear();
    impl_->disturbYear();
    ++impl_->year;
}

// The disturbance events of the year, at its end (after growth and the year's deaths), in
// month order: each on the living trees, the killed removed before the next.
void EcoModel::Impl::disturbYear() {
    if (!disturbanceOn) return;
    const std::vector<PlannedEvent> events = eventsOfYear(disturbance, seed, year);
    if (events.empty()) return;
    wakeAll(year + 1);  // the events see every tree, in creation order
    std::vector<double> tolerance(sp.size());
    for (std::size_t s = 0; s < sp.size(); ++s)
        tolerance[s] = std::isnan(fireTolerance[s]) ? disturbance.fire.defaultTolerance : fireTolerance[s];
    for (const PlannedEvent& e : events) {
        const DisturbanceSite site = disturbanceSite(siteElevation, siteMoisture[static_cast<std::size_t>(e.month)], siteWind,
                                                     biome.wind, area.x0, area.y0, area.x1, area.y1);
        const PlantArrays arrays{size(), id.data(), species.data(), x.data(), y.data(), height.data()};
        DisturbanceOutcome out = runDisturbance(e, disturbance, site, arrays, tolerance, sp.size(), seed);
        fate.assign(size(), 0);
        for (std::size_t p = 0; p < size(); ++p)
            if (out.killed[p]) {
                fate[p] = 3;
                ++counters.diedDisturbance;
            }
        compact();
        disturbanceEvents.push_back(std::move(out.record));
    }
}

void EcoModel::setDisturbance(const DisturbanceSettings& settings) {
    settings.validate("disturbance");
    Impl& m = *impl_;
    m.disturbance = settings;
    m.disturbanceOn = settings.enabled();
    m.fingerprintValue = m.computeFingerprint();
}
const DisturbanceSettings& EcoModel::disturbance() const { return impl_->disturbance; }
const std::vector<DisturbanceRecord>& EcoModel::disturbances() const { return impl_->disturbanceEvents; }

int EcoModel::yearsDone() const { return impl_->year; }
std::size_t EcoModel::plantCount() const { return impl_->size() + impl_->sleepersLive + impl_->dozersLive; }
std::size_t EcoModel::setAsideCount() const { return impl_->sleepersLive; }
EcoModel::CacheCounts EcoModel::cacheCounts() const { return impl_->cacheCounts; }
void EcoModel::forgetCaches() {
    Impl& m = *impl_;
    m.wakeAll(m.year);
    std::fill(m.witness.begin(), m.witness.end(), Impl::kNoWitness);
    std::fill(m.sure.begin(), m.sure.end(), std::uint8_t{0});
    std::fill(m.gridKey.begin(), m.gridKey.end(), Impl::kNoKey);
    m.gridBase = 0;  // the grids' base and every key computed afresh
    m.coverGuess.clear();
}
void EcoModel::checkSleeperCalendar(bool on) { impl_->checkCalendar = on; }
std::size_t EcoModel::dozingCount() const { return impl_->dozersLive; }
void EcoModel::setDozing(bool on) {
    impl_->dozing = on;
    if (!on) impl_->wakeAll(impl_->year);
}

std::vector<UndergrowthPlant> EcoModel::plants() const {
    const Impl& m = *impl_;
    std::vector<UndergrowthPlant> out;
    out.reserve(m.size() + m.sleepersLive + m.dozersLive);
    m.forEachTree([&](std::uint64_t pid, std::int32_t s, double px, double py, double h, double r, double g, std::int32_t ageYears,
                      double, float vv, std::int32_t) {
        UndergrowthPlant& u = out.emplace_back();
        u.id = pid;
        u.speciesId = s;
        u.xM = px;
        u.yM = py;
        u.groundZM = m.elevation.sampleBilinear(px, py);
        u.heightM = h;
        u.crownRadiusM = r;
        u.ageYears = ageYears;
        u.growthAgeYears = g;
        u.vigour = vv;
        u.pool = h / m.hRef * m.sp[static_cast<std::size_t>(s)].persistence * vv;
        const std::size_t cell = m.cellOf(px, py);
        u.sunShare = m.cellSun[cell];
        u.waterShare = m.cellMoisture[cell];
    });
    return out;
}

YearRecord EcoModel::census() const {
    const Impl& m = *impl_;
    const std::size_t ns = m.sp.size();
    YearRecord r;
    r.year = m.year;
    r.count.assign(ns, 0);
    r.meanHeightM.assign(ns, 0);
    r.meanVigour.assign(ns, 0);
    r.crownAreaM2.assign(ns, 0);
    m.forEachTree([&](std::uint64_t, std::int32_t sid, double, double, double h, double rad, double, std::int32_t, double, float vv,
                      std::int32_t) {
        const std::size_t s = static_cast<std::size_t>(sid);
        ++r.count[s];
        r.meanHeightM[s] += h;
        r.meanVigour[s] += vv;
        r.crownAreaM2[s] += kPi * rad * rad;
    });
    for (std::size_t s = 0; s < ns; ++s)
        if (r.count[s] > 0) {
            r.meanHeightM[s] /= r.count[s];
            r.meanVigour[s] /= r.count[s];
        }
    return r;
}

const SimCounters& EcoModel::counters() const { return impl_->counters; }
std::size_t EcoModel::droppedInitialPlants() const { return impl_->droppedInitial; }
const SimParams& EcoModel::params() const { return impl_->params; }
const Biome& EcoModel::biome() const { return impl_->biome; }
std::uint64_t EcoModel::seed() const { return impl_->seed; }
SimArea EcoModel::area() const { return impl_->area; }
const Grid<float>& EcoModel::gridGeometry() const { return impl_->geom; }
const std::vector<Plant>& EcoModel::relevantCanopy() const { return impl_->canopy; }
const std::vector<EcoModSpeciesParams>& EcoModel::speciesParams() const { return impl_->sp; }
double EcoModel::suitability(int s, double xM, double yM) const {
    if (s < 0 || static_cast<std::size_t>(s) >= impl_->sp.size() || !impl_->inArea(xM, yM)) return 0.0;
    return impl_->suitAt(s, xM, yM);
}
std::uint64_t EcoModel::fingerprint() const { return impl_->fingerprintValue; }
std::size_t EcoModel::removeTrees(const std::vector<std::uint8_t>& dead) {
    Impl& m = *impl_;
    m.wakeAll(m.year);  // `dead` is indexed as plants()
    if (dead.size() != m.size())
        throw ValidationError("removeTrees: " + std::to_string(dead.size()) + " flags for " + std::to_string(m.size()) + " trees");
    std::size_t removed = 0;
    m.fate.assign(m.size(), 0);
    for (std::size_t p = 0; p < dead.size(); ++p)
        if (dead[p]) {
            m.fate[p] = 1;
            ++removed;
        }
    m.compact();
    return removed;
}
std::size_t EcoModel::bytesPerPlant() const {
    // The store: id, species, age, lives, six doubles, v, witness, sure, grid key; twice (the
    // second copy that growStore writes).
    const std::size_t store = sizeof(std::uint64_t) + 3 * sizeof(std::int32_t) + 6 * sizeof(double) + sizeof(float) +
                              sizeof(std::uint32_t) + sizeof(std::uint8_t) + sizeof(std::uint32_t);
    return 2 * store +
           /* step scratch: ability, fate, dominated, bucket, slot, new index, two packed copies */
           sizeof(double) + 2 + 3 * sizeof(std::uint32_t) + 2 * sizeof(Impl::Entry);
}

void EcoModel::saveState(h5::File& f, const std::string& group) const {
    const Impl& m = *impl_;
    const hsize_t n = m.size() + m.sleepersLive + m.dozersLive;
    f.ensureGroup(group);
    f.setAttr(group, "model", std::string("ecomod"));
    f.setAttr(group, "fingerprint", hex64(fingerprint()));
    f.setAttr(group, "years_done", static_cast<std::int64_t>(m.year));
    f.setAttr(group, "next_id", static_cast<std::int64_t>(m.nextId));
    f.setAttr(group, "plant_months", static_cast<std::int64_t>(m.counters.plantMonths));
    f.setAttr(group, "germinated", static_cast<std::int64_t>(m.counters.germinated));
    f.setAttr(group, "died_at_max_age", static_cast<std::int64_t>(m.counters.diedBackgroundOrStress));
    f.setAttr(group, "died_dominated", static_cast<std::int64_t>(m.counters.diedDominated));
    f.setAttr(group, "dropped_initial", static_cast<std::int64_t>(m.droppedInitial));
    if (m.disturbanceOn) {  // the events so far (the draws are keyed by seed and event: no generator state)
        f.setAttr(group, "died_disturbance", static_cast<std::int64_t>(m.counters.diedDisturbance));
        writeDisturbanceTable(f, group + "/disturbance", m.disturbanceEvents, m.biome);
    }
    // Every tree in creation order (the store and the sleepers merged).
    std::vector<std::int32_t> idLo, idHi, sps, ages, livesLeft;
    std::vector<double> xs, ys, hs, gs, ds;
    for (auto* a : {&idLo, &idHi, &sps, &ages, &livesLeft}) a->reserve(n);
    for (auto* a : {&xs, &ys, &hs, &gs, &ds}) a->reserve(n);
    m.forEachTree([&](std::uint64_t pid, std::int32_t s, double px, double py, double h, double, double g, std::int32_t ageYears,
                      double dAge, float, std::int32_t lv) {
        idLo.push_back(static_cast<std::int32_t>(static_cast<std::uint32_t>(pid)));
        idHi.push_back(static_cast<std::int32_t>(static_cast<std::uint32_t>(pid >> 32)));
        sps.push_back(s);
        xs.push_back(px);
        ys.push_back(py);
        hs.push_back(h);
        gs.push_back(g);
        ds.push_back(dAge);
        ages.push_back(ageYears);
        livesLeft.push_back(lv);
    });
    f.writeI32(group + "/id_lo", idLo, {n}, "1");
    f.writeI32(group + "/id_hi", idHi, {n}, "1");
    f.writeI32(group + "/species", sps, {n}, "1");
    f.writeF64(group + "/x", xs, {n}, "m");
    f.writeF64(group + "/y", ys, {n}, "m");
    f.writeF64(group + "/height", hs, {n}, "m");
    f.writeF64(group + "/growth_age", gs, {n}, "years");
    f.writeF64(group + "/death_age", ds, {n}, "years");
    f.writeI32(group + "/age", ages, {n}, "years");
    f.writeI32(group + "/dominated_lives", livesLeft, {n}, "years");  // dominated years still survived (2^30: every one)
}

void EcoModel::loadState(const h5::File& f, const std::string& group) {
    Impl& m = *impl_;
    const std::string where = f.path() + ": " + group;
    if (!f.exists(group)) throw IoError(where + ": no simulation state");
    if (!f.hasAttr(group, "model") || f.attrString(group, "model") != "ecomod")
        throw IoError(where + ": the checkpoint is not of an ecomod run");
    const std::string fp = f.attrString(group, "fingerprint");
    if (fp != hex64(fingerprint()))
        throw IoError(where + ": the checkpoint belongs to another run (different inputs, biome, area, seed, model "
                              "parameters or disturbance settings; fingerprint " + fp + ", this run " + hex64(fingerprint()) + ")");
    const auto idLo = f.readI32(group + "/id_lo");
    const auto idHi = f.readI32(group + "/id_hi");
    const auto sps = f.readI32(group + "/species");
    const auto xs = f.readF64(group + "/x");
    const auto ys = f.readF64(group + "/y");
    const auto hs = f.readF64(group + "/height");
    const auto gs = f.readF64(group + "/growth_age");
    const auto ds = f.readF64(group + "/death_age");
    const auto as = f.readI32(group + "/age");
    if (!f.exists(group + "/dominated_lives")) throw IoError(where + ": no dominated_lives (a checkpoint of an older EcoMod)");
    const auto ls = f.readI32(group + "/dominated_lives");
    const std::size_t n = sps.size();
    for (std::size_t len : {idLo.size(), idHi.size(), xs.size(), ys.size(), hs.size(), gs.size(), ds.size(), as.size(), ls.size()})
        if (len != n) throw IoError(where + ": plant arrays differ in length");
    m.id.clear();
    m.species.clear();
    for (auto* a : {&m.x, &m.y, &m.height, &m.radius, &m.growthAge, &m.deathAge}) a->clear();
    m.age.clear();
    m.v.clear();
    m.witness.clear();
    m.sure.clear();
    m.lives.clear();
    m.gridKey.clear();
    m.sleepers.clear();  // every tree in the store; the dominated seedlings go to sleep again in the next year
    m.sleepEvent.clear();
    m.sleepWitness.clear();
    m.watched.clear();
    m.clearCalendar();
    m.sleepersLive = 0;
    m.dozers.clear();  // and the dozers: they doze again from the next year on
    m.dozerEvent.clear();
    m.dozerWitness.clear();
    m.dozerKey.clear();
    m.dozerOrder.clear();
    m.dozerAbility.clear();
    m.dozerDue.clear();
    m.dozersLive = 0;
    for (std::size_t p = 0; p < n; ++p) {
        if (sps[p] < 0 || static_cast<std::size_t>(sps[p]) >= m.sp.size()) throw IoError(where + ": plant " + std::to_string(p) + " has a bad species");
        const std::uint64_t pid = (static_cast<std::uint64_t>(static_cast<std::uint32_t>(idHi[p])) << 32) |
                                  static_cast<std::uint32_t>(idLo[p]);
        if (ls[p] < 0 || ls[p] > Impl::kInfiniteLives) throw IoError(where + ": plant " + std::to_string(p) + " has bad dominated_lives");
        m.push(pid, sps[p], xs[p], ys[p], hs[p], gs[p], as[p], ds[p]);
        m.lives.back() = ls[p];
    }
    m.fate.assign(n, 0);
    m.year = static_cast<int>(f.attrInt(group, "years_done"));
    m.nextId = static_cast<std::uint64_t>(f.attrInt(group, "next_id"));
    m.counters = SimCounters{};
    m.counters.plantMonths = f.attrInt(group, "plant_months");
    m.counters.germinated = f.attrInt(group, "germinated");
    m.counters.diedBackgroundOrStress = f.attrInt(group, "died_at_max_age");
    m.counters.diedDominated = f.attrInt(group, "died_dominated");
    m.droppedInitial = static_cast<std::size_t>(f.attrInt(group, "dropped_initial"));
    m.counters.diedDisturbance = f.hasAttr(group, "died_disturbance") ? f.attrInt(group, "died_disturbance") : 0;
    m.disturbanceEvents.clear();
    if (m.disturbanceOn && f.exists(group + "/disturbance"))
        m.disturbanceEvents = readDisturbanceTable(f, group + "/disturbance", m.sp.size());
}

}  // namespace eco::sim
