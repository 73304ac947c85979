// Memory checked before large allocations (issue 26): a scene, grid or candidate set that
// would not fit is refused with what it needs and what the machine has, instead of a
// std::bad_alloc deep inside a computation (or an abort inside an OpenMP region).
#pragma once

#include <cstddef>
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

/// Prepares `bytes` of fresh memory (a vector's reserved capacity, before it is filled)
/// when it is large: advised for transparent huge pages (Linux) and first touched by all
/// OpenMP threads in blocks of 2 MB, so that the kernel's page faults are fewer and shared
/// between the threads instead of all taken, 4 kB at a time, by the one thread that fills it.
/// The contents are left as zeros. Does nothing below `kLargeBufferBytes` (16 MB: at 4 MB,
/// tried 2026-11-27, bench_synth's 1024^2 sampling was no faster on the idle machine).
inline constexpr std::size_t kLargeBufferBytes = std::size_t{16} << 20;
void prepareLargeBuffer(void* p, std::size_t bytes);

/// `v.assign(n, value)` for a vector without room for n items yet, its fresh memory prepared
/// first (prepareLargeBuffer) when large: on a virtual machine of the benchmarks a page
/// fault of 4 kB cost about 17 us of CPU time, so a serial fill of 100 MB of fresh pages
/// (25 k faults: the canopy cover of the sizes at 3072^2) cost about 0.4 s.
template <typename Vector>
void assignFresh(Vector& v, std::size_t n, const typename Vector::value_type& value) {
    using T = typename Vector::value_type;
    if (v.empty() && v.capacity() < n && n * sizeof(T) >= kLargeBufferBytes) {
        v.reserve(n);
        prepareLargeBuffer(v.data(), n * sizeof(T));
    }
    v.assign(n, value);
}
/// `v.resize(n)` (value-initialised items) of an empty vector, prepared like assignFresh.
template <typename Vector>
void resizeFresh(Vector& v, std::size_t n) {
    using T = typename Vector::value_type;
    if (v.empty() && v.capacity() < n && n * sizeof(T) >= kLargeBufferBytes) {
        v.reserve(n);
        prepareLargeBuffer(v.data(), n * sizeof(T));
    }
    v.resize(n);
}

/// Keeps the memory of freed buffers in the process for the buffers that follow, instead of
/// handing it back to the kernel (glibc: blocks up to 1 GB from the heap rather than from
/// mappings of their own, and up to 2 GB of free memory kept at the heap's top). Fresh
/// memory from the kernel must be zeroed, and on a virtual machine that reports free pages
/// to its host (the benchmarks' machine) first be given back by the host: about 2 s of CPU
/// time per GB there, against 0.1 s for memory the process already holds. Called by
/// `eco synth`, `eco canopy` and bench_synth, which run one large computation after another
/// (not by `eco run`); their resident size stays near its peak. Results never change.
/// Nothing outside glibc.
void retainFreedMemory();

}  // namespace eco
