// BumpRegion's contract, which both image decoders' allocator hooks rest on: blocks are
// aligned, disjoint and inside the region; a request that does not fit (also one larger than
// the region, or near SIZE_MAX) is refused without moving anything; Reset() serves the same
// addresses again; the high-water mark survives resets.
#include "arena/bump_region.h"

#include <doctest/doctest.h>

#include <array>
#include <cstdint>
#include <limits>

namespace zm {
namespace {

TEST_CASE("bump region: aligned, disjoint blocks inside the region, then a refusal") {
  alignas(64) std::array<std::byte, 256> storage{};
  BumpRegion r{storage.data(), storage.size()};
  auto* a = static_cast<std::byte*>(r.Take(1, 16));
  auto* b = static_cast<std::byte*>(r.Take(17, 16));
  auto* c = static_cast<std::byte*>(r.Take(0, 16));
  REQUIRE(a != nullptr);
  REQUIRE(b != nullptr);
  REQUIRE(c != nullptr);
  CHECK(a == storage.data());
  CHECK(b == a + 16);  // 1 byte rounded up to 16
  CHECK(c == b + 32);  // 17 bytes rounded up to 32
  CHECK(reinterpret_cast<std::uintptr_t>(b) % 16 == 0);
  CHECK(r.used == 48);
  CHECK(r.Take(256 - 48, 16) != nullptr);  // exactly what is left
  CHECK(r.used == 256);
  CHECK(r.Take(1, 16) == nullptr);
  CHECK(r.used == 256);
  CHECK(r.high == 256);
}

TEST_CASE("bump region: oversize and near-SIZE_MAX requests are refused, nothing moves") {
  alignas(64) std::array<std::byte, 128> storage{};
  BumpRegion r{storage.data(), storage.size()};
  REQUIRE(r.Take(40, 16) != nullptr);
  CHECK(r.Take(129, 16) == nullptr);
  CHECK(r.Take(std::numeric_limits<std::size_t>::max(), 16) == nullptr);
  CHECK(r.Take(std::numeric_limits<std::size_t>::max() - 7, 64) == nullptr);
  CHECK(r.Take(128 - 48 + 1, 16) == nullptr);  // one byte more than what is left, rounded
  CHECK(r.used == 48);
  CHECK(r.high == 48);
}

TEST_CASE("bump region: Reset serves the same addresses again and keeps the high-water mark") {
  alignas(64) std::array<std::byte, 512> storage{};
  BumpRegion r{storage.data(), storage.size()};
  void* first = r.Take(300, 64);
  REQUIRE(first != nullptr);
  r.Reset();
  CHECK(r.used == 0);
  CHECK(r.Take(100, 64) == first);
  CHECK(r.high == 320);
  CHECK(r.used == 128);
}

}  // namespace
}  // namespace zm
