// A benchmark-only variant of the scalar Hamming kernels written with __builtin_popcountll and
// compiled (in the benchmark target only, see bench/CMakeLists.txt) with -mpopcnt on x86-64, so
// the benchmark can show what the POPCNT instruction buys over the portable build. The library
// never calls it: shipped x86 code is the baseline-ISA scalar path (no -march=native).
#pragma once

#include <cstddef>
#include <cstdint>

#include "simd/hamming.h"

namespace zm::simd::popcnt {

[[nodiscard]] const char* KernelName();  // "popcnt" when compiled with POPCNT, else "builtin"
void HammingOneToMany(const std::uint8_t* query, const std::uint8_t* train, std::size_t n,
                      std::uint16_t* out);
void BestTwoMatches(const std::uint8_t* queries, std::size_t nq, const std::uint8_t* train,
                    std::size_t nt, BestTwo* out);

}  // namespace zm::simd::popcnt
