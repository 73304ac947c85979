// Shared by the libFuzzer targets (fuzz/*_fuzz.cpp): the input bytes as a file for readers
// that take a path, and the rule of what counts as a finding.
//
// A reader may refuse any input with eco::Error (IoError, ValidationError): that is the
// documented behaviour, and the target returns. Everything else is a finding that libFuzzer
// reports and saves: a crash, an AddressSanitizer or UndefinedBehaviorSanitizer report, an
// exception of another type escaping (std::bad_alloc, std::out_of_range, toml++'s parse
// error, ...: an internal error, exit code 4 of eco), an allocation above -malloc_limit_mb
// or a process above -rss_limit_mb (a size the memory checks let through), a timeout.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>

#include "error.h"

namespace eco::fuzz {

/// Called from LLVMFuzzerInitialize: one OpenMP thread (libFuzzer runs one input at a time;
/// threads only add noise), and a memory budget for core/memory.h's checks of half the
/// -rss_limit_mb given to libFuzzer (2048 MB when not given, libFuzzer's default), so that
/// sizes the checks should refuse are refused before libFuzzer's own limit is hit.
void initialize(int* argc, char*** argv);

/// Write the input to a file named `name` (e.g. "input.asc": readers dispatch on the
/// extension) in this process's private scratch folder (under /dev/shm when it exists, else
/// TMPDIR or /tmp) and return its path. The folder is removed at exit.
std::string writeInput(const std::uint8_t* data, std::size_t size, const std::string& name);

/// This process's scratch folder (for outputs a reader insists on creating).
const std::string& scratchDir();

/// H5garbage_collect (declared here so that the targets need not include hdf5.h).
void collectHdf5Garbage();

/// Run a reader on one input: eco::Error is a refusal, anything else propagates to libFuzzer.
template <class Reader>
int run(Reader&& reader) {
    try {
        reader();
    } catch (const eco::Error&) {
    }
    return 0;
}

}  // namespace eco::fuzz

namespace eco::fuzz {

/// Whether the HDF5 library itself survives the file: a child process opens it, visits every
/// object and reads every dataset and attribute of up to 64 MB with the HDF5 C API alone.
/// HDF5 1.10.8 (Debian 12) crashes on some damaged files (a SEGV in H5HG_read within seconds
/// of fuzzing), which no reader of ours can prevent; the HDF5 targets skip such inputs so that
/// what they report is in our code. Costs a fork per input.
bool hdf5LibrarySurvives(const std::string& path);

/// Run one HDF5 reader on the input: inputs the HDF5 library cannot walk are skipped (above);
/// afterwards the library's free lists are emptied so that the process's memory (watched by
/// -rss_limit_mb) reflects what our readers keep, not HDF5's caches.
template <class Reader>
int runHdf5(const std::string& path, Reader&& reader) {
    if (!hdf5LibrarySurvives(path)) return 0;
    run(reader);
    collectHdf5Garbage();
    return 0;
}

}  // namespace eco::fuzz
