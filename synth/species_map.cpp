#include "species_map.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <sstream>

#include "error.h"
#include "terrain_io.h"
#include "text_format.h"

namespace eco::synth {

namespace {

std::string num(double v) { return formatNumber(v, 6); }

std::string geometryText(const Grid<float>& g) {
    return std::to_string(g.width()) + " x " + std::to_string(g.height()) + " cells of " + num(g.cellSizeM()) +
           " m, origin (" + num(g.originX()) + ", " + num(g.originY()) + ")";
}

std::string canopyNames(const Biome& biome) {
    std::string out;
    for (const auto& s : biome.species)
        if (s.canopy) out += (out.empty() ? "" : ", ") + s.name;
    return out;
}

/// Species coefficients copied out of the biome for the inner loop.
struct Coeffs {
    int species;
    double alpha, maxHeightM;
    Responses responses;
};

/// Evaluates the unweighted vigour of the canopy species exactly as unweightedVigour().
class VigourTable {
public:
    explicit VigourTable(const Biome& biome) : a_(biome.vigour.a), lnq_(std::log(biome.vigour.q)), p_(biome.vigour.p) {
        for (int s : canopySpeciesOf(biome)) {
            const Species& sp = biome.species[static_cast<std::size_t>(s)];
            coeffs_.push_back({s, sp.alpha, sp.maxHeightM, sp.responses});
        }
    }
    const std::vector<Coeffs>& coeffs() const { return coeffs_; }
    /// alpha * g(max normalised distance): the same operations, in the same order, as
    /// VigourShape::g applied to the largest of the normalised distances (vigour.h).
    double raw(const Coeffs& c, const Features& x) const {
        return vigourAtDistance(c.alpha, maxNormalisedDistance(c.responses, x), a_, p_, lnq_);
    }

private:
    double a_, lnq_, p_;
    std::vector<Coeffs> coeffs_;
};

/// Per-cell user weights of every species: global weights overridden by the brushes.
class WeightField {
public:
    WeightField(const Biome& biome, const SpeciesMapParams& p) : p_(p) {
        global_.assign(biome.species.size(), 1.0);
        for (std::size_t i = 0; i < p.weights.size() && i < global_.size(); ++i) global_[i] = p.weights[i];
    }
    bool hasLocal() const { return !p_.localWeights.empty(); }
    /// Weight of species s at cell index i.
    double at(int s, std::size_t i) const {
        double w = global_[static_cast<std::size_t>(s)];
        for (const auto& lw : p_.localWeights)
            if (lw.species == s && lw.mask->data()[i] != 0) w = lw.weight;
        return w;
    }
    /// True when a brush (rather than the global weight) sets species s at cell i.
    bool local(int s, std::size_t i) const {
        for (const auto& lw : p_.localWeights)
            if (lw.species == s && lw.mask->data()[i] != 0) return true;
        return false;
    }

private:
    const SpeciesMapParams& p_;
    std::vector<double> global_;
};

/// Best species at one cell: its weighted vigour (0 when none is positive) and index (-1 when
/// none). Ties go to the lower species index.
struct Best {
    double vigour;
    int species;
};

// A conservative bound on g: (1 + a) * exp(x) - a can round one ulp above 1.
constexpr double kBoundSlack = 1.0 + 1e-9;

Best bestAt(const VigourTable& table, const WeightField& weights, std::size_t cell, const Features& x, double chm) {
    Best best{0.0, -1};
    for (const Coeffs& c : table.coeffs()) {
        if (c.maxHeightM < chm) continue;
        const double w = weights.at(c.species, cell);
        // Species come in index order, so a later one must be strictly better.
        if (!(w * c.alpha * kBoundSlack > best.vigour)) continue;
        const double v = w * table.raw(c, x);
        if (v > best.vigour) best = {v, c.species};
    }
    return best;
}

/// Does species s (weighted vigour v) win a cell whose best competitor is `other`?
inline bool wins(double v, int s, const Best& other) {
    if (!(v > 0)) return false;
    if (other.species < 0) return true;
    return other.species < s ? v > other.vigour : v >= other.vigour;
}

void requireSameGeometry(const Grid<float>& ref, const Grid<float>& g, const std::string& what) {
    if (!ref.sameGeometry(g))
        throw ValidationError("species map: " + what + " (" + geometryText(g) + ") differs in geometry from the CHM (" +
                              geometryText(ref) + ")");
}

void requireFiniteGrid(const Grid<float>& g, const std::string& what) {
    for (int iy = 0; iy < g.height(); ++iy)
        for (int ix = 0; ix < g.width(); ++ix)
            if (!std::isfinite(g(ix, iy)))
                throw ValidationError("species map: " + what + " has a non-finite value at cell (" + std::to_string(ix) +
                                      ", " + std::to_string(iy) + ")");
}

void requireMask(const Grid<std::uint8_t>& mask, const Grid<float>& like, const std::string& name) {
    if (!like.sameGeometry(mask))
        throw ValidationError("species map: mask " + (name.empty() ? std::string("(unnamed)") : "'" + name + "'") + " is " +
                              std::to_string(mask.width()) + " x " + std::to_string(mask.height()) +
                              " cells; it must have the CHM's geometry (" + geometryText(like) + ")");
}

int requireCanopySpecies(const Biome& biome, int species) {
    if (species < 0 || static_cast<std::size_t>(species) >= biome.species.size())
        throw ValidationError("species map: species index " + std::to_string(species) + " is not in biome '" +
                              biome.name + "' (" + std::to_string(biome.species.size()) + " species)");
    if (!biome.species[static_cast<std::size_t>(species)].canopy)
        throw ValidationError("species map: '" + biome.species[static_cast<std::size_t>(species)].name +
                              "' is not a canopy species of biome '" + biome.name + "' (canopy species: " +
                              canopyNames(biome) + ")");
    return species;
}

void requireFraction(double fraction, const std::string& species) {
    if (!std::isfinite(fraction) || fraction < 0.0 || fraction > 1.0)
        throw ValidationError("target fraction for '" + species + "' must lie in [0, 1], got " + num(fraction));
}

}  // namespace

// ---------------------------------------------------------------------------------------

std::vector<int> canopySpeciesOf(const Biome& biome) {
    std::vector<int> out;
    for (std::size_t s = 0; s < biome.species.size(); ++s)
        if (biome.species[s].canopy) out.push_back(static_cast<int>(s));
    return out;
}

double unweightedVigour(const Biome& biome, int s, const Features& x) {
    const Species& sp = biome.species.at(static_cast<std::size_t>(s));
    const VigourShape& g = biome.vigour;
    return vigourAtDistance(sp.alpha, maxNormalisedDistance(sp.responses, x), g.a, g.p, std::log(g.q));
}

SpeciesMapInputs speciesMapInputs(const Abiotics& abiotics, const Grid<float>& chmM) {
    SpeciesMapInputs in;
    in.features = annualFactors(abiotics);
    in.chmM = chmM;
    validateSpeciesMapInputs(in);
    return in;
}

void validateSpeciesMapInputs(const SpeciesMapInputs& in) {
    if (in.chmM.empty()) throw ValidationError("species map: the CHM is empty");
    for (std::size_t f = 0; f < kFactorCount; ++f)
        requireSameGeometry(in.chmM, in.features.maps[f], std::string("the ") + kFactors[f].label + " map");
    for (std::size_t f = 0; f < kFactorCount; ++f)
        requireFiniteGrid(in.features.maps[f], std::string("the ") + kFactors[f].label + " map");
    requireFiniteGrid(in.chmM, "the CHM");
    for (int iy = 0; iy < in.chmM.height(); ++iy)
        for (int ix = 0; ix < in.chmM.width(); ++ix)
            if (in.chmM(ix, iy) < 0)
                throw ValidationError("species map: the CHM has a negative height " + num(in.chmM(ix, iy)) +
                                      " m at cell (" + std::to_string(ix) + ", " + std::to_string(iy) + ")");
}

const std::vector<SpeciesMapParamField>& speciesMapParamFields() {
    using K = SpeciesMapParamField::Kind;
    using R = ParamRange;
    using P = SpeciesMapParams;
    static const std::vector<SpeciesMapParamField> fields = {
        {"target_tolerance", "species map: a target is met within this share", "", K::Real, &P::targetTolerance, nullptr,
         R{R::Bound::Open, 0, R::Bound::Open, 1}},
        {"max_bisection_steps", "species map: evaluations per bisection", "", K::Integer, nullptr, &P::maxBisectionSteps,
         R::closed(1, 10000)},
        {"target_sweeps", "species map: rounds over several targets", "", K::Integer, nullptr, &P::targetSweeps,
         R::closed(1, 1000)},
    };
    return fields;
}

void validateSpeciesMapParams(const SpeciesMapParams& p, const Biome& biome) {
    if (!std::isfinite(p.canopyThresholdM) || p.canopyThresholdM < 0)
        throw ValidationError("species map: canopy_threshold_m must be >= 0, got " + num(p.canopyThresholdM));
    if (p.weights.size() > biome.species.size())
        throw ValidationError("species map: " + std::to_string(p.weights.size()) + " weights for " +
                              std::to_string(biome.species.size()) + " species");
    for (std::size_t s = 0; s < p.weights.size(); ++s)
        if (!std::isfinite(p.weights[s]) || p.weights[s] < 0)
            throw ValidationError("species map: weight of '" + biome.species[s].name + "' must be >= 0, got " +
                                  num(p.weights[s]));
    for (const auto& lw : p.localWeights) {
        if (lw.species < 0 || static_cast<std::size_t>(lw.species) >= biome.species.size())
            throw ValidationError("species map: brush weight for species index " + std::to_string(lw.species) +
                                  " outside the biome");
        if (!std::isfinite(lw.weight) || lw.weight < 0)
            throw ValidationError("species map: brush weight of '" + biome.species[static_cast<std::size_t>(lw.species)].name +
                                  "' must be >= 0, got " + num(lw.weight));
        if (!lw.mask) throw ValidationError("species map: brush weight without a mask");
    }
    validateParams(p, speciesMapParamFields(), "species map parameter");
}

Grid<std::int32_t> computeSpeciesMap(const Biome& biome, const SpeciesMapInputs& in, const SpeciesMapParams& params) {
    validateSpeciesMapInputs(in);
    validateSpeciesMapParams(params, biome);
    for (const auto& lw : params.localWeights) requireMask(*lw.mask, in.chmM, lw.maskName);
    const VigourTable table(biome);
    const WeightField weights(biome, params);
    Grid<std::int32_t> out = Grid<std::int32_t>::like(in.chmM, -1);
    const int w = in.chmM.width(), h = in.chmM.height();
#pragma omp parallel for schedule(dynamic, 8)
    for (int iy = 0; iy < h; ++iy)
        for (int ix = 0; ix < w; ++ix) {
            const std::size_t i = in.chmM.index(ix, iy);
            const Best b = bestAt(table, weights, i, in.features.at(i), in.chmM.data()[i]);
            out.data()[i] = b.species;
        }
    return out;
}

std::size_t forestedCells(const Grid<float>& chmM, double canopyThresholdM, const Grid<std::uint8_t>* mask) {
    std::size_t n = 0;
    for (std::size_t i = 0; i < chmM.size(); ++i)
        if (chmM.data()[i] >= canopyThresholdM && (!mask || mask->data()[i] != 0)) ++n;
    return n;
}

double speciesFraction(const Grid<std::int32_t>& speciesMap, const Grid<float>& chmM, int species,
                       double canopyThresholdM, const Grid<std::uint8_t>* mask) {
    if (!speciesMap.sameGeometry(chmM))
        throw ValidationError("species fraction: the species map and the CHM differ in geometry");
    if (mask && !chmM.sameGeometry(*mask))
        throw ValidationError("species fraction: the mask and the CHM differ in geometry");
    std::size_t n = 0, k = 0;
    for (std::size_t i = 0; i < chmM.size(); ++i) {
        if (!(chmM.data()[i] >= canopyThresholdM) || (mask && mask->data()[i] == 0)) continue;
        ++n;
        if (speciesMap.data()[i] == species) ++k;
    }
    return n ? static_cast<double>(k) / static_cast<double>(n) : 0.0;
}

SpeciesTarget parseSpeciesTarget(const std::string& text, const Biome& biome) {
    const auto eq = text.rfind('=');
    if (eq == std::string::npos)
        throw ValidationError("target '" + text + "': expected SPECIES=FRACTION, e.g. 'Redwood=0.4'");
    auto trim = [](std::string s) {
        const auto b = s.find_first_not_of(" \t");
        const auto e = s.find_last_not_of(" \t");
        return b == std::string::npos ? std::string() : s.substr(b, e - b + 1);
    };
    SpeciesTarget t;
    t.species = trim(text.substr(0, eq));
    const std::string value = trim(text.substr(eq + 1));
    int index = -1;
    for (const auto& s : biome.species)
        if (s.name == t.species) index = s.id;
    if (index < 0)
        throw ValidationError("target '" + text + "': unknown species '" + t.species + "' (canopy species of biome '" +
                              biome.name + "': " + canopyNames(biome) + ")");
    if (!biome.species[static_cast<std::size_t>(index)].canopy)
        throw ValidationError("target '" + text + "': '" + t.species + "' is not a canopy species (canopy species of biome '" +
                              biome.name + "': " + canopyNames(biome) + ")");
    std::size_t used = 0;
    double f = std::numeric_limits<double>::quiet_NaN();
    try {
        f = std::stod(value, &used);
    } catch (const std::exception&) {
        used = 0;
    }
    if (value.empty() || used != value.size())
        throw ValidationError("target '" + text + "': fraction '" + value + "' is not a number");
    requireFraction(f, t.species);
    t.fraction = f;
    return t;
}

namespace {

/// Per forested cell of the region: the best weighted vigour among the "tuned" weights of a
/// group of species (those a search scales), and the best among everything else.
struct GroupCells {
    std::vector<double> groupVigour;   ///< max w * raw over tuned group members (0 when none positive)
    std::vector<std::int32_t> groupSpecies;  ///< its species (-1 when none)
    std::vector<Best> fixed;           ///< best of the other species and of untuned group members
    std::vector<char> fixedInGroup;    ///< the fixed best is itself a group member
    std::int64_t size() const { return static_cast<std::int64_t>(groupVigour.size()); }
};

/// Is the weight of species s at cell i the one being searched? With a mask: the brush of s
/// on that mask (the last one of s, so it wins inside). Without: the global weight, unless a
/// brush of s covers the cell.
bool tunedAt(const WeightField& weights, const std::shared_ptr<const Grid<std::uint8_t>>& mask, int s, std::size_t i) {
    return mask ? true : !weights.local(s, i);
}

/// Take (v, s) when it beats b: higher vigour, or equal vigour and a lower species index
/// (what scanning the species in index order with a strict > gives). v must be > 0.
inline void consider(Best& b, double v, int s) {
    if (v > b.vigour || (v == b.vigour && b.species >= 0 && s < b.species)) b = {v, s};
}

/// The expensive part of a target search, computed once per meetTargets call: per forested
/// cell of the region, the unweighted vigour of each targeted species and the best weighted
/// vigour among the other canopy species (their weights do not change during the search).
struct VigourCache {
    std::vector<std::size_t> cells;
    std::vector<int> species;              ///< the targeted species
    std::vector<std::vector<double>> raw;  ///< [target][cell]: alpha * g; NaN where too short
    std::vector<Best> others;              ///< best weighted vigour of the other species
};

VigourCache buildCache(const Biome& biome, const SpeciesMapInputs& in, const SpeciesMapParams& params,
                       std::vector<std::size_t> cells, const std::vector<int>& species) {
    const VigourTable table(biome);
    const WeightField weights(biome, params);
    VigourCache c;
    c.cells = std::move(cells);
    c.species = species;
    const std::size_t n = c.cells.size();
    c.raw.assign(species.size(), std::vector<double>(n, std::numeric_limits<double>::quiet_NaN()));
    c.others.assign(n, Best{0.0, -1});
    std::vector<int> targetOf(biome.species.size(), -1);
    for (std::size_t t = 0; t < species.size(); ++t) targetOf[static_cast<std::size_t>(species[t])] = static_cast<int>(t);
#pragma omp parallel for schedule(static)
    for (std::ptrdiff_t k = 0; k < static_cast<std::ptrdiff_t>(n); ++k) {
        const std::size_t j = static_cast<std::size_t>(k), i = c.cells[j];
        const Features x = in.features.at(i);
        const double chm = in.chmM.data()[i];
        Best others{0.0, -1};
        for (const Coeffs& co : table.coeffs()) {  // index order: strict > keeps ties on the lower index
            if (co.maxHeightM < chm) continue;
            const double r = table.raw(co, x);
            const int t = targetOf[static_cast<std::size_t>(co.species)];
            if (t >= 0) {
                c.raw[static_cast<std::size_t>(t)][j] = r;
                continue;
            }
            const double v = weights.at(co.species, i) * r;
            if (v > others.vigour) others = {v, co.species};
        }
        c.others[j] = others;
    }
    return c;
}

/// Split the cached cells for a search over the targets flagged in `inGroup` (by target
/// position), with the current weights.
GroupCells groupFromCache(const Biome& biome, const VigourCache& c, const SpeciesMapParams& params,
                          const std::vector<char>& inGroup, const std::shared_ptr<const Grid<std::uint8_t>>& mask) {
    const WeightField weights(biome, params);
    const std::size_t n = c.cells.size();
    GroupCells g;
    g.groupVigour.assign(n, 0.0);
    g.groupSpecies.assign(n, -1);
    g.fixed.assign(n, Best{0.0, -1});
    g.fixedInGroup.assign(n, 0);
#pragma omp parallel for schedule(static)
    for (std::ptrdiff_t k = 0; k < static_cast<std::ptrdiff_t>(n); ++k) {
        const std::size_t j = static_cast<std::size_t>(k), i = c.cells[j];
        Best tuned{0.0, -1}, fixed = c.others[j];
        int fixedTarget = -1;
        for (std::size_t t = 0; t < c.species.size(); ++t) {
            const double r = c.raw[t][j];
            if (std::isnan(r)) continue;
            const int s = c.species[t];
            const double v = weights.at(s, i) * r;
            if (inGroup[t] && tunedAt(weights, mask, s, i)) {
                consider(tuned, v, s);
            } else {
                const int before = fixed.species;
                consider(fixed, v, s);
                if (fixed.species != before) fixedTarget = static_cast<int>(t);
            }
        }
        g.groupVigour[j] = tuned.vigour;
        g.groupSpecies[j] = tuned.species;
        g.fixed[j] = fixed;
        g.fixedInGroup[j] = fixedTarget >= 0 && fixed.species == c.species[static_cast<std::size_t>(fixedTarget)] &&
                            inGroup[static_cast<std::size_t>(fixedTarget)];
    }
    return g;
}

/// Cells the group holds when its tuned weights are multiplied by `scale` (non-decreasing in scale).
std::int64_t groupCount(const GroupCells& g, double scale) {
    std::int64_t won = 0;
    const std::int64_t n = g.size();
#pragma omp parallel for schedule(static) reduction(+ : won)
    for (std::int64_t k = 0; k < n; ++k) {
        const std::size_t j = static_cast<std::size_t>(k);
        if (g.fixedInGroup[j] || (g.groupSpecies[j] >= 0 && wins(scale * g.groupVigour[j], g.groupSpecies[j], g.fixed[j])))
            ++won;
    }
    return won;
}

struct ScaleSearch {
    double scale = 0;
    std::int64_t count = 0;
    std::int64_t atInf = 0;
    int evaluations = 0;
};

/// The scale >= 0 whose group count is closest to `wanted` (ties: the smaller scale): the
/// count is a non-decreasing step function from count(0) to count(inf); bracket from
/// `start` by factors of 4, then bisect, at most maxSteps evaluations in all.
ScaleSearch searchScale(const GroupCells& g, std::int64_t wanted, double start, int maxSteps) {
    ScaleSearch r;
    auto count = [&](double scale) {
        ++r.evaluations;
        return groupCount(g, scale);
    };
    const std::int64_t atZero = count(0.0);
    r.atInf = count(std::numeric_limits<double>::infinity());
    r.scale = 0.0;
    r.count = atZero;
    auto consider = [&](double scale, std::int64_t c) {
        const auto d = std::llabs(c - wanted), dBest = std::llabs(r.count - wanted);
        if (d < dBest || (d == dBest && scale < r.scale)) {
            r.scale = scale;
            r.count = c;
        }
    };
    if (wanted <= atZero) return r;
    const std::int64_t goal = std::min(wanted, r.atInf);
    double hi = start > 0 && std::isfinite(start) ? start : 1.0, lo = 0.0;
    std::int64_t cHi = count(hi);
    consider(hi, cHi);
    if (cHi < goal) {
        while (cHi < goal && r.evaluations < maxSteps && hi < 1e300) {
            lo = hi;
            hi *= 4.0;
            cHi = count(hi);
            consider(hi, cHi);
        }
    } else {
        lo = hi * 0.25;
        while (lo > 1e-300 && r.evaluations < maxSteps) {
            const std::int64_t c = count(lo);
            consider(lo, c);
            if (c < goal) break;
            hi = lo;
            lo *= 0.25;
        }
        if (!(lo > 1e-300)) lo = 0.0;
    }
    // Bisection on [lo, hi]: count(lo) < goal <= count(hi).
    while (r.count != wanted && r.evaluations < maxSteps && hi - lo > 1e-15 * hi) {
        const double mid = 0.5 * (lo + hi);
        const std::int64_t c = count(mid);
        consider(mid, c);
        if (c < goal) lo = mid;
        else hi = mid;
    }
    return r;
}

/// Forested cells of the region (inside the mask when given).
std::vector<std::size_t> regionCells(const SpeciesMapInputs& in, double thresholdM, const Grid<std::uint8_t>* mask) {
    std::vector<std::size_t> cells;
    for (std::size_t i = 0; i < in.chmM.size(); ++i)
        if (in.chmM.data()[i] >= thresholdM && (!mask || mask->data()[i] != 0)) cells.push_back(i);
    return cells;
}

/// The user weight of `species` that a search sets: the global one, or its brush on `mask`.
double currentWeight(const SpeciesMapParams& p, int species, const std::shared_ptr<const Grid<std::uint8_t>>& mask) {
    if (!mask) return species < static_cast<int>(p.weights.size()) ? p.weights[static_cast<std::size_t>(species)] : 1.0;
    for (const auto& lw : p.localWeights)
        if (lw.species == species && lw.mask == mask) return lw.weight;
    return 1.0;
}

/// Set that weight; a brush is (re)placed last so that it wins inside its mask.
void setWeight(SpeciesMapParams& p, const Biome& biome, int species, double weight,
               const std::shared_ptr<const Grid<std::uint8_t>>& mask, const std::string& maskName) {
    if (!mask) {
        if (p.weights.size() < biome.species.size()) p.weights.resize(biome.species.size(), 1.0);
        p.weights[static_cast<std::size_t>(species)] = weight;
        return;
    }
    auto& lws = p.localWeights;
    lws.erase(std::remove_if(lws.begin(), lws.end(),
                             [&](const LocalWeight& lw) { return lw.species == species && lw.mask == mask; }),
              lws.end());
    lws.push_back({species, weight, mask, maskName});
}

void checkRegion(const std::vector<std::size_t>& cells, const std::string& what, double thresholdM,
                 const std::shared_ptr<const Grid<std::uint8_t>>& mask, const std::string& maskName) {
    if (cells.empty())
        throw ValidationError(what + ": no forested cell (CHM >= " + num(thresholdM) + " m)" +
                              (mask ? " inside the mask" + (maskName.empty() ? "" : " '" + maskName + "'") : ""));
}

}  // namespace

namespace {

/// One target over a cache that holds its species at position `t`.
TargetResult meetCachedTarget(const Biome& biome, const VigourCache& cache, SpeciesMapParams& params, std::size_t t,
                              double fraction, const std::shared_ptr<const Grid<std::uint8_t>>& mask,
                              const std::string& maskName) {
    const int species = cache.species[t];
    const Species& sp = biome.species[static_cast<std::size_t>(species)];
    // Search the weight itself: with the tuned weight at 1, scale * raw is exactly the
    // weighted vigour the map computes with weight = scale.
    const double start = currentWeight(params, species, mask);
    setWeight(params, biome, species, 1.0, mask, maskName);
    std::vector<char> inGroup(cache.species.size(), 0);
    inGroup[t] = 1;
    const GroupCells g = groupFromCache(biome, cache, params, inGroup, mask);
    const double total = static_cast<double>(cache.cells.size());
    const auto wanted = static_cast<std::int64_t>(std::llround(fraction * total));
    const ScaleSearch found = searchScale(g, wanted, start, params.maxBisectionSteps);
    setWeight(params, biome, species, found.scale, mask, maskName);

    TargetResult r;
    r.species = sp.name;
    r.requested = fraction;
    r.achieved = static_cast<double>(found.count) / total;
    r.reachable = static_cast<double>(found.atInf) / total;
    r.feasible = std::abs(r.achieved - fraction) <= params.targetTolerance;
    r.weight = found.scale;
    r.alpha = found.scale * sp.alpha;
    r.iterations = found.evaluations;
    return r;
}

}  // namespace

TargetResult meetTarget(const Biome& biome, const SpeciesMapInputs& in, SpeciesMapParams& params, int species,
                        double fraction, const std::shared_ptr<const Grid<std::uint8_t>>& mask,
                        const std::string& maskName) {
    validateSpeciesMapInputs(in);
    validateSpeciesMapParams(params, biome);
    requireCanopySpecies(biome, species);
    const Species& sp = biome.species[static_cast<std::size_t>(species)];
    requireFraction(fraction, sp.name);
    if (mask) requireMask(*mask, in.chmM, maskName);
    for (const auto& lw : params.localWeights) requireMask(*lw.mask, in.chmM, lw.maskName);
    std::vector<std::size_t> cells = regionCells(in, params.canopyThresholdM, mask.get());
    checkRegion(cells, "target for '" + sp.name + "'", params.canopyThresholdM, mask, maskName);
    const VigourCache cache = buildCache(biome, in, params, std::move(cells), {species});
    return meetCachedTarget(biome, cache, params, 0, fraction, mask, maskName);
}

std::vector<TargetResult> meetTargets(const Biome& biome, const SpeciesMapInputs& in, SpeciesMapParams& params,
                                      const std::vector<SpeciesTarget>& targets,
                                      const std::shared_ptr<const Grid<std::uint8_t>>& mask,
                                      const std::string& maskName) {
    validateSpeciesMapInputs(in);
    validateSpeciesMapParams(params, biome);
    std::vector<int> index;
    double sum = 0;
    for (const auto& t : targets) {
        const int s = biome.speciesIndex(t.species);
        requireCanopySpecies(biome, s);
        requireFraction(t.fraction, t.species);
        if (std::find(index.begin(), index.end(), s) != index.end())
            throw ValidationError("target for '" + t.species + "' is given twice");
        index.push_back(s);
        sum += t.fraction;
    }
    if (sum > 1.0 + 1e-9)
        throw ValidationError("target fractions sum to " + num(sum) + " > 1 (each is a share of the same forested area)");
    if (targets.empty()) return {};
    if (mask) requireMask(*mask, in.chmM, maskName);
    for (const auto& lw : params.localWeights) requireMask(*lw.mask, in.chmM, lw.maskName);
    std::vector<std::size_t> cells = regionCells(in, params.canopyThresholdM, mask.get());
    checkRegion(cells, "targets", params.canopyThresholdM, mask, maskName);
    const VigourCache cache = buildCache(biome, in, params, std::move(cells), index);
    const double total = static_cast<double>(cache.cells.size());

    std::vector<TargetResult> results(targets.size());
    std::vector<int> evaluations(targets.size(), 0);
    for (int sweep = 0; sweep < params.targetSweeps; ++sweep) {
        // Several targets: first scale all their weights together so that they hold their
        // summed share. Meeting targets one by one alone converges slowly when the targeted
        // species compete mostly with each other (their weights then drift down together).
        if (targets.size() > 1) {
            const GroupCells g = groupFromCache(biome, cache, params, std::vector<char>(targets.size(), 1), mask);
            const auto wanted = static_cast<std::int64_t>(std::llround(sum * total));
            const ScaleSearch found = searchScale(g, wanted, 1.0, params.maxBisectionSteps);
            for (std::size_t k = 0; k < targets.size(); ++k) {
                setWeight(params, biome, index[k], currentWeight(params, index[k], mask) * found.scale, mask, maskName);
                evaluations[k] += found.evaluations;
            }
        }
        for (std::size_t k = 0; k < targets.size(); ++k) {
            results[k] = meetCachedTarget(biome, cache, params, k, targets[k].fraction, mask, maskName);
            evaluations[k] += results[k].iterations;
        }
        // Later targets move the earlier ones' shares: measure all with the final weights.
        std::vector<char> all(targets.size(), 0);
        bool allMet = true;
        for (std::size_t k = 0; k < targets.size(); ++k) {
            std::fill(all.begin(), all.end(), 0);
            all[k] = 1;
            // The share of target k alone: its group of one at scale 1 (its own weights).
            const GroupCells g = groupFromCache(biome, cache, params, all, mask);
            results[k].achieved = static_cast<double>(groupCount(g, 1.0)) / total;
            results[k].feasible = std::abs(results[k].achieved - results[k].requested) <= params.targetTolerance;
            results[k].iterations = evaluations[k];
            allMet = allMet && results[k].feasible;
        }
        if (allMet) break;
    }
    return results;
}

Grid<std::uint8_t> readMaskImage(const std::string& path, const Grid<float>& like) {
    TerrainReadOptions opt;
    opt.cellSizeM = like.cellSizeM();
    opt.originX = like.originX();
    opt.originY = like.originY();
    const std::string ext = fileExtension(path);
    if (!isTerrainImageExtension(ext))
        throw IoError(path + ": a mask must be an image (" + supportedTerrainExtensions() + "), got '" + ext + "'");
    const Grid<float> grey = readTerrainImage(path, opt);
    if (grey.width() != like.width() || grey.height() != like.height())
        throw ValidationError(path + ": mask is " + std::to_string(grey.width()) + " x " + std::to_string(grey.height()) +
                              " pixels but the CHM is " + std::to_string(like.width()) + " x " +
                              std::to_string(like.height()) + " cells; a mask is never resampled");
    Grid<std::uint8_t> mask = Grid<std::uint8_t>::like(like, 0);
    for (std::size_t i = 0; i < grey.size(); ++i) mask.data()[i] = grey.data()[i] >= 0.5f ? 1 : 0;
    return mask;
}

}  // namespace eco::synth
