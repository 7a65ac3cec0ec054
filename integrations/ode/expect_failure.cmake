# A negative control of cadmm_ode_joints (CTest), run with cmake -P:
#
#   cmake -DPROGRAM=<program> -DARGS=<;-list> -DEXPECT=<;-list of regexes>
#         -P expect_failure.cmake
#
# Passes only when PROGRAM exits with 1 (its "check failed" code), its output matches every
# regex of EXPECT (the failed check's own message) and holds no sanitizer report: a crash,
# a refused step or another failure does not count as the check firing. (The top-level
# project's cmake/ExpectCheckFailure.cmake does the same for the stack driver; this
# project stands alone.)
cmake_minimum_required(VERSION 3.16)

foreach(_var PROGRAM EXPECT)
  if(NOT DEFINED ${_var} OR "${${_var}}" STREQUAL "")
    message(FATAL_ERROR "expect_failure: -D${_var}=... is required")
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
