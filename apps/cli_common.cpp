#include "cli_common.h"

#include <unistd.h>

#include <cstdio>
#include <iostream>

namespace eco::cli {

Progress::Progress(std::string label, long total)
    : label_(std::move(label)), total_(total > 0 ? total : 1), tty_(::isatty(STDERR_FILENO) != 0),
      start_(std::chrono::steady_clock::now()) {}

void Progress::update(long done) {
    const double frac = std::min(1.0, static_cast<double>(done) / static_cast<double>(total_));
    const double elapsed =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
    const double left = frac > 0 ? elapsed * (1.0 - frac) / frac : 0.0;
    if (tty_) {
        const int width = 30;
        const int filled = static_cast<int>(frac * width);
        std::fprintf(stderr, "\r%s [%s%s] %3.0f%%  %.1fs elapsed, ~%.1fs left ", label_.c_str(),
                     std::string(static_cast<std::size_t>(filled), '#').c_str(),
                     std::string(static_cast<std::size_t>(width - filled), '.').c_str(), frac * 100.0,
                     elapsed, left);
        std::fflush(stderr);
    } else {
        const int decile = static_cast<int>(frac * 10.0);
        if (decile != lastDecile_) {
            lastDecile_ = decile;
            std::fprintf(stderr, "%s: %3d%%  (%.1fs elapsed)\n", label_.c_str(), decile * 10, elapsed);
        }
    }
}

void Progress::finish() {
    const double elapsed =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
    if (tty_) std::fprintf(stderr, "\r\033[K");
    std::fprintf(stderr, "%s: done in %.2fs\n", label_.c_str(), elapsed);
}

void info(const std::string& line) { std::cerr << line << "\n"; }

}  // namespace eco::cli
