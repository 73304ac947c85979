// The fidelity protocol's measures (fidelity.h; formulas in docs/fidelity.md).
#include "fidelity.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <sstream>

#include "atomic_file.h"
#include "error.h"
#include "rng.h"
#include "scene.h"
#include "text_format.h"
#include "undergrowth.h"

namespace eco::validate {

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

std::string num(double v, int precision = 6) { return formatNumber(v, precision); }

/// The region map cropped to the cells whose centre lies in the plot (others -1), as a
/// sub-grid with the same cell size and world coordinates.
Grid<std::int32_t> croppedLabels(const Grid<std::int32_t>& map, const RectWindow& w) {
    const int ix0 = std::clamp(map.cellX(w.x0), 0, map.width() - 1);
    const int ix1 = std::clamp(map.cellX(w.x1), 0, map.width() - 1);
    const int iy0 = std::clamp(map.cellY(w.y0), 0, map.height() - 1);
    const int iy1 = std::clamp(map.cellY(w.y1), 0, map.height() - 1);
    Grid<std::int32_t> out(ix1 - ix0 + 1, iy1 - iy0 + 1, map.cellSizeM(), map.originX() + ix0 * map.cellSizeM(),
                           map.originY() + iy0 * map.cellSizeM(), -1);
    for (int iy = iy0; iy <= iy1; ++iy)
        for (int ix = ix0; ix <= ix1; ++ix)
            if (w.contains(map.cellCentreX(ix), map.cellCentreY(iy))) out(ix - ix0, iy - iy0) = map(ix, iy);
    return out;
}

int labelAt(const Grid<std::int32_t>& labels, double x, double y) {
    const int ix = labels.cellX(x), iy = labels.cellY(y);
    if (ix < 0 || iy < 0 || ix >= labels.width() || iy >= labels.height()) return -1;
    return labels(ix, iy);
}

/// Crown cover raster over the plot widened by the edge band, and each in-plot raster
/// cell's light class.
struct CoverRaster {
    double ox = 0, oy = 0, res = 0.2;
    int nx = 0, ny = 0;
    std::vector<std::uint8_t> covered;  ///< [nx * ny]
    std::vector<std::int8_t> lightClass;  ///< [nx * ny], -1 outside the plot
    int cx(double x) const { return std::clamp(static_cast<int>(std::floor((x - ox) / res)), 0, nx - 1); }
    int cy(double y) const { return std::clamp(static_cast<int>(std::floor((y - oy) / res)), 0, ny - 1); }
    std::size_t at(int x, int y) const { return static_cast<std::size_t>(y) * static_cast<std::size_t>(nx) + static_cast<std::size_t>(x); }
};

CoverRaster coverRaster(const std::vector<Plant>& canopy, const FidelityParams& p) {
    CoverRaster c;
    c.res = p.coverRasterM;
    const double band = p.edgeBandM;
    c.ox = p.window.x0 - band;
    c.oy = p.window.y0 - band;
    c.nx = static_cast<int>(std::ceil((p.window.widthM() + 2 * band) / c.res));
    c.ny = static_cast<int>(std::ceil((p.window.heightM() + 2 * band) / c.res));
    c.covered.assign(static_cast<std::size_t>(c.nx) * static_cast<std::size_t>(c.ny), 0);
    for (const Plant& t : canopy) {
        const double r = t.crownRadiusM;
        if (!(r > 0)) continue;
        const int x0 = static_cast<int>(std::floor((t.xM - r - c.ox) / c.res));
        const int x1 = static_cast<int>(std::floor((t.xM + r - c.ox) / c.res));
        const int y0 = static_cast<int>(std::floor((t.yM - r - c.oy) / c.res));
        const int y1 = static_cast<int>(std::floor((t.yM + r - c.oy) / c.res));
        for (int y = std::max(0, y0); y <= std::min(c.ny - 1, y1); ++y)
            for (int x = std::max(0, x0); x <= std::min(c.nx - 1, x1); ++x) {
                const double dx = c.ox + (x + 0.5) * c.res - t.xM, dy = c.oy + (y + 0.5) * c.res - t.yM;
                if (dx * dx + dy * dy <= r * r) c.covered[c.at(x, y)] = 1;
            }
    }
    // Offsets within the band, nearest first, so that most cells stop early. The edge lies
    // between a cell and the nearest centre of the other class, on average about a quarter
    // of a raster cell short of that centre (on curved and oblique edges the nearest of
    // many candidate centres is closer than the half cell of an axis-aligned edge): a cell is
    // within the band when that centre is within band + res / 4 (checked against the exact
    // ring areas of a disc, tests/fidelity_test.cpp).
    struct Off {
        int dx, dy;
        double d2;
    };
    std::vector<Off> offs;
    const double reachM = band + 0.25 * c.res;
    const int reach = static_cast<int>(std::ceil(reachM / c.res));
    for (int dy = -reach; dy <= reach; ++dy)
        for (int dx = -reach; dx <= reach; ++dx) {
            const double d2 = (dx * c.res) * (dx * c.res) + (dy * c.res) * (dy * c.res);
            if ((dx || dy) && d2 <= reachM * reachM) offs.push_back({dx, dy, d2});
        }
    std::stable_sort(offs.begin(), offs.end(), [](const Off& a, const Off& b) { return a.d2 < b.d2; });
    c.lightClass.assign(c.covered.size(), -1);
    for (int y = 0; y < c.ny; ++y)
        for (int x = 0; x < c.nx; ++x) {
            if (!p.window.contains(c.ox + (x + 0.5) * c.res, c.oy + (y + 0.5) * c.res)) continue;
            const std::uint8_t mine = c.covered[c.at(x, y)];
            bool nearEdge = false;
            for (const Off& o : offs) {
                const int xx = x + o.dx, yy = y + o.dy;
                if (xx < 0 || yy < 0 || xx >= c.nx || yy >= c.ny) continue;  // beyond the band: unknown, treated as same
                if (c.covered[c.at(xx, yy)] != mine) {
                    nearEdge = true;
                    break;
                }
            }
            c.lightClass[c.at(x, y)] =
                static_cast<std::int8_t>(nearEdge ? LightClass::Edge : (mine ? LightClass::Deep : LightClass::Clearing));
        }
    return c;
}

/// Canopy index: the tallest crown covering a point (0 when none).
struct CrownIndex {
    PointGrid grid;
    std::vector<double> radius, height;
    double maxRadius = 0;
    explicit CrownIndex(const std::vector<Plant>& canopy) {
        std::vector<double> xs, ys, rs, hs;
        for (const Plant& t : canopy) {
            xs.push_back(t.xM);
            ys.push_back(t.yM);
            rs.push_back(t.crownRadiusM);
            hs.push_back(t.heightM);
            maxRadius = std::max(maxRadius, t.crownRadiusM);
        }
        grid = PointGrid(xs, ys, std::max(1.0, maxRadius));
        radius = grid.permuted(rs);
        height = grid.permuted(hs);
    }
    /// Height of the tallest crown whose disc holds (x, y), -1 when none.
    double tallestCover(double x, double y) const {
        double best = -1;
        if (grid.size() == 0) return best;
        grid.forEachWithin(x, y, maxRadius + 1e-9, [&](std::size_t s, double, double, double d2) {
            if (d2 <= radius[s] * radius[s]) best = std::max(best, height[s]);
        });
        return best;
    }
};

}  // namespace

// ------------------------------------------------------------------------- parameters

const std::vector<ParamDesc<FidelityParams>>& fidelityParamFields() {
    using K = ParamDesc<FidelityParams>::Kind;
    using R = ParamRange;
    using P = FidelityParams;
    static const std::vector<ParamDesc<P>> fields = {
        {"edge_band_m", "light classes: the gap-edge band either side of the crown-cover edge", "m", K::Real, &P::edgeBandM,
         nullptr, R::above(0)},
        {"cover_raster_m", "cell of the crown-cover raster the light classes are read from (at most edge_band_m)", "m",
         K::Real, &P::coverRasterM, nullptr, R::above(0)},
        {"trunk_exclusion_factor", "the CSR reference: no plant within this share of a crown radius of a trunk", "crown radii",
         K::Real, &P::trunkExclusionFactor, nullptr, R{ParamRange::Bound::Closed, 0, ParamRange::Bound::Open, 1}},
        {"chm_threshold_m", "heights against the CHM only where it is at least this tall (the simulator's canopy_threshold_m)",
         "m", K::Real, &P::chmThresholdM, nullptr, R::atLeast(0)},
        {"csr_seed", "seed of the CSR reference pattern", "", K::Seed, nullptr, nullptr, R::any(),
         &P::csrSeed},
        {"score_guard_fraction",
         "a score is given only when d(CSR, B) - d(A, B) exceeds this share of d(CSR, B) (else n/a)", "", K::Real,
         &P::scoreGuardFraction, nullptr, R{ParamRange::Bound::Closed, 0, ParamRange::Bound::Open, 1}},
    };
    return fields;
}

void FidelityParams::validate() const {
    window.validate("fidelity plot window");
    bins.validate("fidelity distance bins");
    if (bins.rMaxM > 0.5 * std::min(window.widthM(), window.heightM()))
        throw ValidationError("fidelity: rmax " + num(bins.rMaxM) + " m exceeds half the plot's shorter side (" +
                              num(0.5 * std::min(window.widthM(), window.heightM())) + " m)");
    validateParams(*this, fidelityParamFields(), "fidelity parameter");
    if (coverRasterM > edgeBandM)
        throw ValidationError("fidelity parameter 'cover_raster_m' must not exceed edge_band_m (" + num(edgeBandM) + "), got " +
                              num(coverRasterM));
}

std::vector<std::pair<std::string, std::string>> FidelityParams::asParameters() const {
    std::vector<std::pair<std::string, std::string>> out = {
        {"window", num(window.x0) + "," + num(window.y0) + "," + num(window.x1) + "," + num(window.y1)},
        {"pcf_rmax_m", num(bins.rMaxM)},
        {"pcf_bins", std::to_string(bins.count)}};
    for (const auto& f : fidelityParamFields()) out.emplace_back(f.key, paramText(f, *this, 6));
    return out;
}

// ------------------------------------------------------------------------- small pieces

std::int64_t PatternSummary::Scope::total() const {
    std::int64_t n = 0;
    for (auto c : count) n += c;
    return n;
}

double PatternSummary::Scope::classDensity(LightClass c) const {
    const int i = static_cast<int>(c);
    return classAreaM2[i] > 0 ? static_cast<double>(classCount[i]) / classAreaM2[i] : kNaN;
}

double rmsDifference(const std::vector<double>& a, const std::vector<double>& b) {
    if (a.size() != b.size()) throw ValidationError("rmsDifference: curves of " + std::to_string(a.size()) + " and " +
                                                    std::to_string(b.size()) + " values");
    if (a.empty()) return 0.0;
    double s = 0;
    for (std::size_t i = 0; i < a.size(); ++i) s += (a[i] - b[i]) * (a[i] - b[i]);
    return std::sqrt(s / static_cast<double>(a.size()));
}

std::vector<double> ripleyLMinusR(const PairSums& sums) {
    const int nb = sums.bins.count;
    std::vector<double> out(static_cast<std::size_t>(nb), 0.0);
    const double norm = sums.normalisation(0, 0);
    double k = 0;
    for (int b = 0; b < nb; ++b) {
        if (norm > 0) k += sums.translateSum[sums.index(0, 0, b)] / norm;
        out[static_cast<std::size_t>(b)] = norm > 0 ? std::sqrt(k / M_PI) - sums.bins.hiM(b) : 0.0;
    }
    return out;
}

double sortedQuantile(const std::vector<double>& v, double q) {
    if (v.empty()) return kNaN;
    const double pos = q * static_cast<double>(v.size() - 1);
    const std::size_t i = static_cast<std::size_t>(std::floor(pos));
    if (i + 1 >= v.size()) return v.back();
    const double t = pos - static_cast<double>(i);
    return v[i] * (1 - t) + v[i + 1] * t;
}

double pctDev(double synthesis, double sample) {
    return sample != 0.0 ? std::abs(synthesis - sample) / std::abs(sample) * 100.0 : kNaN;
}

double fidelityScore(double dScene, double dReplicate, double dCsr, double guardFraction, bool& scored) {
    const double span = dCsr - dReplicate;
    scored = std::isfinite(dScene) && std::isfinite(span) && span > 1e-9 && span > guardFraction * std::abs(dCsr);
    return scored ? (dScene - dReplicate) / span : kNaN;
}

// ------------------------------------------------------------------------- summary

PatternSummary summarisePattern(const std::string& name, const std::vector<Plant>& undergrowth,
                                const FidelityContext& ctx, const FidelityParams& params) {
    if (!ctx.biome) throw ValidationError("fidelity: no biome");
    const int S = static_cast<int>(ctx.biome->species.size());
    const int nScopes = 1 + ctx.nRegions;
    const RectWindow& W = params.window;
    const Grid<std::int32_t> labels = croppedLabels(ctx.regionMap, W);
    const CoverRaster cover = coverRaster(ctx.canopy, params);
    const CrownIndex crowns(ctx.canopy);

    PatternSummary out;
    out.name = name;
    out.scopes.resize(static_cast<std::size_t>(nScopes));
    for (auto& s : out.scopes) {
        s.count.assign(static_cast<std::size_t>(S), 0);
        s.underCrown.assign(static_cast<std::size_t>(S), 0);
        s.radiusRatio.assign(static_cast<std::size_t>(S), {});
    }
    // Areas: seeded cells of the region map; light classes on the cover raster.
    const double cellArea = labels.cellSizeM() * labels.cellSizeM();
    for (int iy = 0; iy < labels.height(); ++iy)
        for (int ix = 0; ix < labels.width(); ++ix) {
            const int l = labels(ix, iy);
            if (l < 0 || l >= ctx.nRegions) continue;
            out.scopes[0].seededAreaM2 += cellArea;
            out.scopes[static_cast<std::size_t>(1 + l)].seededAreaM2 += cellArea;
        }
    const double rasterArea = cover.res * cover.res;
    for (int y = 0; y < cover.ny; ++y)
        for (int x = 0; x < cover.nx; ++x) {
            const int c = cover.lightClass[cover.at(x, y)];
            if (c < 0) continue;
            const int l = labelAt(labels, cover.ox + (x + 0.5) * cover.res, cover.oy + (y + 0.5) * cover.res);
            if (l < 0 || l >= ctx.nRegions) continue;
            out.scopes[0].classAreaM2[c] += rasterArea;
            out.scopes[static_cast<std::size_t>(1 + l)].classAreaM2[c] += rasterArea;
        }

    std::vector<Plant> inPlot;
    PointPattern pooled;
    pooled.typeNames = {"undergrowth"};
    for (const Plant& p : undergrowth) {
        if (!W.contains(p.xM, p.yM)) continue;
        const int l = labelAt(labels, p.xM, p.yM);
        if (l < 0 || l >= ctx.nRegions) continue;
        if (p.speciesId < 0 || p.speciesId >= S)
            throw ValidationError("fidelity: pattern '" + name + "' has a plant of species id " + std::to_string(p.speciesId) +
                                  " outside the biome's " + std::to_string(S) + " species");
        inPlot.push_back(p);
        pooled.x.push_back(p.xM);
        pooled.y.push_back(p.yM);
        pooled.type.push_back(0);
        const auto sp = static_cast<std::size_t>(p.speciesId);
        const double tallest = crowns.tallestCover(p.xM, p.yM);
        const int lc = cover.lightClass[cover.at(cover.cx(p.xM), cover.cy(p.yM))];
        const double allometric = ctx.biome->species[sp].allometry.crownRadiusM(p.heightM);
        bool aboveChm = false;
        if (!ctx.chmM.empty()) {
            const int cx = ctx.chmM.cellX(p.xM), cy = ctx.chmM.cellY(p.yM);
            if (cx >= 0 && cy >= 0 && cx < ctx.chmM.width() && cy < ctx.chmM.height()) {
                const double h = ctx.chmM(cx, cy);
                aboveChm = h >= params.chmThresholdM && p.heightM > h;
            }
        }
        for (int scope : {0, 1 + l}) {
            auto& s = out.scopes[static_cast<std::size_t>(scope)];
            ++s.count[sp];
            if (tallest >= 0) ++s.underCrown[sp];
            if (tallest >= 0 && p.heightM > tallest) ++s.tallerThanCrown;
            if (aboveChm) ++s.tallerThanChm;
            if (lc >= 0) ++s.classCount[lc];
            if (allometric > 0) s.radiusRatio[sp].push_back(p.crownRadiusM / allometric);
        }
    }
    for (auto& s : out.scopes)
        for (auto& v : s.radiusRatio) std::sort(v.begin(), v.end());

    // Pair correlation per region (region windows), canopy trees as categories.
    const synth::ScenePairStats stats = synth::scenePairStatistics(ctx.canopy, inPlot, labels, ctx.nRegions, S, params.bins, &W, 0, 1);
    const int nCat = stats.nCategories, nb = params.bins.count;
    out.pairs.resize(static_cast<std::size_t>(ctx.nRegions));
    for (int r = 0; r < ctx.nRegions; ++r) {
        const auto& R = stats.regions[static_cast<std::size_t>(r)];
        auto& P = out.pairs[static_cast<std::size_t>(r)];
        P.areaM2 = R.areaM2;
        P.count = R.count;
        if (R.count.empty()) P.count.assign(static_cast<std::size_t>(nCat), 0);
        P.g.assign(static_cast<std::size_t>(nCat) * static_cast<std::size_t>(nCat) * static_cast<std::size_t>(nb), 0.0);
        if (!R.count.empty() && !R.weighted.empty())
            for (int i = 0; i < nCat; ++i)
                for (int j = 0; j < nCat; ++j)
                    for (int k = 0; k < nb; ++k)
                        P.g[(static_cast<std::size_t>(i) * static_cast<std::size_t>(nCat) + static_cast<std::size_t>(j)) *
                                static_cast<std::size_t>(nb) +
                            static_cast<std::size_t>(k)] = R.g(i, j, k, params.bins, nCat);
        out.scopes[static_cast<std::size_t>(1 + r)].pooledG =
            R.count.empty() ? std::vector<double>(static_cast<std::size_t>(nb), 0.0) : synth::pooledUndergrowthG(stats, r, S);
    }
    // Unmarked pattern in the plot rectangle: g and Ripley's L.
    PcfOptions opt;
    opt.bins = params.bins;
    opt.isotropic = false;
    const PairSums sums = countPairs(pooled, W, opt);
    out.gRect.resize(static_cast<std::size_t>(nb));
    for (int k = 0; k < nb; ++k) out.gRect[static_cast<std::size_t>(k)] = sums.gTranslate(0, 0, k);
    out.lMinusR = ripleyLMinusR(sums);
    double m = 0;
    for (double v : out.lMinusR) m += v;
    out.ripleyIndex = nb > 0 ? m / nb : 0.0;
    return out;
}

// ------------------------------------------------------------------------- CSR

std::vector<Plant> csrPattern(const std::vector<Plant>& reference, const FidelityContext& ctx, const FidelityParams& params) {
    const RectWindow& W = params.window;
    const Grid<std::int32_t> labels = croppedLabels(ctx.regionMap, W);
    std::vector<std::pair<int, int>> cells;
    for (int iy = 0; iy < labels.height(); ++iy)
        for (int ix = 0; ix < labels.width(); ++ix)
            if (labels(ix, iy) >= 0 && labels(ix, iy) < ctx.nRegions) cells.emplace_back(ix, iy);
    std::vector<Plant> out;
    for (const Plant& p : reference)
        if (W.contains(p.xM, p.yM) && labelAt(labels, p.xM, p.yM) >= 0 && labelAt(labels, p.xM, p.yM) < ctx.nRegions)
            out.push_back(p);
    if (cells.empty() || out.empty()) return out;
    // Trunk exclusion discs (the synthesizer's rule), through a grid of trunks.
    std::vector<double> tx, ty, tr;
    double maxR = 0;
    for (const Plant& t : ctx.canopy) {
        tx.push_back(t.xM);
        ty.push_back(t.yM);
        tr.push_back(params.trunkExclusionFactor * t.crownRadiusM);
        maxR = std::max(maxR, params.trunkExclusionFactor * t.crownRadiusM);
    }
    const PointGrid trunks(tx, ty, std::max(1.0, maxR));
    const std::vector<double> trunkR = trunks.permuted(tr);
    const double cs = labels.cellSizeM();
    for (std::size_t i = 0; i < out.size(); ++i) {
        RandomStream rng(params.csrSeed, mixStream(0x6373720000000001ULL, i));
        for (int attempt = 0;; ++attempt) {
            if (attempt > 10000)
                throw ValidationError("fidelity CSR: no position off the trunks found for plant " + std::to_string(i));
            const auto& c = cells[rng.below(static_cast<std::uint32_t>(cells.size()))];
            const double x = labels.originX() + (c.first + rng.uniform()) * cs;
            const double y = labels.originY() + (c.second + rng.uniform()) * cs;
            if (!W.contains(x, y)) continue;
            bool onTrunk = false;
            if (trunks.size() > 0)
                trunks.forEachWithin(x, y, maxR + 1e-9, [&](std::size_t s, double, double, double d2) {
                    if (d2 < trunkR[s] * trunkR[s]) onTrunk = true;
                });
            if (onTrunk) continue;
            out[i].xM = x;
            out[i].yM = y;
            break;
        }
    }
    // Crown radii permuted within species (Fisher-Yates, one stream): no height-radius coupling.
    const int S = ctx.biome ? static_cast<int>(ctx.biome->species.size()) : 0;
    RandomStream shuffle(params.csrSeed, 0x6373720000000002ULL);
    for (int sp = 0; sp < S; ++sp) {
        std::vector<std::size_t> idx;
        for (std::size_t i = 0; i < out.size(); ++i)
            if (out[i].speciesId == sp) idx.push_back(i);
        for (std::size_t k = idx.size(); k > 1; --k) {
            const std::size_t j = shuffle.below(static_cast<std::uint32_t>(k));
            std::swap(out[idx[k - 1]].crownRadiusM, out[idx[j]].crownRadiusM);
        }
    }
    return out;
}

// ------------------------------------------------------------------------- distances

namespace {

double pairsOf(const std::vector<std::int64_t>& count, int i, int j) {
    const double ni = static_cast<double>(count[static_cast<std::size_t>(i)]);
    const double nj = static_cast<double>(count[static_cast<std::size_t>(j)]);
    return i == j ? ni * (ni - 1) : ni * nj;
}

enum class PairSet { All, CanopyCross };

/// Pair-weighted RMS difference of g over category pairs (pcfDistance's formula, with B's
/// pair counts as weights); per region (sqrt of its weighted mean) and overall.
std::pair<std::vector<double>, double> pairDistance(const PatternSummary& x, const PatternSummary& b, int S, int nb,
                                                     PairSet set) {
    const int nCat = 2 * S;
    std::vector<double> perRegion(b.pairs.size(), kNaN);
    double sum = 0, weight = 0;
    for (std::size_t r = 0; r < b.pairs.size(); ++r) {
        const auto& B = b.pairs[r];
        const auto& X = x.pairs[r];
        double rs = 0, rw = 0;
        for (int i = 0; i < nCat; ++i)
            for (int j = i; j < nCat; ++j) {
                if (i >= S && j >= S) continue;  // canopy with canopy: fixed
                if (set == PairSet::CanopyCross && !(i < S && j >= S)) continue;
                const double w = pairsOf(B.count, i, j);
                if (!(w > 0)) continue;
                double mse = 0;
                for (int k = 0; k < nb; ++k) {
                    const std::size_t idx =
                        (static_cast<std::size_t>(i) * static_cast<std::size_t>(nCat) + static_cast<std::size_t>(j)) *
                            static_cast<std::size_t>(nb) +
                        static_cast<std::size_t>(k);
                    const double d = X.g[idx] - B.g[idx];
                    mse += d * d;
                }
                rs += w * mse / nb;
                rw += w;
            }
        if (rw > 0) perRegion[r] = std::sqrt(rs / rw);
        sum += rs;
        weight += rw;
    }
    return {perRegion, weight > 0 ? std::sqrt(sum / weight) : kNaN};
}

double share(std::int64_t a, std::int64_t n) { return n > 0 ? static_cast<double>(a) / static_cast<double>(n) : kNaN; }

/// The figures that are computed per scope (the whole plot or one region).
std::vector<std::pair<std::string, double>> scopeDistances(const PatternSummary::Scope& x, const PatternSummary::Scope& b) {
    std::vector<std::pair<std::string, double>> out;
    const std::int64_t nx = x.total(), nbT = b.total();
    const std::size_t S = b.count.size();
    // Under-crown share, weighted by B's species shares.
    double uc = 0, ucW = 0;
    for (std::size_t s = 0; s < S; ++s) {
        if (b.count[s] == 0) continue;
        const double sx = x.count[s] > 0 ? share(x.underCrown[s], x.count[s]) : 0.0;
        const double w = static_cast<double>(b.count[s]);
        uc += w * std::abs(sx - share(b.underCrown[s], b.count[s]));
        ucW += w;
    }
    out.emplace_back("under-crown share (|difference|, weighted by species)", ucW > 0 ? uc / ucW : kNaN);
    // Light classes.
    const double bDeep = b.classDensity(LightClass::Deep), xDeep = x.classDensity(LightClass::Deep);
    const double bEdge = b.classDensity(LightClass::Edge) / bDeep, xEdge = x.classDensity(LightClass::Edge) / xDeep;
    const double bClear = b.classDensity(LightClass::Clearing) / bDeep, xClear = x.classDensity(LightClass::Clearing) / xDeep;
    out.emplace_back("density edge / deep (|difference|)", std::abs(xEdge - bEdge));
    out.emplace_back("density clearing / deep (|difference|)", std::abs(xClear - bClear));
    // Radius / allometric radius.
    double dMed = 0, dP5 = 0, dQ = 0, rw = 0;
    for (std::size_t s = 0; s < S; ++s) {
        if (b.radiusRatio[s].empty() || x.radiusRatio[s].empty()) continue;
        const double w = static_cast<double>(b.radiusRatio[s].size());
        dMed += w * std::abs(sortedQuantile(x.radiusRatio[s], 0.5) - sortedQuantile(b.radiusRatio[s], 0.5));
        dP5 += w * std::abs(sortedQuantile(x.radiusRatio[s], 0.05) - sortedQuantile(b.radiusRatio[s], 0.05));
        // The whole distribution: quantiles 5, 10, ..., 95 % of ln(ratio), so that the long
        // upper tail of independently drawn sizes (ratios of 10 and more) does not swamp it.
        const auto lnq = [](const std::vector<double>& v, double q) { return std::log(std::max(1e-3, sortedQuantile(v, q))); };
        double q = 0;
        for (int k = 1; k <= 19; ++k) q += std::abs(lnq(x.radiusRatio[s], 0.05 * k) - lnq(b.radiusRatio[s], 0.05 * k));
        dQ += w * q / 19.0;
        rw += w;
    }
    out.emplace_back("radius / allometric radius, median (|difference|, weighted)", rw > 0 ? dMed / rw : kNaN);
    out.emplace_back("radius / allometric radius, 5th percentile (|difference|, weighted)", rw > 0 ? dP5 / rw : kNaN);
    out.emplace_back("radius / allometric radius, quantiles 5-95 % (mean |ln difference|, weighted)", rw > 0 ? dQ / rw : kNaN);
    // Heights against the canopy.
    out.emplace_back("share taller than the crown above (|difference|)",
                     std::abs((nx > 0 ? share(x.tallerThanCrown, nx) : 0.0) - share(b.tallerThanCrown, nbT)));
    out.emplace_back("share taller than the CHM (|difference|)",
                     std::abs((nx > 0 ? share(x.tallerThanChm, nx) : 0.0) - share(b.tallerThanChm, nbT)));
    // Density and species shares (eco compare's measures).
    out.emplace_back("density (relative |difference|)", b.density() > 0 ? std::abs(x.density() - b.density()) / b.density() : kNaN);
    double maxShare = 0, pct = 0;
    int pctN = 0;
    for (std::size_t s = 0; s < S; ++s) {
        maxShare = std::max(maxShare, std::abs((nx > 0 ? share(x.count[s], nx) : 0.0) - share(b.count[s], nbT)));
        if (b.count[s] > 0) {
            pct += pctDev(static_cast<double>(x.count[s]), static_cast<double>(b.count[s]));
            ++pctN;
        }
    }
    out.emplace_back("species shares (max |difference|)", nbT > 0 ? maxShare : kNaN);
    out.emplace_back("PCT.DEV density, mean over species (%)", pctN > 0 ? pct / pctN : kNaN);
    return out;
}

}  // namespace

FigureDistances figureDistances(const PatternSummary& x, const PatternSummary& b, const FidelityContext& ctx) {
    const int S = static_cast<int>(ctx.biome->species.size());
    const int nb = b.gRect.empty() ? 0 : static_cast<int>(b.gRect.size());
    FigureDistances out;
    // Pooled undergrowth g per region; overall weighted by B's pooled pairs.
    double gs = 0, gw = 0;
    std::vector<double> pooledRegion(static_cast<std::size_t>(ctx.nRegions), kNaN);
    for (int r = 0; r < ctx.nRegions; ++r) {
        const auto& B = b.scopes[static_cast<std::size_t>(1 + r)];
        const auto& X = x.scopes[static_cast<std::size_t>(1 + r)];
        const double n = static_cast<double>(B.total());
        if (n < 2 || B.pooledG.empty()) continue;
        const double d = rmsDifference(X.pooledG, B.pooledG);
        pooledRegion[static_cast<std::size_t>(r)] = d;
        gs += n * (n - 1) * d * d;
        gw += n * (n - 1);
    }
    const auto pairs = pairDistance(x, b, S, nb, PairSet::All);
    const auto cross = pairDistance(x, b, S, nb, PairSet::CanopyCross);
    out.overall.emplace_back("g pooled undergrowth (RMS, regions)", gw > 0 ? std::sqrt(gs / gw) : kNaN);
    out.overall.emplace_back("g species pairs incl. canopy (pair-weighted RMS)", pairs.second);
    out.overall.emplace_back("g canopy -> undergrowth (pair-weighted RMS)", cross.second);
    out.overall.emplace_back("g pooled undergrowth, plot rectangle (RMS)", rmsDifference(x.gRect, b.gRect));
    out.overall.emplace_back("L(r) - r, plot rectangle (RMS, m)", rmsDifference(x.lMinusR, b.lMinusR));
    out.overall.emplace_back("PCT.DEV Ripley aggregation index (%)", pctDev(x.ripleyIndex, b.ripleyIndex));
    for (auto& f : scopeDistances(x.scopes[0], b.scopes[0])) out.overall.push_back(f);
    out.perRegion.resize(static_cast<std::size_t>(ctx.nRegions));
    for (int r = 0; r < ctx.nRegions; ++r) {
        auto& v = out.perRegion[static_cast<std::size_t>(r)];
        v.emplace_back("g pooled undergrowth (RMS, regions)", pooledRegion[static_cast<std::size_t>(r)]);
        v.emplace_back("g species pairs incl. canopy (pair-weighted RMS)", pairs.first[static_cast<std::size_t>(r)]);
        v.emplace_back("g canopy -> undergrowth (pair-weighted RMS)", cross.first[static_cast<std::size_t>(r)]);
        for (auto& f : scopeDistances(x.scopes[static_cast<std::size_t>(1 + r)], b.scopes[static_cast<std::size_t>(1 + r)]))
            v.push_back(f);
    }
    return out;
}

// ------------------------------------------------------------------------- the protocol

FidelityReport evaluateFidelity(const std::vector<Plant>& scene, const std::vector<Plant>& referenceA,
                                const std::vector<Plant>& replicateB, const FidelityContext& ctx,
                                const FidelityParams& params) {
    params.validate();
    if (!ctx.biome) throw ValidationError("fidelity: no biome");
    if (static_cast<int>(ctx.regionNames.size()) != ctx.nRegions)
        throw ValidationError("fidelity: " + std::to_string(ctx.regionNames.size()) + " region names for " +
                              std::to_string(ctx.nRegions) + " regions");
    const std::vector<Plant> csr = csrPattern(replicateB, ctx, params);
    const PatternSummary sS = summarisePattern("scene", scene, ctx, params);
    const PatternSummary sA = summarisePattern("A", referenceA, ctx, params);
    const PatternSummary sB = summarisePattern("B", replicateB, ctx, params);
    const PatternSummary sC = summarisePattern("CSR", csr, ctx, params);
    if (sB.scopes[0].total() == 0)
        throw ValidationError("fidelity: the held-out simulation B has no undergrowth plant in the plot " +
                              num(params.window.x0) + "," + num(params.window.y0) + "," + num(params.window.x1) + "," +
                              num(params.window.y1) + " on cells of a region");
    const FigureDistances dS = figureDistances(sS, sB, ctx), dA = figureDistances(sA, sB, ctx),
                          dC = figureDistances(sC, sB, ctx);
    FidelityReport rep;
    rep.params = params;
    const auto addScope = [&](const std::string& scope, const std::vector<std::pair<std::string, double>>& s,
                              const std::vector<std::pair<std::string, double>>& a,
                              const std::vector<std::pair<std::string, double>>& c) {
        for (std::size_t i = 0; i < s.size(); ++i) {
            FidelityFigure f;
            f.figure = s[i].first;
            f.scope = scope;
            f.scene = s[i].second;
            f.replicate = a[i].second;
            f.csr = c[i].second;
            f.score = fidelityScore(f.scene, f.replicate, f.csr, params.scoreGuardFraction, f.scored);
            rep.figures.push_back(f);
        }
    };
    addScope("overall", dS.overall, dA.overall, dC.overall);
    for (int r = 0; r < ctx.nRegions; ++r)
        if (sB.scopes[static_cast<std::size_t>(1 + r)].total() > 0)
            addScope(ctx.regionNames[static_cast<std::size_t>(r)], dS.perRegion[static_cast<std::size_t>(r)],
                     dA.perRegion[static_cast<std::size_t>(r)], dC.perRegion[static_cast<std::size_t>(r)]);

    // Per-species values over the whole plot.
    const auto& S0 = sS.scopes[0];
    const auto& A0 = sA.scopes[0];
    const auto& B0 = sB.scopes[0];
    const auto& C0 = sC.scopes[0];
    for (std::size_t sp = 0; sp < B0.count.size(); ++sp) {
        if (B0.count[sp] == 0 && S0.count[sp] == 0 && A0.count[sp] == 0) continue;
        const std::string name = ctx.biome->species[sp].name;
        const auto row = [&](const std::string& q, auto f) {
            rep.species.push_back({q, name, f(S0), f(A0), f(B0), f(C0), B0.count[sp]});
        };
        row("plants", [&](const PatternSummary::Scope& s) { return static_cast<double>(s.count[sp]); });
        row("under-crown share", [&](const PatternSummary::Scope& s) { return share(s.underCrown[sp], s.count[sp]); });
        row("radius / allometric, median", [&](const PatternSummary::Scope& s) { return sortedQuantile(s.radiusRatio[sp], 0.5); });
        row("radius / allometric, 5th percentile",
            [&](const PatternSummary::Scope& s) { return sortedQuantile(s.radiusRatio[sp], 0.05); });
    }
    // Raw values per scope.
    const auto values = [&](const std::string& scope, std::size_t k) {
        const auto v = [&](const std::string& q, auto f) {
            rep.values.push_back({q, scope, f(sS.scopes[k]), f(sA.scopes[k]), f(sB.scopes[k]), f(sC.scopes[k])});
        };
        using Sc = PatternSummary::Scope;
        v("plants", [](const Sc& s) { return static_cast<double>(s.total()); });
        v("density /m2 (seeded area)", [](const Sc& s) { return s.density(); });
        v("density deep shade /m2", [](const Sc& s) { return s.classDensity(LightClass::Deep); });
        v("density gap edge /m2", [](const Sc& s) { return s.classDensity(LightClass::Edge); });
        v("density clearing /m2", [](const Sc& s) { return s.classDensity(LightClass::Clearing); });
        v("edge / deep", [](const Sc& s) { return s.classDensity(LightClass::Edge) / s.classDensity(LightClass::Deep); });
        v("clearing / deep", [](const Sc& s) { return s.classDensity(LightClass::Clearing) / s.classDensity(LightClass::Deep); });
        v("under any crown, share of all", [](const Sc& s) {
            std::int64_t u = 0;
            for (auto c : s.underCrown) u += c;
            return share(u, s.total());
        });
        v("taller than the crown above (plants)", [](const Sc& s) { return static_cast<double>(s.tallerThanCrown); });
        v("taller than the CHM (plants)", [](const Sc& s) { return static_cast<double>(s.tallerThanChm); });
    };
    values("overall", 0);
    rep.values.push_back({"Ripley aggregation index (mean L(r) - r, m)", "overall", sS.ripleyIndex, sA.ripleyIndex,
                          sB.ripleyIndex, sC.ripleyIndex});
    const int bin = params.bins.binOf(0.875);
    if (bin >= 0)
        rep.values.push_back({"pooled g at 0.875 m (plot rectangle)", "overall", sS.gRect[static_cast<std::size_t>(bin)],
                              sA.gRect[static_cast<std::size_t>(bin)], sB.gRect[static_cast<std::size_t>(bin)],
                              sC.gRect[static_cast<std::size_t>(bin)]});
    for (int r = 0; r < ctx.nRegions; ++r)
        if (sB.scopes[static_cast<std::size_t>(1 + r)].total() > 0) values(ctx.regionNames[static_cast<std::size_t>(r)], 1 + static_cast<std::size_t>(r));
    for (int k = 0; k < params.bins.count; ++k) rep.binUpperM.push_back(params.bins.hiM(k));
    rep.gScene = sS.gRect;
    rep.gA = sA.gRect;
    rep.gB = sB.gRect;
    rep.gCsr = sC.gRect;
    rep.lScene = sS.lMinusR;
    rep.lA = sA.lMinusR;
    rep.lB = sB.lMinusR;
    rep.lCsr = sC.lMinusR;
    return rep;
}

// ------------------------------------------------------------------------- output

namespace {

std::string cell(double v, int decimals = 3) {
    if (!std::isfinite(v)) return "n/a";
    char buf[64];
    std::snprintf(buf, sizeof buf, "%.*f", decimals, v);
    return buf;
}

std::string csvNum(double v) { return std::isfinite(v) ? formatNumber(v, 8) : std::string(); }

}  // namespace

std::string fidelityMarkdown(const FidelityReport& r, const std::string& heading) {
    std::ostringstream md;
    md << heading << "\n\n"
       << "Distances to the held-out simulation B inside the plot " << num(r.params.window.x0) << ","
       << num(r.params.window.y0) << "," << num(r.params.window.x1) << "," << num(r.params.window.y1)
       << ": scene = d(scene, B), replicate = d(A, B), CSR = d(CSR, B); score = (scene - replicate) / (CSR - "
          "replicate), 0 = as good as a replicate simulation, 1 = no structure (n/a: CSR not distinguishable from "
          "the replicate for this figure).\n\n"
       << "| figure | scope | scene | replicate | CSR | score |\n|---|---|---:|---:|---:|---:|\n";
    for (const auto& f : r.figures)
        if (f.scope == "overall")
            md << "| " << markdownCell(f.figure) << " | " << f.scope << " | " << cell(f.scene) << " | " << cell(f.replicate) << " | "
               << cell(f.csr) << " | " << (f.scored ? cell(f.score, 2) : std::string("n/a")) << " |\n";
    md << "\n### Per species (whole plot): scene, A (reference), B (held out), CSR\n\n"
       << "| quantity | species | B plants | scene | A | B | CSR |\n|---|---|---:|---:|---:|---:|---:|\n";
    for (const auto& s : r.species)
        md << "| " << s.quantity << " | " << s.species << " | " << s.countB << " | "
           << cell(s.scene, s.quantity == "plants" ? 0 : 3) << " | " << cell(s.reference, s.quantity == "plants" ? 0 : 3)
           << " | " << cell(s.replicate, s.quantity == "plants" ? 0 : 3) << " | " << cell(s.csr, s.quantity == "plants" ? 0 : 3)
           << " |\n";
    md << "\n### Values (whole plot): scene, A, B, CSR\n\n| quantity | scene | A | B | CSR |\n|---|---:|---:|---:|---:|\n";
    for (const auto& v : r.values)
        if (v.scope == "overall")
            md << "| " << markdownCell(v.quantity) << " | " << cell(v.scene) << " | " << cell(v.reference) << " | " << cell(v.replicate)
               << " | " << cell(v.csr) << " |\n";
    md << "\n### Per region\n\n| figure | region | scene | replicate | CSR | score |\n|---|---|---:|---:|---:|---:|\n";
    for (const auto& f : r.figures)
        if (f.scope != "overall")
            md << "| " << markdownCell(f.figure) << " | " << f.scope << " | " << cell(f.scene) << " | " << cell(f.replicate) << " | "
               << cell(f.csr) << " | " << (f.scored ? cell(f.score, 2) : std::string("n/a")) << " |\n";
    return md.str();
}

void writeFidelityCsv(const std::string& path, const FidelityReport& r) {
    std::ostringstream csv;
    csv << "kind,quantity,scope,species,scene,reference_a,replicate_b,csr,score\n";
    for (const auto& f : r.figures)
        csv << "figure," << csvField(f.figure) << "," << csvField(f.scope) << ",," << csvNum(f.scene) << ",,"
            << csvNum(f.replicate) << "," << csvNum(f.csr) << "," << (f.scored ? csvNum(f.score) : std::string()) << "\n";
    for (const auto& s : r.species)
        csv << "species," << csvField(s.quantity) << ",overall," << csvField(s.species) << "," << csvNum(s.scene) << ","
            << csvNum(s.reference) << "," << csvNum(s.replicate) << "," << csvNum(s.csr) << ",\n";
    for (const auto& v : r.values)
        csv << "value," << csvField(v.quantity) << "," << csvField(v.scope) << ",," << csvNum(v.scene) << ","
            << csvNum(v.reference) << "," << csvNum(v.replicate) << "," << csvNum(v.csr) << ",\n";
    for (std::size_t k = 0; k < r.binUpperM.size(); ++k) {
        const std::string rr = csvNum(r.binUpperM[k]);
        csv << "curve,g pooled (plot rectangle) at r_hi_m," << rr << ",," << csvNum(r.gScene[k]) << "," << csvNum(r.gA[k])
            << "," << csvNum(r.gB[k]) << "," << csvNum(r.gCsr[k]) << ",\n";
        csv << "curve,L(r) - r (plot rectangle) at r_hi_m," << rr << ",," << csvNum(r.lScene[k]) << "," << csvNum(r.lA[k])
            << "," << csvNum(r.lB[k]) << "," << csvNum(r.lCsr[k]) << ",\n";
    }
    for (const auto& [k, v] : r.params.asParameters()) csv << "parameter," << csvField(k) << ",,," << csvField(v) << ",,,,\n";
    writeTextFile(path, csv.str());
}

}  // namespace eco::validate
