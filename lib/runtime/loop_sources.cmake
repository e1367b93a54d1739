set(ZM_RUNTIME_LOOP_SOURCES
  ${CMAKE_CURRENT_LIST_DIR}/line_protocol.cc
  ${CMAKE_CURRENT_LIST_DIR}/telemetry.cc
)
