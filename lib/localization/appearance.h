// Global appearance score of a keyframe for the current frame: a tiny bag of binary words.
// Each 256-bit descriptor yields two 16-bit words (bytes 0-1 and bytes 16-17, i.e. two disjoint
// locality-sensitive hashes: a descriptor seen again with a few flipped bits keeps each word
// with probability (1 - p)^16). The frame's words are marked in two 65536-bit sets; a
// keyframe's score is the number of (feature, hash) pairs of the keyframe whose word the frame
// also has. Random unrelated descriptors score about 2 * n_kf * n_frame / 65536 (a few points),
// a keyframe seeing the same place scores on the order of the shared features.
//
// Invariants: the two sets are allocated once (16 KiB) in the constructor; SetQuery/Score/
// ClearQuery never allocate; ClearQuery must be given the same descriptors as SetQuery so the
// sets are empty again between frames (cheaper than zeroing 16 KiB).
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

namespace zm {

class AppearanceScorer {
 public:
  static constexpr std::size_t kWordSpace = 1u << 16;
  AppearanceScorer();

  // Marks the words of n query descriptors (n * 32 contiguous bytes, any alignment).
  void SetQuery(const std::uint8_t* descriptors, std::size_t n);
  // Score of n keyframe descriptors against the marked query words.
  [[nodiscard]] std::uint32_t Score(const std::uint8_t* descriptors, std::size_t n) const;
  // Unmarks what SetQuery marked.
  void ClearQuery(const std::uint8_t* descriptors, std::size_t n);

 private:
  std::vector<std::uint64_t> set_a_;  // kWordSpace bits
  std::vector<std::uint64_t> set_b_;
};

}  // namespace zm
