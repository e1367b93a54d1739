# The example robot (examples/robot/robot.py) and the short soak (scripts/soak.py), run by ctest
# against the zonemapd just built (under qemu-aarch64 in a cross build), on a small scenario the
# built `zonemap sim` generates first (a test fixture). Included from tests/app/CMakeLists.txt.
# Without python3 they are reported as skipped (return code 77), never as passed.
find_package(Python3 COMPONENTS Interpreter QUIET)
set(ZM_ROBOT_TESTS robot_example_pipe robot_example_udp zonemapd_soak_short)
if(NOT Python3_Interpreter_FOUND)
  foreach(t ${ZM_ROBOT_TESTS})
    add_test(NAME ${t} COMMAND sh -c
      "echo 'SKIPPED: python3 not found: the example robot and the soak need it (apt-get install python3)'; exit 77")
    set_tests_properties(${t} PROPERTIES SKIP_RETURN_CODE 77 LABELS app)
  endforeach()
  return()
endif()

set(ZM_ROBOT_EMULATOR "")
if(CMAKE_CROSSCOMPILING AND CMAKE_CROSSCOMPILING_EMULATOR)
  list(JOIN CMAKE_CROSSCOMPILING_EMULATOR " " ZM_ROBOT_EMULATOR)
endif()
# Dense keyframes at 2 % of the device's footprint (about 90 x 68 pixels): the features, poses,
# zones and the protocol are those of a full-size map, but a zone load decodes in microseconds,
# not the ~8 ms a 640 x 480 keyframe takes, so the tests (and the short soak under ASan or qemu)
# stay within minutes. The example is a host with its own front-end (it sends `frame` lines with
# features), and 90 x 68 pixels leave ORB nothing: the oracle's features, named (issue 26).
set(ZM_ROBOT_SCENARIO ${CMAKE_CURRENT_BINARY_DIR}/robot_scenario)
add_test(NAME robot_example_scenario COMMAND sh -c
  "rm -rf '${ZM_ROBOT_SCENARIO}' && ${ZM_ROBOT_EMULATOR} '$<TARGET_FILE:zonemap>' sim hospital --seed 3 --area 300 --tasks 2 --footprint-scale 0.02 --features oracle --quiet --out '${ZM_ROBOT_SCENARIO}' > /dev/null")
# COST (here and below): ctest -j starts the long tests first, so the last minutes of a run are
# not one long test on one core while the other has nothing left (cmake/ZmTestChunks.cmake).
set_tests_properties(robot_example_scenario PROPERTIES FIXTURES_SETUP zm_robot_scenario
  LABELS app TIMEOUT 900 COST 100)

# MemoryThr 120 of the scenario's keyframes: zones are loaded and evicted along the patrol.
foreach(transport pipe udp)
  add_test(NAME robot_example_${transport} COMMAND ${Python3_EXECUTABLE}
    ${PROJECT_SOURCE_DIR}/examples/robot/robot.py --zonemapd $<TARGET_FILE:zonemapd>
    --scenario ${ZM_ROBOT_SCENARIO} --memory-thr 120 --transport ${transport} --check
    --emulator "${ZM_ROBOT_EMULATOR}")
  set_tests_properties(robot_example_${transport} PROPERTIES
    FIXTURES_REQUIRED zm_robot_scenario LABELS app TIMEOUT 900 COST 100)
endforeach()

# The soak's short version: the real daemon through the line protocol, resident <= K_max on every
# pose line, budgets lowered and raised, insane lines counted by reason (scripts/soak.py, levers
# every 1,000 ticks). RSS is reported, not checked: a few thousand ticks are still warm-up, and
# under ASan the allocator is ASan's; the 1,000,000-tick Release run in docs/reliability.md is
# the flat-memory proof.
if(CMAKE_CROSSCOMPILING)
  set(ZM_SOAK_TICKS 1000)
else()
  set(ZM_SOAK_TICKS 2000)
endif()
add_test(NAME zonemapd_soak_short COMMAND ${Python3_EXECUTABLE}
  ${PROJECT_SOURCE_DIR}/scripts/soak.py --zonemapd $<TARGET_FILE:zonemapd>
  --scenario ${ZM_ROBOT_SCENARIO} --ticks ${ZM_SOAK_TICKS} --period 1000 --memory-thr 120
  --no-rss-check --out ${CMAKE_CURRENT_BINARY_DIR}/soak_short --emulator "${ZM_ROBOT_EMULATOR}")
set_tests_properties(zonemapd_soak_short PROPERTIES
  FIXTURES_REQUIRED zm_robot_scenario LABELS app TIMEOUT 1200 COST 100)
