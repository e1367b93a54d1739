zm_add_test(zm_runtime_loop_test
  SOURCES ${CMAKE_CURRENT_LIST_DIR}/line_protocol_test.cc ${CMAKE_CURRENT_LIST_DIR}/telemetry_test.cc
          ${CMAKE_CURRENT_LIST_DIR}/tick_loop_test.cc
  DEPS zm_runtime)
