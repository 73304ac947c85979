// Disturbance events: fire spread and kills, windthrow (sim/disturbance.h,
// docs/disturbance.md).
#include "disturbance.h"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <utility>

#include "error.h"
#include "rng.h"
#include "param_desc.h"

namespace eco::sim {

namespace {

// Streams of the disturbance draws, derived from the run seed like every stream of the
// simulator (core/rng.h): "disturb" in ASCII, then the kind / the event / the entity.
constexpr std::uint64_t kDisturbanceStream = 0x6469737475726221ull;
constexpr std::uint64_t kIgnitionSalt = 0x69676E6974696F6Eull;
constexpr std::uint64_t kPlantSalt = 0x706C616E74736B6Cull;
constexpr double kPi = 3.14159265358979323846;

double unit32(std::uint32_t w) { return static_cast<double>(w) * 0x1.0p-32; }

const EventTiming& timingOf(const DisturbanceSettings& s, DisturbanceKind k) {
    return k == DisturbanceKind::Fire ? s.fire.timing : s.storm.timing;
}

}  // namespace

const char* disturbanceKindName(DisturbanceKind k) { return k == DisturbanceKind::Fire ? "fire" : "storm"; }

const std::vector<ParamDesc<EventTiming>>& eventTimingParamFields() {
    using K = ParamDesc<EventTiming>::Kind;
    using R = ParamRange;
    using T = EventTiming;
    static const std::vector<ParamDesc<EventTiming>> fields = {
        {"probability_per_year", "chance of an event in a year (0: forced years only)", "", K::Real, &T::probabilityPerYear,
         nullptr, R::closed(0, 1)},
        {"month", "the month at whose end events strike (0 = January)", "month", K::Integer, nullptr, &T::month,
         R::closed(0, 11), nullptr, "must lie in 0..11 (0 = January)"},
    };
    return fields;
}

// Positive lengths and moistures are capped at 1e9 (a typo such as 1e300 is refused).
const std::vector<ParamDesc<FireSettings>>& fireParamFields() {
    using K = ParamDesc<FireSettings>::Kind;
    using R = ParamRange;
    using F = FireSettings;
    static const std::vector<ParamDesc<FireSettings>> fields = {
        {"spread_probability",
         "p0: probability that fire passes from a burning cell to a neighbour on flat, calm, dry ground", "", K::Real,
         &F::spreadProbability, nullptr, R::closed(0, 1)},
        {"slope_factor", "slope bias: a step's probability x exp(this x rise / run)", "", K::Real, &F::slopeFactor, nullptr,
         R::closed(0, 100)},
        {"wind_factor", "wind bias: a step's probability x exp(this x U x cos phi), U the burning cell's wind exposure", "per m/s",
         K::Real, &F::windFactor, nullptr, R::closed(0, 100)},
        {"extinction_moisture_mm",
         "moisture at and above which a cell does not burn; below it the probability into the cell x (1 - moisture / this)",
         "mm/month", K::Real, &F::extinctionMoistureMm, nullptr, R::openClosed(0, 1e9), nullptr,
         "must be positive (at most 1e9)"},
        {"severity", "kill probability of a plant of tolerance 0 below the scorch height in a burnt cell", "", K::Real,
         &F::severity, nullptr, R::closed(0, 1)},
        {"scorch_height_m", "plants up to this height are scorched whole, taller ones with probability x this / height", "m",
         K::Real, &F::scorchHeightM, nullptr, R::openClosed(0, 1e9), nullptr, "must be positive (at most 1e9)"},
        {"default_tolerance", "fire tolerance of species whose biome entry has no `fire_tolerance`", "", K::Real,
         &F::defaultTolerance, nullptr, R::closed(0, 1)},
    };
    return fields;
}

const std::vector<ParamDesc<StormSettings>>& stormParamFields() {
    using K = ParamDesc<StormSettings>::Kind;
    using R = ParamRange;
    using W = StormSettings;
    static const std::vector<ParamDesc<StormSettings>> fields = {
        {"severity", "kill probability of a plant of the reference height on fully exposed ground", "", K::Real, &W::severity,
         nullptr, R::closed(0, 1)},
        {"reference_height_m", "height scale: the probability x min(1, (height / this)^height_exponent)", "m", K::Real,
         &W::referenceHeightM, nullptr, R::openClosed(0, 1e9), nullptr, "must be positive (at most 1e9)"},
        {"height_exponent", "exponent of the height scale", "", K::Real, &W::heightExponent, nullptr, R::closed(0, 100)},
        {"reference_wind_ms", "wind exposure counted as fully exposed; 0: the biome's prevailing wind strength", "m/s",
         K::Real, &W::referenceWindMS, nullptr, R::closed(0, 1000)},
    };
    return fields;
}

namespace {
// The keys every kind has, in the order they are written (enabled and return_interval_years
// are not written: a written table is on, and the interval is written as its probability),
// then the kind's own numbers.
template <typename S>
std::vector<DisturbanceField<S>> eventFields(const std::vector<ParamDesc<S>>& own) {
    using D = DisturbanceField<S>;
    using K = typename D::Kind;
    const auto& timing = eventTimingParamFields();
    D enabled{K::Enabled};
    enabled.ownKey = "enabled";
    enabled.ownDoc = "false: as if the table were absent (the table alone switches the kind on)";
    enabled.ownDefault = "true";
    enabled.ownAllowed = "true, false";
    D interval{K::ReturnInterval};
    interval.ownKey = "return_interval_years";
    interval.ownDoc = "instead of probability_per_year (not both): the probability is 1 / this";
    interval.ownUnit = "years";
    interval.ownDefault = "-";
    interval.ownAllowed = ">= 1";
    interval.range = ParamRange::atLeast(1);
    interval.rule = "must be at least 1 (years)";
    D years{K::ForcedYears};
    years.ownKey = "years";
    years.ownDoc = "forced events: one in each of these years (0 = the first simulated year)";
    years.ownDefault = "[]";
    years.ownAllowed = "a list of integers in [0, 2147483647]";
    years.range = ParamRange::closed(0, 2147483647);
    years.rule = "must lie in 0..2147483647 (0 = the first simulated year)";
    std::vector<D> out = {enabled, D::timingField(paramField(timing, "probability_per_year")), interval, years,
                          D::timingField(paramField(timing, "month"))};
    for (const auto& f : own) out.push_back(D::settingField(f));
    return out;
}
}  // namespace

const std::vector<DisturbanceField<FireSettings>>& fireFields() {
    static const std::vector<DisturbanceField<FireSettings>> fields = eventFields(fireParamFields());
    return fields;
}
const std::vector<DisturbanceField<StormSettings>>& stormFields() {
    static const std::vector<DisturbanceField<StormSettings>> fields = eventFields(stormParamFields());
    return fields;
}

template <typename S>
std::string disturbanceTomlLines(const S& s, const std::vector<DisturbanceField<S>>& fields, bool withDocs) {
    std::string out;
    for (const auto& f : fields) {
        if (!f.written()) continue;
        out += std::string(f.key()) + " = " + f.tomlValue(s);
        if (withDocs) out += std::string("  # ") + f.doc() + (*f.unit() ? std::string(", ") + f.unit() : std::string());
        out += "\n";
    }
    return out;
}

template <typename S>
std::string firstInvalidDisturbanceValue(const S& s, const std::vector<DisturbanceField<S>>& fields) {
    using K = typename DisturbanceField<S>::Kind;
    for (const auto& f : fields) {
        const std::string key = f.key();
        switch (f.kind) {
            case K::Enabled:
            case K::ReturnInterval: break;  // not stored (read into enabled / the probability)
            case K::ForcedYears:
                for (int y : s.timing.forcedYears)
                    if (!f.range.contains(y)) return key + " = " + std::to_string(y) + ": " + f.ruleText();
                break;
            case K::Timing:
                if (!f.timing->range.contains(f.timing->value(s.timing))) return key + " = " + f.tomlValue(s) + ": " + f.ruleText();
                break;
            case K::Setting:
                if (!f.setting->range.contains(f.setting->value(s))) return key + " = " + f.tomlValue(s) + ": " + f.ruleText();
                break;
        }
    }
    return {};
}

template std::string disturbanceTomlLines(const FireSettings&, const std::vector<DisturbanceField<FireSettings>>&, bool);
template std::string disturbanceTomlLines(const StormSettings&, const std::vector<DisturbanceField<StormSettings>>&, bool);
template std::string firstInvalidDisturbanceValue(const FireSettings&, const std::vector<DisturbanceField<FireSettings>>&);
template std::string firstInvalidDisturbanceValue(const StormSettings&, const std::vector<DisturbanceField<StormSettings>>&);

void DisturbanceSettings::validate(const std::string& source) const {
    if (fire.enabled)
        if (const std::string bad = firstInvalidDisturbanceValue(fire, fireFields()); !bad.empty())
            throw ValidationError(source + ": [disturbance.fire] " + bad);
    if (storm.enabled)
        if (const std::string bad = firstInvalidDisturbanceValue(storm, stormFields()); !bad.empty())
            throw ValidationError(source + ": [disturbance.storm] " + bad);
}

std::string DisturbanceSettings::toToml() const {
    std::string out;
    if (fire.enabled) out += "[disturbance.fire]\n" + disturbanceTomlLines(fire, fireFields(), false);
    if (storm.enabled) out += "[disturbance.storm]\n" + disturbanceTomlLines(storm, stormFields(), false);
    return out;
}

std::vector<PlannedEvent> eventsOfYear(const DisturbanceSettings& s, std::uint64_t seed, int year) {
    std::vector<PlannedEvent> out;
    for (DisturbanceKind k : {DisturbanceKind::Fire, DisturbanceKind::Storm}) {
        if (!(k == DisturbanceKind::Fire ? s.fire.enabled : s.storm.enabled)) continue;
        const EventTiming& t = timingOf(s, k);
        bool strikes = std::find(t.forcedYears.begin(), t.forcedYears.end(), year) != t.forcedYears.end();
        if (!strikes && t.probabilityPerYear > 0) {
            const auto w = randomBits(seed, mixStream(kDisturbanceStream, static_cast<std::uint64_t>(k)),
                                      static_cast<std::uint64_t>(year));
            strikes = bitsToUnit(w[0], w[1]) < t.probabilityPerYear;
        }
        if (!strikes) continue;
        PlannedEvent e;
        e.kind = k;
        e.year = year;
        e.month = t.month;
        e.key = mixStream(mixStream(kDisturbanceStream + 1, static_cast<std::uint64_t>(k)), static_cast<std::uint64_t>(year));
        out.push_back(e);
    }
    std::stable_sort(out.begin(), out.end(), [](const PlannedEvent& a, const PlannedEvent& b) { return a.month < b.month; });
    return out;
}

DisturbanceSite disturbanceSite(Grid<float> elevationM, Grid<float> moistureMm, Grid<float> windMS, const Wind& wind,
                                double x0, double y0, double x1, double y1) {
    DisturbanceSite site;
    site.elevationM = std::move(elevationM);
    site.moistureMm = std::move(moistureMm);
    site.windMS = std::move(windMS);
    site.windFromDeg = wind.directionDeg;
    site.windStrengthMS = wind.strengthMS;
    site.x0 = x0;
    site.y0 = y0;
    site.x1 = x1;
    site.y1 = y1;
    return site;
}

DisturbanceSite abioticsDisturbanceSite(const Abiotics& abio, const Wind& wind, int month, double x0, double y0, double x1,
                                        double y1) {
    const Grid<float>& ag = abio.slopeDeg;
    const int cx0 = std::clamp(ag.cellX(x0), 0, ag.width() - 1), cy0 = std::clamp(ag.cellY(y0), 0, ag.height() - 1);
    const int cx1 = std::clamp(ag.cellX(std::nextafter(x1, x0)), 0, ag.width() - 1);
    const int cy1 = std::clamp(ag.cellY(std::nextafter(y1, y0)), 0, ag.height() - 1);
    const int w = cx1 - cx0 + 1, h = cy1 - cy0 + 1;
    const double cs = ag.cellSizeM();
    auto crop = [&](const Grid<float>& src) {
        Grid<float> g(w, h, cs, ag.originX() + cx0 * cs, ag.originY() + cy0 * cs, 0.0f);
        if (src.width() == ag.width() && src.height() == ag.height())
            for (int y = 0; y < h; ++y)
                for (int x = 0; x < w; ++x) g(x, y) = src(cx0 + x, cy0 + y);
        return g;
    };
    return disturbanceSite(crop(abio.elevationM), crop(abio.moistureMm.months[static_cast<std::size_t>(month)]),
                           crop(abio.windMS), wind, x0, y0, x1, y1);
}

double fireStepProbability(const DisturbanceSite& site, const FireSettings& f, int ax, int ay, int dx, int dy) {
    const Grid<float>& z = site.elevationM;
    const int bx = ax + dx, by = ay + dy;
    const double moist = site.moistureMm(bx, by);
    if (!(moist < f.extinctionMoistureMm)) return 0.0;
    const double dry = 1.0 - std::max(0.0, moist) / f.extinctionMoistureMm;
    const double len = std::hypot(static_cast<double>(dx), static_cast<double>(dy));
    const double rise = (static_cast<double>(z(bx, by)) - z(ax, ay)) / (len * z.cellSizeM());
    // Downwind unit vector (x east, y north): the wind comes FROM windFromDeg (clockwise from north).
    const double th = site.windFromDeg * kPi / 180.0;
    const double cosPhi = (dx * -std::sin(th) + dy * -std::cos(th)) / len;
    const double u = site.windMS(ax, ay);
    const double p = f.spreadProbability * std::exp(f.slopeFactor * rise + f.windFactor * u * cosPhi) * dry;
    return std::min(1.0, p);
}

std::vector<std::uint8_t> spreadFire(const DisturbanceSite& site, const FireSettings& f, int ix, int iy,
                                     std::uint64_t seed, std::uint64_t eventKey) {
    const Grid<float>& g = site.elevationM;
    const int w = g.width(), h = g.height();
    std::vector<std::uint8_t> burnt(static_cast<std::size_t>(w) * static_cast<std::size_t>(h), 0);
    if (!g.inside(ix, iy) || !(site.moistureMm(ix, iy) < f.extinctionMoistureMm)) return burnt;
    static constexpr int kDx[8] = {1, 1, 0, -1, -1, -1, 0, 1}, kDy[8] = {0, 1, 1, 1, 0, -1, -1, -1};
    std::vector<std::size_t> queue{g.index(ix, iy)};
    burnt[queue[0]] = 1;
    for (std::size_t head = 0; head < queue.size(); ++head) {
        const std::size_t a = queue[head];
        const int ax = static_cast<int>(a % static_cast<std::size_t>(w)), ay = static_cast<int>(a / static_cast<std::size_t>(w));
        // One draw per direction of cell a: eight 32-bit words of two blocks of its stream.
        const std::uint64_t stream = mixStream(eventKey, a);
        const auto w0 = randomBits(seed, stream, 0), w1 = randomBits(seed, stream, 1);
        const std::uint32_t words[8] = {w0[0], w0[1], w0[2], w0[3], w1[0], w1[1], w1[2], w1[3]};
        for (int k = 0; k < 8; ++k) {
            const int bx = ax + kDx[k], by = ay + kDy[k];
            if (bx < 0 || by < 0 || bx >= w || by >= h) continue;
            const std::size_t b = g.index(bx, by);
            if (burnt[b]) continue;
            if (unit32(words[k]) < fireStepProbability(site, f, ax, ay, kDx[k], kDy[k])) {
                burnt[b] = 1;
                queue.push_back(b);
            }
        }
    }
    return burnt;
}

std::vector<std::uint8_t> fireBurntCells(const PlannedEvent& e, const FireSettings& f, const DisturbanceSite& site,
                                         std::uint64_t seed, double* ignitionX, double* ignitionY) {
    const Grid<float>& g = site.elevationM;
    RandomStream rs(seed, mixStream(e.key, kIgnitionSalt));
    const double xM = site.x0 + (site.x1 - site.x0) * rs.uniform();
    const double yM = site.y0 + (site.y1 - site.y0) * rs.uniform();
    if (ignitionX) *ignitionX = xM;
    if (ignitionY) *ignitionY = yM;
    const int ix = std::clamp(g.cellX(xM), 0, g.width() - 1), iy = std::clamp(g.cellY(yM), 0, g.height() - 1);
    return spreadFire(site, f, ix, iy, seed, e.key);
}

double fireKillProbability(const FireSettings& f, double heightM, double tolerance) {
    const double scorch = heightM <= f.scorchHeightM ? 1.0 : f.scorchHeightM / heightM;
    return f.severity * (1.0 - std::clamp(tolerance, 0.0, 1.0)) * scorch;
}

double stormKillProbability(const StormSettings& s, double heightM, double exposureMS, double referenceWindMS) {
    const double exposure = referenceWindMS > 0 ? std::clamp(exposureMS / referenceWindMS, 0.0, 1.0) : 0.0;
    const double tall = std::min(1.0, std::pow(std::max(0.0, heightM) / s.referenceHeightM, s.heightExponent));
    return s.severity * exposure * tall;
}

namespace {
// The area of cell c of grid g inside the site's area, m^2.
double clippedCellArea(const DisturbanceSite& site, const Grid<float>& g, int cx, int cy) {
    const double cs = g.cellSizeM();
    const double x0 = g.originX() + cx * cs, y0 = g.originY() + cy * cs;
    const double wx = std::min(x0 + cs, site.x1) - std::max(x0, site.x0);
    const double wy = std::min(y0 + cs, site.y1) - std::max(y0, site.y0);
    return wx > 0 && wy > 0 ? wx * wy : 0.0;
}
}  // namespace

DisturbanceOutcome runDisturbance(const PlannedEvent& e, const DisturbanceSettings& s, const DisturbanceSite& site,
                                  const PlantArrays& plants, const std::vector<double>& tolerance,
                                  std::size_t speciesCount, std::uint64_t seed) {
    const Grid<float>& g = site.elevationM;
    DisturbanceOutcome out;
    DisturbanceRecord& r = out.record;
    r.year = e.year;
    r.month = e.month;
    r.kind = disturbanceKindName(e.kind);
    r.killed.assign(speciesCount, 0);
    out.killed.assign(plants.n, 0);
    auto plantUniform = [&](std::size_t p) {
        const auto w = randomBits(seed, mixStream(e.key ^ kPlantSalt, plants.id[p]), 0);
        return bitsToUnit(w[0], w[1]);
    };
    std::vector<std::uint8_t> damaged(g.size(), 0);
    if (e.kind == DisturbanceKind::Fire) {
        out.burnt = fireBurntCells(e, s.fire, site, seed, &r.xM, &r.yM);
        damaged = out.burnt;
    } else {
        r.xM = 0.5 * (site.x0 + site.x1);
        r.yM = 0.5 * (site.y0 + site.y1);
    }
    const double refWind = s.storm.referenceWindMS > 0 ? s.storm.referenceWindMS : site.windStrengthMS;
    for (std::size_t p = 0; p < plants.n; ++p) {
        const int cx = g.cellX(plants.x[p]), cy = g.cellY(plants.y[p]);
        if (!g.inside(cx, cy)) continue;
        const std::size_t c = g.index(cx, cy);
        const std::size_t sp = static_cast<std::size_t>(plants.species[p]);
        double prob;
        if (e.kind == DisturbanceKind::Fire) {
            if (!out.burnt[c]) continue;
            prob = fireKillProbability(s.fire, plants.height[p], sp < tolerance.size() ? tolerance[sp] : s.fire.defaultTolerance);
        } else {
            prob = stormKillProbability(s.storm, plants.height[p], site.windMS(cx, cy), refWind);
        }
        if (prob > 0 && plantUniform(p) < prob) {
            out.killed[p] = 1;
            if (sp < r.killed.size()) ++r.killed[sp];
            damaged[c] = 1;
        }
    }
    // The event's mask (fire: the burnt cells; storm: the cells with a plant thrown), in
    // ascending cell order, and its area inside the site's area.
    r.mask.width = g.width();
    r.mask.height = g.height();
    r.mask.originX = g.originX();
    r.mask.originY = g.originY();
    r.mask.cellSizeM = g.cellSizeM();
    for (int cy = 0; cy < g.height(); ++cy)
        for (int cx = 0; cx < g.width(); ++cx)
            if (damaged[g.index(cx, cy)]) {
                r.areaM2 += clippedCellArea(site, g, cx, cy);
                r.mask.cells.push_back(static_cast<std::int32_t>(g.index(cx, cy)));
            }
    return out;
}

}  // namespace eco::sim
