# cmake -D PROBE=<gtest_main_probe> -P gtest_main_exit_codes.cmake: the test main's exit codes.
# Pass: 0; pass + skip: 77 (ctest: skipped); pass + skip + fail: 1 (ctest: failed, not skipped).
foreach(pair "Probe.Passes=0" "Probe.Passes:Probe.Skips=77" "Probe.Passes:Probe.Skips:Probe.Fails=1"
             "Probe.Skips=77")
  string(REPLACE "=" ";" pair "${pair}")
  list(GET pair 0 filter)
  list(GET pair 1 want)
  execute_process(COMMAND ${PROBE} --gtest_filter=${filter} RESULT_VARIABLE got OUTPUT_QUIET ERROR_QUIET)
  if(NOT got STREQUAL want)
    message(FATAL_ERROR "FAIL: --gtest_filter=${filter} exited ${got}, expected ${want}")
  endif()
  message(STATUS "--gtest_filter=${filter}: exit ${got}")
endforeach()
