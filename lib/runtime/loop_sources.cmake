set(ZM_RUNTIME_LOOP_SOURCES
  ${CMAKE_CURRENT_LIST_DIR}/line_protocol.cc
  ${CMAKE_CURRENT_LIST_DIR}/telemetry.cc
  ${CMAKE_CURRENT_LIST_DIR}/frame_source.cc
  ${CMAKE_CURRENT_LIST_DIR}/tick_loop.cc
  ${CMAKE_CURRENT_LIST_DIR}/run.cc
  ${CMAKE_CURRENT_LIST_DIR}/device_run.cc
)
