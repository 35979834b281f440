# Runs a command and checks its exit status and combined output.
#   CMD           the command, arguments separated by |
#   EXPECT_EXIT   zero or nonzero
#   EXPECT_REGEX  must match stdout+stderr (CMake regex; . matches newlines)
#   NO_FILE       optional path that must not exist afterwards
#   FILE_GLOB     optional glob that must match a file afterwards
#   NO_GLOB       optional glob that must match nothing afterwards
#   PRE           optional shell command run first (e.g. to clear a folder)
#   LIMIT_FILE_KB optional file-size limit (ulimit -f) for the command
string(REPLACE "|" ";" cmd "${CMD}")
if(NO_FILE)
  file(REMOVE "${NO_FILE}")
endif()
if(PRE)
  execute_process(COMMAND sh -c "${PRE}")
endif()
if(LIMIT_FILE_KB)
  # ulimit -f counts 512-byte blocks in POSIX sh's default mode on dash/bash.
  math(EXPR _blocks "${LIMIT_FILE_KB} * 2")
  execute_process(COMMAND sh -c "ulimit -f ${_blocks} && exec \"$@\"" sh ${cmd}
    RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
else()
  execute_process(COMMAND ${cmd} RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
endif()
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
if(FILE_GLOB)
  file(GLOB _found "${FILE_GLOB}")
  if(NOT _found)
    message(FATAL_ERROR "no file matches ${FILE_GLOB}")
  endif()
endif()
if(NO_GLOB)
  file(GLOB _found "${NO_GLOB}")
  if(_found)
    message(FATAL_ERROR "files left behind: ${_found}")
  endif()
endif()
