// CRC-32C with the SSE4.2 `crc32` instruction (x86-64; see crc32c.h). Only the functions below
// are compiled for SSE4.2 (target attribute): the rest of the build stays baseline x86-64, and
// crc32c.cc calls this kernel only after cpuid reported SSE4.2.
//
// crc32 on 8 bytes has a latency of 3 cycles and a throughput of 1 per cycle, so one stream
// runs at a third of the instruction's speed. The bulk is cut into three adjacent blocks
// crunched as three independent streams, joined with the shift tables (crc32c_internal.h):
// long blocks (3 x 8 KiB) first, then short ones (3 x 256 B), then one stream, then bytes.
#include <nmmintrin.h>

#include <cstring>

#include "simd/crc32c.h"
#include "simd/crc32c_internal.h"

namespace zm::simd::sse42 {
namespace {

using crc32c_internal::kLongBlock;
using crc32c_internal::kShortBlock;
using crc32c_internal::ShiftTable;

inline std::uint64_t Load64(const std::uint8_t* p) {
  std::uint64_t w;
  std::memcpy(&w, p, 8);
  return w;
}

// Three streams over p[0, block), p[block, 2 block), p[2 block, 3 block) while n allows; r is
// the running register (not inverted).
__attribute__((target("sse4.2"))) inline std::uint64_t ThreeWay(std::uint64_t r,
                                                                  const std::uint8_t*& p,
                                                                  std::size_t& n, std::size_t block,
                                                                  const ShiftTable& shift) {
  while (n >= 3 * block) {
    std::uint64_t r1 = 0;
    std::uint64_t r2 = 0;
    const std::uint8_t* end = p + block;
    for (; p < end; p += 8) {
      r = _mm_crc32_u64(r, Load64(p));
      r1 = _mm_crc32_u64(r1, Load64(p + block));
      r2 = _mm_crc32_u64(r2, Load64(p + 2 * block));
    }
    r = shift.Shift(static_cast<std::uint32_t>(r)) ^ r1;
    r = shift.Shift(static_cast<std::uint32_t>(r)) ^ r2;
    p += 2 * block;
    n -= 3 * block;
  }
  return r;
}

}  // namespace

const char* Crc32cKernelName() { return "sse42"; }

__attribute__((target("sse4.2"))) std::uint32_t Crc32c(const void* data, std::size_t n,
                                                        std::uint32_t crc) {
  const auto* p = static_cast<const std::uint8_t*>(data);
  std::uint64_t r = static_cast<std::uint32_t>(~crc);
  r = ThreeWay(r, p, n, kLongBlock, crc32c_internal::kShiftLong);
  r = ThreeWay(r, p, n, kShortBlock, crc32c_internal::kShiftShort);
  for (; n >= 8; n -= 8, p += 8) r = _mm_crc32_u64(r, Load64(p));
  auto r32 = static_cast<std::uint32_t>(r);
  for (; n > 0; --n, ++p) r32 = _mm_crc32_u8(r32, *p);
  return ~r32;
}

}  // namespace zm::simd::sse42
