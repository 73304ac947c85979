#include "thinning.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace eco::validate {

std::pair<int, int> thinningPhase(const std::vector<StandYear>& stats, const ThinningRule& rule) {
    int first = -1, last = -1;
    for (const StandYear& y : stats) {
        if (y.year == 0) continue;
        if (first < 0 && y.coverFraction >= rule.onsetCoverFraction &&
            y.mortality > rule.onsetMortalityFactor * rule.backgroundMortality)
            first = y.year;
        if (first < 0) continue;
        if (y.alive < rule.minPlants || y.coverFraction < rule.onsetCoverFraction) break;
        last = y.year;
    }
    return {first, last};
}

double densityDropLog10(const std::vector<StandYear>& stats, std::pair<int, int> phase) {
    const double nan = std::numeric_limits<double>::quiet_NaN();
    if (phase.first < 0) return nan;
    double d0 = nan, d1 = nan;
    for (const StandYear& y : stats) {
        if (y.year == phase.first) d0 = y.densityPerM2;
        if (y.year == phase.second) d1 = y.densityPerM2;
    }
    return d0 > 0 && d1 > 0 ? std::log10(d0 / d1) : nan;
}

double deathSizeRank(const std::vector<std::pair<std::uint64_t, double>>& atStart, const std::vector<std::uint64_t>& aliveAtEnd) {
    const double nan = std::numeric_limits<double>::quiet_NaN();
    const std::size_t n = atStart.size();
    if (n == 0) return nan;
    std::vector<std::size_t> order(n);
    for (std::size_t i = 0; i < n; ++i) order[i] = i;
    std::sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
        return atStart[a].second != atStart[b].second ? atStart[a].second < atStart[b].second : atStart[a].first < atStart[b].first;
    });
    std::vector<double> rank(n);
    for (std::size_t i = 0; i < n;) {  // ties share the mean of their ranks
        std::size_t j = i;
        while (j < n && atStart[order[j]].second == atStart[order[i]].second) ++j;
        const double r = (0.5 * static_cast<double>(i + j - 1) + 0.5) / static_cast<double>(n);
        for (std::size_t k = i; k < j; ++k) rank[order[k]] = r;
        i = j;
    }
    std::vector<std::uint64_t> alive = aliveAtEnd;
    std::sort(alive.begin(), alive.end());
    double sum = 0;
    std::size_t dead = 0;
    for (std::size_t i = 0; i < n; ++i)
        if (!std::binary_search(alive.begin(), alive.end(), atStart[i].first)) {
            sum += rank[i];
            ++dead;
        }
    return dead > 0 ? sum / static_cast<double>(dead) : nan;
}

}  // namespace eco::validate
