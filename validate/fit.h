// Least-squares line fits for the validation suite (Eigen), e.g. the self-thinning slope of
// log mean mass against log density.
#pragma once

#include <cstddef>
#include <vector>

namespace eco::validate {

/// y = intercept + slope * x fitted by ordinary least squares.
struct LineFit {
    double slope = 0.0;
    double intercept = 0.0;
    double rSquared = 0.0;       ///< coefficient of determination, 1 - SS_res / SS_tot
    double slopeStdError = 0.0;  ///< standard error of the slope (0 with two points)
    std::size_t points = 0;
};

/// Ordinary least-squares fit of a line through (x[i], y[i]) with Eigen (QR of the
/// design matrix [1 x]). ValidationError when the lengths differ, fewer than two points
/// are given, a value is not finite, or all x are equal.
LineFit fitLine(const std::vector<double>& x, const std::vector<double>& y);

/// Whether a rising count accelerates, as an exponential does and a linear rise does not: the
/// window's points are split at their middle point (shared by both halves) and a line is
/// fitted to each half; `ratio` is the second half's slope over the first half's. An
/// exponential N0 e^(r t) over a window of W years gives about e^(r W / 2) (5 for a 25-fold
/// rise), a straight line 1, a rise that slows down less than 1.
struct GrowthAcceleration {
    double firstSlope = 0.0;   ///< count per unit of x over the first half
    double secondSlope = 0.0;  ///< count per unit of x over the second half
    double ratio = 0.0;        ///< secondSlope / firstSlope
};

/// ValidationError (from fitLine) for fewer than 5 points or a value that is not finite, and
/// when the count does not rise over the first half (firstSlope <= 0: the ratio would mean
/// nothing).
GrowthAcceleration growthAcceleration(const std::vector<double>& x, const std::vector<double>& count);

}  // namespace eco::validate
