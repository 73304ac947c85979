// Helpers shared by the tests: running the eco binary (command-line tests) and temporary directories.
#pragma once

#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <vector>
#include <fstream>
#include <iterator>
#include <map>

#include <cmath>
#include <memory>

#include "image_codec.h"

// AddressSanitizer reserves terabytes of address space at start, so a process built with it
// cannot run under `ulimit -v`; such builds pass the limit as ECO_MEMORY_LIMIT_MB instead
// (core/memory.h), which the memory checks read the same way.
#if defined(__SANITIZE_ADDRESS__)
#define ECO_TEST_ASAN 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define ECO_TEST_ASAN 1
#endif
#endif

namespace eco::test {

struct CommandResult {
    int exitCode = -1;
    std::string output;  ///< stdout and stderr together
};

#ifdef ECO_BINARY  // defined for eco_cli_tests only: unit tests do not run the binary
/// Runs a shell command line, capturing its output; exitCode -1 when it did not exit.
inline CommandResult runShell(const std::string& cmd) {
    CommandResult r;
    FILE* pipe = ::popen(cmd.c_str(), "r");
    if (!pipe) return r;
    std::array<char, 4096> buf{};
    std::size_t n;
    while ((n = std::fread(buf.data(), 1, buf.size(), pipe)) > 0) r.output.append(buf.data(), n);
    const int status = ::pclose(pipe);
    r.exitCode = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
    return r;
}

/// Run the eco binary with `args` (a shell-quoted string), capturing its output.
/// Runs eco with its arguments; with `memoryLimitKb` > 0 under that address-space limit
/// (ulimit -v), so that memory checks are tested the same on any machine.
/// ECO_TEST_BINARY in the environment runs another build's binary instead (e.g. the bad-input
/// corpus against an older commit).
inline CommandResult runEco(const std::string& args, long memoryLimitKb = 0) {
    const char* other = std::getenv("ECO_TEST_BINARY");
    const std::string run = std::string(other != nullptr && *other != '\0' ? other : ECO_BINARY) + " " + args + " 2>&1";
#ifdef ECO_TEST_ASAN
    const std::string limit = "ECO_MEMORY_LIMIT_MB=" + std::to_string(memoryLimitKb / 1024) + " ";
#else
    const std::string limit = "ulimit -v " + std::to_string(memoryLimitKb) + "; ";
#endif
    const std::string cmd = memoryLimitKb > 0 ? limit + run : run;
    return runShell(cmd);
}

/// Run the eco binary under `mpirun -n ranks` (as root too, which mpirun refuses unless told;
/// --oversubscribe: any number of ranks on any machine), capturing the output of every rank.
inline CommandResult runEcoMpi(int ranks, const std::string& args) {
    return runShell("OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 mpirun --oversubscribe -n " + std::to_string(ranks) + " " +
                    std::string(ECO_BINARY) + " " + args + " 2>&1");
}
#endif

/// A fresh empty directory under the system temp dir, removed at scope exit.
class TempDir {
public:
    explicit TempDir(const std::string& tag) {
        path_ = std::filesystem::temp_directory_path() /
                ("eco_test_" + tag + "_" + std::to_string(::getpid()) + "_" + std::to_string(counter()++));
        std::filesystem::remove_all(path_);
        std::filesystem::create_directories(path_);
    }
    ~TempDir() {
        std::error_code ec;
        std::filesystem::remove_all(path_, ec);
    }
    std::string file(const std::string& name) const { return (path_ / name).string(); }
    const std::filesystem::path& path() const { return path_; }

private:
    static int& counter() {
        static int c = 0;
        return c;
    }
    std::filesystem::path path_;
};

/// The whole of a file.
inline std::string readAll(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    std::string s((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    return s;
}

/// Writes text to a file exactly (binary mode), replacing it.
inline void writeText(const std::string& path, const std::string& text) {
    std::ofstream out(path, std::ios::binary);
    out << text;
}

/// Number of newline characters in s.
inline int lineCount(const std::string& s) {
    int n = 0;
    for (char c : s) n += c == '\n';
    return n;
}

/// Path of a file in the source tree.
inline std::string sourcePath(const std::string& rel) { return std::string(ECO_SOURCE_DIR) + "/" + rel; }

/// The rows of a CSV file with a header line, each as column name -> field (fields split at
/// commas outside double quotes; "" inside quotes is a quote). An empty list when the file
/// is missing.
inline std::vector<std::map<std::string, std::string>> readCsvRows(const std::string& path) {
    std::ifstream in(path);
    std::vector<std::map<std::string, std::string>> rows;
    const auto split = [](const std::string& line) {
        std::vector<std::string> fields(1);
        bool quoted = false;
        for (std::size_t k = 0; k < line.size(); ++k) {
            const char c = line[k];
            if (c == '"' && quoted && k + 1 < line.size() && line[k + 1] == '"') fields.back() += line[++k];
            else if (c == '"') quoted = !quoted;
            else if (c == ',' && !quoted) fields.emplace_back();
            else fields.back() += c;
        }
        return fields;
    };
    std::string line;
    if (!std::getline(in, line)) return rows;
    const std::vector<std::string> header = split(line);
    while (std::getline(in, line)) {
        const std::vector<std::string> fields = split(line);
        std::map<std::string, std::string> row;
        for (std::size_t i = 0; i < header.size(); ++i) row[header[i]] = i < fields.size() ? fields[i] : std::string("<missing>");
        if (fields.size() != header.size()) row["<fields>"] = std::to_string(fields.size());
        rows.push_back(std::move(row));
    }
    return rows;
}

/// An image's pixels as 8-bit values (rows from the top, channels interleaved), read through
/// core's image door (image_codec.h); its size and channels in w, h, channels. Empty when it
/// cannot be read.
inline std::vector<unsigned char> readImage8(const std::string& path, int& w, int& h, int& channels) {
    std::string error;
    const std::unique_ptr<eco::ImageFileReader> in = eco::openImageFile(path, error);
    if (!in) return {};
    w = in->width();
    h = in->height();
    channels = in->channels();
    std::vector<float> f(static_cast<std::size_t>(w) * h * channels);
    if (!in->readFloat(channels, f.data())) return {};
    std::vector<unsigned char> px(f.size());
    for (std::size_t i = 0; i < f.size(); ++i)
        px[i] = static_cast<unsigned char>(std::lround(std::min(1.f, std::max(0.f, f[i])) * 255.f));
    return px;
}

/// An 8-bit RGB PNG's pixels, row by row; its size in w, h. Empty when it cannot be read or
/// has not 3 channels.
inline std::vector<unsigned char> readPngRgb(const std::string& path, int& w, int& h) {
    int channels = 0;
    std::vector<unsigned char> px = readImage8(path, w, h, channels);
    return channels == 3 ? px : std::vector<unsigned char>();
}

/// Writes an image file (format from the extension: .png, .tif or .exr) with `channels`
/// channels stored as `stored`, from pixels of type `given` (rows from the top). True when
/// written.
inline bool writeImage(const std::string& path, int w, int h, int channels, eco::SampleType stored,
                       eco::SampleType given, const void* pixels) {
    eco::ImageWriteSpec spec;
    const std::string ext = std::filesystem::path(path).extension().string();
    spec.format = ext == ".png" ? "png" : ext == ".exr" ? "openexr" : "tiff";
    spec.width = w;
    spec.height = h;
    spec.channels = channels;
    spec.stored = stored;
    return eco::writeImageFile(path, spec, given, pixels).ok();
}

}  // namespace eco::test
