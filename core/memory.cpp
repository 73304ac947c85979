// Memory checks before large allocations (memory.h).
#include "memory.h"

#include <sys/mman.h>
#if defined(__GLIBC__)
#include <malloc.h>
#endif
#include <sys/resource.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <limits>
#include <sstream>

#include "error.h"

namespace eco {

std::uint64_t availableMemoryBytes() {
    std::uint64_t avail = 0;
    std::ifstream in("/proc/meminfo");
    std::string line;
    while (std::getline(in, line)) {
        if (line.rfind("MemAvailable:", 0) != 0) continue;
        std::istringstream ss(line.substr(13));
        std::uint64_t kb = 0;
        if (ss >> kb) avail = kb * 1024;
        break;
    }
    rlimit lim{};
    if (getrlimit(RLIMIT_AS, &lim) == 0 && lim.rlim_cur != RLIM_INFINITY) {
        const auto cap = static_cast<std::uint64_t>(lim.rlim_cur);
        avail = avail == 0 ? cap : std::min(avail, cap);
    }
    if (const char* env = std::getenv("ECO_MEMORY_LIMIT_MB")) {
        char* end = nullptr;
        const unsigned long long mb = std::strtoull(env, &end, 10);
        if (end != env && *end == '\0' && mb > 0 && mb < (1ull << 40)) {
            const std::uint64_t cap = mb * 1024 * 1024;
            avail = avail == 0 ? cap : std::min(avail, cap);
        }
    }
    return avail;
}

std::string bytesText(double bytes) {
    char buf[64];
    if (bytes >= 1e9) std::snprintf(buf, sizeof buf, "%.3g GB", bytes / 1e9);
    else std::snprintf(buf, sizeof buf, "%.3g MB", bytes / 1e6);
    return buf;
}

void requireMemory(double bytes, const std::string& what, const std::string& hint) {
    const std::uint64_t avail = availableMemoryBytes();
    if (avail == 0 || bytes <= static_cast<double>(avail)) return;
    throw ValidationError(what + " needs about " + bytesText(bytes) + " of memory but the machine has " +
                          bytesText(static_cast<double>(avail)) + " available" + (hint.empty() ? "" : " (" + hint + ")"));
}

void retainFreedMemory() {
#if defined(__GLIBC__)
    // Setting either also stops glibc's own adjustment of the mapping threshold (which
    // never goes above 32 MB: the scenes' grids and lists are larger).
    mallopt(M_MMAP_THRESHOLD, 1 << 30);
    mallopt(M_TRIM_THRESHOLD, std::numeric_limits<int>::max());
#endif
}

void prepareLargeBuffer(void* p, std::size_t bytes) {
    if (p == nullptr || bytes < kLargeBufferBytes) return;
    constexpr std::size_t kBlock = std::size_t{1} << 21;
#if defined(__linux__) && defined(MADV_HUGEPAGE)
    const std::uintptr_t a = (reinterpret_cast<std::uintptr_t>(p) + kBlock - 1) & ~(kBlock - 1);
    const std::uintptr_t b = (reinterpret_cast<std::uintptr_t>(p) + bytes) & ~(kBlock - 1);
    if (b > a) madvise(reinterpret_cast<void*>(a), b - a, MADV_HUGEPAGE);
#endif
    unsigned char* base = static_cast<unsigned char*>(p);
    const std::int64_t blocks = static_cast<std::int64_t>((bytes + kBlock - 1) / kBlock);
#pragma omp parallel for schedule(static)
    for (std::int64_t k = 0; k < blocks; ++k) {
        const std::size_t at = static_cast<std::size_t>(k) * kBlock;
        std::memset(base + at, 0, std::min(kBlock, bytes - at));
    }
}

}  // namespace eco
