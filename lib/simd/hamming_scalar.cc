// Scalar reference Hamming kernels (see hamming.h for the contracts). Portable C++20: each
// 256-bit descriptor is read as four uint64 words through memcpy (any alignment, no aliasing
// issue) and std::popcount counts the XOR's bits. On x86-64 without -mpopcnt GCC lowers
// std::popcount to a bit-twiddling sequence; bench/hamming_bench.cc measures what the POPCNT
// instruction would add. This is also the shape the NEON kernel must reproduce bit for bit.
#include <bit>
#include <cstring>

#include "simd/hamming.h"

namespace zm::simd::scalar {
namespace {

// Popcount of (a XOR b) for two 32-byte descriptors.
inline std::uint32_t Distance(const std::uint8_t* a, const std::uint8_t* b) {
  std::uint64_t wa[4];
  std::uint64_t wb[4];
  std::memcpy(wa, a, kHammingBytes);
  std::memcpy(wb, b, kHammingBytes);
  return static_cast<std::uint32_t>(std::popcount(wa[0] ^ wb[0]) + std::popcount(wa[1] ^ wb[1]) +
                                    std::popcount(wa[2] ^ wb[2]) + std::popcount(wa[3] ^ wb[3]));
}

}  // namespace

const char* KernelName() { return "scalar"; }

void HammingOneToMany(const std::uint8_t* query, const std::uint8_t* train, std::size_t n,
                      std::uint16_t* out) {
  for (std::size_t i = 0; i < n; ++i) {
    out[i] = static_cast<std::uint16_t>(Distance(query, train + i * kHammingBytes));
  }
}

void HammingOneToMany(const std::uint8_t* query, const std::uint8_t* train, std::size_t n,
                      std::uint32_t* out) {
  for (std::size_t i = 0; i < n; ++i) out[i] = Distance(query, train + i * kHammingBytes);
}

void BestTwoMatches(const std::uint8_t* queries, std::size_t nq, const std::uint8_t* train,
                    std::size_t nt, BestTwo* out) {
  for (std::size_t q = 0; q < nq; ++q) {
    const std::uint8_t* qd = queries + q * kHammingBytes;
    // best/second start above any real distance (256) so the first train always wins.
    std::uint32_t best = kNoSecond;
    std::uint32_t second = kNoSecond;
    std::uint32_t best_index = kNoMatch;
    for (std::size_t t = 0; t < nt; ++t) {
      const std::uint32_t d = Distance(qd, train + t * kHammingBytes);
      if (d < best) {  // strict: the first minimum keeps the index
        second = best;
        best = d;
        best_index = static_cast<std::uint32_t>(t);
      } else if (d < second) {  // includes d == best: a tie becomes the second distance
        second = d;
      }
    }
    out[q] =
        BestTwo{best_index, static_cast<std::uint16_t>(best), static_cast<std::uint16_t>(second)};
  }
}

std::size_t MatchRatioTest(const std::uint8_t* queries, std::size_t nq, const std::uint8_t* train,
                           std::size_t nt, const RatioTestParams& params, DescriptorMatch* out) {
  std::size_t count = 0;
  for (std::size_t q = 0; q < nq; ++q) {
    BestTwo b;
    scalar::BestTwoMatches(queries + q * kHammingBytes, 1, train, nt, &b);
    if (PassesRatioTest(b, params)) {
      out[count++] = DescriptorMatch{static_cast<std::uint32_t>(q), b.best_index, b.best_distance};
    }
  }
  return count;
}

}  // namespace zm::simd::scalar
