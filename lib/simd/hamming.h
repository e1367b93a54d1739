// Hamming distance kernels for 256-bit binary descriptors (ORB-like, 32 bytes each), laid out as
// docs/style.md §7 asks: this header declares the same functions in zm::simd::scalar (the
// reference, hamming_scalar.cc, built everywhere; the x86 path, std::popcount on uint64) and
// zm::simd::neon (hamming_neon.cc, built only when ZM_SIMD_NEON=1, i.e. aarch64 without
// ZM_FORCE_SCALAR). The unqualified zm::simd:: functions dispatch at compile time.
//
// Contracts shared by every implementation (tests/simd proves them identical):
//   - a descriptor array is n * 32 contiguous bytes; NO alignment is assumed (any base address);
//   - distances are in [0, 256];
//   - best-two: best_index is the FIRST train index with the minimum distance; second_distance
//     is the second smallest distance of the multiset (equal to best when two trains tie), and
//     kNoSecond when there are fewer than two trains; with no train at all best_index is
//     kNoMatch and both distances kNoSecond;
//   - the ratio test is PassesRatioTest() below (one expression, shared, so float rounding
//     cannot differ between kernels): accept if best <= max_distance and, when a second exists,
//     best < ratio * second;
//   - no allocation, no exceptions, no state: plain functions (hot path, no virtual calls).
#pragma once

#include <cstddef>
#include <cstdint>

#ifndef ZM_SIMD_NEON
#error "ZM_SIMD_NEON must be defined to 0 or 1 by the build (cmake/ZmSimd.cmake)"
#endif

namespace zm::simd {

inline constexpr std::size_t kHammingBytes = 32;        // 256-bit descriptors
inline constexpr std::uint32_t kNoMatch = 0xFFFFFFFFu;  // best_index without trains
inline constexpr std::uint16_t kNoSecond = 0xFFFFu;     // distance that does not exist

struct BestTwo {
  std::uint32_t best_index = kNoMatch;      // train index of the best match
  std::uint16_t best_distance = kNoSecond;  // its Hamming distance
  std::uint16_t second_distance = kNoSecond;
};

struct RatioTestParams {
  float ratio = 0.8f;               // Lowe's ratio: best < ratio * second
  std::uint32_t max_distance = 64;  // absolute gate on the best distance (bits of 256)
};

struct DescriptorMatch {
  std::uint32_t query = 0;     // index into the query array
  std::uint32_t train = 0;     // index into the train array
  std::uint32_t distance = 0;  // Hamming distance
};

// The ratio test used by every kernel (see the file comment).
[[nodiscard]] inline bool PassesRatioTest(const BestTwo& b, const RatioTestParams& p) {
  if (b.best_index == kNoMatch || b.best_distance > p.max_distance) return false;
  if (b.second_distance == kNoSecond) return true;  // a single train: only the gate applies
  return static_cast<float>(b.best_distance) < p.ratio * static_cast<float>(b.second_distance);
}

// The same declarations in each kernel namespace.
#define ZM_SIMD_DECLARE_HAMMING_KERNELS                                                       \
  /* "scalar" or "neon": which implementation this namespace is. */                           \
  [[nodiscard]] const char* KernelName();                                                     \
  /* out[i] = popcount(query XOR train[i]) for i < n. */                                      \
  void HammingOneToMany(const std::uint8_t* query, const std::uint8_t* train, std::size_t n,  \
                        std::uint16_t* out);                                                  \
  void HammingOneToMany(const std::uint8_t* query, const std::uint8_t* train, std::size_t n,  \
                        std::uint32_t* out);                                                  \
  /* For each of nq queries, the best two trains among nt (out has nq entries). */            \
  void BestTwoMatches(const std::uint8_t* queries, std::size_t nq, const std::uint8_t* train, \
                      std::size_t nt, BestTwo* out);                                          \
  /* Writes the queries that pass the ratio test to out (capacity >= nq), in query order; */  \
  /* returns how many. */                                                                     \
  [[nodiscard]] std::size_t MatchRatioTest(const std::uint8_t* queries, std::size_t nq,       \
                                           const std::uint8_t* train, std::size_t nt,         \
                                           const RatioTestParams& params, DescriptorMatch* out);

namespace scalar {
ZM_SIMD_DECLARE_HAMMING_KERNELS
}  // namespace scalar

#if ZM_SIMD_NEON
namespace neon {
ZM_SIMD_DECLARE_HAMMING_KERNELS
}  // namespace neon
namespace active = neon;  // compile-time choice
#else
namespace active = scalar;
#endif

#undef ZM_SIMD_DECLARE_HAMMING_KERNELS

// Dispatch: the build's kernel (NEON on aarch64 unless ZM_FORCE_SCALAR, else scalar).
[[nodiscard]] inline const char* ActiveHammingKernel() { return active::KernelName(); }
inline void HammingOneToMany(const std::uint8_t* query, const std::uint8_t* train, std::size_t n,
                             std::uint16_t* out) {
  active::HammingOneToMany(query, train, n, out);
}
inline void HammingOneToMany(const std::uint8_t* query, const std::uint8_t* train, std::size_t n,
                             std::uint32_t* out) {
  active::HammingOneToMany(query, train, n, out);
}
inline void BestTwoMatches(const std::uint8_t* queries, std::size_t nq, const std::uint8_t* train,
                           std::size_t nt, BestTwo* out) {
  active::BestTwoMatches(queries, nq, train, nt, out);
}
[[nodiscard]] inline std::size_t MatchRatioTest(const std::uint8_t* queries, std::size_t nq,
                                                const std::uint8_t* train, std::size_t nt,
                                                const RatioTestParams& params,
                                                DescriptorMatch* out) {
  return active::MatchRatioTest(queries, nq, train, nt, params, out);
}

}  // namespace zm::simd
