# CTest cases of the ODE integration (integrations/ode), included by the top-level
# CMakeLists.txt after c_tests/ (whose cadmm_test_dependency_missing it uses); the steps
# themselves are in cmake/OdeIntegrationTest.cmake.
#
# ode_integration_build installs this build tree into a prefix and builds the separate
# project integrations/ode against it with find_package(cadmm); the ode_stack_* cases run
# its driver: cadmm on every scene with --check (nothing falls, top drift below 1 mm, every
# step solved to 1e-8), ODE's two solvers once each (they must run), and one run where the
# check must fail (ODE QuickStep lets the 1000:1 stack collapse).
find_package(PkgConfig QUIET)
if(PKG_CONFIG_FOUND)
  pkg_check_modules(CADMM_ODE QUIET ode)
endif()
if(CADMM_ODE_FOUND)
  set(_ode_work "${CMAKE_BINARY_DIR}/ode_integration")
  set(_ode_script "${PROJECT_SOURCE_DIR}/cmake/OdeIntegrationTest.cmake")
  add_test(NAME ode_integration_build
    COMMAND ${CMAKE_COMMAND} -DSTEP=build "-DBUILD_DIR=${CMAKE_BINARY_DIR}"
      "-DWORK_DIR=${_ode_work}" "-DSOURCE_DIR=${PROJECT_SOURCE_DIR}/integrations/ode"
      "-DC_COMPILER=${CMAKE_C_COMPILER}" "-DGENERATOR=${CMAKE_GENERATOR}"
      "-DSANITIZE=${CADMM_SANITIZE}" -P "${_ode_script}")
  set_tests_properties(ode_integration_build PROPERTIES LABELS "integration;ode" TIMEOUT 600
    FIXTURES_SETUP cadmm_ode)
  # ode_run(<test name> <program> <expected exit code> [VALGRIND] <arguments...>)
  function(ode_run name program expect)
    cmake_parse_arguments(R "VALGRIND" "" "" ${ARGN})
    string(REPLACE ";" "\\;" _args "${R_UNPARSED_ARGUMENTS}")
    set(_memcheck "")
    set(_labels "integration;ode")
    if(R_VALGRIND)
      set(_memcheck "-DVALGRIND=${VALGRIND_EXECUTABLE}"
                    "-DSUPPRESSIONS=${PROJECT_SOURCE_DIR}/cmake/valgrind.supp")
      set(_labels "integration;ode;valgrind")
    endif()
    add_test(NAME ${name}
      COMMAND ${CMAKE_COMMAND} -DSTEP=run "-DWORK_DIR=${_ode_work}" "-DPROGRAM=${program}"
        "-DEXPECT_EXIT=${expect}" "-DARGS=${_args}" ${_memcheck} -P "${_ode_script}")
    set_tests_properties(${name} PROPERTIES LABELS "${_labels}" TIMEOUT 120
      FIXTURES_REQUIRED cadmm_ode)
  endfunction()
  function(ode_stack name expect)
    ode_run(ode_stack_${name} cadmm_ode_stack ${expect} ${ARGN})
  endfunction()
  ode_run(ode_errors cadmm_ode_errors 0)
  foreach(_scene tower mass-ratio-100 mass-ratio-1000 pyramid)
    ode_stack(cadmm_${_scene} 0 --scene ${_scene} --solver cadmm --seconds 2 --json --check)
  endforeach()
  ode_stack(cadmm_cold_tower 0 --scene tower --solver cadmm --seconds 1 --json --check --cold)
  ode_stack(quickstep_runs 0 --scene pyramid --solver ode-quickstep --seconds 1 --json)
  ode_stack(step_runs 0 --scene mass-ratio-100 --solver ode-step --seconds 1 --json)
  ode_stack(check_fails_quickstep 1 --scene mass-ratio-1000 --solver ode-quickstep
            --seconds 2 --json --check)
  if(VALGRIND_EXECUTABLE AND CADMM_VALGRIND AND NOT CADMM_SANITIZE)
    ode_run(valgrind_ode_errors cadmm_ode_errors 0 VALGRIND)
    ode_run(valgrind_ode_stack_cadmm cadmm_ode_stack 0 VALGRIND
            --scene tower --solver cadmm --seconds 0.25 --json --check)
  endif()
else()
  cadmm_test_dependency_missing("cadmm: ODE (libode-dev, pkg-config module ode) not found: "
                  "the ode_* integration tests are not registered")
endif()
