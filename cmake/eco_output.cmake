# cmake -DECO=path/to/eco "-DARGS=a;b" -DOUT=file -P eco_output.cmake: runs eco with ARGS and
# writes its standard output to OUT, replacing it only when the run succeeded (a failed run
# leaves no half-written file and fails the build).
execute_process(COMMAND ${ECO} --quiet ${ARGS} OUTPUT_VARIABLE text RESULT_VARIABLE status)
if(NOT status EQUAL 0)
  message(FATAL_ERROR "eco ${ARGS} failed (${status})")
endif()
file(WRITE ${OUT}.tmp "${text}")
file(RENAME ${OUT}.tmp ${OUT})
