// Counter-based random numbers (Philox4x32-10, Salmon et al. 2011).
//
// A value is a pure function of (seed, stream, counter): parallel code keys the stream by
// the entity (plant, cell, tree) and the counter by the step (month, draw), so results are
// bit-identical whatever the number of threads or the schedule.
#pragma once

#include <array>
#include <cmath>
#include <cstdint>

namespace eco {

/// Philox4x32-10 block: 128-bit counter, 64-bit key, 128 random bits out.
inline std::array<std::uint32_t, 4> philox4x32(std::array<std::uint32_t, 4> ctr,
                                               std::array<std::uint32_t, 2> key) {
    constexpr std::uint32_t kMul0 = 0xD2511F53u, kMul1 = 0xCD9E8D57u;
    constexpr std::uint32_t kWeyl0 = 0x9E3779B9u, kWeyl1 = 0xBB67AE85u;
    for (int round = 0; round < 10; ++round) {
        const std::uint64_t p0 = static_cast<std::uint64_t>(kMul0) * ctr[0];
        const std::uint64_t p1 = static_cast<std::uint64_t>(kMul1) * ctr[2];
        ctr = {static_cast<std::uint32_t>(p1 >> 32) ^ ctr[1] ^ key[0], static_cast<std::uint32_t>(p1),
               static_cast<std::uint32_t>(p0 >> 32) ^ ctr[3] ^ key[1], static_cast<std::uint32_t>(p0)};
        key[0] += kWeyl0;
        key[1] += kWeyl1;
    }
    return ctr;
}

/// 128 random bits for (seed, stream, counter).
inline std::array<std::uint32_t, 4> randomBits(std::uint64_t seed, std::uint64_t stream,
                                               std::uint64_t counter) {
    return philox4x32({static_cast<std::uint32_t>(counter), static_cast<std::uint32_t>(counter >> 32),
                       static_cast<std::uint32_t>(stream), static_cast<std::uint32_t>(stream >> 32)},
                      {static_cast<std::uint32_t>(seed), static_cast<std::uint32_t>(seed >> 32)});
}

/// Uniform double in [0, 1) with 53 random bits.
inline double bitsToUnit(std::uint32_t hi, std::uint32_t lo) {
    const std::uint64_t v = (static_cast<std::uint64_t>(hi) << 21) ^ (lo >> 11);
    return static_cast<double>(v & ((std::uint64_t{1} << 53) - 1)) * 0x1.0p-53;
}

/// Sequential draws from one (seed, stream): each block of four 32-bit words is
/// philox(seed, stream, block). Cheap to construct; use one per entity and step.
class RandomStream {
public:
    RandomStream(std::uint64_t seed, std::uint64_t stream, std::uint64_t firstBlock = 0)
        : seed_(seed), stream_(stream), block_(firstBlock) {}

    std::uint32_t nextU32() {
        if (used_ == 4) {
            buf_ = randomBits(seed_, stream_, block_++);
            used_ = 0;
        }
        return buf_[used_++];
    }
    /// Uniform in [0, 1).
    double uniform() {
        const std::uint32_t a = nextU32();
        const std::uint32_t b = nextU32();
        return bitsToUnit(a, b);
    }
    /// Uniform in [lo, hi).
    double uniform(double lo, double hi) { return lo + (hi - lo) * uniform(); }
    /// Uniform integer in [0, n), n > 0 (rejection-free multiply-shift; bias < 2^-32).
    std::uint32_t below(std::uint32_t n) {
        return static_cast<std::uint32_t>((static_cast<std::uint64_t>(nextU32()) * n) >> 32);
    }
    /// Standard normal (Box-Muller; uses two uniforms).
    double normal() {
        const double u1 = 1.0 - uniform();  // (0, 1]
        const double u2 = uniform();
        return std::sqrt(-2.0 * std::log(u1)) * std::cos(6.283185307179586 * u2);
    }

private:
    std::uint64_t seed_, stream_, block_;
    std::array<std::uint32_t, 4> buf_{};
    int used_ = 4;
};

/// Combine several identifiers into one 64-bit stream id (SplitMix64 finaliser).
inline std::uint64_t mixStream(std::uint64_t a, std::uint64_t b) {
    std::uint64_t z = a * 0x9E3779B97F4A7C15ull + b + 0x632BE59BD9B4E019ull;
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
}

}  // namespace eco
