// The fingerprint helpers of both simulator models' checkpoints (simulator_state.cpp,
// ecomod.cpp): bytes folded into a 64-bit hash with rng.h's mixStream, and the hash as the
// 16 hex digits written into the checkpoint.
#pragma once

#include <cstdint>
#include <cstdio>
#include <cstring>
#include <string>

#include "rng.h"

namespace eco::sim {

/// `h` with the `n` bytes at `data` folded in, 8 at a time, the tail and the length last.
inline std::uint64_t hashBytes(std::uint64_t h, const void* data, std::size_t n) {
    const auto* p = static_cast<const unsigned char*>(data);
    std::size_t i = 0;
    for (; i + 8 <= n; i += 8) {
        std::uint64_t w;
        std::memcpy(&w, p + i, 8);
        h = mixStream(h, w);
    }
    std::uint64_t tail = n;
    for (; i < n; ++i) tail = (tail << 8) ^ p[i];
    return mixStream(h, tail);
}

/// 16 lower-case hex digits.
inline std::string hex64(std::uint64_t v) {
    char buf[32];
    std::snprintf(buf, sizeof buf, "%016llx", static_cast<unsigned long long>(v));
    return buf;
}

}  // namespace eco::sim
