# CTest cases of the ODE integration (integrations/ode), included by the top-level
# CMakeLists.txt after c_tests/ (whose cadmm_test_dependency_missing it uses); the steps
# themselves are in cmake/OdeIntegrationTest.cmake.
#
# ode_integration_build installs this build tree into a prefix and builds the separate
# project integrations/ode against it with find_package(cadmm); the ode_stack_* cases run
# its driver: cadmm on every scene with --check (stacks: nothing falls, top drift below 1 mm;
# slide: the launched box stops where Coulomb's law says; every step solved, every answer
# re-measured by the driver's own error measure within 1e-8, no contact deeper than 1.5 mm),
# the larger scenes (big-pyramid at rest, wall and bin in motion) smaller than their defaults
# at an engine's tolerance of 1e-4, ODE's two solvers once each (they must run),
# ode_vehicle_cadmm (a car on four hinge-2 wheels driven over a bump: every step solved and
# re-measured within 1e-8, all wheels over the bump, no wheel joint opened by 1 cm or
# turned by 0.01 rad), ode_stack_cadmm_chain (20 links on ball joints swinging into a box:
# every step solved and re-measured within 1e-8), and the ode_check_* negative controls: runs where one check must
# fail with its own message (cmake/ExpectCheckFailure.cmake), ODE QuickStep letting the
# 1000:1 stack collapse among them.
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
  # ode_check_fails(<name> EXPECT <regex...> ARGS <args...>): a cadmm_ode_stack run whose
  # --check must fail (exit code 1) with every regex in its output.
  function(ode_check_fails name)
    cmake_parse_arguments(C "" "" "EXPECT;ARGS" ${ARGN})
    string(REPLACE ";" "\\;" _args "${C_ARGS}")
    string(REPLACE ";" "\\;" _expect "${C_EXPECT}")
    add_test(NAME ${name} COMMAND ${CMAKE_COMMAND} "-DPROGRAM=${_ode_work}/build/cadmm_ode_stack"
      "-DARGS=${_args}" "-DEXPECT=${_expect}"
      -P "${PROJECT_SOURCE_DIR}/cmake/ExpectCheckFailure.cmake")
    set_tests_properties(${name} PROPERTIES LABELS "integration;ode" TIMEOUT 120
      FIXTURES_REQUIRED cadmm_ode)
  endfunction()
  ode_run(ode_errors cadmm_ode_errors 0)
  foreach(_scene tower mass-ratio-100 mass-ratio-1000 pyramid)
    ode_stack(cadmm_${_scene} 0 --scene ${_scene} --solver cadmm --seconds 2 --json --check)
  endforeach()
  ode_stack(cadmm_slide 0 --scene slide --solver cadmm --seconds 1.5 --json --check)
  ode_stack(cadmm_cold_tower 0 --scene tower --solver cadmm --seconds 1 --json --check --cold)
  # The larger scenes at 1e-4: every step solved and re-measured within 1e-4; the 120-box
  # pyramid keeps the at-rest checks, the wall (30 bricks, the ball at 1 s) and the bin (64
  # boxes) in motion leave them out.
  ode_stack(cadmm_big_pyramid 0 --scene big-pyramid --solver cadmm --seconds 1 --tolerance 1e-4
            --json --check)
  ode_stack(cadmm_wall 0 --scene wall --count 30 --solver cadmm --seconds 1.5 --tolerance 1e-4
            --json --check)
  if(CADMM_WITH_FCLIB)
    # --dump: two of the wall's steps (at rest, and as the ball hits) written as FCLib files,
    # each read back and the step's answer measured on it as on the step's problem; and the
    # check that fires when a file cannot be written.
    ode_stack(cadmm_wall_dump 0 --scene wall --count 30 --solver cadmm --seconds 1.2
              --tolerance 1e-4 --json --check --dump 20,65 --dump-dir ${_ode_work})
    ode_check_fails(ode_check_catches_dump EXPECT "check failed: 1 dumped steps not written"
      ARGS --scene tower --solver cadmm --seconds 0.2 --check --dump 5
           --dump-dir ${_ode_work}/no-such-directory)
  endif()
  ode_stack(cadmm_bin 0 --scene bin --count 64 --seed 3 --solver cadmm --seconds 1.5
            --tolerance 1e-4 --json --check)
  # The vehicle (integrations/ode/scenes.c): 2 s take all four wheels over the bump (at
  # 1.65 s) and the rear ones through their slip coming off it.
  ode_run(ode_vehicle_cadmm cadmm_ode_stack 0 --scene vehicle --solver cadmm --seconds 2 --json
          --check)
  # The chain (scenes.c): released at rest, it strikes the box at about 1.3 s.
  ode_stack(cadmm_chain 0 --scene chain --solver cadmm --seconds 2 --json --check)
  ode_stack(quickstep_runs 0 --scene pyramid --solver ode-quickstep --seconds 1 --json)
  ode_stack(step_runs 0 --scene mass-ratio-100 --solver ode-step --seconds 1 --json)
  # ODE's joint multipliers recovered from its hinge-2 feedback (stack.c) on the way.
  ode_stack(quickstep_vehicle_runs 0 --scene vehicle --solver ode-quickstep --seconds 2 --json)
  # ... and from the chain's ball joints.
  ode_stack(quickstep_chain_runs 0 --scene chain --solver ode-quickstep --seconds 2 --json)
  ode_check_fails(ode_check_fails_quickstep EXPECT "check failed: a body fell"
    ARGS --scene mass-ratio-1000 --solver ode-quickstep --seconds 2 --json --check)
  # One iteration per step, cold: steps end unsolved (and more fails).
  ode_check_fails(ode_check_catches_unsolved EXPECT "check failed: [0-9]+ cadmm solves ended above"
    ARGS --scene tower --solver cadmm --seconds 0.5 --check --cold --max-iterations 1)
  # Solved to 1e-3, checked at 1e-8: only the re-measured error fails.
  ode_check_fails(ode_check_catches_error
    EXPECT "check failed: re-measured error .* above the check tolerance 1e-08"
    ARGS --scene tower --solver cadmm --seconds 0.5 --check --tolerance 1e-3 --check-tolerance 1e-8)
  # Solved and checked at 0.1, cold: the stack sinks 2 mm.
  ode_check_fails(ode_check_catches_penetration EXPECT "check failed: a contact penetrated"
    ARGS --scene tower --solver cadmm --seconds 0.5 --check --cold --tolerance 0.1
         --check-tolerance 1)
  # The vehicle on ice (mu 0.1): its rear wheels spin, it is 1 m along at 2 s, short of the
  # bump.
  ode_check_fails(ode_check_catches_vehicle_stuck
    EXPECT "check failed: the vehicle did not get over the bump"
    ARGS --scene vehicle --solver cadmm --seconds 2 --check --mu 0.1)
  # The solver given mu 0.45 where the scene's closed form has 0.5: the box slides 15 cm too far.
  ode_check_fails(ode_check_catches_slide EXPECT "check failed: the box slid .* Coulomb's law says"
    ARGS --scene slide --solver cadmm --seconds 1 --check --mu 0.45)
  if(VALGRIND_EXECUTABLE AND CADMM_VALGRIND AND NOT CADMM_SANITIZE)
    ode_run(valgrind_ode_errors cadmm_ode_errors 0 VALGRIND)
    ode_run(valgrind_ode_stack_cadmm cadmm_ode_stack 0 VALGRIND
            --scene tower --solver cadmm --seconds 0.25 --json --check)
    ode_run(valgrind_ode_stack_slide cadmm_ode_stack 0 VALGRIND
            --scene slide --solver cadmm --seconds 1 --json --check)
  endif()
else()
  cadmm_test_dependency_missing("cadmm: ODE (libode-dev, pkg-config module ode) not found: "
                  "the ode_* integration tests are not registered")
endif()
