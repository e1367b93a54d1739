// Bag-of-binary-words score: a revisit scores high, an unrelated keyframe low, and the query
// sets are empty again after ClearQuery (no state leaks between frames), without allocating.
#include "localization/appearance.h"

#include <doctest/doctest.h>

#include <random>
#include <vector>

#include "mapdb/keyframe_payload.h"
#include "support/counting_allocator.h"

namespace zm {
namespace {

std::vector<std::uint8_t> Random(std::mt19937& rng, std::size_t n) {
  std::uniform_int_distribution<int> b(0, 255);
  std::vector<std::uint8_t> d(n * kDescriptorBytes);
  for (auto& x : d) x = static_cast<std::uint8_t>(b(rng));
  return d;
}

TEST_CASE("appearance: revisit scores far above an unrelated place and clear resets") {
  std::mt19937 rng(3);
  const auto place = Random(rng, 300);
  const auto other = Random(rng, 300);
  auto revisit = place;
  std::uniform_int_distribution<std::size_t> bit(0, 300 * 256 - 1);
  for (int i = 0; i < 300 * 6; ++i) {  // ~6 flipped bits per descriptor
    const std::size_t b = bit(rng);
    revisit[b / 8] ^= static_cast<std::uint8_t>(1u << (b % 8));
  }
  AppearanceScorer s;
  test::AllocationCounter allocs;
  s.SetQuery(revisit.data(), 300);
  const std::uint32_t same = s.Score(place.data(), 300);
  const std::uint32_t unrelated = s.Score(other.data(), 300);
  s.ClearQuery(revisit.data(), 300);
  CHECK(allocs.allocations() == 0);
  CHECK(same > 200);
  CHECK(unrelated < 20);
  CHECK(s.Score(place.data(), 300) == 0);  // nothing marked any more
}

}  // namespace
}  // namespace zm
