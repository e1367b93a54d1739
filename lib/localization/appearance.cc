// Bag-of-binary-words appearance score (see appearance.h).
#include "localization/appearance.h"

#include "mapdb/keyframe_payload.h"

namespace zm {
namespace {

// The two 16-bit words of a descriptor: bytes 0-1 and bytes 16-17 (disjoint bits).
inline std::uint32_t WordA(const std::uint8_t* d) {
  return static_cast<std::uint32_t>(d[0]) | (static_cast<std::uint32_t>(d[1]) << 8);
}
inline std::uint32_t WordB(const std::uint8_t* d) {
  return static_cast<std::uint32_t>(d[16]) | (static_cast<std::uint32_t>(d[17]) << 8);
}
inline bool Test(const std::vector<std::uint64_t>& s, std::uint32_t w) {
  return ((s[w >> 6] >> (w & 63u)) & 1u) != 0;
}

}  // namespace

AppearanceScorer::AppearanceScorer() : set_a_(kWordSpace / 64, 0), set_b_(kWordSpace / 64, 0) {}

void AppearanceScorer::SetQuery(const std::uint8_t* descriptors, std::size_t n) {
  for (std::size_t i = 0; i < n; ++i) {
    const std::uint8_t* d = descriptors + i * kDescriptorBytes;
    const std::uint32_t a = WordA(d);
    const std::uint32_t b = WordB(d);
    set_a_[a >> 6] |= std::uint64_t{1} << (a & 63u);
    set_b_[b >> 6] |= std::uint64_t{1} << (b & 63u);
  }
}

std::uint32_t AppearanceScorer::Score(const std::uint8_t* descriptors, std::size_t n) const {
  std::uint32_t score = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const std::uint8_t* d = descriptors + i * kDescriptorBytes;
    score += static_cast<std::uint32_t>(Test(set_a_, WordA(d))) +
             static_cast<std::uint32_t>(Test(set_b_, WordB(d)));
  }
  return score;
}

void AppearanceScorer::ClearQuery(const std::uint8_t* descriptors, std::size_t n) {
  for (std::size_t i = 0; i < n; ++i) {
    const std::uint8_t* d = descriptors + i * kDescriptorBytes;
    set_a_[WordA(d) >> 6] = 0;
    set_b_[WordB(d) >> 6] = 0;
  }
}

}  // namespace zm
