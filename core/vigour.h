// The vigour kernel of Eq. 1 over the factor axis (factors.h), in its two arithmetic forms:
//   * scalar:  g(d) per factor with a division and pow (Biome::vigourOf, the species map,
//              the forest floor's grass suitability);
//   * batch:   the exponent of g at the largest normalised distance, with reciprocal ranges
//              and x^4.5 as x^4 sqrt(x), whose exps a caller takes for a whole block at once
//              (batch_math.h's batchExp), then the vigour from each exp (the simulator).
// g is decreasing in |d| / r, so min_f g(d_f) = g(max_f |d_f| / r_f): both forms compute
// Eq. 1; they differ in rounding only (an ulp or so), and each caller keeps its form so that
// every result stays the same bits. Every function is templated on the number of factors N
// (Features has N = kFactorCount; tests instantiate other N).
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <initializer_list>
#include <limits>
#include <utility>

#include "factors.h"

namespace eco {

/// One abiotic response: optimum c and range r (same units as the abiotic).
struct Response {
    double c = 0.0;
    double r = 1.0;
    /// No response: an infinite range, so every finite value lies at normalised distance
    /// |x - c| / r = 0 (the batch form's 1 / r is 0) and g is g(0), the largest g can be.
    /// The factor then never wins the min (or the max distance) of Eq. 1: a species
    /// without a response to an optional factor (FactorInfo::responseRequired false) has
    /// the vigour of the other factors, bit for bit (tests/factors_test.cpp).
    static Response indifferent() { return Response{0.0, std::numeric_limits<double>::infinity()}; }
    /// True for indifferent(): the species (or the grass) does not respond to the factor.
    bool isIndifferent() const { return r == std::numeric_limits<double>::infinity(); }
};

/// A species' (or the grass's) responses, one per factor, in factor order.
template <std::size_t N>
using ResponsesOf = std::array<Response, N>;
using Responses = ResponsesOf<kFactorCount>;

/// Responses of a new species (or the grass) before any is read: {0, 1} for the factors a
/// biome must give, indifferent() for the optional ones, so that code building a species
/// by hand does not make it respond to a factor it never heard of.
inline Responses defaultResponses() {
    Responses r{};
    for (std::size_t f = 0; f < kFactorCount; ++f)
        if (!kFactors[f].responseRequired) r[f] = Response::indifferent();
    return r;
}

/// Responses given for some factors, indifferent() for every other: the forest floor's
/// grass, whose defaults name the paper's four factors, so that a factor added later
/// leaves the grass indifferent to it with no line of its own (docs/factors.md).
inline Responses responsesFor(std::initializer_list<std::pair<Factor, Response>> given) {
    Responses r;
    r.fill(Response::indifferent());
    for (const auto& [f, response] : given) r[factorIndex(f)] = response;
    return r;
}

/// Vigour response shape g(d) = (1 + a) exp((d / r)^p ln q) - a (Eq. 1).
struct VigourShape {
    double a = 0.2;
    double q = 0.01;
    double p = 4.5;
    /// g(d) for distance d from the optimum and range r.
    double g(double d, double r) const { return (1.0 + a) * std::exp(std::pow(std::abs(d) / r, p) * std::log(q)) - a; }
};

// ------------------------------------------------------------------ scalar form

/// min over the factors of g(x_f - c_f, r_f): Eq. 1 without alpha.
template <std::size_t N>
double minResponse(const VigourShape& shape, const ResponsesOf<N>& resp, const FeaturesOf<N>& x) {
    double m = shape.g(x[0] - resp[0].c, resp[0].r);
    for (std::size_t f = 1; f < N; ++f) m = std::min(m, shape.g(x[f] - resp[f].c, resp[f].r));
    return m;
}

/// Largest normalised distance max_f |x_f - c_f| / r_f (the argument of g that wins the min).
template <std::size_t N>
double maxNormalisedDistance(const ResponsesOf<N>& resp, const FeaturesOf<N>& x) {
    double d = std::abs(x[0] - resp[0].c) / resp[0].r;
    for (std::size_t f = 1; f < N; ++f) d = std::max(d, std::abs(x[f] - resp[f].c) / resp[f].r);
    return d;
}

/// alpha g at normalised distance `ratio`, with ln q given (hoisted by callers in loops).
inline double vigourAtDistance(double alpha, double ratio, double a, double p, double lnQ) {
    return alpha * ((1.0 + a) * std::exp(std::pow(ratio, p) * lnQ) - a);
}

// ------------------------------------------------------------------ batch form

/// A species' coefficients for the batch form: alpha, the optima and reciprocal ranges.
template <std::size_t N>
struct VigourCoeffsOf {
    double alpha = 0;
    std::array<double, N> c{};
    std::array<double, N> invR{};
    static VigourCoeffsOf from(double alpha, const ResponsesOf<N>& resp) {
        VigourCoeffsOf k;
        k.alpha = alpha;
        for (std::size_t f = 0; f < N; ++f) {
            k.c[f] = resp[f].c;
            k.invR[f] = 1.0 / resp[f].r;
        }
        return k;
    }
};
using VigourCoeffs = VigourCoeffsOf<kFactorCount>;

/// Eq. 1's shape for the batch form, held by value so that hot loops keep it in locals.
struct BatchVigourShape {
    bool fourAndHalf = true;  ///< p = 4.5: x^4 sqrt(x) instead of pow (exact to an ulp, 5x faster)
    double p = 4.5, lnQ = std::log(0.01), a = 0.2;

    static BatchVigourShape from(const VigourShape& s) { return BatchVigourShape{s.p == 4.5, s.p, std::log(s.q), s.a}; }
    /// The exponent (max_f |x_f - c_f| / r_f)^p ln q, whose exp gives g.
    template <std::size_t N>
    double exponent(const VigourCoeffsOf<N>& k, const FeaturesOf<N>& x) const {
        double d = std::abs(x[0] - k.c[0]) * k.invR[0];
        for (std::size_t f = 1; f < N; ++f) d = std::max(d, std::abs(x[f] - k.c[f]) * k.invR[f]);
        const double xp = fourAndHalf ? (d * d) * (d * d) * std::sqrt(d) : std::pow(d, p);
        return xp * lnQ;
    }
    /// The vigour alpha ((1 + a) e - a) from e = exp(exponent(...)).
    double fromExp(double alpha, double e) const { return alpha * ((1.0 + a) * e - a); }
};

}  // namespace eco
