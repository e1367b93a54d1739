# Tests of the runtime infrastructure (profiles, device ledger, memory caps, co-tenant stand-in,
# sample statistics). The co-tenant process test runs build/<dir>/app/zonemap-cotenant; when
# cross-compiling it goes through the emulator (ZM_TEST_EMULATOR), since qemu-user cannot exec
# an aarch64 program directly.
zm_add_test(zm_runtime_infra_test
  SOURCES
    ${CMAKE_CURRENT_LIST_DIR}/profile_test.cc
    ${CMAKE_CURRENT_LIST_DIR}/device_ledger_test.cc
    ${CMAKE_CURRENT_LIST_DIR}/memory_cap_test.cc
    ${CMAKE_CURRENT_LIST_DIR}/cotenant_test.cc
    ${CMAKE_CURRENT_LIST_DIR}/stats_test.cc
  DEPS zm_runtime)
string(REPLACE ";" " " zm_infra_emulator "${CMAKE_CROSSCOMPILING_EMULATOR}")
target_compile_definitions(zm_runtime_infra_test PRIVATE
  ZM_TEST_EMULATOR="${zm_infra_emulator}"
  ZM_TEST_COTENANT_EXE="$<TARGET_FILE:zonemap-cotenant>")
add_dependencies(zm_runtime_infra_test zonemap-cotenant)
