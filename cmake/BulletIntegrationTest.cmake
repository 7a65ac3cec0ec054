# Build step of the Bullet integration tests (CTest case bullet_build), run with cmake -P:
#  1. `cmake --install` the build tree BUILD_DIR into WORK_DIR/prefix;
#  2. configure and build the separate project SOURCE_DIR (integrations/bullet) against that
#     prefix only, with find_package(cadmm CONFIG REQUIRED), into WORK_DIR/build.
# The bullet_* test cases then run WORK_DIR/build/cadmm_bullet_stack.
cmake_minimum_required(VERSION 3.16)

foreach(_var BUILD_DIR WORK_DIR SOURCE_DIR CXX_COMPILER)
  if(NOT DEFINED ${_var} OR "${${_var}}" STREQUAL "")
    message(FATAL_ERROR "BulletIntegrationTest: -D${_var}=... is required")
  endif()
endforeach()

function(run)
  string(REPLACE ";" " " _pretty "${ARGN}")
  message(STATUS "[bullet_build] ${_pretty}")
  execute_process(COMMAND ${ARGN} RESULT_VARIABLE _rc OUTPUT_VARIABLE _out ERROR_VARIABLE _err)
  if(NOT _rc EQUAL 0)
    message(FATAL_ERROR "[bullet_build] command failed (${_rc}): ${_pretty}\n--- stdout\n${_out}\n--- stderr\n${_err}")
  endif()
endfunction()

set(_prefix "${WORK_DIR}/prefix")
file(REMOVE_RECURSE "${_prefix}")
run("${CMAKE_COMMAND}" --install "${BUILD_DIR}" --prefix "${_prefix}")

set(_gen_args "")
if(GENERATOR)
  set(_gen_args -G "${GENERATOR}")
endif()
run("${CMAKE_COMMAND}" -S "${SOURCE_DIR}" -B "${WORK_DIR}/build" ${_gen_args}
    "-DCMAKE_CXX_COMPILER=${CXX_COMPILER}" -DCMAKE_BUILD_TYPE=Release
    "-DCMAKE_PREFIX_PATH=${_prefix}"
    -DCMAKE_FIND_USE_PACKAGE_REGISTRY=OFF -DCMAKE_FIND_USE_SYSTEM_PACKAGE_REGISTRY=OFF
    "-DCADMM_BULLET_SANITIZE=${SANITIZE}")
run("${CMAKE_COMMAND}" --build "${WORK_DIR}/build")
message(STATUS "[bullet_build] built ${WORK_DIR}/build/cadmm_bullet_stack")
