# The install test (issue 31 item 7; CTest install_package): cmake --install of this build into
# a fresh prefix, then a program of one's own (consumer/) configured with find_package(eco)
# against that prefix alone, built and run; and the man page and completion installed where
# man and bash-completion look.
#   cmake -DBUILD=<build dir> -DSOURCE=<source dir> -DWORK=<scratch dir> -DECO=<eco> -P run.cmake
file(REMOVE_RECURSE ${WORK})
set(prefix ${WORK}/prefix)
function(run)
  execute_process(COMMAND ${ARGN} RESULT_VARIABLE status OUTPUT_VARIABLE out ERROR_VARIABLE err)
  if(NOT status EQUAL 0)
    string(REPLACE ";" " " line "${ARGN}")
    message(FATAL_ERROR "failed (${status}): ${line}\n${out}\n${err}")
  endif()
  set(out "${out}" PARENT_SCOPE)
  set(err "${err}" PARENT_SCOPE)
endfunction()

run(${CMAKE_COMMAND} --install ${BUILD} --prefix ${prefix})
foreach(f bin/eco share/man/man1/eco.1 share/bash-completion/completions/eco lib/cmake/eco/ecoConfig.cmake
          lib/cmake/eco/ecoConfigVersion.cmake include/eco/biome.h include/eco/eco_version.h include/eco/sim_config.h
          lib/libeco_core.a lib/libeco_validate.a lib/eco/eco_oiio.so lib/eco/eco_gdal.so share/doc/eco/LICENSE share/doc/eco/CITATION.cff)
  if(NOT EXISTS ${prefix}/${f})
    message(FATAL_ERROR "cmake --install did not install ${f}")
  endif()
endforeach()
if(EXISTS ${prefix}/include/eco/scenario_context.h)
  message(FATAL_ERROR "a private header of validate/scenarios was installed")
endif()

# The consumer sees only the installed prefix (and Debian's packages), not this build.
run(${CMAKE_COMMAND} -S ${SOURCE}/tests/install/consumer -B ${WORK}/consumer -DCMAKE_BUILD_TYPE=Release
    -DCMAKE_PREFIX_PATH=${prefix} -DCMAKE_FIND_USE_PACKAGE_REGISTRY=OFF)
run(${CMAKE_COMMAND} --build ${WORK}/consumer)
# The consumer draws a PNG: OpenImageIO's plugin is found through ECO_PLUGIN_DIR, as
# docs/install.md says for an install outside the prefix eco was configured with.
run(${CMAKE_COMMAND} -E env ECO_PLUGIN_DIR=${prefix}/lib/eco ${WORK}/consumer/consumer ${WORK}/consumer.png)
set(consumer_out "${out}")
if(NOT EXISTS ${WORK}/consumer.png)
  message(FATAL_ERROR "the consumer wrote no PNG:\n${consumer_out}")
endif()
# The installed eco finds the installed plugin next to itself (../lib/eco), not the build's.
run(${CMAKE_COMMAND} -E env --unset=ECO_PLUGIN_DIR LD_DEBUG=files ${prefix}/bin/eco terrain generate --width 8 --height 8
    --out ${WORK}/t.png)
if(NOT err MATCHES "file=${prefix}/lib/eco/eco_oiio.so")
  message(FATAL_ERROR "the installed eco did not load the installed plugin ${prefix}/lib/eco/eco_oiio.so:\n${err}")
endif()
run(${prefix}/bin/eco --version)
string(REGEX MATCH "[0-9]+\\.[0-9]+\\.[0-9]+" version "${out}")
if(NOT consumer_out MATCHES "version ${version}\n")
  message(FATAL_ERROR "the consumer reports another version than eco ${version}:\n${consumer_out}")
endif()
# The embedded biome as eco prints it: its name and species count must be what the library gave.
run(${prefix}/bin/eco biome show)
string(REGEX MATCHALL "\n\\[\\[species\\]\\]" species "${out}")
list(LENGTH species count)
if(NOT consumer_out MATCHES "species ${count}\n" OR count LESS 2)
  message(FATAL_ERROR "the consumer's species count differs from eco biome show's ${count}:\n${consumer_out}")
endif()
message(STATUS "installed and used from ${prefix}:\n${consumer_out}")
