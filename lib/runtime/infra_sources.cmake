# Runtime infrastructure (docs/runtime-infra.md): device profiles, device ledger, process memory
# caps, the co-tenant stand-in and sample statistics. Included by lib/runtime/CMakeLists.txt.
set(ZM_RUNTIME_INFRA_SOURCES
  ${CMAKE_CURRENT_LIST_DIR}/profile.cc
  ${CMAKE_CURRENT_LIST_DIR}/device_ledger.cc
  ${CMAKE_CURRENT_LIST_DIR}/memory_cap.cc
  ${CMAKE_CURRENT_LIST_DIR}/cotenant.cc
  ${CMAKE_CURRENT_LIST_DIR}/stats.cc)
# Bare profile names resolve here first when $ZM_PROFILES_DIR is unset (profile.h).
set_source_files_properties(${CMAKE_CURRENT_LIST_DIR}/profile.cc PROPERTIES
  COMPILE_DEFINITIONS "ZM_PROFILES_DIR=\"${PROJECT_SOURCE_DIR}/profiles\"")
