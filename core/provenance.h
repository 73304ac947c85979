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
void writeProvenance(h5::File& file, const std::vector<ProvenanceEntry>& entries);

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
