// Small shared pieces of the benchmarks: wall and CPU clocks, machine load, size lists.
#pragma once

#include <time.h>

#include <chrono>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

namespace eco::bench {

using Clock = std::chrono::steady_clock;

inline double secondsSince(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

/// CPU seconds of the whole process (all threads).
inline double processCpuSeconds() {
    timespec t{};
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
    return static_cast<double>(t.tv_sec) + 1e-9 * static_cast<double>(t.tv_nsec);
}

/// One-minute load average (-1 when unknown): figures measured on a busy machine say so.
inline double loadAverage() {
    std::ifstream in("/proc/loadavg");
    double l = -1;
    in >> l;
    return l;
}

/// Prints `usage` and returns true when the first argument asks for help (-h, --help) or is
/// any other option: the benchmarks take positional arguments, and a flag must not become
/// the name of the results file.
inline bool wantsUsage(int argc, char** argv, const char* usage) {
    if (argc < 2 || argv[1][0] != '-') return false;
    std::cout << usage;
    return true;
}

/// "1024,2048,3072" -> {1024, 2048, 3072}.
inline std::vector<int> parseSizes(const std::string& s) {
    std::vector<int> out;
    std::stringstream ss(s);
    std::string item;
    while (std::getline(ss, item, ',')) out.push_back(std::stoi(item));
    return out;
}

/// A KEY=VALUE argument with a number as its value; anything else is refused with the
/// argument named.
struct KeyValue {
    std::string key;
    double value = 0;
};
inline KeyValue parseKeyValue(const std::string& kv) {
    const auto eq = kv.find('=');
    if (eq == std::string::npos || eq == 0) throw std::runtime_error("expected KEY=VALUE, got '" + kv + "'");
    const std::string text = kv.substr(eq + 1);
    char* end = nullptr;
    const double v = std::strtod(text.c_str(), &end);
    if (text.empty() || end != text.c_str() + text.size())
        throw std::runtime_error("argument '" + kv + "': value '" + text + "' is not a number");
    return {kv.substr(0, eq), v};
}

/// Write the report to `path` (creating its folder) and say so on stdout.
inline void writeReport(const std::string& path, const std::string& text) {
    const std::filesystem::path p(path);
    if (p.has_parent_path()) std::filesystem::create_directories(p.parent_path());
    std::ofstream(path) << text;
    std::cout << "wrote " << path << "\n";
}

/// FNV-1a over the bits of every plant's species, position, ground z, height and crown radius:
/// equal hashes = the same scene or placement (an optimisation of the sampler or the placer
/// must keep it).
/// (A template on eco::Plant, so that this header needs no library of the project.)
template <class PlantT>
std::uint64_t plantsHash(const std::vector<PlantT>& plants) {
    std::uint64_t h = 1469598103934665603ULL;
    auto add = [&](const void* p, std::size_t n) {
        const unsigned char* b = static_cast<const unsigned char*>(p);
        for (std::size_t i = 0; i < n; ++i) h = (h ^ b[i]) * 1099511628211ULL;
    };
    for (const PlantT& p : plants) {
        add(&p.speciesId, sizeof p.speciesId);
        for (const double v : {p.xM, p.yM, p.groundZM, p.heightM, p.crownRadiusM}) add(&v, sizeof v);
    }
    return h;
}

}  // namespace eco::bench
