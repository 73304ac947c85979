// The Sobol' low-discrepancy sequence (Sobol' 1967), for quasi-random Sobol-index designs of
// eco sensitivity (docs/sensitivity.md, "Quasi-random sampling"). Own implementation of the
// construction of Bratley and Fox (1988, Algorithm 659) as described by Joe and Kuo (2003),
// with Joe and Kuo's direction numbers (S. Joe and F. Y. Kuo, "Constructing Sobol sequences
// with better two-dimensional projections", SIAM J. Sci. Comput. 30, 2635-2654, 2008; the
// file new-joe-kuo-6.21201 of https://web.maths.unsw.edu.au/~fkuo/sobol/, its first 50
// dimensions). Points in Gray-code order, point 0 the origin: the same points in the same
// order as Joe and Kuo's reference program sobol.cc.
#pragma once

#include <cstdint>
#include <vector>

namespace eco::pipeline {

class SobolSequence {
public:
    static constexpr int kMaxDimensions = 50;
    static constexpr int kBits = 32;  ///< points 0 .. 2^32 - 1, coordinates multiples of 2^-32

    /// ValidationError unless 1 <= dimensions <= kMaxDimensions.
    explicit SobolSequence(int dimensions);
    int dimensions() const { return dimensions_; }

    /// Point `index` (0-based), each coordinate in [0, 1). Stateless: point n is the XOR of
    /// the direction numbers at the set bits of n's Gray code n ^ (n >> 1).
    std::vector<double> point(std::uint32_t index) const;

    /// direction(d, j): the j-th direction number (j = 1 .. 32) of dimension d (0-based),
    /// as a 32-bit fraction: v_j = m_j / 2^j is direction(d, j) / 2^32.
    std::uint32_t direction(int d, int j) const;

private:
    int dimensions_;
    std::vector<std::uint32_t> v_;  ///< v_[d * kBits + (j - 1)]
};

}  // namespace eco::pipeline
