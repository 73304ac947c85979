// The undergrowth simulator's public front (simulator.h) and the monthly step that runs the
// phases; the engine's data layout is in simulator_impl.h and each phase has its own file.
// The model is in processes.h; docs/simulator.md describes the data layout and the parallel
// sweep ("Parallel sweep without races").
#include "simulator_impl.h"

#include "ecomod.h"

namespace eco::sim {

// The monthly step of Algorithm 2: the layout (simulator_layout.cpp), the band sweep
// (simulator_sweep.cpp), the plant processes (simulator_plants.cpp) and, in the seeding
// month, germination (simulator_germination.cpp).
void Simulation::Impl::stepMonth() {
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
    if (disturbanceOn) disturb(m);
    if (m == params.seedingMonth) {
        germinate(static_cast<std::uint64_t>(month / 12));
        lap(phaseSeconds.germination);
    }
    ++month;
}

// The disturbance events of month m (sim/disturbance.h): after the month's mortality and
// before germination, so that a fire in the seeding month clears ground for that year's
// seedlings. The dead are settled first and the killed ones removed at once.
void Simulation::Impl::disturb(int m) {
    const int year = static_cast<int>(month / 12);
    std::vector<PlannedEvent> events = eventsOfYear(disturbance, seed, year);
    events.erase(std::remove_if(events.begin(), events.end(), [m](const PlannedEvent& e) { return e.month != m; }), events.end());
    if (events.empty()) return;
    std::vector<double> tolerance(spc.size());
    for (std::size_t s = 0; s < spc.size(); ++s) {
        const double t = biome.species[s].fireTolerance;
        tolerance[s] = std::isnan(t) ? disturbance.fire.defaultTolerance : t;
    }
    for (const PlannedEvent& e : events) {
        compact();  // the store holds the living only
        // The abiotics cells covering the area: the event's ground.
        const DisturbanceSite site = abioticsDisturbanceSite(abio, biome.wind, m, area.x0, area.y0, area.x1, area.y1);
        PlantArrays arrays{pl.size(), pl.id.data(), pl.species.data(), pl.x.data(), pl.y.data(), pl.height.data()};
        DisturbanceOutcome out = runDisturbance(e, disturbance, site, arrays, tolerance, spc.size(), seed);
        fate.assign(pl.size(), 0);
        for (std::size_t p = 0; p < pl.size(); ++p)
            if (out.killed[p]) {
                fate[p] = 4;
                ++deadPending;
                ++counters.diedDisturbance;
            }
        compact();
        disturbanceEvents.push_back(std::move(out.record));
    }
}

UndergrowthPlant Simulation::Impl::plantAt(std::size_t p) const {
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

// ====================================================================== public API

void setParallelThresholds(std::size_t plants, std::size_t cells) {
    kParallelPlants = plants;
    kParallelCells = cells;
}

Simulation::Simulation(SimInputs inputs, SimParams params, std::uint64_t seed,
                       const std::vector<UndergrowthPlant>& initial)
{
    if (params.kind == ModelKind::EcoMod) {
        eco_ = std::make_unique<EcoModel>(std::move(inputs), params, seed, initial);
        return;
    }
    impl_ = std::make_unique<Impl>();
    impl_->setup(std::move(inputs), params, seed);
    impl_->addInitial(initial);
}

void Simulation::requireMonthly(const char* what) const {
    if (eco_) throw ValidationError(std::string("simulation: ") + what + " belongs to the monthly model, not to ecomod");
}

Simulation::~Simulation() = default;

void Simulation::setDisturbance(const DisturbanceSettings& settings) {
    settings.validate("disturbance");
    if (eco_) return eco_->setDisturbance(settings);  // yearly: the events at the year's end
    impl_->disturbance = settings;
    impl_->disturbanceOn = settings.enabled();
    impl_->fingerprintReady = false;
}
const DisturbanceSettings& Simulation::disturbance() const {
    return eco_ ? eco_->disturbance() : impl_->disturbance;
}
const std::vector<DisturbanceRecord>& Simulation::disturbances() const {
    return eco_ ? eco_->disturbances() : impl_->disturbanceEvents;
}

void Simulation::stepMonth() {
    requireMonthly("a monthly step");
    impl_->stepMonth();
}
void Simulation::stepYear() {
    if (eco_) return eco_->stepYear();
    for (int i = 0; i < 12; ++i) impl_->stepMonth();
}
std::int64_t Simulation::monthsDone() const { return eco_ ? 12 * static_cast<std::int64_t>(eco_->yearsDone()) : impl_->month; }
// The observers below see the living plants only: those that take the store's order settle
// the dead first (settleDead: the state the monthly step would reach anyway), which changes
// nothing observable. Like the rest of the class, not for concurrent use.
std::size_t Simulation::plantCount() const { return eco_ ? eco_->plantCount() : impl_->pl.size() - impl_->deadPending; }

std::vector<UndergrowthPlant> Simulation::plants() const {
    if (eco_) return eco_->plants();
    impl_->settleDead();
    std::vector<UndergrowthPlant> out(impl_->pl.size());
    for (std::size_t p = 0; p < out.size(); ++p) out[p] = impl_->plantAt(p);
    return out;
}

YearRecord Simulation::census() const {
    if (eco_) return eco_->census();
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

const SimCounters& Simulation::counters() const { return eco_ ? eco_->counters() : impl_->counters; }
const SimPhaseSeconds& Simulation::phaseSeconds() const {
    static const SimPhaseSeconds none{};
    return eco_ ? none : impl_->phaseSeconds;
}
std::size_t Simulation::droppedInitialPlants() const { return eco_ ? eco_->droppedInitialPlants() : impl_->droppedInitial; }
const SimParams& Simulation::params() const { return eco_ ? eco_->params() : impl_->params; }
const Biome& Simulation::biome() const { return eco_ ? eco_->biome() : impl_->biome; }
std::uint64_t Simulation::seed() const { return eco_ ? eco_->seed() : impl_->seed; }
SimArea Simulation::area() const { return eco_ ? eco_->area() : impl_->area; }
const Grid<float>& Simulation::gridGeometry() const { return eco_ ? eco_->gridGeometry() : impl_->seedProb; }
const std::vector<Plant>& Simulation::relevantCanopy() const { return eco_ ? eco_->relevantCanopy() : impl_->canopy; }
const Grid<float>& Simulation::seedProbability() const {
    requireMonthly("the seedbank");
    return impl_->seedProb;
}
const Grid<float>& Simulation::canopyTransmission() const {
    requireMonthly("the canopy transmission");
    return impl_->canopyTrans;
}

Grid<std::int32_t> Simulation::seedPackages() const {
    requireMonthly("the seedbank");
    Grid<std::int32_t> g(impl_->W, impl_->H, impl_->cell, impl_->ox, impl_->oy, 0);
    for (std::size_t i = 0; i < g.size(); ++i) g.data()[i] = impl_->seedPkg[i];
    return g;
}

bool Simulation::leftoverMeans(int ix, int iy, int period, double& sunHours, double& waterMm) const {
    requireMonthly("leftover resources");
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
    requireMonthly("the germination roulette");
    const Impl& s = *impl_;
    if (ix < 0 || iy < 0 || ix >= s.W || iy >= s.H) throw ValidationError("germinationWeights: cell out of range");
    std::vector<double> w(s.spc.size()), arg(s.spc.size());
    std::vector<int> cand(s.spc.size());
    s.weightsAt(ix, iy, w.data(), arg.data(), cand.data());
    return w;
}

std::size_t Simulation::bytesPerCell() const {
    if (eco_) return eco_->speciesParams().size() * sizeof(float) + 2 * sizeof(float);  // suitability per species, sun, moisture
    return sizeof(float) /*canopy transmission*/ + sizeof(std::uint8_t) /*canopy trees*/ + sizeof(std::uint16_t) /*occupants*/ +
           sizeof(float) /*seed probability*/ + sizeof(std::uint16_t) /*package*/ + impl_->periods() * 2 * sizeof(float);
}

std::size_t Simulation::bytesPerPlant() const {
    // State arrays plus the per-plant scratch: row and band bounds, the footprint's radius
    // range, slot starts, about 1.1 band slots of partials and band entries, the span pool
    // (live and dead spans; a repack briefly holds a second, live-only copy), order and
    // radix scratch, fate and the slots' dead marks. Per living plant: the dead still in the
    // store (at most an eighth of it, compactIfDue) are counted in.
    if (eco_) return eco_->bytesPerPlant();
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
