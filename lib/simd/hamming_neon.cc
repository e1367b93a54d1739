// NEON Hamming kernels for 256-bit descriptors (see hamming.h for the contracts; the scalar
// reference in hamming_scalar.cc defines the results this file must reproduce bit for bit).
// Built only when ZM_SIMD_NEON=1 (aarch64 without ZM_FORCE_SCALAR).
//
// One descriptor is two 128-bit registers. Per train descriptor:
//   x = q XOR t                  (veorq_u8, two halves)
//   c = vcntq_u8(x_lo) + vcntq_u8(x_hi)   per-byte popcounts, each lane <= 8 + 8 = 16
// Four descriptors are reduced together with pairwise adds, keeping every lane in range:
//   vpaddq_u8(c0, c1)  lanes 0-7 = c0 pair sums (<= 32), 8-15 = c1
//   vpaddq_u8(p01,p23) lanes 0-3 c0, 4-7 c1, 8-11 c2, 12-15 c3 (<= 64)
//   vpaddq_u8(p, p)    lanes 0-1 c0, 2-3 c1, 4-5 c2, 6-7 c3 (<= 128, still fits u8)
//   vpaddlq_u8(r)      widening: u16 lanes 0..3 = the four distances (<= 256 needs 9 bits)
// A lone descriptor (the n % 4 tail) uses vaddlvq_u8 (widening across-lane sum; a plain
// vaddvq_u8 would wrap at 256 when all bits differ).
// Loads are vld1q_u8, which has no alignment requirement, so any base address works.
#include <arm_neon.h>

#include "simd/hamming.h"

#if !ZM_SIMD_NEON || !defined(__aarch64__)
#error "hamming_neon.cc is only built for aarch64 with ZM_SIMD_NEON=1"
#endif

namespace zm::simd::neon {
namespace {

// Per-byte popcounts of (q XOR t), both 16-byte halves summed (each lane <= 16).
inline uint8x16_t ByteCounts(uint8x16_t q0, uint8x16_t q1, const std::uint8_t* t) {
  const uint8x16_t t0 = vld1q_u8(t);
  const uint8x16_t t1 = vld1q_u8(t + 16);
  return vaddq_u8(vcntq_u8(veorq_u8(q0, t0)), vcntq_u8(veorq_u8(q1, t1)));
}

// Distances of q to the four consecutive descriptors at t.
inline uint16x4_t Distances4(uint8x16_t q0, uint8x16_t q1, const std::uint8_t* t) {
  const uint8x16_t c0 = ByteCounts(q0, q1, t);
  const uint8x16_t c1 = ByteCounts(q0, q1, t + 32);
  const uint8x16_t c2 = ByteCounts(q0, q1, t + 64);
  const uint8x16_t c3 = ByteCounts(q0, q1, t + 96);
  const uint8x16_t p = vpaddq_u8(vpaddq_u8(c0, c1), vpaddq_u8(c2, c3));
  const uint8x16_t r = vpaddq_u8(p, p);
  return vget_low_u16(vpaddlq_u8(r));
}

inline std::uint16_t Distance1(uint8x16_t q0, uint8x16_t q1, const std::uint8_t* t) {
  return vaddlvq_u8(ByteCounts(q0, q1, t));
}

// The scalar reference's update rule, applied in train order (identical ties).
inline void Update(std::uint32_t d, std::uint32_t index, std::uint32_t* best, std::uint32_t* second,
                   std::uint32_t* best_index) {
  if (d < *best) {
    *second = *best;
    *best = d;
    *best_index = index;
  } else if (d < *second) {
    *second = d;
  }
}

}  // namespace

const char* KernelName() { return "neon"; }

void HammingOneToMany(const std::uint8_t* query, const std::uint8_t* train, std::size_t n,
                      std::uint16_t* out) {
  const uint8x16_t q0 = vld1q_u8(query);
  const uint8x16_t q1 = vld1q_u8(query + 16);
  std::size_t i = 0;
  for (; i + 4 <= n; i += 4) vst1_u16(out + i, Distances4(q0, q1, train + i * kHammingBytes));
  for (; i < n; ++i) out[i] = Distance1(q0, q1, train + i * kHammingBytes);
}

void HammingOneToMany(const std::uint8_t* query, const std::uint8_t* train, std::size_t n,
                      std::uint32_t* out) {
  const uint8x16_t q0 = vld1q_u8(query);
  const uint8x16_t q1 = vld1q_u8(query + 16);
  std::size_t i = 0;
  for (; i + 4 <= n; i += 4) {
    vst1q_u32(out + i, vmovl_u16(Distances4(q0, q1, train + i * kHammingBytes)));
  }
  for (; i < n; ++i) out[i] = Distance1(q0, q1, train + i * kHammingBytes);
}

void BestTwoMatches(const std::uint8_t* queries, std::size_t nq, const std::uint8_t* train,
                    std::size_t nt, BestTwo* out) {
  for (std::size_t q = 0; q < nq; ++q) {
    const std::uint8_t* qd = queries + q * kHammingBytes;
    const uint8x16_t q0 = vld1q_u8(qd);
    const uint8x16_t q1 = vld1q_u8(qd + 16);
    std::uint32_t best = kNoSecond;
    std::uint32_t second = kNoSecond;
    std::uint32_t best_index = kNoMatch;
    std::size_t t = 0;
    for (; t + 4 <= nt; t += 4) {
      const uint16x4_t d = Distances4(q0, q1, train + t * kHammingBytes);
      // Exact shortcut: a block whose minimum is not below `second` cannot change anything
      // (an update needs d < best <= second or d < second).
      if (vminv_u16(d) >= second) continue;
      const auto i = static_cast<std::uint32_t>(t);
      Update(vget_lane_u16(d, 0), i, &best, &second, &best_index);
      Update(vget_lane_u16(d, 1), i + 1, &best, &second, &best_index);
      Update(vget_lane_u16(d, 2), i + 2, &best, &second, &best_index);
      Update(vget_lane_u16(d, 3), i + 3, &best, &second, &best_index);
    }
    for (; t < nt; ++t) {
      Update(Distance1(q0, q1, train + t * kHammingBytes), static_cast<std::uint32_t>(t), &best,
             &second, &best_index);
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
    neon::BestTwoMatches(queries + q * kHammingBytes, 1, train, nt, &b);
    if (PassesRatioTest(b, params)) {
      out[count++] = DescriptorMatch{static_cast<std::uint32_t>(q), b.best_index, b.best_distance};
    }
  }
  return count;
}

}  // namespace zm::simd::neon
