#include "atomic_file.h"

#include <fcntl.h>
#include <signal.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>
#include <system_error>

#include "error.h"

namespace eco {

namespace {

namespace fs = std::filesystem;

// The set open on this thread (AtomicOutputSet): commits of AtomicOutput go to it.
thread_local AtomicOutputSet* currentSet = nullptr;

constexpr const char* kJournalHeader = "eco-output-set 1";
constexpr const char* kJournalEnd = "end";

fs::path directoryOf(const fs::path& p) { return p.has_parent_path() ? p.parent_path() : fs::path("."); }

/// Whether no process of id `pid` runs on this machine (a process we may not signal counts
/// as running: not ours to judge).
bool processIsGone(pid_t pid) { return pid > 0 && pid != ::getpid() && ::kill(pid, 0) != 0 && errno == ESRCH; }

/// A hidden name AtomicOutput or AtomicOutputSet gives: `.<output name><tag><pid>`, with tag
/// ".tmp" (a temporary) or ".set" (a set's journal), and for a temporary possibly a writer's
/// extension after the pid (`.<name>.tmp<pid>.png`: the PNG and EXR writers, whose library
/// picks the format from the extension). Fills `output` and `pid`.
bool parseHiddenName(const std::string& name, const char* tag, std::string& output, pid_t& pid) {
    if (name.size() < 2 || name[0] != '.') return false;
    const std::size_t at = name.rfind(tag);
    if (at == std::string::npos || at <= 1) return false;
    std::string digits = name.substr(at + std::strlen(tag));
    const std::size_t dot = digits.find('.');
    if (dot != std::string::npos && std::strcmp(tag, ".tmp") == 0) {
        const std::string ext = digits.substr(dot + 1);
        if (ext.empty() || ext.size() > 8 || ext.find_first_not_of("abcdefghijklmnopqrstuvwxyz0123456789") != std::string::npos)
            return false;
        digits.resize(dot);
    }
    if (digits.empty() || digits.size() > 9 || digits.find_first_not_of("0123456789") != std::string::npos) return false;
    output = name.substr(1, at - 1);
    pid = static_cast<pid_t>(std::stol(digits));
    return true;
}

void syncDirectory(const fs::path& dir) {
    // Best effort: some file systems refuse fsync on a directory.
    const int fd = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY);
    if (fd >= 0) {
        ::fsync(fd);
        ::close(fd);
    }
}

/// fsync of a finished temporary; IoError naming the output when the data cannot be flushed.
void syncPath(const std::string& temp, const std::string& output) {
    const int fd = ::open(temp.c_str(), O_RDONLY);
    if (fd < 0) throw IoError(output + ": cannot open the finished output to flush it: " + std::strerror(errno));
    const int rc = ::fsync(fd);
    const int err = errno;
    ::close(fd);
    if (rc != 0 && err != EINVAL && err != EROFS)  // EINVAL: the file system does not sync (pipes, some FUSE)
        throw IoError(output + ": cannot flush the output to disk: " + std::strerror(err));
}

/// Finish the set commit a dead process recorded in `journal` when the journal is complete
/// (every temporary it names was whole before the first rename): rename the temporaries
/// still there. An incomplete journal (killed while writing it) commits nothing. The journal
/// is removed either way.
void completeSet(const fs::path& journal) {
    std::ifstream in(journal);
    std::string line;
    std::vector<std::pair<std::string, std::string>> moves;
    bool complete = false, header = false;
    while (std::getline(in, line)) {
        if (!header) {
            header = line == kJournalHeader;
            if (!header) break;
            continue;
        }
        if (line == kJournalEnd) {
            complete = true;
            break;
        }
        const std::size_t tab = line.find('\t');
        if (tab == std::string::npos) break;
        moves.emplace_back(line.substr(0, tab), line.substr(tab + 1));
    }
    in.close();
    if (complete) {
        std::set<fs::path> dirs;
        for (const auto& [temp, final] : moves) {
            std::error_code ec;
            if (!fs::exists(temp, ec)) continue;  // renamed before the kill
            fs::rename(temp, final, ec);
            if (!ec) dirs.insert(directoryOf(final));
        }
        for (const fs::path& d : dirs) syncDirectory(d);
    }
    std::error_code ec;
    fs::remove(journal, ec);
}

/// Cleans `dir` after dead writers; only of the output named `onlyOutput` when not empty.
void cleanDirectory(const fs::path& dir, const std::string& onlyOutput) {
    // Two passes: interrupted set commits first (their temporaries are the set's files), then
    // the temporaries of dead writers.
    for (const char* tag : {".set", ".tmp"}) {
        std::vector<fs::path> found;
        std::error_code ec;
        fs::directory_iterator it(dir, ec);
        for (const fs::directory_iterator end; !ec && it != end; it.increment(ec)) {
            std::string output;
            pid_t pid = 0;
            if (!parseHiddenName(it->path().filename().string(), tag, output, pid)) continue;
            if (!onlyOutput.empty() && output != onlyOutput) continue;
            if (processIsGone(pid)) found.push_back(it->path());
        }
        for (const fs::path& p : found) {
            if (tag[1] == 's') {
                completeSet(p);
            } else {
                std::error_code removeError;
                fs::remove(p, removeError);
            }
        }
    }
}

}  // namespace

// ------------------------------------------------------------------ cleaning up

void cleanUpAfterDeadWriters(const std::string& finalPath) {
    const fs::path p(finalPath);
    if (p.filename().empty()) return;
    cleanDirectory(directoryOf(p), p.filename().string());
}

void cleanUpDirectoryAfterDeadWriters(const std::string& dir) {
    std::error_code ec;
    if (fs::is_directory(dir, ec)) cleanDirectory(dir, "");
}

// ------------------------------------------------------------------ the test seam

void testPausePoint(const std::string& point) {
    struct Wanted {
        std::string point;
        long count = 1;
        long reached = 0;
    };
    static Wanted wanted = [] {
        Wanted w;
        const char* spec = std::getenv("ECO_TEST_PAUSE_AT");
        if (!spec) return w;
        w.point = spec;
        const std::size_t hash = w.point.rfind('#');
        if (hash != std::string::npos && hash + 1 < w.point.size() &&
            w.point.find_first_not_of("0123456789", hash + 1) == std::string::npos) {
            w.count = std::stol(w.point.substr(hash + 1));
            w.point.resize(hash);
        }
        return w;
    }();
    if (wanted.point.empty() || point != wanted.point) return;
    if (++wanted.reached == wanted.count) ::raise(SIGSTOP);
}

// ------------------------------------------------------------------ one output

AtomicOutput::AtomicOutput(std::string finalPath) : final_(std::move(finalPath)) {
    const fs::path p(final_);
    const fs::path dir = directoryOf(p);
    if (!fs::is_directory(dir))
        throw IoError(final_ + ": output directory '" + dir.string() + "' does not exist");
    cleanUpAfterDeadWriters(final_);
    temp_ = (dir / ("." + p.filename().string() + ".tmp" + std::to_string(::getpid()))).string();
}

AtomicOutput::~AtomicOutput() {
    if (!committed_) std::remove(temp_.c_str());
}

void AtomicOutput::midWritePoint() const { testPausePoint("write:" + fs::path(final_).filename().string()); }

void AtomicOutput::commit() {
    testPausePoint("commit:" + fs::path(final_).filename().string());
    // The data on disk before the name: after a power cut the output is the old file or the
    // whole new one, never a new name over a partly written file (rename alone orders nothing).
    syncPath(temp_, final_);
    if (currentSet) {
        currentSet->adopt(temp_, final_);
        committed_ = true;
        return;
    }
    std::error_code ec;
    fs::rename(temp_, final_, ec);
    if (ec) throw IoError(final_ + ": cannot move finished output into place: " + ec.message());
    committed_ = true;
    syncDirectory(directoryOf(fs::path(final_)));
    // A killed simulation's checkpoint can be gigabytes: removed as soon as possible.
    cleanUpAfterDeadWriters(final_);
}

// ------------------------------------------------------------------ a set of outputs

AtomicOutputSet::AtomicOutputSet() : outer_(currentSet) { currentSet = this; }

AtomicOutputSet::~AtomicOutputSet() {
    if (currentSet == this) currentSet = outer_;
    if (!committed_)
        for (const Member& m : members_) std::remove(m.temp.c_str());
}

void AtomicOutputSet::adopt(const std::string& temp, const std::string& final) {
    const std::string absTemp = fs::absolute(temp).string(), absFinal = fs::absolute(final).string();
    for (Member& m : members_)
        if (m.final == absFinal) {  // written twice: the later file counts
            if (m.temp != absTemp) std::remove(m.temp.c_str());
            m.temp = absTemp;
            return;
        }
    members_.push_back({absTemp, absFinal});
}

std::string AtomicOutputSet::readablePath(const std::string& finalPath) const {
    const std::string absFinal = fs::absolute(finalPath).string();
    for (const Member& m : members_)
        if (m.final == absFinal) return m.temp;
    return finalPath;
}

std::vector<std::string> AtomicOutputSet::finalPaths() const {
    std::vector<std::string> out;
    for (const Member& m : members_) out.push_back(m.final);
    return out;
}

void AtomicOutputSet::commit() {
    if (currentSet == this) currentSet = outer_;
    if (committed_ || members_.empty()) {
        committed_ = true;
        return;
    }
    const fs::path first(members_.front().final);
    const fs::path journal = directoryOf(first) / ("." + first.filename().string() + ".set" + std::to_string(::getpid()));
    if (members_.size() > 1) {
        // The journal, flushed before the first rename: from here on the set is decided.
        std::FILE* f = std::fopen(journal.c_str(), "w");
        if (!f) throw IoError(members_.front().final + ": cannot write the journal of its output set " + journal.string());
        bool ok = std::fprintf(f, "%s\n", kJournalHeader) > 0;
        for (const Member& m : members_) ok = ok && std::fprintf(f, "%s\t%s\n", m.temp.c_str(), m.final.c_str()) > 0;
        ok = ok && std::fprintf(f, "%s\n", kJournalEnd) > 0;
        ok = ok && std::fflush(f) == 0 && (::fsync(::fileno(f)) == 0 || errno == EINVAL || errno == EROFS);
        if (std::fclose(f) != 0 || !ok) {
            std::remove(journal.c_str());
            throw IoError(members_.front().final + ": cannot write the journal of its output set " + journal.string());
        }
        syncDirectory(directoryOf(first));
    }
    committed_ = true;  // the temporaries now belong to the journal (completed by the next writer if we die)
    std::set<fs::path> dirs;
    for (const Member& m : members_) {
        testPausePoint("rename:" + fs::path(m.final).filename().string());
        std::error_code ec;
        fs::rename(m.temp, m.final, ec);
        if (ec)
            throw IoError(m.final + ": cannot move finished output into place: " + ec.message() +
                          (members_.size() > 1 ? " (its output set is incomplete; journal " + journal.string() + ")" : ""));
        dirs.insert(directoryOf(fs::path(m.final)));
    }
    for (const fs::path& d : dirs) syncDirectory(d);
    if (members_.size() > 1) {
        std::error_code ec;
        fs::remove(journal, ec);
        syncDirectory(directoryOf(first));
    }
    for (const Member& m : members_) cleanUpAfterDeadWriters(m.final);
}

// ------------------------------------------------------------------ helpers

void writeTextFile(const std::string& path, const std::string& text) {
    AtomicOutput out(path);
    {
        std::FILE* f = std::fopen(out.tempPath().c_str(), "wb");
        if (!f) throw IoError(path + ": cannot write");
        const bool ok = std::fwrite(text.data(), 1, text.size(), f) == text.size();
        if (std::fclose(f) != 0 || !ok) throw IoError(path + ": error while writing");
    }
    out.commit();
}

std::string readTextFile(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    std::ostringstream s;
    s << in.rdbuf();
    return s.str();
}

void ensureDirectory(const std::string& dir) {
    std::error_code ec;
    fs::create_directories(dir, ec);
    if (ec || !fs::is_directory(dir))
        throw IoError(dir + ": cannot create output directory" + (ec ? ": " + ec.message() : ""));
}

}  // namespace eco
