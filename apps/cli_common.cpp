#include "cli_common.h"

#include "error.h"

#include <unistd.h>

#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
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

namespace {
CLI::Validator numberCheck(bool zeroAllowed) {
    return CLI::Validator(
        [zeroAllowed](std::string& text) -> std::string {
            char* end = nullptr;
            errno = 0;
            const double v = std::strtod(text.c_str(), &end);
            if (text.empty() || *end != '\0' || errno == ERANGE || !std::isfinite(v)) return "'" + text + "' is not a number";
            if (zeroAllowed ? v < 0 : v <= 0) return std::string("must be ") + (zeroAllowed ? ">= 0" : "> 0") + ", got " + text;
            return "";
        },
        zeroAllowed ? "NUMBER >= 0" : "NUMBER > 0");
}
}  // namespace

const CLI::Validator& positiveNumber() {
    static const CLI::Validator v = numberCheck(false);
    return v;
}
const CLI::Validator& nonNegativeNumber() {
    static const CLI::Validator v = numberCheck(true);
    return v;
}

void AbioticsProgress::operator()(const std::string& stage, double fraction) {
    if (stage != stage_) {
        if (bar_) bar_->finish();
        bar_ = std::make_unique<Progress>("abiotics " + stage, 1000);
        stage_ = stage;
    }
    bar_->update(static_cast<long>(fraction * 1000.0 + 0.5));
}

void AbioticsProgress::finish() {
    if (bar_) bar_->finish();
    bar_.reset();
}

Abiotics abioticsForTerrain(const std::string& abioticsPath, const Grid<float>& terrain,
                            const std::string& terrainPath, const Biome& biome, const std::string& note) {
    if (!abioticsPath.empty()) {
        Abiotics abiotics = readAbiotics(abioticsPath);
        if (!abiotics.slopeDeg.sameGeometry(terrain))
            throw ValidationError("abiotics '" + abioticsPath + "' (" + abiotics.slopeDeg.geometryText() +
                                  ") and terrain '" + terrainPath + "' (" + terrain.geometryText() +
                                  ") differ in geometry");
        info("abiotics: " + abioticsPath);
        return abiotics;
    }
    info("no --abiotics: computing the abiotic maps from the terrain with default parameters (" + note + ")");
    validateElevation(terrain, terrainPath);
    AbioticsProgress progress;
    Abiotics abiotics = computeAbiotics(terrain, biome, AbioticParams{},
                                        [&](const std::string& s, double f) { progress(s, f); });
    progress.finish();
    return abiotics;
}

/// "x0,y0,x1,y1" (or "x,y,side" for a square when `allowSquare`) in metres.
RectWindow parseWindow(const std::string& text, const std::string& option, bool allowSquare) {
    std::vector<double> v;
    std::stringstream ss(text);
    std::string item;
    while (std::getline(ss, item, ',')) {
        std::size_t used = 0;
        double d = 0;
        try {
            d = std::stod(item, &used);
        } catch (const std::exception&) {
            used = 0;
        }
        if (used == 0 || item.find_first_not_of(" \t", used) != std::string::npos || !std::isfinite(d))
            throw ValidationError(option + " '" + text + "': '" + item + "' is not a number");
        v.push_back(d);
    }
    RectWindow w;
    if (allowSquare && v.size() == 3) {
        if (!(v[2] > 0)) throw ValidationError(option + " '" + text + "': the side must be positive");
        w = RectWindow{v[0] - 0.5 * v[2], v[1] - 0.5 * v[2], v[0] + 0.5 * v[2], v[1] + 0.5 * v[2]};
    } else if (v.size() == 4) {
        w = RectWindow{v[0], v[1], v[2], v[3]};
    } else {
        throw ValidationError(option + " '" + text + "': expected " +
                              (allowSquare ? std::string("x_centre,y_centre,side or ") : std::string()) + "x0,y0,x1,y1 in metres");
    }
    w.validate(option);
    return w;
}

}  // namespace eco::cli
