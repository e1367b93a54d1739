// __builtin_popcountll Hamming kernels for the benchmark (see hamming_popcnt.h). Same results
// and tie rules as hamming_scalar.cc; the benchmark checks that before timing.
#include "simd/hamming_popcnt.h"

#include <cstring>

namespace zm::simd::popcnt {
namespace {

inline std::uint32_t Distance(const std::uint8_t* a, const std::uint8_t* b) {
  unsigned long long wa[4];  // NOLINT(runtime/int): the builtin's type
  unsigned long long wb[4];  // NOLINT(runtime/int)
  std::memcpy(wa, a, kHammingBytes);
  std::memcpy(wb, b, kHammingBytes);
  return static_cast<std::uint32_t>(
      __builtin_popcountll(wa[0] ^ wb[0]) + __builtin_popcountll(wa[1] ^ wb[1]) +
      __builtin_popcountll(wa[2] ^ wb[2]) + __builtin_popcountll(wa[3] ^ wb[3]));
}

}  // namespace

const char* KernelName() {
#if defined(__POPCNT__)
  return "popcnt";
#else
  return "builtin";
#endif
}

void HammingOneToMany(const std::uint8_t* query, const std::uint8_t* train, std::size_t n,
                      std::uint16_t* out) {
  for (std::size_t i = 0; i < n; ++i) {
    out[i] = static_cast<std::uint16_t>(Distance(query, train + i * kHammingBytes));
  }
}

void BestTwoMatches(const std::uint8_t* queries, std::size_t nq, const std::uint8_t* train,
                    std::size_t nt, BestTwo* out) {
  for (std::size_t q = 0; q < nq; ++q) {
    const std::uint8_t* qd = queries + q * kHammingBytes;
    std::uint32_t best = kNoSecond;
    std::uint32_t second = kNoSecond;
    std::uint32_t best_index = kNoMatch;
    for (std::size_t t = 0; t < nt; ++t) {
      const std::uint32_t d = Distance(qd, train + t * kHammingBytes);
      if (d < best) {
        second = best;
        best = d;
        best_index = static_cast<std::uint32_t>(t);
      } else if (d < second) {
        second = d;
      }
    }
    out[q] =
        BestTwo{best_index, static_cast<std::uint16_t>(best), static_cast<std::uint16_t>(second)};
  }
}

}  // namespace zm::simd::popcnt
