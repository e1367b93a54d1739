// CRC-32C arithmetic shared by the kernels (internal to lib/simd). All in the reflected
// representation CRC-32C uses: bit 31 of a uint32 is the coefficient of x^0, bit 0 that of x^31.
//
// Why: the hardware kernels run three independent crc32 streams over three adjacent blocks
// (the instruction has a 3-cycle latency on x86 and 2 on Cortex-A78, one per cycle
// throughput), then join them. Joining needs the CRC register "moved past" the bytes of the
// later blocks: for a register r over block A, the register over A||B is
// shift(r, |B|) XOR crc_register(0, B), where shift(r, n) = r * x^(8n) mod P. That product is
// linear in r, so for a fixed n it is four table lookups, one per byte of r (ShiftTable).
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>

namespace zm::simd::crc32c_internal {

inline constexpr std::uint32_t kPoly = 0x82F63B78u;  // Castagnoli, reflected

// a * b mod P (carry-less, reflected).
constexpr std::uint32_t MulModP(std::uint32_t a, std::uint32_t b) {
  std::uint32_t product = 0;
  for (int i = 0; i < 32; ++i) {
    if ((a & (0x80000000u >> i)) != 0) product ^= b;  // coefficient of x^i in a
    b = (b & 1u) != 0 ? (b >> 1) ^ kPoly : b >> 1;    // b *= x
  }
  return product;
}

// x^(8n) mod P, by squaring (few enough steps for any compiler's constexpr limit).
constexpr std::uint32_t XPow8N(std::size_t n) {
  std::uint32_t power = 0x80000000u;  // x^0
  std::uint32_t square = 1u << 23;    // x^8, then x^16, x^32, ... (x^(8 * 2^k))
  for (; n > 0; n >>= 1) {
    if ((n & 1u) != 0) power = MulModP(power, square);
    square = MulModP(square, square);
  }
  return power;
}

struct ShiftTable {
  std::array<std::array<std::uint32_t, 256>, 4> t{};
  // r * x^(8n) mod P for the table's n.
  [[nodiscard]] std::uint32_t Shift(std::uint32_t r) const {
    return t[0][r & 0xFFu] ^ t[1][(r >> 8) & 0xFFu] ^ t[2][(r >> 16) & 0xFFu] ^ t[3][r >> 24];
  }
};

constexpr ShiftTable MakeShiftTable(std::size_t n) {
  ShiftTable s;
  const std::uint32_t power = XPow8N(n);
  for (std::uint32_t k = 0; k < 4; ++k) {
    for (std::uint32_t b = 0; b < 256; ++b) s.t[k][b] = MulModP(power, b << (8 * k));
  }
  return s;
}

// Block sizes of the three-stream loops: long blocks for the bulk, short ones for what is left
// of a mid-sized buffer. Each join costs two Shift()s (8 lookups) per 3 blocks.
inline constexpr std::size_t kLongBlock = 8192;
inline constexpr std::size_t kShortBlock = 256;

// Defined in crc32c_scalar.cc (built everywhere), computed at compile time.
extern const ShiftTable kShiftLong;   // n = kLongBlock
extern const ShiftTable kShiftShort;  // n = kShortBlock

}  // namespace zm::simd::crc32c_internal
