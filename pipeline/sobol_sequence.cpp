#include "sobol_sequence.h"

#include <string>

#include "error.h"

namespace eco::pipeline {

namespace {

/// Joe and Kuo (2008), new-joe-kuo-6.21201, dimensions 2 .. 50 (dimension 1 is the van der
/// Corput sequence, every m = 1): the degree s of the primitive polynomial, its inner
/// coefficients a (bit s - 1 - k is the coefficient of x^k's partner a_k, k = 1 .. s - 1, as
/// in the file) and the initial direction integers m_1 .. m_s (odd, m_k < 2^k).
struct DirectionRow {
    int s;
    unsigned a;
    unsigned m[8];
};
constexpr DirectionRow kJoeKuo[] = {
    {1, 0, {1}},
    {2, 1, {1, 3}},
    {3, 1, {1, 3, 1}},
    {3, 2, {1, 1, 1}},
    {4, 1, {1, 1, 3, 3}},
    {4, 4, {1, 3, 5, 13}},
    {5, 2, {1, 1, 5, 5, 17}},
    {5, 4, {1, 1, 5, 5, 5}},
    {5, 7, {1, 1, 7, 11, 19}},
    {5, 11, {1, 1, 5, 1, 1}},
    {5, 13, {1, 1, 1, 3, 11}},
    {5, 14, {1, 3, 5, 5, 31}},
    {6, 1, {1, 3, 3, 9, 7, 49}},
    {6, 13, {1, 1, 1, 15, 21, 21}},
    {6, 16, {1, 3, 1, 13, 27, 49}},
    {6, 19, {1, 1, 1, 15, 7, 5}},
    {6, 22, {1, 3, 1, 15, 13, 25}},
    {6, 25, {1, 1, 5, 5, 19, 61}},
    {7, 1, {1, 3, 7, 11, 23, 15, 103}},
    {7, 4, {1, 3, 7, 13, 13, 15, 69}},
    {7, 7, {1, 1, 3, 13, 7, 35, 63}},
    {7, 8, {1, 3, 5, 9, 1, 25, 53}},
    {7, 14, {1, 3, 1, 13, 9, 35, 107}},
    {7, 19, {1, 3, 1, 5, 27, 61, 31}},
    {7, 21, {1, 1, 5, 11, 19, 41, 61}},
    {7, 28, {1, 3, 5, 3, 3, 13, 69}},
    {7, 31, {1, 1, 7, 13, 1, 19, 1}},
    {7, 32, {1, 3, 7, 5, 13, 19, 59}},
    {7, 37, {1, 1, 3, 9, 25, 29, 41}},
    {7, 41, {1, 3, 5, 13, 23, 1, 55}},
    {7, 42, {1, 3, 7, 3, 13, 59, 17}},
    {7, 50, {1, 3, 1, 3, 5, 53, 69}},
    {7, 55, {1, 1, 5, 5, 23, 33, 13}},
    {7, 56, {1, 1, 7, 7, 1, 61, 123}},
    {7, 59, {1, 1, 7, 9, 13, 61, 49}},
    {7, 62, {1, 3, 3, 5, 3, 55, 33}},
    {8, 14, {1, 3, 1, 15, 31, 13, 49, 245}},
    {8, 21, {1, 3, 5, 15, 31, 59, 63, 97}},
    {8, 22, {1, 3, 1, 11, 11, 11, 77, 249}},
    {8, 38, {1, 3, 1, 11, 27, 43, 71, 9}},
    {8, 47, {1, 1, 7, 15, 21, 11, 81, 45}},
    {8, 49, {1, 3, 7, 3, 25, 31, 65, 79}},
    {8, 50, {1, 3, 1, 1, 19, 11, 3, 205}},
    {8, 52, {1, 1, 5, 9, 19, 21, 29, 157}},
    {8, 56, {1, 3, 7, 11, 1, 33, 89, 185}},
    {8, 67, {1, 3, 3, 3, 15, 9, 79, 71}},
    {8, 70, {1, 3, 7, 11, 15, 39, 119, 27}},
    {8, 84, {1, 1, 3, 1, 11, 31, 97, 225}},
    {8, 97, {1, 1, 1, 3, 23, 43, 57, 177}},
};
static_assert(sizeof(kJoeKuo) / sizeof(kJoeKuo[0]) == SobolSequence::kMaxDimensions - 1, "one row per dimension 2 .. 50");

}  // namespace

SobolSequence::SobolSequence(int dimensions) : dimensions_(dimensions) {
    if (dimensions < 1 || dimensions > kMaxDimensions)
        throw ValidationError("Sobol sequence: " + std::to_string(dimensions) + " dimensions (1 .. " + std::to_string(kMaxDimensions) +
                              " with the direction numbers included)");
    v_.assign(static_cast<std::size_t>(dimensions) * kBits, 0);
    for (int d = 0; d < dimensions; ++d) {
        std::uint32_t* v = v_.data() + static_cast<std::size_t>(d) * kBits;  // v[j - 1] = v_j
        if (d == 0) {
            for (int j = 1; j <= kBits; ++j) v[j - 1] = std::uint32_t{1} << (kBits - j);
            continue;
        }
        const DirectionRow& row = kJoeKuo[d - 1];
        const int s = row.s;
        for (int j = 1; j <= s; ++j) v[j - 1] = static_cast<std::uint32_t>(row.m[j - 1]) << (kBits - j);
        // v_j = v_{j-s} ^ (v_{j-s} >> s) ^ sum over k = 1 .. s-1 of a_k v_{j-k}.
        for (int j = s + 1; j <= kBits; ++j) {
            std::uint32_t x = v[j - s - 1] ^ (v[j - s - 1] >> s);
            for (int k = 1; k < s; ++k)
                if ((row.a >> (s - 1 - k)) & 1u) x ^= v[j - k - 1];
            v[j - 1] = x;
        }
    }
}

std::uint32_t SobolSequence::direction(int d, int j) const {
    if (d < 0 || d >= dimensions_ || j < 1 || j > kBits) throw ValidationError("Sobol sequence: no direction number (" + std::to_string(d) + ", " + std::to_string(j) + ")");
    return v_[static_cast<std::size_t>(d) * kBits + static_cast<std::size_t>(j - 1)];
}

std::vector<double> SobolSequence::point(std::uint32_t index) const {
    const std::uint32_t gray = index ^ (index >> 1);
    std::vector<double> x(static_cast<std::size_t>(dimensions_));
    for (int d = 0; d < dimensions_; ++d) {
        const std::uint32_t* v = v_.data() + static_cast<std::size_t>(d) * kBits;
        std::uint32_t bits = 0;
        for (int j = 0; j < kBits; ++j)
            if ((gray >> j) & 1u) bits ^= v[j];
        x[static_cast<std::size_t>(d)] = static_cast<double>(bits) * 0x1p-32;
    }
    return x;
}

}  // namespace eco::pipeline
