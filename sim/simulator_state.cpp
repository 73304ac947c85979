// Persistence: the run's fingerprint and the dynamic state written into and restored from a
// checkpoint group.
#include "simulator_impl.h"

#include "ecomod.h"
#include "state_hash.h"

namespace eco::sim {

namespace {

template <typename T>
std::uint64_t hashVector(std::uint64_t h, const std::vector<T>& v) {
    return hashBytes(h, v.data(), v.size() * sizeof(T));
}

}  // namespace

std::uint64_t Simulation::Impl::computeFingerprint() const {
    std::uint64_t h = 0x65636F73696D3031ull;
    for (const auto& [k, v] : params.namedValues()) {
        // The readings added on 2026-11-26 count only away from their defaults, so that
        // checkpoints written before them stay resumable.
        if (v == 0 && (k == "germination_cells" || k == "germination_vigour" || k == "canopy_limit")) continue;
        h = hashBytes(h, k.data(), k.size());
        h = hashBytes(h, &v, sizeof v);
    }
    h = mixStream(h, seed);
    if (disturbanceOn) {  // only when on: checkpoints of runs without it keep their fingerprint
        const std::string d = disturbance.toToml();
        h = hashBytes(h, d.data(), d.size());
    }
    const std::string toml = biomeToToml(biome);
    h = hashBytes(h, toml.data(), toml.size());
    const double a[4] = {area.x0, area.y0, area.x1, area.y1};
    h = hashBytes(h, a, sizeof a);
    for (const Plant& t : canopy) {  // field by field: the struct has padding
        const double v[5] = {t.xM, t.yM, t.groundZM, t.heightM, t.crownRadiusM};
        h = mixStream(h, static_cast<std::uint64_t>(t.speciesId));
        h = hashBytes(h, v, sizeof v);
    }
    // The maps of kAbioticMaps, monthly ones first, then the static ones (the order of the
    // fingerprint before the table, so old checkpoints still resume). The map of an optional
    // factor (FactorInfo::responseRequired false, the wind) only when a species responds to
    // it: otherwise the run does not read it, and a checkpoint of a biome indifferent to it
    // keeps its fingerprint of before the factor.
    auto mapRead = [&](Factor f) {
        if (kFactors[factorIndex(f)].responseRequired) return true;
        for (const Species& sp : biome.species)
            if (!sp.response(f).isIndifferent()) return true;
        return false;
    };
    for (const bool monthly : {true, false})
        for (const AbioticMapInfo& m : kAbioticMaps)
            if (m.isMonthly() == monthly && mapRead(m.factor))
                forEachPlane(abio, m, [&](const Grid<float>& g) { h = hashVector(h, g.data()); });
    h = hashVector(h, abio.elevationM.data());
    h = hashVector(h, chm.data());
    return h;
}

std::uint64_t Simulation::fingerprint() const {
    if (eco_) return eco_->fingerprint();
    if (!impl_->fingerprintReady) {
        impl_->fingerprintCache = impl_->computeFingerprint();
        impl_->fingerprintReady = true;
    }
    return impl_->fingerprintCache;
}

void Simulation::saveState(h5::File& f, const std::string& group) const {
    if (eco_) return eco_->saveState(f, group);
    impl_->settleDead();
    const Impl& s = *impl_;
    const PlantStore& pl = s.pl;
    const hsize_t n = pl.size();
    f.ensureGroup(group);
    f.setAttr(group, "fingerprint", hex64(fingerprint()));
    f.setAttr(group, "months_done", static_cast<std::int64_t>(s.month));
    f.setAttr(group, "next_id", static_cast<std::int64_t>(s.nextId));  // the uint64's bits
    f.setAttr(group, "window_mask", static_cast<std::int64_t>(s.windowMask));
    f.setAttr(group, "plant_months", static_cast<std::int64_t>(s.counters.plantMonths));
    f.setAttr(group, "plant_cell_months", static_cast<std::int64_t>(s.counters.plantCellMonths));
    f.setAttr(group, "germinated", static_cast<std::int64_t>(s.counters.germinated));
    f.setAttr(group, "died_background_or_stress", static_cast<std::int64_t>(s.counters.diedBackgroundOrStress));
    f.setAttr(group, "died_at_canopy", static_cast<std::int64_t>(s.counters.diedAtCanopy));
    f.setAttr(group, "died_dominated", static_cast<std::int64_t>(s.counters.diedDominated));
    f.setAttr(group, "dropped_initial", static_cast<std::int64_t>(s.droppedInitial));
    if (s.disturbanceOn) {  // the events so far (the draws are keyed by seed and event: no generator state)
        f.setAttr(group, "died_disturbance", static_cast<std::int64_t>(s.counters.diedDisturbance));
        writeDisturbanceTable(f, group + "/disturbance", s.disturbanceEvents, s.biome);
    }
    // Ids split in two exact 32-bit halves.
    std::vector<std::int32_t> idLo(n), idHi(n);
    for (std::size_t p = 0; p < n; ++p) {
        idLo[p] = static_cast<std::int32_t>(static_cast<std::uint32_t>(pl.id[p]));
        idHi[p] = static_cast<std::int32_t>(static_cast<std::uint32_t>(pl.id[p] >> 32));
    }
    f.writeI32(group + "/id_lo", idLo, {n}, "1");
    f.writeI32(group + "/id_hi", idHi, {n}, "1");
    f.writeI32(group + "/species", pl.species, {n}, "1");
    f.writeF64(group + "/x", pl.x, {n}, "m");
    f.writeF64(group + "/y", pl.y, {n}, "m");
    f.writeF64(group + "/growth_age", pl.growthAge, {n}, "years");
    f.writeF64(group + "/pool", pl.pool, {n}, "1");
    std::vector<std::int32_t> ageMonths(n);
    for (std::size_t p = 0; p < n; ++p) ageMonths[p] = static_cast<std::int32_t>(s.month - pl.birthMonth[p]);
    f.writeI32(group + "/age_months", ageMonths, {n}, "months");
    f.writeI32(group + "/root_ix", pl.rootIx, {n}, "1");
    f.writeI32(group + "/root_iy", pl.rootIy, {n}, "1");
    f.writeF32(group + "/vigour", pl.vigour, {n}, "1");
    f.writeF32(group + "/sun", pl.sun, {n}, "hours/day");
    f.writeF32(group + "/water", pl.water, {n}, "mm/month");
    // Height and radius are kept bit-exactly (they follow growth age, but only in growth
    // months, so they cannot be recomputed from it for every plant).
    f.writeF64(group + "/height", pl.height, {n}, "m");
    f.writeF64(group + "/radius", pl.radius, {n}, "m");
    for (std::size_t g = 0; g < s.periods(); ++g) {
        const hsize_t dims[2] = {static_cast<hsize_t>(s.H), static_cast<hsize_t>(s.W)};
        std::vector<float> sun(s.cellCount()), water(s.cellCount());
        for (std::size_t c = 0; c < s.cellCount(); ++c) {
            sun[c] = s.deficitAt(c, g)[0];
            water[c] = s.deficitAt(c, g)[1];
        }
        f.writeF32(group + "/deficit_sun_" + std::to_string(g), sun, {dims[0], dims[1]}, "hours/day");
        f.writeF32(group + "/deficit_water_" + std::to_string(g), water, {dims[0], dims[1]}, "mm/month");
    }
    if (!s.monthDeficit.empty())  // germination_vigour = "mean_vigour": (row, column, month, {sun, water})
        f.writeF32(group + "/month_deficit", s.monthDeficit,
                   {static_cast<hsize_t>(s.H), static_cast<hsize_t>(s.W), 12, 2}, "1");
}

void Simulation::loadState(const h5::File& f, const std::string& group) {
    if (eco_) return eco_->loadState(f, group);
    if (f.exists(group) && f.hasAttr(group, "model"))
        throw IoError(f.path() + ": " + group + ": the checkpoint is of an " + f.attrString(group, "model") +
                      " run, not of the monthly model");
    Impl& s = *impl_;
    const std::string where = f.path() + ": " + group;
    if (!f.exists(group)) throw IoError(where + ": no simulation state");
    const std::string fp = f.attrString(group, "fingerprint");
    if (fp != hex64(fingerprint()))
        throw IoError(where + ": the checkpoint belongs to another run (different inputs, biome, area, seed, model "
                              "parameters or disturbance settings; fingerprint " + fp + ", this run " + hex64(fingerprint()) + ")");
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
    if (!s.monthDeficit.empty()) {
        auto md = f.readF32(group + "/month_deficit");
        if (md.size() != s.monthDeficit.size()) throw IoError(where + ": month_deficit has the wrong size");
        s.monthDeficit = std::move(md);
    }
    s.pl = std::move(pl);
    s.fpRange.clear();  // footprints are recomputed (buildBands)
    s.fate.assign(s.pl.size(), 0);
    s.deadPending = 0;
    s.layoutReusable = false;
    s.month = f.attrInt(group, "months_done");
    for (std::int32_t& b : s.pl.birthMonth) b = static_cast<std::int32_t>(s.month - b);
    // int64 (the uint64's bits) since typed attributes; 16 hex digits in checkpoints before.
    s.nextId = f.attrIsString(group, "next_id") ? std::stoull(f.attrString(group, "next_id"), nullptr, 16)
                                                : static_cast<std::uint64_t>(f.attrInt(group, "next_id"));
    s.windowMask = static_cast<std::uint32_t>(f.attrInt(group, "window_mask"));
    s.counters.plantMonths = f.attrInt(group, "plant_months");
    s.counters.plantCellMonths = f.hasAttr(group, "plant_cell_months") ? f.attrInt(group, "plant_cell_months") : 0;
    s.counters.germinated = f.attrInt(group, "germinated");
    s.counters.diedBackgroundOrStress = f.attrInt(group, "died_background_or_stress");
    s.counters.diedAtCanopy = f.attrInt(group, "died_at_canopy");
    s.counters.diedDominated = f.hasAttr(group, "died_dominated") ? f.attrInt(group, "died_dominated") : 0;
    s.droppedInitial = static_cast<std::size_t>(f.attrInt(group, "dropped_initial"));
    s.counters.diedDisturbance = f.hasAttr(group, "died_disturbance") ? f.attrInt(group, "died_disturbance") : 0;
    s.disturbanceEvents.clear();
    if (s.disturbanceOn && f.exists(group + "/disturbance"))
        s.disturbanceEvents = readDisturbanceTable(f, group + "/disturbance", s.spc.size());
}

}  // namespace eco::sim
