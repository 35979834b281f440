# Runs a command and checks its exit status and combined output.
#   CMD           the command, arguments separated by |
#   EXPECT_EXIT   zero or nonzero
#   EXPECT_REGEX  must match stdout+stderr (CMake regex; . matches newlines)
#   NO_FILE       optional path that must not exist afterwards
string(REPLACE "|" ";" cmd "${CMD}")
if(NO_FILE)
  file(REMOVE "${NO_FILE}")
endif()
execute_process(COMMAND ${cmd} RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
set(all "${out}${err}")
message("exit status: ${rc}\n--- output ---\n${all}--------------")
if(EXPECT_EXIT STREQUAL "zero" AND NOT rc EQUAL 0)
  message(FATAL_ERROR "expected exit status 0, got ${rc}")
elseif(EXPECT_EXIT STREQUAL "nonzero" AND (rc EQUAL 0 OR NOT rc MATCHES "^[0-9]+$"))
  message(FATAL_ERROR "expected a non-zero exit status (and no crash), got ${rc}")
endif()
if(NOT all MATCHES "${EXPECT_REGEX}")
  message(FATAL_ERROR "output does not match: ${EXPECT_REGEX}")
endif()
if(NO_FILE AND EXISTS "${NO_FILE}")
  message(FATAL_ERROR "${NO_FILE} exists: a failed run must not leave output behind")
endif()
