#include "provenance.h"

#include <atomic>
#include <cstdio>
#include <ctime>
#include <fstream>
#include <mutex>

#include "build_info.h"

namespace eco {

namespace {
std::atomic<bool> gRecorded{true};

// What identifies the run, process-wide (set from main() and the pipeline, read by writers).
struct RunIdentity {
    std::mutex mutex;
    std::string commandLine;
    std::string stageCommand;
    std::vector<std::pair<std::string, std::string>> inputs;  // path, hash
};
RunIdentity& identity() {
    static RunIdentity id;
    return id;
}

/// An argument as a POSIX shell reads it back: bare when it has only safe characters.
std::string shellQuoted(const std::string& arg) {
    const bool safe = !arg.empty() && arg.find_first_not_of("abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ"
                                                            "0123456789-_./=:,+@%") == std::string::npos;
    if (safe) return arg;
    std::string out = "'";
    for (char c : arg) out += c == '\'' ? std::string("'\\''") : std::string(1, c);
    return out + "'";
}
}  // namespace

void setCommandLine(int argc, const char* const* argv) {
    std::string line;
    for (int i = 0; i < argc; ++i) line += (i ? " " : "") + shellQuoted(argv[i]);
    std::lock_guard<std::mutex> lock(identity().mutex);
    identity().commandLine = line;
}

std::string processCommandLine() {
    std::lock_guard<std::mutex> lock(identity().mutex);
    return identity().commandLine;
}

void beginStage(const std::string& stageCommand) {
    std::lock_guard<std::mutex> lock(identity().mutex);
    identity().stageCommand = stageCommand;
    identity().inputs.clear();
}

std::string fnv1a64OfFile(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    if (!in) return "unreadable";
    // FNV-1a, 64 bits: offset basis and prime of the published parameters.
    std::uint64_t h = 0xcbf29ce484222325ull;
    constexpr std::uint64_t kPrime = 0x100000001b3ull;
    std::vector<char> buf(1 << 16);
    while (in) {
        in.read(buf.data(), static_cast<std::streamsize>(buf.size()));
        const std::streamsize n = in.gcount();
        for (std::streamsize i = 0; i < n; ++i) {
            h ^= static_cast<unsigned char>(buf[static_cast<std::size_t>(i)]);
            h *= kPrime;
        }
    }
    char hex[24];
    std::snprintf(hex, sizeof hex, "%016llx", static_cast<unsigned long long>(h));
    return hex;
}

void noteInputFile(const std::string& path) {
    if (!provenanceRecorded()) return;
    {
        std::lock_guard<std::mutex> lock(identity().mutex);
        for (const auto& [p, hash] : identity().inputs)
            if (p == path) return;
    }
    const std::string hash = fnv1a64OfFile(path);  // outside the lock: it reads the file
    std::lock_guard<std::mutex> lock(identity().mutex);
    for (const auto& [p, h] : identity().inputs)
        if (p == path) return;
    identity().inputs.emplace_back(path, hash);
}

std::vector<std::pair<std::string, std::string>> inputFiles() {
    std::lock_guard<std::mutex> lock(identity().mutex);
    return identity().inputs;
}

void setProvenanceRecorded(bool recorded) { gRecorded = recorded; }
bool provenanceRecorded() { return gRecorded; }

void writeProvenance(h5::File& file, const std::vector<ProvenanceEntry>& entries) {
    if (!provenanceRecorded()) return;
    file.ensureGroup(kProvenanceGroup);
    file.setAttr(kProvenanceGroup, "note",
                 std::string("measured, not computed: varies between runs of the same inputs and seed; comparison "
                             "tools skip this group (eco --no-provenance omits it)"));
    file.setAttr(kProvenanceGroup, "code_version", std::string(codeVersion()));
    file.setAttr(kProvenanceGroup, "git_commit", std::string(gitCommit()));
    std::string stage;
    {
        std::lock_guard<std::mutex> lock(identity().mutex);
        stage = identity().stageCommand;
    }
    const std::string command = processCommandLine();
    file.setAttr(kProvenanceGroup, "command_line", command.empty() ? std::string("(not recorded: not run by eco)") : command);
    if (!stage.empty()) file.setAttr(kProvenanceGroup, "stage_command", stage);
    std::vector<std::string> paths, hashes;
    for (const auto& [p, h] : inputFiles()) {
        if (p == file.path()) continue;  // a file read back while being made is not its own input
        paths.push_back(p);
        hashes.push_back(h);
    }
    file.setAttr(kProvenanceGroup, "input_files", paths);
    file.setAttr(kProvenanceGroup, "input_fnv1a64", hashes);
    for (const ProvenanceEntry& e : entries)
        std::visit([&](const auto& v) { file.setAttr(kProvenanceGroup, e.name, v); }, e.value);
}

std::optional<double> readProvenanceDouble(const h5::File& file, const std::string& name,
                                           const std::string& legacyRootAttr) {
    if (file.hasAttr(kProvenanceGroup, name)) return file.attrDouble(kProvenanceGroup, name);
    if (!legacyRootAttr.empty() && file.hasAttr("/", legacyRootAttr)) return file.attrDouble("/", legacyRootAttr);
    return std::nullopt;
}

std::optional<std::string> readProvenanceString(const h5::File& file, const std::string& name,
                                                const std::string& legacyRootAttr) {
    if (file.hasAttr(kProvenanceGroup, name)) return file.attrString(kProvenanceGroup, name);
    if (!legacyRootAttr.empty() && file.hasAttr("/", legacyRootAttr)) return file.attrString("/", legacyRootAttr);
    return std::nullopt;
}

std::string utcTimestamp() {
    const std::time_t now = std::time(nullptr);
    std::tm tm{};
    gmtime_r(&now, &tm);
    char buf[32];
    std::strftime(buf, sizeof buf, "%Y-%m-%dT%H:%M:%SZ", &tm);
    return buf;
}

}  // namespace eco
