// Kind "deussen_circles" (Deussen et al. 1998 §4.2, Fig. 5), standalone: Deussen's own
// self-thinning test with growing circles (deussen_circles.h), no simulator.
#include "scenario_context.h"

#include <cmath>

#include "deussen_circles.h"
#include "error.h"
#include "plots.h"
#include "scenario_keys.h"
#include "strict_toml.h"

namespace eco::validate {

namespace {

struct CirclesSettings {
    CirclesParams params;  ///< plantCount, fieldSideM and seed are set per size
    struct Size {
        int plantCount = 62500;
        double fieldSideM = 250;
        std::uint64_t seed = 1;
    };
    Size quick, full;
};

using K = ParamDesc<CirclesParams>::Kind;
using R = ParamRange;

/// [circles]: the circles' growth and the fit (CirclesParams::validate checks the rules
/// between keys: max radius >= min, limit radius above the max and below half the field).
const std::vector<ParamDesc<CirclesParams>>& circlesFields() {
    using P = CirclesParams;
    static const std::vector<ParamDesc<P>> fields = {
        {"initial_radius_min_m", "initial radii uniform in [min, max]: the smallest", "m", K::Real, &P::initialRadiusMinM,
         nullptr, R::atLeast(0), nullptr, "must not be negative"},
        {"initial_radius_max_m", "initial radii uniform in [min, max]: the largest (>= the smallest)", "m", K::Real,
         &P::initialRadiusMaxM},
        {"growth_per_step_m", "radius increment of every circle per step", "m", K::Real, &P::growthPerStepM, nullptr,
         R::above(0), nullptr, "must be positive"},
        {"limit_radius_m", "a circle reaching this radius is old and dies (above initial_radius_max_m, below half the field side)",
         "m", K::Real, &P::limitRadiusM},
        {"max_steps", "steps at most (the run stops earlier when every circle is dead)", "", K::Integer, nullptr,
         &P::maxSteps, R::closed(1, 1e7)},
        {"onset_killed_fraction", "the fitted thinning phase starts when this share of the circles died of competition", "",
         K::Real, &P::onsetKilledFraction, nullptr, R{ParamRange::Bound::Closed, 0, ParamRange::Bound::Open, 1}},
        {"min_plants_in_fit", "the fitted phase ends before the first old death or below this many circles", "",
         K::Integer, nullptr, &P::minPlantsInFit, R::closed(2, 1e9)},
    };
    return fields;
}

/// [quick] and [full]: the field of each size.
const std::vector<ParamDesc<CirclesSettings::Size>>& circlesSizeFields() {
    using P = CirclesSettings::Size;
    using SK = ParamDesc<P>::Kind;
    static const std::vector<ParamDesc<P>> fields = {
        {"plant_count", "circles placed at the start (Deussen: 62,500)", "", SK::Integer, nullptr, &P::plantCount,
         R::closed(2, 5e7)},
        {"field_side_m", "side of the square field", "m", SK::Real, &P::fieldSideM, nullptr, R::above(0), nullptr, "must be positive"},
        {"seed", "seed of the placement (replicate k adds k x 1000)", "", SK::Seed, nullptr, nullptr, R::any(),
         &P::seed},
    };
    return fields;
}

class DeussenCircles final : public Scenario {
public:
    explicit DeussenCircles(const ScenarioParse& in);
    std::vector<std::string> checkIds() const override { return {"slope", "r_squared"}; }
    void run(const ScenarioConfig& sc, ScenarioContext& ctx, ScenarioResult& r) const override;

private:
    CirclesSettings settings_;
};

DeussenCircles::DeussenCircles(const ScenarioParse& in) {
    CirclesParams& p = settings_.params;
    StrictTable s(in.top.table("circles"), in.path, "[circles]");
    readScenarioParams(s, p, circlesFields());
    s.finish();
    in.sizes([&](Mode m, StrictTable& z) {
        auto& size = m == Mode::Quick ? settings_.quick : settings_.full;
        readScenarioParams(z, size, circlesSizeFields());
        CirclesParams q = p;
        q.plantCount = size.plantCount;
        q.fieldSideM = size.fieldSideM;
        try {
            q.validate();
        } catch (const ValidationError& e) {
            throw ValidationError(in.path + ": [circles] / [" + modeName(m) + "]: " + e.what());
        }
    });
}

void DeussenCircles::run(const ScenarioConfig& sc, ScenarioContext& ctx, ScenarioResult& r) const {
    CirclesParams p = settings_.params;
    const auto& size = ctx.mode() == Mode::Quick ? settings_.quick : settings_.full;
    p.plantCount = size.plantCount;
    p.fieldSideM = size.fieldSideM;
    p.seed = ctx.seed(size.seed);
    ctx.log("validate: Deussen circles: " + std::to_string(p.plantCount) + " plants in a " + num(p.fieldSideM) + " m field");
    const auto t0 = Clock::now();
    const CirclesResult res = runDeussenCircles(p);
    const std::string note = res.fitted ? "" : "no thinning phase with two or more steps";
    r.checks.push_back(makeCheck(sc, "slope", "slope of log10 mean circle area against log10 density over the thinning phase",
                                 res.fitted ? res.fit.slope : kNaN, note));
    r.checks.push_back(makeCheck(sc, "r_squared", "R^2 of that fit", res.fitted ? res.fit.rSquared : kNaN, note));
    const CirclesStep* a = nullptr;
    const CirclesStep* b = nullptr;
    for (const auto& s : res.steps) {
        if (s.step == res.fitFirstStep) a = &s;
        if (s.step == res.fitLastStep) b = &s;
    }
    r.details.push_back("- " + std::to_string(p.plantCount) + " circles placed uniformly in a " + num(p.fieldSideM) + " m x " +
                        num(p.fieldSideM) + " m field, initial radii uniform in [" + num(p.initialRadiusMinM) + ", " +
                        num(p.initialRadiusMaxM) + "] m, every radius grows " + num(p.growthPerStepM) +
                        " m per step; the smaller of two intersecting circles dies (resolved largest first); a circle "
                        "reaching " + num(p.limitRadiusM) + " m dies old. " + std::to_string(res.steps.size()) + " steps in " +
                        fixed(secondsSince(t0), 2) + " s.");
    if (a && b)
        r.details.push_back("- Thinning phase: from the step at which " + fixed(100 * p.onsetKilledFraction, 0) +
                            " % of the plants had died of competition (step " + std::to_string(a->step) + ", " +
                            std::to_string(a->alive) + " plants, cover " + fixed(a->coveredFraction, 2) +
                            ") to the last step before the first old death or while at least " +
                            std::to_string(p.minPlantsInFit) + " plants live (step " + std::to_string(b->step) + ", " +
                            std::to_string(b->alive) + " plants, cover " + fixed(b->coveredFraction, 2) + "); slope " +
                            fixed(res.fit.slope, 3) + " ± " + fixed(res.fit.slopeStdError, 3) + ", R^2 " +
                            fixed(res.fit.rSquared, 4) + ".");
    PlotSeries all{"every 5th step", {}, {}, {0.6f, 0.6f, 0.6f}, false, 2.0};
    PlotSeries used{"thinning phase (every 5th step)", {}, {}, {0.85f, 0.3f, 0.1f}, false, 3.0};
    for (const auto& s : res.steps) {
        if (s.alive == 0 || s.step % 5 != 0) continue;
        PlotSeries& dst = (s.step >= res.fitFirstStep && s.step <= res.fitLastStep) ? used : all;
        dst.x.push_back(std::log10(s.densityPerM2));
        dst.y.push_back(std::log10(s.meanAreaM2));
    }
    std::vector<PlotSeries> series{all, used};
    if (res.fitted && a && b) {
        const double x0 = std::log10(a->densityPerM2), x1 = std::log10(b->densityPerM2);
        series.push_back(PlotSeries{"fit, slope " + fixed(res.fit.slope, 2), {x0, x1},
                                    {res.fit.intercept + res.fit.slope * x0, res.fit.intercept + res.fit.slope * x1},
                                    {0.1f, 0.3f, 0.8f}, true, 0});
    }
    const std::string png = sc.name + "_loglog.png";
    writeXYPlotPng(ctx.file(png), "Deussen 1998 self-thinning of circles", "log10 density (plants per m^2)",
                   "log10 mean area (m^2)", series);
    r.figures.push_back({png, "Log mean circle area against log density (the paper's Fig. 5) with the fitted thinning phase."});
}

}  // namespace

std::unique_ptr<Scenario> createDeussenCircles(const ScenarioParse& in) { return std::make_unique<DeussenCircles>(in); }
std::vector<ScenarioKeyDoc> deussenCirclesKeys() {
    return joinKeyDocs({scenarioKeyDocs("[circles]", circlesFields()), scenarioKeyDocs("[quick], [full]", circlesSizeFields())});
}

}  // namespace eco::validate
