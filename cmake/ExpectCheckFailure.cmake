# A negative control of an integration's --check (CTest), run with cmake -P:
#
#   cmake -DPROGRAM=<driver> -DARGS=<;-list> -DEXPECT=<;-list of regexes>
#         -P ExpectCheckFailure.cmake
#
# Runs PROGRAM with ARGS and passes only when it exits with 1 (the drivers' "check failed"
# code), its output matches every regex of EXPECT (the failed checks' own messages) and
# holds no sanitizer report: a crash, a refused step or another check failing instead does
# not count as the check firing.
cmake_minimum_required(VERSION 3.16)

foreach(_var PROGRAM EXPECT)
  if(NOT DEFINED ${_var} OR "${${_var}}" STREQUAL "")
    message(FATAL_ERROR "ExpectCheckFailure: -D${_var}=... is required")
  endif()
endforeach()

# The lists arrive with their separators escaped (\;), as CTest passed them through.
string(REPLACE "\\;" ";" ARGS "${ARGS}")
string(REPLACE "\\;" ";" EXPECT "${EXPECT}")
string(REPLACE ";" " " _pretty "${PROGRAM} ${ARGS}")
execute_process(COMMAND "${PROGRAM}" ${ARGS} RESULT_VARIABLE _rc OUTPUT_VARIABLE _out
                ERROR_VARIABLE _err)
message("${_out}${_err}")
if(NOT "${_rc}" STREQUAL "1")
  message(FATAL_ERROR "exit code ${_rc}, expected 1 (check failed): ${_pretty}")
endif()
if("${_out}${_err}" MATCHES "Sanitizer|runtime error:")
  message(FATAL_ERROR "a sanitizer report, not the check, failed the run: ${_pretty}")
endif()
foreach(_re IN LISTS EXPECT)
  if(NOT "${_out}${_err}" MATCHES "${_re}")
    message(FATAL_ERROR "the output does not match \"${_re}\": ${_pretty}")
  endif()
endforeach()
message(STATUS "the check fired as expected: ${_pretty}")
