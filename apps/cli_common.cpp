#include "cli_common.h"

#include "error.h"
#include "simulator.h"
#include "text_format.h"

#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <csignal>
#include <cstdarg>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <iostream>
#include <map>
#include <streambuf>

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

namespace {
Verbosity gVerbosity = Verbosity::Normal;

class NullBuffer : public std::streambuf {
protected:
    int overflow(int c) override { return traits_type::not_eof(c); }
    std::streamsize xsputn(const char*, std::streamsize n) override { return n; }
};

class NullBar : public pipeline::ProgressBar {
public:
    void update(long) override {}
    void finish() override {}
};
}  // namespace

void setVerbosity(Verbosity v) { gVerbosity = v; }
Verbosity verbosity() { return gVerbosity; }

void info(const std::string& line) {
    if (gVerbosity != Verbosity::Quiet) std::cerr << line << "\n";
}

void detail(const std::string& line) {
    if (gVerbosity == Verbosity::Verbose) std::cerr << line << "\n";
}

std::ostream& resultStream() {
    static NullBuffer nullBuffer;
    static std::ostream sink(&nullBuffer);
    return gVerbosity == Verbosity::Quiet ? sink : std::cout;
}

void printResult(const char* format, ...) {
    if (gVerbosity == Verbosity::Quiet) return;
    std::va_list args;
    va_start(args, format);
    std::vfprintf(stdout, format, args);
    va_end(args);
}

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

CLI::Validator numberIn(double lo, double hi) {
    const std::string range = "[" + formatNumber(lo, 10) + ", " + formatNumber(hi, 10) + "]";
    return CLI::Validator(
        [lo, hi, range](std::string& text) -> std::string {
            char* end = nullptr;
            errno = 0;
            const double v = std::strtod(text.c_str(), &end);
            if (text.empty() || *end != '\0' || errno == ERANGE || !std::isfinite(v)) return "'" + text + "' is not a number";
            if (v < lo || v > hi) return "must lie in " + range + ", got " + text;
            return "";
        },
        "NUMBER in " + range);
}

namespace {
std::map<const CLI::Option*, ParamFlag>& paramFlags() {
    static std::map<const CLI::Option*, ParamFlag> flags;
    return flags;
}
std::string firstLongName(const CLI::Option* o) { return o->get_lnames().empty() ? std::string() : o->get_lnames().front(); }
}  // namespace

void noteParamFlag(const CLI::Option* option, const void* table, const std::string& key) {
    paramFlags()[option] = ParamFlag{table, key, firstLongName(option)};
}

const ParamFlag* paramFlagOf(const CLI::Option* option) {
    const auto it = paramFlags().find(option);
    return it != paramFlags().end() && it->second.flag == firstLongName(option) ? &it->second : nullptr;
}

CLI::Validator oneOf(const std::vector<std::string>& choices) {
    std::string list;
    for (const auto& c : choices) list += (list.empty() ? "" : ", ") + c;
    return CLI::Validator(
        [choices, list](std::string& text) -> std::string {
            for (const auto& c : choices)
                if (text == c) return "";
            return "'" + text + "' is not one of " + list;
        },
        "one of " + list, kOneOfValidatorName);
}

CLI::Validator parsedBy(const std::string& flag, const std::function<void(const std::string&)>& parse) {
    return CLI::Validator(
        [flag, parse](std::string& text) -> std::string {
            try {
                parse(text);
            } catch (const Error& e) {
                std::string why = e.what();
                for (const std::string& prefix : {flag + ": ", flag + " "})
                    if (why.rfind(prefix, 0) == 0) why = why.substr(prefix.size());
                return why;
            }
            return "";
        },
        "");
}

void usageError(const std::string& flags, const std::string& message) { throw CLI::ValidationError(flags, message); }

const CLI::Validator& cellSizeRange() {
    static const CLI::Validator v = numberIn(kMinCellSizeM, kMaxCellSizeM);
    return v;
}

const CLI::Validator& positiveNumber() {
    static const CLI::Validator v = numberCheck(false);
    return v;
}
const CLI::Validator& nonNegativeNumber() {
    static const CLI::Validator v = numberCheck(true);
    return v;
}

namespace {

std::atomic<bool> gStop{false};
extern "C" void onStopSignal(int) { gStop = true; }

// Progress line: year, plants alive, plant-months per second, time left. Installs the
// SIGINT / SIGTERM handlers while it lives (a stop request ends the run after the year).
class SimProgress : public pipeline::SimulationProgress {
public:
    explicit SimProgress(int totalYears)
        : total_(totalYears), tty_(::isatty(STDERR_FILENO) != 0), print_(verbosity() != Verbosity::Quiet),
          everyYear_(verbosity() == Verbosity::Verbose) {
        // The stop request works with --quiet too: only the printing is switched off.
        gStop = false;
        previousInt_ = std::signal(SIGINT, onStopSignal);
        previousTerm_ = std::signal(SIGTERM, onStopSignal);
    }
    ~SimProgress() override {
        std::signal(SIGINT, previousInt_);
        std::signal(SIGTERM, previousTerm_);
    }
    SimProgress(const SimProgress&) = delete;
    SimProgress& operator=(const SimProgress&) = delete;
    void update(const sim::Simulation& s) override {
        if (!print_) return;
        const auto now = std::chrono::steady_clock::now();
        if (!started_) {
            started_ = true;
            start_ = now;
            startYear_ = s.yearsDone();
            startPlantMonths_ = s.counters().plantMonths;
        }
        const double elapsed = std::chrono::duration<double>(now - start_).count();
        const int year = s.yearsDone();
        const double rate = elapsed > 0 ? static_cast<double>(s.counters().plantMonths - startPlantMonths_) / elapsed : 0.0;
        const int doneHere = year - startYear_;
        const double left = doneHere > 0 ? elapsed / doneHere * (total_ - year) : 0.0;
        const int filled = total_ > 0 ? std::min(20, 20 * year / total_) : 20;
        const std::string bar = std::string(static_cast<std::size_t>(filled), '#') + std::string(static_cast<std::size_t>(20 - filled), '.');
        char line[256];
        std::snprintf(line, sizeof line, "simulate [%s] year %d/%d  plants %zu  %.2fM plant-months/s  ~%.0fs left", bar.c_str(),
                      year, total_, s.plantCount(), rate / 1e6, left);
        if (tty_) {
            std::fprintf(stderr, "\r\033[K%s", line);
        } else if (everyYear_ || year == total_ || elapsed - lastPrint_ >= 5.0 || year == startYear_) {
            std::fprintf(stderr, "%s\n", line);
            lastPrint_ = elapsed;
        }
        std::fflush(stderr);
    }
    void finish() override {
        if (tty_ && started_) std::fprintf(stderr, "\n");
    }

private:
    int total_;
    bool tty_;
    bool print_;      // false with --quiet
    bool everyYear_;  // --verbose: a line every year, not every 5 s (logs)
    bool started_ = false;
    std::chrono::steady_clock::time_point start_;
    int startYear_ = 0;
    long long startPlantMonths_ = 0;
    double lastPrint_ = -1e9;
    void (*previousInt_)(int) = SIG_DFL;
    void (*previousTerm_)(int) = SIG_DFL;
};

}  // namespace

namespace {
bool gThreadsFlagGiven = false;
}
bool threadsFlagGiven() { return gThreadsFlagGiven; }
void setThreadsFlagGiven(bool given) { gThreadsFlagGiven = given; }

std::ostream& CliReporter::out() { return resultStream(); }
void CliReporter::info(const std::string& line) { cli::info(line); }
void CliReporter::detail(const std::string& line) { cli::detail(line); }
std::unique_ptr<pipeline::ProgressBar> CliReporter::progress(const std::string& label, long total) {
    if (verbosity() == Verbosity::Quiet) return std::make_unique<NullBar>();
    return std::make_unique<Progress>(label, total);
}
std::unique_ptr<pipeline::SimulationProgress> CliReporter::simulationProgress(int totalYears) {
    return std::make_unique<SimProgress>(totalYears);
}
bool CliReporter::stopRequested() { return gStop.load(); }

}  // namespace eco::cli
