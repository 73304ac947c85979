// Provenance: what a file records about how it was made (wall times, thread counts, dates,
// whether a run was resumed) rather than what it holds. These values are measured, not
// computed, so they differ between two runs of the same inputs and seed; every writer keeps
// them in one group, /provenance (attributes only), that comparison tools skip. Everything
// else in a file is a function of the inputs and the seed alone, byte for byte, whatever
// the thread count (docs/hdf5.md).
//
// `eco --no-provenance` turns the group off for a process, so that two runs write
// byte-identical files.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <variant>
#include <vector>

#include "h5io.h"

namespace eco {

/// The group of every file that holds the run's measured values.
inline constexpr const char* kProvenanceGroup = "/provenance";

/// Whether writers record provenance (true unless turned off). Process-wide, as the
/// OpenMP thread count is: set it once, before any output is written.
void setProvenanceRecorded(bool recorded);
bool provenanceRecorded();

/// One provenance attribute: its name and value (seconds, a count, a date, or an array).
struct ProvenanceEntry {
    std::string name;
    std::variant<double, std::int64_t, std::string, std::vector<double>> value;
};

/// Write /provenance with `entries` and a note saying what the group is, when provenance is
/// recorded; write nothing otherwise. Call on the writing thread, after the other objects.
/// Every group also gets what identifies the run (docs/hdf5.md "Provenance"): code_version,
/// git_commit, command_line (and stage_command inside eco run), and the input files the
/// command read with their FNV-1a 64-bit hashes (input_files, input_fnv1a64).
void writeProvenance(h5::File& file, const std::vector<ProvenanceEntry>& entries);

/// The command line of this process (argv joined with spaces, arguments with spaces or
/// quotes quoted as a shell would need), recorded in /provenance. Set once in main().
void setCommandLine(int argc, const char* const* argv);
std::string processCommandLine();

/// Inside eco run: the command of the stage being run (empty outside a stage). Recorded as
/// /provenance `stage_command`; starting a stage also forgets the input files noted so far,
/// so that each stage's files list what that stage read.
void beginStage(const std::string& stageCommand);

/// Note that the command read the file at `path` (an input of whatever it writes next):
/// its path and the FNV-1a 64-bit hash of its bytes are recorded in /provenance. Each path
/// once, in the order first read; nothing is hashed when provenance is off.
void noteInputFile(const std::string& path);
/// The input files noted so far, with their hashes as 16 hex digits.
std::vector<std::pair<std::string, std::string>> inputFiles();

/// FNV-1a 64-bit hash of a file's bytes as 16 hex digits; "unreadable" when it cannot be read.
std::string fnv1a64OfFile(const std::string& path);

/// A number from /provenance, or from the root attribute `legacyRootAttr` of a file written
/// before the group existed (when non-empty); nullopt when neither is there.
std::optional<double> readProvenanceDouble(const h5::File& file, const std::string& name,
                                           const std::string& legacyRootAttr = "");
/// A string from /provenance (or the legacy root attribute); nullopt when neither is there.
std::optional<std::string> readProvenanceString(const h5::File& file, const std::string& name,
                                                const std::string& legacyRootAttr = "");

/// Current UTC time in ISO 8601 ("2026-01-31T12:00:00Z"): for provenance only.
std::string utcTimestamp();

}  // namespace eco
