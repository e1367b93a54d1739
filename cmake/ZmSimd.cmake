# Compile-time kernel choice (docs/style.md §7): NEON on aarch64 unless ZM_FORCE_SCALAR.
# ZM_SIMD_NEON reaches the code as a 0/1 macro so tests can assert which kernel ran.
if(CMAKE_SYSTEM_PROCESSOR MATCHES "^(aarch64|arm64|ARM64)$" AND NOT ZM_FORCE_SCALAR)
  set(ZM_SIMD_NEON ON)
  set(ZM_SIMD_NAME neon)
else()
  set(ZM_SIMD_NEON OFF)
  set(ZM_SIMD_NAME scalar)
endif()
message(STATUS "zonemap: SIMD kernels = ${ZM_SIMD_NAME} (processor ${CMAKE_SYSTEM_PROCESSOR}, ZM_FORCE_SCALAR=${ZM_FORCE_SCALAR})")
