// Memory checked before large allocations (issue 26): a scene, grid or candidate set that
// would not fit is refused with what it needs and what the machine has, instead of a
// std::bad_alloc deep inside a computation (or an abort inside an OpenMP region).
#pragma once

#include <cstdint>
#include <string>

namespace eco {

/// Bytes this process can still allocate: the smaller of the machine's available memory
/// (MemAvailable in /proc/meminfo), the address-space limit (RLIMIT_AS) and the environment
/// variable ECO_MEMORY_LIMIT_MB (megabytes, when set to a positive integer); 0 when none is
/// known. The variable is for processes that cannot run under `ulimit -v`, such as builds
/// with AddressSanitizer (which reserves terabytes of address space) and the fuzz targets.
std::uint64_t availableMemoryBytes();

/// "12.3 GB" / "512 MB": a byte count for messages.
std::string bytesText(double bytes);

/// ValidationError "<what> needs about N GB of memory but the machine has M GB available
/// (<hint>)" when `bytes` exceeds what is available; nothing when the amount is unknown.
/// `bytes` is a double so that products of sizes cannot overflow before the check.
void requireMemory(double bytes, const std::string& what, const std::string& hint);

}  // namespace eco
