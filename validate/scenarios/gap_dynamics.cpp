// Kind "gap_dynamics" (paper §7.2), forest scene: undergrowth density at forest edges and in
// clearings against deep canopy. docs/validation.md defines the classes and measures.
#include "scenario_context.h"

#include <array>
#include <cmath>

#include "image_out.h"
#include "scenario_keys.h"
#include "strict_toml.h"

namespace eco::validate {

namespace {

/// Squared Euclidean distance transform (Felzenszwalb & Huttenlocher): for every cell, the
/// squared distance in cells to the nearest cell where `target` is set (infinity if none).
std::vector<double> squaredDistanceTransform(const std::vector<char>& target, int w, int h) {
    const double inf = 1e30;
    std::vector<double> f(target.size());
    for (std::size_t i = 0; i < target.size(); ++i) f[i] = target[i] ? 0.0 : inf;
    auto pass1d = [inf](std::vector<double>& line) {
        const int n = static_cast<int>(line.size());
        std::vector<double> d(line.size()), z(line.size() + 1);
        std::vector<int> v(line.size());
        int k = 0;
        v[0] = 0;
        z[0] = -inf;
        z[1] = inf;
        for (int q = 1; q < n; ++q) {
            double s;
            while (true) {
                const int p = v[static_cast<std::size_t>(k)];
                s = ((line[static_cast<std::size_t>(q)] + double(q) * q) - (line[static_cast<std::size_t>(p)] + double(p) * p)) /
                    (2.0 * q - 2.0 * p);
                if (s <= z[static_cast<std::size_t>(k)] && k > 0) {
                    --k;
                    continue;
                }
                break;
            }
            if (s <= z[static_cast<std::size_t>(k)]) {  // k == 0
                v[0] = q;
                z[0] = -inf;
                z[1] = inf;
                continue;
            }
            ++k;
            v[static_cast<std::size_t>(k)] = q;
            z[static_cast<std::size_t>(k)] = s;
            z[static_cast<std::size_t>(k) + 1] = inf;
        }
        k = 0;
        for (int q = 0; q < n; ++q) {
            while (z[static_cast<std::size_t>(k) + 1] < q) ++k;
            const int p = v[static_cast<std::size_t>(k)];
            d[static_cast<std::size_t>(q)] = double(q - p) * (q - p) + line[static_cast<std::size_t>(p)];
        }
        line.swap(d);
    };
    std::vector<double> line;
    for (int y = 0; y < h; ++y) {
        line.assign(f.begin() + static_cast<std::ptrdiff_t>(y) * w, f.begin() + static_cast<std::ptrdiff_t>(y + 1) * w);
        pass1d(line);
        std::copy(line.begin(), line.end(), f.begin() + static_cast<std::ptrdiff_t>(y) * w);
    }
    line.resize(static_cast<std::size_t>(h));
    for (int x = 0; x < w; ++x) {
        for (int y = 0; y < h; ++y) line[static_cast<std::size_t>(y)] = f[static_cast<std::size_t>(y) * w + x];
        pass1d(line);
        for (int y = 0; y < h; ++y) f[static_cast<std::size_t>(y) * w + x] = line[static_cast<std::size_t>(y)];
    }
    return f;
}

struct GapSettings {
    double edgeBandM = 2.0;      ///< within this distance of the canopy boundary (either side): edge
    double deepMinDepthM = 4.0;  ///< covered cells at least this far from open ground: deep canopy
    int windowYears = 25;        ///< densities averaged over the snapshots of these last years
    double minClassAreaM2 = 20;  ///< a class smaller than this makes the check not evaluable
};

/// [classes] (deep_min_depth_m >= edge_band_m is checked after them).
const std::vector<ParamDesc<GapSettings>>& gapFields() {
    using P = GapSettings;
    using K = ParamDesc<P>::Kind;
    static const std::vector<ParamDesc<P>> fields = {
        {"edge_band_m", "cells within this distance of the canopy boundary, either side, are edge", "m", K::Real,
         &P::edgeBandM, nullptr, ParamRange::above(0), nullptr, "must be positive"},
        {"deep_min_depth_m", "covered cells at least this far from open ground are deep canopy (at least edge_band_m)",
         "m", K::Real, &P::deepMinDepthM, nullptr, ParamRange::above(0), nullptr, "must be positive"},
        {"window_years", "densities are averaged over the snapshots of this many last years", "years", K::Integer, nullptr,
         &P::windowYears, ParamRange::closed(1, 100000)},
        {"min_class_area_m2", "a class smaller than this makes the check not evaluable", "m^2", K::Real,
         &P::minClassAreaM2, nullptr, ParamRange::above(0), nullptr, "must be positive"},
    };
    return fields;
}

class GapDynamics final : public Scenario {
public:
    explicit GapDynamics(const ScenarioParse& in);
    std::vector<std::string> checkIds() const override { return {"edge_vs_deep", "clearing_vs_deep"}; }
    int windowYears() const override { return settings_.windowYears; }
    void run(const ScenarioConfig& sc, ScenarioContext& ctx, ScenarioResult& r) const override;

private:
    GapSettings settings_;
};

GapDynamics::GapDynamics(const ScenarioParse& in) {
    GapSettings& g = settings_;
    StrictTable s(in.top.table("classes"), in.path, "[classes]");
    readScenarioParams(s, g, gapFields());
    if (g.deepMinDepthM < g.edgeBandM) s.fail("deep_min_depth_m", "must not be below edge_band_m");
    s.finish();
}

void GapDynamics::run(const ScenarioConfig& sc, ScenarioContext& ctx, ScenarioResult& r) const {
    const GapSettings& cfg = settings_;
    const ForestRun& run = ctx.forest(sc.scenePath, sim::CompetitionMode::Resources, 0);
    const int Y = ctx.measureYear(sc);
    ctx.describeRun(run, Y, r, ctx.scene(sc));
    const Grid<float>& tr = run.transmission;
    const int w = tr.width(), h = tr.height();
    const double cell = tr.cellSizeM();
    std::vector<char> covered(tr.size()), open(tr.size());
    for (std::size_t i = 0; i < tr.size(); ++i) {
        covered[i] = tr.data()[i] < 1.0f - 1e-6f;
        open[i] = !covered[i];
    }
    const std::vector<double> toOpen = squaredDistanceTransform(open, w, h);       // for covered cells
    const std::vector<double> toCovered = squaredDistanceTransform(covered, w, h); // for open cells
    enum Cls { None = -1, Deep = 0, Edge = 1, Clearing = 2 };
    Grid<std::int32_t> cls = Grid<std::int32_t>::like(tr, None);
    std::array<double, 3> areaM2{0, 0, 0};
    const double band2 = std::pow(cfg.edgeBandM / cell, 2), deep2 = std::pow(cfg.deepMinDepthM / cell, 2);
    for (std::size_t i = 0; i < tr.size(); ++i) {
        int c = None;
        if (covered[i]) {
            if (toOpen[i] >= deep2) c = Deep;
            else if (toOpen[i] < band2) c = Edge;
        } else {
            if (toCovered[i] < band2) c = Edge;
            else if (run.seedProb.data()[i] > 0) c = Clearing;
        }
        cls.data()[i] = c;
        if (c >= 0) areaM2[static_cast<std::size_t>(c)] += cell * cell;
    }
    const auto snaps = run.window(Y - cfg.windowYears + 1, Y);
    std::array<std::vector<double>, 3> density;
    for (const Snapshot* s : snaps) {
        std::array<double, 3> count{0, 0, 0};
        for (const LitePlant& p : s->plants) {
            const int ix = tr.cellX(p.x), iy = tr.cellY(p.y);
            if (!tr.inside(ix, iy)) continue;
            const int c = cls(ix, iy);
            if (c >= 0) count[static_cast<std::size_t>(c)] += 1;
        }
        for (int c = 0; c < 3; ++c)
            if (areaM2[static_cast<std::size_t>(c)] > 0)
                density[static_cast<std::size_t>(c)].push_back(count[static_cast<std::size_t>(c)] / areaM2[static_cast<std::size_t>(c)]);
    }
    const double dDeep = mean(density[Deep]), dEdge = mean(density[Edge]), dClear = mean(density[Clearing]);
    auto ratio = [&](int c, double d, std::string& note) {
        if (areaM2[static_cast<std::size_t>(c)] < cfg.minClassAreaM2 || areaM2[Deep] < cfg.minClassAreaM2) {
            note = "class area below " + num(cfg.minClassAreaM2) + " m^2 (deep " + num(areaM2[Deep]) + ", this " +
                   num(areaM2[static_cast<std::size_t>(c)]) + ")";
            return kNaN;
        }
        return dDeep > 0 ? d / dDeep : kNaN;
    };
    std::string n1, n2;
    const double eVsD = ratio(Edge, dEdge, n1), cVsD = ratio(Clearing, dClear, n2);
    r.checks.push_back(makeCheck(sc, "edge_vs_deep", "undergrowth density at forest edges / under deep canopy", eVsD, n1));
    r.checks.push_back(makeCheck(sc, "clearing_vs_deep", "undergrowth density in clearings / under deep canopy", cVsD, n2));
    r.details.push_back("- Classes of the 0.2 m simulation cells: **deep canopy** = under a crown and at least " +
                        num(cfg.deepMinDepthM) + " m from open ground; **edge** = within " + num(cfg.edgeBandM) +
                        " m of the canopy boundary, on either side; **clearing** = open ground farther than " +
                        num(cfg.edgeBandM) + " m from any crown but inside the seedbank (germination probability > 0). "
                        "Covered cells between the edge band and the deep threshold are not used.");
    r.details.push_back("- Areas: deep " + fixed(areaM2[Deep], 0) + " m^2, edge " + fixed(areaM2[Edge], 0) + " m^2, clearing " +
                        fixed(areaM2[Clearing], 0) + " m^2. Densities (plants per m^2, mean over " + std::to_string(snaps.size()) +
                        " snapshots of the last " + std::to_string(cfg.windowYears) + " years): deep " + num(dDeep) +
                        ", edge " + num(dEdge) + ", clearing " + num(dClear) + ".");
    const std::string png = sc.name + "_classes.png";
    writeCategoryPng(ctx.file(png), cls, "Gap-dynamics classes", {"deep canopy", "edge", "clearing"}, "not used");
    r.figures.push_back({png, "Classes used for the densities (north up)."});
}

}  // namespace

std::unique_ptr<Scenario> createGapDynamics(const ScenarioParse& in) { return std::make_unique<GapDynamics>(in); }
std::vector<ScenarioKeyDoc> gapDynamicsKeys() { return scenarioKeyDocs("[classes]", gapFields()); }

}  // namespace eco::validate
