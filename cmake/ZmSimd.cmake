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

# CRC-32C (lib/simd/crc32c.h): the hardware kernel of the target ISA is compiled beside the
# scalar reference (only that file gets the instructions, through a target attribute, never
# -march=native) and chosen at run time when the CPU has them. ZM_FORCE_SCALAR leaves it out.
#   sse42: x86-64 SSE4.2 `crc32`;  armv8: the ARMv8 CRC extension (`crc32cx`, Cortex-A78AE has it)
set(ZM_CRC32C_HW "")
if(NOT ZM_FORCE_SCALAR)
  if(CMAKE_SYSTEM_PROCESSOR MATCHES "^(x86_64|AMD64|amd64)$")
    set(ZM_CRC32C_HW sse42)
  elseif(CMAKE_SYSTEM_PROCESSOR MATCHES "^(aarch64|arm64|ARM64)$")
    set(ZM_CRC32C_HW armv8)
  endif()
endif()
message(STATUS "zonemap: CRC-32C hardware kernel = ${ZM_CRC32C_HW} (empty: scalar only)")
