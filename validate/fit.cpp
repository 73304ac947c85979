#include "fit.h"

#include <Eigen/Dense>

#include <cmath>
#include <string>

#include "error.h"

namespace eco::validate {

LineFit fitLine(const std::vector<double>& x, const std::vector<double>& y) {
    if (x.size() != y.size())
        throw ValidationError("fitLine: " + std::to_string(x.size()) + " x values but " + std::to_string(y.size()) +
                              " y values");
    const auto n = static_cast<Eigen::Index>(x.size());
    if (n < 2) throw ValidationError("fitLine: need at least two points, got " + std::to_string(x.size()));
    Eigen::MatrixXd design(n, 2);
    Eigen::VectorXd rhs(n);
    for (Eigen::Index i = 0; i < n; ++i) {
        const double xi = x[static_cast<std::size_t>(i)], yi = y[static_cast<std::size_t>(i)];
        if (!std::isfinite(xi) || !std::isfinite(yi))
            throw ValidationError("fitLine: point " + std::to_string(i) + " is not finite");
        design(i, 0) = 1.0;
        design(i, 1) = xi;
        rhs(i) = yi;
    }
    if (design.col(1).maxCoeff() == design.col(1).minCoeff())
        throw ValidationError("fitLine: all x values are equal; the slope is undefined");
    // Column-pivoting QR: numerically sound without forming the normal equations.
    const Eigen::Vector2d beta = design.colPivHouseholderQr().solve(rhs);
    LineFit f;
    f.intercept = beta(0);
    f.slope = beta(1);
    f.points = static_cast<std::size_t>(n);
    const Eigen::VectorXd residual = rhs - design * beta;
    const double ssRes = residual.squaredNorm();
    const double ssTot = (rhs.array() - rhs.mean()).matrix().squaredNorm();
    f.rSquared = ssTot > 0.0 ? 1.0 - ssRes / ssTot : 1.0;
    if (n > 2) {
        const double sxx = (design.col(1).array() - design.col(1).mean()).matrix().squaredNorm();
        f.slopeStdError = std::sqrt(ssRes / static_cast<double>(n - 2) / sxx);
    }
    return f;
}

GrowthAcceleration growthAcceleration(const std::vector<double>& x, const std::vector<double>& count) {
    if (x.size() != count.size())
        throw ValidationError("growthAcceleration: " + std::to_string(x.size()) + " x values but " +
                              std::to_string(count.size()) + " counts");
    if (x.size() < 5)
        throw ValidationError("growthAcceleration: need at least 5 points (3 per half), got " + std::to_string(x.size()));
    const auto mid = static_cast<std::ptrdiff_t>((x.size() - 1) / 2);
    const auto half = [&](std::ptrdiff_t from, std::ptrdiff_t to) {
        return fitLine(std::vector<double>(x.begin() + from, x.begin() + to + 1),
                       std::vector<double>(count.begin() + from, count.begin() + to + 1));
    };
    GrowthAcceleration g;
    g.firstSlope = half(0, mid).slope;
    g.secondSlope = half(mid, static_cast<std::ptrdiff_t>(x.size()) - 1).slope;
    if (!(g.firstSlope > 0.0))
        throw ValidationError("growthAcceleration: the count does not rise over the first half of the window (slope " +
                              std::to_string(g.firstSlope) + ")");
    g.ratio = g.secondSlope / g.firstSlope;
    return g;
}

}  // namespace eco::validate
