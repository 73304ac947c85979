// Write-then-rename: an output file appears complete or not at all.
#pragma once

#include <string>

namespace eco {

/// Hands out a temporary path beside `finalPath`; commit() renames it into place, and the
/// destructor removes the temporary when commit() was never reached (an error was thrown).
class AtomicOutput {
public:
    explicit AtomicOutput(std::string finalPath);
    AtomicOutput(const AtomicOutput&) = delete;
    AtomicOutput& operator=(const AtomicOutput&) = delete;
    ~AtomicOutput();

    const std::string& tempPath() const { return temp_; }
    const std::string& finalPath() const { return final_; }
    /// Atomically replace finalPath with the temporary file, flushed to disk first (fsync of the
    /// file, then of its directory after the rename). Throws IoError on failure. Then
    /// removes the temporaries of finalPath left by processes that no longer run (killed
    /// before their own commit or cleanup).
    void commit();

private:
    std::string final_;
    std::string temp_;
    bool committed_ = false;
};

/// Write `text` to `path` atomically (reports, Markdown tables); IoError naming the path.
void writeTextFile(const std::string& path, const std::string& text);

/// Create a directory and its parents (no-op if it exists); IoError naming it on failure.
void ensureDirectory(const std::string& dir);

}  // namespace eco
