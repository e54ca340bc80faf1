# Runs one libFuzzer target for SECONDS on the seeds in SEEDS (cmake -P).
# libFuzzer adds the inputs it finds to its first corpus folder, so that is a
# scratch folder (WORK), removed afterwards; SEEDS is only read. A finding
# writes its input to ARTIFACTS (crash-*, leak-*, timeout-*, oom-*) and fails.
foreach(_var FUZZER SEEDS WORK ARTIFACTS SECONDS)
  if(NOT DEFINED ${_var})
    message(FATAL_ERROR "run_fuzzer.cmake: -D${_var}=... is required")
  endif()
endforeach()
file(REMOVE_RECURSE ${WORK})
file(MAKE_DIRECTORY ${WORK} ${ARTIFACTS})
execute_process(COMMAND ${FUZZER} -max_total_time=${SECONDS} -timeout=20 -rss_limit_mb=2048
                        -artifact_prefix=${ARTIFACTS}/ -print_final_stats=1 ${WORK} ${SEEDS}
                RESULT_VARIABLE _result)
file(REMOVE_RECURSE ${WORK})
if(NOT _result EQUAL 0)
  message(FATAL_ERROR "${FUZZER} failed (${_result}); the input is in ${ARTIFACTS}")
endif()
