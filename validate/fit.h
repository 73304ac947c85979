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

}  // namespace eco::validate
