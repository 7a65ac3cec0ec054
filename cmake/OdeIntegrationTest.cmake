# ODE integration tests (CTest cases ode_*), run with cmake -P.
#
#   -DSTEP=build: install the build tree BUILD_DIR into WORK_DIR/prefix, then configure and
#                 build the separate project SOURCE_DIR (integrations/ode) against that
#                 prefix alone with find_package(cadmm).
#   -DSTEP=run:   run WORK_DIR/build/PROGRAM (default cadmm_ode_stack) with ARGS (a ;-list)
#                 and require the exit code EXPECT_EXIT (default 0; the driver's --check
#                 exits with 1). With VALGRIND (its path) and SUPPRESSIONS, under memcheck:
#                 any error or definite/possible leak fails.
cmake_minimum_required(VERSION 3.16)

foreach(_var STEP WORK_DIR)
  if(NOT DEFINED ${_var} OR "${${_var}}" STREQUAL "")
    message(FATAL_ERROR "OdeIntegrationTest: -D${_var}=... is required")
  endif()
endforeach()

function(run)
  cmake_parse_arguments(R "" "EXPECT" "COMMAND" ${ARGN})
  if(NOT DEFINED R_EXPECT)
    set(R_EXPECT 0)
  endif()
  string(REPLACE ";" " " _pretty "${R_COMMAND}")
  message(STATUS "[ode] ${_pretty}")
  execute_process(COMMAND ${R_COMMAND} WORKING_DIRECTORY "${WORK_DIR}"
                  RESULT_VARIABLE _rc OUTPUT_VARIABLE _out ERROR_VARIABLE _err)
  message("${_out}${_err}")
  if(NOT "${_rc}" STREQUAL "${R_EXPECT}")
    message(FATAL_ERROR "[ode] exit code ${_rc}, expected ${R_EXPECT}: ${_pretty}")
  endif()
endfunction()

set(PREFIX "${WORK_DIR}/prefix")
if(NOT PROGRAM)
  set(PROGRAM cadmm_ode_stack)
endif()
set(EXE "${WORK_DIR}/build/${PROGRAM}")

if(STEP STREQUAL "build")
  foreach(_var BUILD_DIR SOURCE_DIR C_COMPILER)
    if(NOT DEFINED ${_var} OR "${${_var}}" STREQUAL "")
      message(FATAL_ERROR "OdeIntegrationTest: -D${_var}=... is required for STEP=build")
    endif()
  endforeach()
  file(REMOVE_RECURSE "${WORK_DIR}")
  file(MAKE_DIRECTORY "${WORK_DIR}")
  run(COMMAND "${CMAKE_COMMAND}" --install "${BUILD_DIR}" --prefix "${PREFIX}")
  set(_gen "")
  if(GENERATOR)
    set(_gen -G "${GENERATOR}")
  endif()
  # The prefix alone: no package registry, no system cadmm.
  run(COMMAND "${CMAKE_COMMAND}" -S "${SOURCE_DIR}" -B "${WORK_DIR}/build" ${_gen}
              -DCMAKE_BUILD_TYPE=Release "-DCMAKE_C_COMPILER=${C_COMPILER}"
              "-DCMAKE_PREFIX_PATH=${PREFIX}" -DCMAKE_FIND_USE_PACKAGE_REGISTRY=OFF
              -DCMAKE_FIND_USE_SYSTEM_PACKAGE_REGISTRY=OFF "-DCADMM_ODE_SANITIZE=${SANITIZE}")
  run(COMMAND "${CMAKE_COMMAND}" --build "${WORK_DIR}/build")
  if(NOT EXISTS "${EXE}")
    message(FATAL_ERROR "[ode] the build produced no ${EXE}")
  endif()
elseif(STEP STREQUAL "run")
  if(NOT DEFINED EXPECT_EXIT)
    set(EXPECT_EXIT 0)
  endif()
  set(_wrap "")
  if(VALGRIND)
    set(_wrap "${VALGRIND}" --error-exitcode=99 --leak-check=full
              --errors-for-leak-kinds=definite,possible "--suppressions=${SUPPRESSIONS}")
  endif()
  run(COMMAND ${_wrap} "${EXE}" ${ARGS} EXPECT ${EXPECT_EXIT})
else()
  message(FATAL_ERROR "OdeIntegrationTest: STEP must be build or run, not '${STEP}'")
endif()
