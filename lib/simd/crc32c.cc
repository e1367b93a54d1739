// CRC-32C run-time dispatch (see crc32c.h): the hardware kernel this build compiled, if the CPU
// reports its instructions, else the scalar reference. Decided once, at the first call (a
// function-local static: thread-safe, no static-initialisation order to worry about), so the
// per-call cost is one predictable branch and an indirect call per checksummed buffer.
#include "simd/crc32c.h"

#include <atomic>

#if ZM_CRC32C_ARMV8
#include <sys/auxv.h>
#ifndef HWCAP_CRC32
#define HWCAP_CRC32 (1 << 7)  // asm/hwcap.h; not every libc header exposes it
#endif
#endif

namespace zm::simd {
namespace {

using Fn = std::uint32_t (*)(const void*, std::size_t, std::uint32_t);

struct Kernel {
  Fn fn;
  const char* name;
};

#if ZM_CRC32C_SSE42 || ZM_CRC32C_ARMV8
bool CpuHasCrc32c() {
#if ZM_CRC32C_SSE42
  __builtin_cpu_init();
  return __builtin_cpu_supports("sse4.2") != 0;
#else
  return (getauxval(AT_HWCAP) & HWCAP_CRC32) != 0;
#endif
}
#endif

const Kernel& Hardware() {
  static const Kernel k = [] {
#if ZM_CRC32C_SSE42
    if (CpuHasCrc32c()) return Kernel{&sse42::Crc32c, sse42::Crc32cKernelName()};
#elif ZM_CRC32C_ARMV8
    if (CpuHasCrc32c()) return Kernel{&armv8::Crc32c, armv8::Crc32cKernelName()};
#endif
    return Kernel{&scalar::Crc32c, scalar::Crc32cKernelName()};
  }();
  return k;
}

std::atomic<bool> g_force_scalar{false};

const Kernel& Active() {
  static const Kernel kScalar{&scalar::Crc32c, scalar::Crc32cKernelName()};
  return g_force_scalar.load(std::memory_order_relaxed) ? kScalar : Hardware();
}

}  // namespace

const char* Crc32cHardwareKernel() {
#if ZM_CRC32C_SSE42
  return "sse42";
#elif ZM_CRC32C_ARMV8
  return "armv8";
#else
  return nullptr;
#endif
}

bool Crc32cHardwareAvailable() { return Hardware().fn != &scalar::Crc32c; }

const char* ActiveCrc32cKernel() { return Active().name; }

void SetCrc32cForceScalar(bool force) { g_force_scalar.store(force, std::memory_order_relaxed); }

std::uint32_t Crc32c(const void* data, std::size_t n, std::uint32_t crc) {
  return Active().fn(data, n, crc);
}

}  // namespace zm::simd
