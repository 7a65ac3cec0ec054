# Install test (CTest case install_consumer), run with cmake -P:
#  1. `cmake --install` the build tree BUILD_DIR into WORK_DIR/prefix;
#  2. check the installed layout (versioned library + symlinks, static library, header,
#     CMake package files, pkg-config file) and the SONAME of the installed library;
#  3. configure, build and test the separate project CONSUMER_SOURCE_DIR with
#     find_package(cadmm CONFIG REQUIRED) against that prefix only;
#  4. check that an incompatible major version is refused (SameMajorVersion);
#  5. check `pkg-config --libs/--cflags/--modversion cadmm` with PKG_CONFIG_PATH pointing
#     into the prefix, and build + run the consumer program with those flags alone.
cmake_minimum_required(VERSION 3.16)

foreach(_var BUILD_DIR WORK_DIR CONSUMER_SOURCE_DIR INSTALL_LIBDIR INSTALL_INCLUDEDIR VERSION
             SHARED_REALNAME SONAME SHARED_LINKNAME STATIC_NAME C_COMPILER)
  if(NOT DEFINED ${_var} OR "${${_var}}" STREQUAL "")
    message(FATAL_ERROR "InstallConsumerTest: -D${_var}=... is required")
  endif()
endforeach()

function(run)
  cmake_parse_arguments(R "" "WORKING_DIRECTORY;OUTPUT" "COMMAND" ${ARGN})
  string(REPLACE ";" " " _pretty "${R_COMMAND}")
  message(STATUS "[install_consumer] ${_pretty}")
  if(NOT R_WORKING_DIRECTORY)
    set(R_WORKING_DIRECTORY "${WORK_DIR}")
  endif()
  execute_process(COMMAND ${R_COMMAND} WORKING_DIRECTORY "${R_WORKING_DIRECTORY}"
                  RESULT_VARIABLE _rc OUTPUT_VARIABLE _out ERROR_VARIABLE _err)
  if(NOT _rc EQUAL 0)
    message(FATAL_ERROR "[install_consumer] command failed (${_rc}): ${_pretty}\n--- stdout\n${_out}\n--- stderr\n${_err}")
  endif()
  if(R_OUTPUT)
    set(${R_OUTPUT} "${_out}" PARENT_SCOPE)
  else()
    message("${_out}")
  endif()
endfunction()

set(PREFIX "${WORK_DIR}/prefix")
file(REMOVE_RECURSE "${WORK_DIR}")
file(MAKE_DIRECTORY "${WORK_DIR}")

# ---- 1. install ---------------------------------------------------------------------------
run(COMMAND "${CMAKE_COMMAND}" --install "${BUILD_DIR}" --prefix "${PREFIX}")

# ---- 2. layout ------------------------------------------------------------------------------
set(_lib "${PREFIX}/${INSTALL_LIBDIR}")
foreach(_f "${_lib}/${SHARED_REALNAME}" "${_lib}/${STATIC_NAME}"
           "${PREFIX}/${INSTALL_INCLUDEDIR}/cadmm.h"
           "${_lib}/cmake/cadmm/cadmmConfig.cmake"
           "${_lib}/cmake/cadmm/cadmmConfigVersion.cmake"
           "${_lib}/cmake/cadmm/cadmmTargets.cmake"
           "${_lib}/pkgconfig/cadmm.pc")
  if(NOT EXISTS "${_f}")
    message(FATAL_ERROR "[install_consumer] not installed: ${_f}")
  endif()
endforeach()
if(IS_SYMLINK "${_lib}/${SHARED_REALNAME}")
  message(FATAL_ERROR "[install_consumer] ${SHARED_REALNAME} must be a regular file")
endif()
foreach(_link "${SONAME}" "${SHARED_LINKNAME}")
  if(NOT IS_SYMLINK "${_lib}/${_link}")
    message(FATAL_ERROR "[install_consumer] ${_lib}/${_link} is not a symlink")
  endif()
  file(READ_SYMLINK "${_lib}/${_link}" _target)
  if(NOT _target STREQUAL SHARED_REALNAME)
    message(FATAL_ERROR "[install_consumer] ${_link} -> ${_target}, expected -> ${SHARED_REALNAME}")
  endif()
endforeach()
run(COMMAND "${CMAKE_COMMAND}" "-DLIBRARY=${_lib}/${SHARED_REALNAME}" "-DEXPECTED_SONAME=${SONAME}"
            "-DREADELF=${READELF}" "-DOBJDUMP=${OBJDUMP}"
            -P "${CMAKE_CURRENT_LIST_DIR}/CheckSoname.cmake")

# ---- 3. consumer project through find_package -------------------------------------------
set(_cbuild "${WORK_DIR}/consumer-build")
set(_gen_args "")
if(GENERATOR)
  set(_gen_args -G "${GENERATOR}")
endif()
run(COMMAND "${CMAKE_COMMAND}" -S "${CONSUMER_SOURCE_DIR}" -B "${_cbuild}" ${_gen_args}
            "-DCMAKE_C_COMPILER=${C_COMPILER}" -DCMAKE_BUILD_TYPE=Release
            "-DCMAKE_PREFIX_PATH=${PREFIX}" "-DCADMM_EXPECTED_PREFIX=${PREFIX}"
            "-DCADMM_EXPECTED_VERSION=${VERSION}"
            -DCMAKE_FIND_USE_PACKAGE_REGISTRY=OFF -DCMAKE_FIND_USE_SYSTEM_PACKAGE_REGISTRY=OFF)
run(COMMAND "${CMAKE_COMMAND}" --build "${_cbuild}")
if(NOT CMAKE_CTEST_COMMAND)
  get_filename_component(_bindir "${CMAKE_COMMAND}" DIRECTORY)
  set(CMAKE_CTEST_COMMAND "${_bindir}/ctest")
endif()
run(COMMAND "${CMAKE_CTEST_COMMAND}" --output-on-failure WORKING_DIRECTORY "${_cbuild}")

# The consumer linked against the SONAME, not the unversioned name or a build path.
if(READELF)
  file(GLOB _exe "${_cbuild}/consumer_shared" "${_cbuild}/*/consumer_shared")
  list(GET _exe 0 _exe)
  run(COMMAND "${READELF}" -d "${_exe}" OUTPUT _dyn)
  if(NOT _dyn MATCHES "\\(NEEDED\\)[^\n]*\\[${SONAME}\\]")
    message(FATAL_ERROR "[install_consumer] consumer_shared does not need ${SONAME}:\n${_dyn}")
  endif()
endif()

# ---- 4. an incompatible major version is refused ----------------------------------------
string(REGEX MATCH "^[0-9]+" _major "${VERSION}")
math(EXPR _next_major "${_major} + 1")
set(_vdir "${WORK_DIR}/version-check")
file(MAKE_DIRECTORY "${_vdir}")
file(WRITE "${_vdir}/CMakeLists.txt" "
cmake_minimum_required(VERSION 3.16)
project(cadmm_version_check C)
find_package(cadmm ${_next_major}.0 CONFIG QUIET)
if(cadmm_FOUND)
  message(FATAL_ERROR \"cadmm ${VERSION} was accepted for a request of version ${_next_major}.0\")
endif()
find_package(cadmm ${_major}.0 CONFIG REQUIRED)
message(STATUS \"version check: found cadmm \${cadmm_VERSION}, ${_next_major}.0 refused\")
")
run(COMMAND "${CMAKE_COMMAND}" -S "${_vdir}" -B "${_vdir}/build" "-DCMAKE_PREFIX_PATH=${PREFIX}")

# ---- 5. pkg-config --------------------------------------------------------------------------
if(NOT PKG_CONFIG)
  message(FATAL_ERROR "[install_consumer] pkg-config not found: cannot check cadmm.pc")
endif()
set(ENV{PKG_CONFIG_PATH} "${_lib}/pkgconfig")
unset(ENV{PKG_CONFIG_LIBDIR})
run(COMMAND "${PKG_CONFIG}" --modversion cadmm OUTPUT _pc_version)
string(STRIP "${_pc_version}" _pc_version)
if(NOT _pc_version STREQUAL VERSION)
  message(FATAL_ERROR "[install_consumer] pkg-config --modversion cadmm = '${_pc_version}', expected ${VERSION}")
endif()
run(COMMAND "${PKG_CONFIG}" --libs cadmm OUTPUT _pc_libs)
run(COMMAND "${PKG_CONFIG}" --cflags cadmm OUTPUT _pc_cflags)
string(STRIP "${_pc_libs}" _pc_libs)
string(STRIP "${_pc_cflags}" _pc_cflags)
message(STATUS "[install_consumer] pkg-config --libs cadmm: ${_pc_libs}")
message(STATUS "[install_consumer] pkg-config --cflags cadmm: ${_pc_cflags}")
if(NOT _pc_libs MATCHES "(^| )-lcadmm( |$)")
  message(FATAL_ERROR "[install_consumer] pkg-config --libs cadmm lacks -lcadmm: ${_pc_libs}")
endif()
if(NOT _pc_libs MATCHES "(^| )-L([^ ]+)")
  message(FATAL_ERROR "[install_consumer] pkg-config --libs cadmm has no -L: ${_pc_libs}")
endif()
get_filename_component(_pc_libdir "${CMAKE_MATCH_2}" REALPATH)
get_filename_component(_want_libdir "${_lib}" REALPATH)
if(NOT _pc_libdir STREQUAL _want_libdir)
  message(FATAL_ERROR "[install_consumer] pkg-config -L points to ${_pc_libdir}, expected ${_want_libdir}")
endif()
if(NOT _pc_cflags MATCHES "-I([^ ]+)")
  message(FATAL_ERROR "[install_consumer] pkg-config --cflags cadmm has no -I: ${_pc_cflags}")
endif()
get_filename_component(_pc_incdir "${CMAKE_MATCH_1}" REALPATH)
get_filename_component(_want_incdir "${PREFIX}/${INSTALL_INCLUDEDIR}" REALPATH)
if(NOT _pc_incdir STREQUAL _want_incdir)
  message(FATAL_ERROR "[install_consumer] pkg-config -I points to ${_pc_incdir}, expected ${_want_incdir}")
endif()

# Build the consumer program with the pkg-config flags alone and run it.
separate_arguments(_cflags_list UNIX_COMMAND "${_pc_cflags}")
separate_arguments(_libs_list UNIX_COMMAND "${_pc_libs}")
set(_pc_exe "${WORK_DIR}/consumer_pkgconfig")
run(COMMAND "${C_COMPILER}" -std=c11 -Wall -Wextra -Werror ${_cflags_list}
            "${CONSUMER_SOURCE_DIR}/main.c" -o "${_pc_exe}" ${_libs_list}
            "-Wl,-rpath,${_lib}" -lm)
run(COMMAND "${_pc_exe}")
message(STATUS "[install_consumer] all install checks passed")
