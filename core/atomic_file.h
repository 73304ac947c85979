// Write-then-rename: an output file appears complete or not at all; the outputs of one
// command appear together (AtomicOutputSet); what killed writers left behind is cleaned up.
#pragma once

#include <string>
#include <vector>

namespace eco {

/// Hands out a temporary path beside `finalPath`; commit() renames it into place, and the
/// destructor removes the temporary when commit() was never reached (an error was thrown).
/// The constructor first cleans up after dead writers of finalPath (cleanUpAfterDeadWriters).
/// While an AtomicOutputSet is open on this thread, commit() only flushes the finished
/// temporary and hands it to the set, which renames all its files together.
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
    /// A named point for the kill tests (testPausePoint "write:<file name>"): writers call it
    /// with their temporary open and partly written.
    void midWritePoint() const;

private:
    std::string final_;
    std::string temp_;
    bool committed_ = false;
};

/// The outputs of one command committed as a set. While the set is open (from construction
/// to commit() or destruction) on this thread, every AtomicOutput committed on the thread is
/// only flushed and kept under its temporary name. commit() then writes a journal beside the
/// first file (`.<first name>.set<pid>`: every temporary and its final path, ended by a line
/// `end`), flushes it, renames the files in the order they were written and removes the
/// journal. A process killed between the renames leaves the journal: the set is then
/// incomplete (some files new, some old), and the next writer of the first file (any eco
/// command that writes it, at its start) completes it from the journal: every temporary is
/// whole, so finishing the renames gives exactly the set the dead process meant to commit.
/// Killed before the journal was complete, the set is dropped: the old files stay, the
/// temporaries are removed as a dead writer's. Destroyed without commit(): the temporaries
/// are removed. Sets nest (the inner one commits into nothing but its own files).
class AtomicOutputSet {
public:
    AtomicOutputSet();
    AtomicOutputSet(const AtomicOutputSet&) = delete;
    AtomicOutputSet& operator=(const AtomicOutputSet&) = delete;
    ~AtomicOutputSet();

    /// Rename every file of the set into place (see the class comment). IoError on failure.
    void commit();
    /// Where a file of the set can be read before commit(): its finished temporary when the set
    /// holds it, else `finalPath` itself.
    std::string readablePath(const std::string& finalPath) const;
    /// The final paths of the files the set holds, in commit order.
    std::vector<std::string> finalPaths() const;

private:
    friend class AtomicOutput;
    struct Member {
        std::string temp, final;
    };
    void adopt(const std::string& temp, const std::string& final);

    std::vector<Member> members_;
    AtomicOutputSet* outer_ = nullptr;
    bool committed_ = false;
};

/// Clean up after writers of `finalPath` that no longer run (killed; the process id is in the
/// temporary's name and is checked on this machine): completes their set commits that were
/// interrupted between renames (a journal `.<name>.set<pid>` beside finalPath that is
/// complete), drops incomplete journals and removes their temporaries `.<name>.tmp<pid>`
/// (checkpoints can be gigabytes), and the image writers' `.<name>.tmp<pid>.<ext>`. Never
/// fails: anything unexpected is left alone. Commands call it for their outputs before they
/// start work; AtomicOutput calls it too.
void cleanUpAfterDeadWriters(const std::string& finalPath);
/// The same for every file in the directory `dir` (directories of pictures); no-op when the
/// directory does not exist.
void cleanUpDirectoryAfterDeadWriters(const std::string& dir);

/// Test-only seam of the kill tests (tests/kill_test.cpp): when the environment variable
/// ECO_TEST_PAUSE_AT is `point` or `point#n`, the process stops itself (SIGSTOP) the n-th
/// time (default the first) it reaches `point`, so that a test can SIGKILL it exactly there.
/// Points: `write:<file name>` (a temporary partly written: AtomicOutput::midWritePoint),
/// `commit:<file name>` (the temporary complete, not yet flushed or renamed) and
/// `rename:<file name>` (a set's journal written, that file not yet renamed). Without the
/// variable this is one cached getenv.
void testPausePoint(const std::string& point);

/// Write `text` to `path` atomically (reports, Markdown tables); IoError naming the path.
void writeTextFile(const std::string& path, const std::string& text);
/// The whole of a small text file (stamps, configurations, reports); "" when it does not
/// exist or cannot be read (callers compare it with what they expect).
std::string readTextFile(const std::string& path);

/// Create a directory and its parents (no-op if it exists); IoError naming it on failure.
void ensureDirectory(const std::string& dir);

}  // namespace eco
