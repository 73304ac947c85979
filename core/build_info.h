// What the running binary was built from: its version and the git commit of its sources.
// Defined in one generated source (build_info.cpp.in, configured at CMake time), so that a new
// commit recompiles that file only, never the code that includes this header.
#pragma once

namespace eco {

/// The project version (CMake's PROJECT_VERSION, as eco --version prints).
const char* codeVersion();
/// `git describe --always --dirty` of the source tree when CMake last configured the build
/// ("unknown" when the sources were not a git checkout or git was missing).
const char* gitCommit();

}  // namespace eco
