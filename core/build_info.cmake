# Writes build_info.cpp (the git commit of the sources, core/build_info.h) at every build, but
# replaces the file only when its text changes: a new commit recompiles that one source and
# relinks; nothing else is rebuilt. Run as cmake -DSOURCE_DIR=... -DIN=... -DOUT=...
# -DPROJECT_VERSION=... -P build_info.cmake.
set(ECO_GIT_COMMIT "unknown")
find_package(Git QUIET)
if(GIT_FOUND)
  execute_process(COMMAND "${GIT_EXECUTABLE}" describe --always --dirty
                  WORKING_DIRECTORY "${SOURCE_DIR}"
                  OUTPUT_VARIABLE described OUTPUT_STRIP_TRAILING_WHITESPACE
                  RESULT_VARIABLE status ERROR_QUIET)
  if(status EQUAL 0 AND NOT described STREQUAL "")
    set(ECO_GIT_COMMIT "${described}")
  endif()
endif()
configure_file("${IN}" "${OUT}.tmp" @ONLY)
file(COPY_FILE "${OUT}.tmp" "${OUT}" ONLY_IF_DIFFERENT)
file(REMOVE "${OUT}.tmp")
