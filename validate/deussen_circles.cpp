#include "deussen_circles.h"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <string>

#include "error.h"
#include "rng.h"

namespace eco::validate {

namespace {
constexpr std::uint64_t kCirclesStreamTag = 0x434952434C455331ull;  // "CIRCLES1"
}

void CirclesParams::validate() const {
    auto bad = [](const std::string& key, double v, const std::string& what) {
        throw ValidationError("Deussen circles: parameter '" + key + "' = " + std::to_string(v) + ": " + what);
    };
    if (plantCount < 2 || plantCount > 50000000) bad("plant_count", plantCount, "must lie in 2..50000000");
    if (!(fieldSideM > 0)) bad("field_side_m", fieldSideM, "must be positive");
    if (!(initialRadiusMinM >= 0)) bad("initial_radius_min_m", initialRadiusMinM, "must not be negative");
    if (!(initialRadiusMaxM >= initialRadiusMinM))
        bad("initial_radius_max_m", initialRadiusMaxM, "must not be below initial_radius_min_m");
    if (!(growthPerStepM > 0)) bad("growth_per_step_m", growthPerStepM, "must be positive");
    if (!(limitRadiusM > initialRadiusMaxM)) bad("limit_radius_m", limitRadiusM, "must exceed initial_radius_max_m");
    if (!(limitRadiusM * 2 < fieldSideM)) bad("limit_radius_m", limitRadiusM, "must be below half the field side");
    if (maxSteps < 1) bad("max_steps", maxSteps, "must be at least 1");
    if (!(onsetKilledFraction >= 0 && onsetKilledFraction < 1))
        bad("onset_killed_fraction", onsetKilledFraction, "must lie in [0, 1)");
    if (minPlantsInFit < 2) bad("min_plants_in_fit", minPlantsInFit, "must be at least 2");
}

CirclesResult runDeussenCircles(const CirclesParams& p) {
    p.validate();
    const std::size_t n = static_cast<std::size_t>(p.plantCount);
    std::vector<double> x(n), y(n), r(n);
    for (std::size_t i = 0; i < n; ++i) {
        RandomStream rs(p.seed, mixStream(i, kCirclesStreamTag));
        x[i] = rs.uniform(0.0, p.fieldSideM);
        y[i] = rs.uniform(0.0, p.fieldSideM);
        r[i] = rs.uniform(p.initialRadiusMinM, p.initialRadiusMaxM);
    }
    // Every radius grows by the same amount, so the size order never changes: sort once,
    // largest first, ties by index.
    std::vector<std::uint32_t> order(n);
    std::iota(order.begin(), order.end(), 0u);
    std::stable_sort(order.begin(), order.end(), [&](std::uint32_t a, std::uint32_t b) { return r[a] > r[b]; });

    // Uniform grid of side >= 2 * limit radius: two intersecting circles lie in the same or
    // adjacent cells. Survivors of the current step are inserted as they are accepted.
    const double cellM = std::max(2.0 * p.limitRadiusM, p.fieldSideM / 4096.0);
    const int cells = std::max(1, static_cast<int>(std::floor(p.fieldSideM / cellM)));
    const double invCell = cells / p.fieldSideM;
    std::vector<std::vector<std::uint32_t>> grid(static_cast<std::size_t>(cells) * static_cast<std::size_t>(cells));
    auto cellOf = [&](double v) { return std::clamp(static_cast<int>(v * invCell), 0, cells - 1); };

    const double fieldArea = p.fieldSideM * p.fieldSideM;
    CirclesResult result;
    std::int64_t killedTotal = 0;
    bool anyOld = false;
    std::vector<std::uint32_t> alive = order;  // in size order
    std::vector<std::uint32_t> next;
    next.reserve(n);
    for (int step = 0; step <= p.maxSteps && !alive.empty(); ++step) {
        CirclesStep st;
        st.step = step;
        if (step > 0)
            for (std::uint32_t i : alive) r[i] += p.growthPerStepM;
        for (auto& c : grid) c.clear();
        next.clear();
        for (std::uint32_t i : alive) {
            if (r[i] >= p.limitRadiusM) {
                ++st.diedOld;
                continue;
            }
            const int cx = cellOf(x[i]), cy = cellOf(y[i]);
            bool dominated = false;
            for (int gy = std::max(0, cy - 1); gy <= std::min(cells - 1, cy + 1) && !dominated; ++gy)
                for (int gx = std::max(0, cx - 1); gx <= std::min(cells - 1, cx + 1) && !dominated; ++gx)
                    for (std::uint32_t j : grid[static_cast<std::size_t>(gy) * static_cast<std::size_t>(cells) +
                                                static_cast<std::size_t>(gx)]) {
                        const double dx = x[i] - x[j], dy = y[i] - y[j], reach = r[i] + r[j];
                        if (dx * dx + dy * dy < reach * reach) {
                            dominated = true;  // j is at least as large and survives: i dies
                            break;
                        }
                    }
            if (dominated) {
                ++st.killedByCompetition;
                continue;
            }
            grid[static_cast<std::size_t>(cy) * static_cast<std::size_t>(cells) + static_cast<std::size_t>(cx)].push_back(i);
            next.push_back(i);
        }
        alive.swap(next);
        killedTotal += st.killedByCompetition;
        st.alive = static_cast<std::int64_t>(alive.size());
        double area = 0;
        for (std::uint32_t i : alive) area += M_PI * r[i] * r[i];
        st.densityPerM2 = static_cast<double>(st.alive) / fieldArea;
        st.meanAreaM2 = st.alive > 0 ? area / static_cast<double>(st.alive) : 0.0;
        st.coveredFraction = area / fieldArea;
        if (st.diedOld > 0) anyOld = true;
        // Thinning phase: after the onset, before the first old death, enough plants.
        if (!anyOld && st.alive >= p.minPlantsInFit &&
            static_cast<double>(killedTotal) >= p.onsetKilledFraction * static_cast<double>(p.plantCount)) {
            if (result.fitFirstStep < 0) result.fitFirstStep = step;
            result.fitLastStep = step;
        }
        result.steps.push_back(st);
    }
    if (result.fitFirstStep >= 0 && result.fitLastStep > result.fitFirstStep) {
        std::vector<double> lx, ly;
        for (const CirclesStep& s : result.steps)
            if (s.step >= result.fitFirstStep && s.step <= result.fitLastStep) {
                lx.push_back(std::log10(s.densityPerM2));
                ly.push_back(std::log10(s.meanAreaM2));
            }
        result.fit = fitLine(lx, ly);
        result.fitted = true;
    }
    return result;
}

}  // namespace eco::validate
