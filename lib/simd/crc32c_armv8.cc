// CRC-32C with the ARMv8 CRC extension (`crc32cx`, __crc32cd; aarch64, see crc32c.h). Optional
// in ARMv8.0, mandatory from ARMv8.1; the Orin's Cortex-A78AE has it. Only the functions below
// are compiled for it (target attribute "+crc"): the rest of the build stays -march=armv8-a (or
// the Jetson preset's -mcpu), and crc32c.cc calls this kernel only after getauxval(AT_HWCAP)
// reported HWCAP_CRC32.
//
// Same structure as the SSE4.2 kernel: crc32cx has a 2-cycle latency and a throughput of one per
// cycle on Cortex-A78, so three independent streams over adjacent blocks, joined with the
// shift tables (crc32c_internal.h), then one stream, then bytes.
#include <arm_acle.h>

#include <cstring>

#include "simd/crc32c.h"
#include "simd/crc32c_internal.h"

namespace zm::simd::armv8 {
namespace {

using crc32c_internal::kLongBlock;
using crc32c_internal::kShortBlock;
using crc32c_internal::ShiftTable;

inline std::uint64_t Load64(const std::uint8_t* p) {
  std::uint64_t w;
  std::memcpy(&w, p, 8);
  return w;
}

__attribute__((target("+crc"))) inline std::uint32_t ThreeWay(std::uint32_t r,
                                                                const std::uint8_t*& p,
                                                                std::size_t& n, std::size_t block,
                                                                const ShiftTable& shift) {
  while (n >= 3 * block) {
    std::uint32_t r1 = 0;
    std::uint32_t r2 = 0;
    const std::uint8_t* end = p + block;
    for (; p < end; p += 8) {
      r = __crc32cd(r, Load64(p));
      r1 = __crc32cd(r1, Load64(p + block));
      r2 = __crc32cd(r2, Load64(p + 2 * block));
    }
    r = shift.Shift(r) ^ r1;
    r = shift.Shift(r) ^ r2;
    p += 2 * block;
    n -= 3 * block;
  }
  return r;
}

}  // namespace

const char* Crc32cKernelName() { return "armv8"; }

__attribute__((target("+crc"))) std::uint32_t Crc32c(const void* data, std::size_t n,
                                                      std::uint32_t crc) {
  const auto* p = static_cast<const std::uint8_t*>(data);
  std::uint32_t r = ~crc;
  r = ThreeWay(r, p, n, kLongBlock, crc32c_internal::kShiftLong);
  r = ThreeWay(r, p, n, kShortBlock, crc32c_internal::kShiftShort);
  for (; n >= 8; n -= 8, p += 8) r = __crc32cd(r, Load64(p));
  for (; n > 0; --n, ++p) r = __crc32cb(r, *p);
  return ~r;
}

}  // namespace zm::simd::armv8
