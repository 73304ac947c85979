// The simulator's processes as small pure functions (paper §6.1, SPEC §5). The engine
// (simulator_*.cpp) calls exactly these, and tests/simulator_test.cpp tests each on its own.
#pragma once

#include <algorithm>
#include <cassert>
#include <cmath>
#include <cstdint>
#include <vector>

#ifdef __SSE2__
#include <emmintrin.h>
#endif

#include "rng.h"
#include "sim_config.h"

namespace eco::sim {

// std::max(0.0, t) and std::min(d, t) without a branch (the compiler emits a compare and a
// jump for them, which the data mispredicts often in the sweep): MAXSD / MINSD return their
// first operand when it compares greater / less, else the second, which is exactly
// std::max(0.0, t) = (0.0 < t ? t : 0.0) and std::min(d, t) = (t < d ? t : d), also for
// signed zeros and NaN.
inline double maxZero(double t) {
#ifdef __SSE2__
    return _mm_cvtsd_f64(_mm_max_sd(_mm_set_sd(t), _mm_setzero_pd()));
#else
    return std::max(0.0, t);
#endif
}
inline double minOf(double d, double t) {
#ifdef __SSE2__
    return _mm_cvtsd_f64(_mm_min_sd(_mm_set_sd(t), _mm_set_sd(d)));
#else
    return std::min(d, t);
#endif
}

/// Third-order smoothstep s(x) = 3x^2 - 2x^3 on [0, 1], clamped outside (Eq. 3, with the
/// paper's "3x^3" typo corrected).
inline double smoothstep(double x) {
    x = std::clamp(x, 0.0, 1.0);
    return x * x * (3.0 - 2.0 * x);
}

/// Idealised height h_s(t) = s(t / maxAge) * maxHeight (Eq. 3); ages in years, metres.
inline double idealHeightM(double growthAgeYears, double maxAgeYears, double maxHeightM) {
    return smoothstep(growthAgeYears / maxAgeYears) * maxHeightM;
}

/// Inverse of idealHeightM on [0, maxHeight]: the growth age (years) of a plant of height h.
inline double growthAgeForHeight(double heightM, double maxAgeYears, double maxHeightM) {
    const double target = std::clamp(heightM / maxHeightM, 0.0, 1.0);
    double lo = 0.0, hi = 1.0;  // s is monotone on [0, 1]: bisection to double precision
    for (int i = 0; i < 60; ++i) {
        const double mid = 0.5 * (lo + hi);
        (smoothstep(mid) < target ? lo : hi) = mid;
    }
    return 0.5 * (lo + hi) * maxAgeYears;
}

/// Carbon-pool capacity: `stressMonths` months of maximum stress, where the most negative
/// vigour of Eq. 1 is -alpha * a (g's minimum is -a).
inline double poolCapacity(double stressMonths, double alpha, double vigourA) {
    return stressMonths * alpha * vigourA;
}

/// One month of the carbon pool: pool += vigour; anything above capacity is the overflow
/// (and the pool is capped at capacity). A negative pool is the underflow (stress).
struct PoolStep {
    double pool = 0;
    double overflow = 0;
};
inline PoolStep updatePool(double pool, double vigour, double capacity) {
    PoolStep s;
    s.pool = pool + vigour;
    if (s.pool > capacity) {
        s.overflow = s.pool - capacity;
        s.pool = capacity;
    }
    return s;
}

/// Growth age after one month with pool overflow `overflow` (years): the growth age advances
/// by one month scaled by the overflow (times `monthsPerOverflow`), in the growth period only.
inline double advanceGrowthAgeYears(double growthAgeYears, double overflow, bool inGrowthPeriod,
                                    double monthsPerOverflow) {
    return inGrowthPeriod ? growthAgeYears + overflow * monthsPerOverflow / 12.0 : growthAgeYears;
}

/// Months of growth age gained per unit of pool overflow in a growth month.
/// Literal (paper as printed): `monthsPerOverflow`. Ideal: also divided by the species'
/// maximum vigour (alpha_s, as g(0) = 1) and multiplied by 12 / (months in its growth
/// period), so that a plant whose pool overflows by its maximum vigour in every month of
/// its growth period gains exactly 12 months of growth age per year and follows Eq. 3
/// (reaching its max height at its max age). 0 when the species can never grow (no growth
/// months or alpha_s <= 0).
inline double growthMonthsPerUnitOverflow(GrowthRule rule, double monthsPerOverflow, double maxVigour,
                                          int growthPeriodMonths) {
    if (rule == GrowthRule::Literal) return monthsPerOverflow;
    if (!(maxVigour > 0) || growthPeriodMonths <= 0) return 0.0;
    return monthsPerOverflow * 12.0 / (maxVigour * growthPeriodMonths);
}

/// Monthly background mortality mu_b = 1 - P_s^(1 / l), with l the max age in MONTHS, so that
/// a fraction P_s of a cohort survives to its max age ((1 - mu_b)^l = P_s).
inline double backgroundMortalityPerMonth(double survivalAtMaxAge, double maxAgeYears) {
    return 1.0 - std::pow(survivalAtMaxAge, 1.0 / (12.0 * maxAgeYears));
}

/// mu = min(mu_b + mu_s, 1) with stress mortality mu_s = max(-pool, 0).
inline double mortalityProbability(double backgroundPerMonth, double pool) {
    return std::min(backgroundPerMonth + std::max(-pool, 0.0), 1.0);
}

/// Stream tags of the counter-based generator (one per random process).
constexpr std::uint64_t kMortalityStreamTag = 0x4D4F5254414C4954ull;    // plant id, counter = month
constexpr std::uint64_t kGerminationStreamTag = 0x4745524D494E4154ull;  // cell index, counter = year
constexpr std::uint64_t kDominationStreamTag = 0x444F4D494E415445ull;   // plant id, counter = month

/// Deussen et al. 1998 competitive ability: vigour x relative size (height / max height).
inline double competitiveAbility(double vigour, double heightM, double maxHeightM) {
    return vigour * (heightM / maxHeightM);
}

/// Whether two crown circles intersect (strictly: touching circles do not).
inline bool crownsIntersect(double x1, double y1, double r1, double x2, double y2, double r2) {
    const double dx = x1 - x2, dy = y1 - y2, rr = r1 + r2;
    return dx * dx + dy * dy < rr * rr;
}

/// Probability of surviving one monthly comparison round while dominated by `dominators`
/// plants, when one year of domination by one plant is survived with `survivalPerYear`:
/// each domination is an independent monthly test with survival survivalPerYear^(1/12).
inline double dominatedSurvivalPerMonth(double survivalPerYear, int dominators) {
    if (dominators <= 0) return 1.0;
    return std::pow(survivalPerYear, static_cast<double>(dominators) / 12.0);
}

/// Uniform [0, 1) for the domination test of plant `plantId` in absolute month `month`.
inline double dominationUniform(std::uint64_t seed, std::uint64_t plantId, std::uint64_t month) {
    const auto b = randomBits(seed, mixStream(plantId, kDominationStreamTag), month);
    return bitsToUnit(b[0], b[1]);
}

/// Uniform [0, 1) for the mortality test of plant `plantId` in absolute month `month`.
inline double mortalityUniform(std::uint64_t seed, std::uint64_t plantId, std::uint64_t month) {
    const auto b = randomBits(seed, mixStream(plantId, kMortalityStreamTag), month);
    return bitsToUnit(b[0], b[1]);
}
/// mortalityUniform of plants id[0 .. n) (n <= kMortalityBatch) into u, four at a time.
constexpr std::size_t kMortalityBatch = 256;
inline void mortalityUniforms(std::uint64_t seed, const std::uint64_t* id, std::uint64_t month, std::size_t n, double* u) {
    assert(n <= kMortalityBatch);
    std::uint64_t stream[kMortalityBatch];
    std::uint32_t w0[kMortalityBatch], w1[kMortalityBatch];
    for (std::size_t i = 0; i < n; ++i) stream[i] = mixStream(id[i], kMortalityStreamTag);
    randomBitsBatch(seed, stream, month, n, w0, w1);
    for (std::size_t i = 0; i < n; ++i) u[i] = bitsToUnit(w0[i], w1[i]);
}

/// Seeding kernel of one canopy tree of crown radius r at distance d: 1 within inner * r,
/// falling linearly to 0 at outer * r, 0 beyond (multiply by gamma for the probability).
inline double seedKernel(double distanceM, double crownRadiusM, double innerFactor, double outerFactor) {
    const double inner = innerFactor * crownRadiusM, outer = outerFactor * crownRadiusM;
    if (distanceM <= inner) return 1.0;
    if (distanceM >= outer) return 0.0;
    return (outer - distanceM) / (outer - inner);
}

/// Germination roulette weight w = max(0, vbar / maxAge^beta) (Eq. 4).
inline double rouletteWeight(double vbar, double maxAgeYears, double beta) {
    return std::max(0.0, vbar / std::pow(maxAgeYears, beta));
}

/// Index chosen by roulette-wheel selection with u in [0, 1): the first i whose cumulative
/// weight exceeds u * total. -1 when every weight is zero.
inline int rouletteSelect(const double* weights, int n, double u) {
    double total = 0;
    for (int i = 0; i < n; ++i) total += weights[i];
    if (!(total > 0)) return -1;
    const double target = u * total;
    double acc = 0;
    int last = -1;
    for (int i = 0; i < n; ++i) {
        if (weights[i] <= 0) continue;
        acc += weights[i];
        last = i;
        if (target < acc) return i;
    }
    return last;  // rounding at the very top of the wheel
}

/// Rank k's minimum-demand share: min(demand, what the k taller occupants left).
inline double waterDemandShareMm(double availableMm, int k, double demandMm) {
    return minOf(demandMm, maxZero(availableMm - k * demandMm));
}
/// One equal share of the remainder (also the seeding share).
inline double waterLeftoverMm(double availableMm, int n, double demandMm) {
    return maxZero(availableMm - n * demandMm) / (n + 1);
}
/// Water of one cell for the occupant at height rank k (0 = tallest undergrowth) among n
/// undergrowth occupants, from `availableMm` (after the canopy trees took their demand):
/// each occupant in height order takes min(demand, what is left); the remainder is split
/// into n + 1 equal shares, one per occupant and one kept for seeding.
inline double waterShareMm(double availableMm, int k, int n, double demandMm) {
    return waterDemandShareMm(availableMm, k, demandMm) + waterLeftoverMm(availableMm, n, demandMm);
}
inline double waterAfterCanopyMm(double cellMm, int canopyTrees, double demandMm) {
    return maxZero(cellMm - canopyTrees * demandMm);
}

}  // namespace eco::sim
