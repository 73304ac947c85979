#include "atomic_file.h"

#include <fcntl.h>
#include <signal.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <system_error>

#include "error.h"

namespace eco {

AtomicOutput::AtomicOutput(std::string finalPath) : final_(std::move(finalPath)) {
    const std::filesystem::path p(final_);
    const std::filesystem::path dir = p.has_parent_path() ? p.parent_path() : std::filesystem::path(".");
    if (!std::filesystem::is_directory(dir))
        throw IoError(final_ + ": output directory '" + dir.string() + "' does not exist");
    temp_ = (dir / ("." + p.filename().string() + ".tmp" + std::to_string(::getpid()))).string();
}

AtomicOutput::~AtomicOutput() {
    if (!committed_) std::remove(temp_.c_str());
}

namespace {

// The temporaries of `finalPath` that processes killed before their commit left behind (a
// kill -9 skips the destructor; a killed simulation's checkpoint can be gigabytes): removed.
// Only names of the form AtomicOutput gives, and only when no process of that id runs on
// this machine; anything unexpected is left alone (this never fails the output).
void removeStaleTemporaries(const std::filesystem::path& finalPath) {
    const std::filesystem::path dir = finalPath.has_parent_path() ? finalPath.parent_path() : std::filesystem::path(".");
    const std::string prefix = "." + finalPath.filename().string() + ".tmp";
    std::error_code ec;
    std::filesystem::directory_iterator it(dir, ec);
    for (const std::filesystem::directory_iterator end; !ec && it != end; it.increment(ec)) {
        const std::string name = it->path().filename().string();
        if (name.size() <= prefix.size() || name.compare(0, prefix.size(), prefix) != 0) continue;
        const std::string digits = name.substr(prefix.size());
        if (digits.size() > 9 || digits.find_first_not_of("0123456789") != std::string::npos) continue;
        const pid_t pid = static_cast<pid_t>(std::stol(digits));
        if (pid <= 0 || pid == ::getpid()) continue;
        if (::kill(pid, 0) == 0 || errno != ESRCH) continue;  // running (or not ours to ask about)
        std::error_code removeError;
        std::filesystem::remove(it->path(), removeError);
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

}  // namespace

void AtomicOutput::commit() {
    // The data on disk before the name: after a power cut the output is the old file or the
    // whole new one, never a new name over a partly written file (rename alone orders nothing).
    syncPath(temp_, final_);
    std::error_code ec;
    std::filesystem::rename(temp_, final_, ec);
    if (ec) throw IoError(final_ + ": cannot move finished output into place: " + ec.message());
    committed_ = true;
    // The directory entry too (best effort: some file systems refuse fsync on a directory).
    const std::filesystem::path p(final_);
    const int dirFd = ::open(p.has_parent_path() ? p.parent_path().c_str() : ".", O_RDONLY | O_DIRECTORY);
    if (dirFd >= 0) {
        ::fsync(dirFd);
        ::close(dirFd);
    }
    removeStaleTemporaries(final_);
}

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

void ensureDirectory(const std::string& dir) {
    std::error_code ec;
    std::filesystem::create_directories(dir, ec);
    if (ec || !std::filesystem::is_directory(dir))
        throw IoError(dir + ": cannot create output directory" + (ec ? ": " + ec.message() : ""));
}

}  // namespace eco
