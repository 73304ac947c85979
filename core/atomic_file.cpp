#include "atomic_file.h"

#include <unistd.h>

#include <cstdio>
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

void AtomicOutput::commit() {
    std::error_code ec;
    std::filesystem::rename(temp_, final_, ec);
    if (ec) throw IoError(final_ + ": cannot move finished output into place: " + ec.message());
    committed_ = true;
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
