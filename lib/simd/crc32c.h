// CRC-32C (Castagnoli; reflected polynomial 0x82F63B78, initial value and final XOR 0xFFFFFFFF:
// the iSCSI / ext4 / RocksDB checksum), the keyframe payload's body checksum. Laid out like the
// Hamming kernels (docs/style.md §7), with one difference: the hardware kernel is chosen at RUN
// time, because x86-64's baseline ISA has no crc32 instruction and the build never assumes the
// machine it runs on (no -march=native).
//
//   zm::simd::scalar  crc32c_scalar.cc  the reference, slice-by-8 tables, built everywhere
//   zm::simd::sse42   crc32c_sse42.cc   x86-64 SSE4.2 `crc32` (built when ZM_CRC32C_SSE42=1)
//   zm::simd::armv8   crc32c_armv8.cc   ARMv8 CRC extension `crc32cx` (ZM_CRC32C_ARMV8=1)
//
// Only the kernel file is compiled for its instructions (a target attribute on its functions);
// crc32c.cc picks it once, at the first call, when the CPU reports the feature (x86: cpuid
// SSE4.2; aarch64: getauxval(AT_HWCAP) & HWCAP_CRC32), else scalar. ZM_FORCE_SCALAR=ON leaves
// the hardware kernels out of the build; SetCrc32cForceScalar(true) forces scalar at run time.
//
// Contract shared by every kernel (tests/simd/crc32c_test.cc proves them identical):
//   - Crc32c(data, n, crc) extends `crc`, the CRC-32C of some earlier bytes (0 for none), by
//     data[0..n): Crc32c(ab, na + nb) == Crc32c(b, nb, Crc32c(a, na)); Crc32c("123456789", 9)
//     == 0xE3069283 (the standard check value);
//   - any alignment, any length (n = 0 returns crc unchanged); data may be null when n == 0;
//   - no allocation, no exceptions, no state besides the one-time kernel choice: plain functions.
#pragma once

#include <cstddef>
#include <cstdint>

#ifndef ZM_CRC32C_SSE42
#error "ZM_CRC32C_SSE42 must be defined to 0 or 1 by the build (lib/simd/CMakeLists.txt)"
#endif
#ifndef ZM_CRC32C_ARMV8
#error "ZM_CRC32C_ARMV8 must be defined to 0 or 1 by the build (lib/simd/CMakeLists.txt)"
#endif

namespace zm::simd {

// The same declarations in each kernel namespace.
#define ZM_SIMD_DECLARE_CRC32C_KERNELS                                                        \
  /* "scalar", "sse42" or "armv8": which implementation this namespace is. */                 \
  [[nodiscard]] const char* Crc32cKernelName();                                               \
  /* CRC-32C of data[0..n) continuing from crc (see the file comment). */                     \
  [[nodiscard]] std::uint32_t Crc32c(const void* data, std::size_t n, std::uint32_t crc = 0);

namespace scalar {
ZM_SIMD_DECLARE_CRC32C_KERNELS
}  // namespace scalar

#if ZM_CRC32C_SSE42
namespace sse42 {
ZM_SIMD_DECLARE_CRC32C_KERNELS
}  // namespace sse42
#endif

#if ZM_CRC32C_ARMV8
namespace armv8 {
ZM_SIMD_DECLARE_CRC32C_KERNELS
}  // namespace armv8
#endif

#undef ZM_SIMD_DECLARE_CRC32C_KERNELS

// The hardware kernel this build compiled ("sse42", "armv8"), or nullptr (scalar only).
[[nodiscard]] const char* Crc32cHardwareKernel();
// Whether the hardware kernel was compiled AND this CPU has the instructions.
[[nodiscard]] bool Crc32cHardwareAvailable();
// The kernel Crc32c() calls now: the hardware one when available and not forced off.
[[nodiscard]] const char* ActiveCrc32cKernel();
// Forces the scalar reference for every later Crc32c() call in the process (benchmarks, and
// ruling the hardware path in or out when diagnosing a checksum mismatch). Thread-safe.
void SetCrc32cForceScalar(bool force);

// Dispatch: CRC-32C with the active kernel.
[[nodiscard]] std::uint32_t Crc32c(const void* data, std::size_t n, std::uint32_t crc = 0);

}  // namespace zm::simd
