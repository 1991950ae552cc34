# Runs CMD with ARGS ('|'-separated); fails unless the exit code is EXPECT and, when MATCH is set,
# stderr matches it (the message names the problem).
string(REPLACE "|" ";" _args "${ARGS}")
execute_process(COMMAND ${CMD} ${_args} RESULT_VARIABLE _rc OUTPUT_QUIET ERROR_VARIABLE _err)
if(NOT _rc EQUAL EXPECT)
  message(FATAL_ERROR "exit code ${_rc}, expected ${EXPECT}; stderr: ${_err}")
endif()
if(DEFINED MATCH AND NOT _err MATCHES "${MATCH}")
  message(FATAL_ERROR "stderr does not match '${MATCH}': ${_err}")
endif()
message(STATUS "exit code ${_rc} as expected; stderr: ${_err}")
