// Scalar reference CRC-32C (see crc32c.h): slice-by-8 over eight 256-entry tables computed at
// compile time, one byte at a time for the tail. Portable C++20 (any alignment: words are read
// through memcpy); about 1-2 GB/s, the reference every hardware kernel must equal bit for bit.
// Also defines the join tables the hardware kernels share (crc32c_internal.h).
#include <bit>
#include <cstring>

#include "simd/crc32c.h"
#include "simd/crc32c_internal.h"

namespace zm::simd {
namespace crc32c_internal {

constinit const ShiftTable kShiftLong = MakeShiftTable(kLongBlock);
constinit const ShiftTable kShiftShort = MakeShiftTable(kShortBlock);

}  // namespace crc32c_internal

namespace scalar {
namespace {

static_assert(std::endian::native == std::endian::little,
              "slice-by-8 reads little-endian words; add a byte-swapped variant for big-endian");

using Tables = std::array<std::array<std::uint32_t, 256>, 8>;

constexpr Tables MakeTables() {
  Tables t{};
  for (std::uint32_t b = 0; b < 256; ++b) {
    std::uint32_t r = b;
    for (int bit = 0; bit < 8; ++bit) r = (r & 1u) != 0 ? (r >> 1) ^ crc32c_internal::kPoly : r >> 1;
    t[0][b] = r;
  }
  // t[k][b]: the register after byte b followed by k zero bytes.
  for (std::size_t k = 1; k < 8; ++k) {
    for (std::uint32_t b = 0; b < 256; ++b) t[k][b] = (t[k - 1][b] >> 8) ^ t[0][t[k - 1][b] & 0xFFu];
  }
  return t;
}

constinit const Tables kTables = MakeTables();

}  // namespace

const char* Crc32cKernelName() { return "scalar"; }

std::uint32_t Crc32c(const void* data, std::size_t n, std::uint32_t crc) {
  const auto* p = static_cast<const std::uint8_t*>(data);
  std::uint32_t r = ~crc;
  for (; n >= 8; n -= 8, p += 8) {
    std::uint64_t w;
    std::memcpy(&w, p, 8);
    w ^= r;
    r = kTables[7][w & 0xFFu] ^ kTables[6][(w >> 8) & 0xFFu] ^ kTables[5][(w >> 16) & 0xFFu] ^
        kTables[4][(w >> 24) & 0xFFu] ^ kTables[3][(w >> 32) & 0xFFu] ^
        kTables[2][(w >> 40) & 0xFFu] ^ kTables[1][(w >> 48) & 0xFFu] ^ kTables[0][w >> 56];
  }
  for (; n > 0; --n, ++p) r = (r >> 8) ^ kTables[0][(r ^ *p) & 0xFFu];
  return ~r;
}

}  // namespace scalar
}  // namespace zm::simd
