// A visual vocabulary over 256-bit binary descriptors (ORB): a tree of k-majority clusters of
// branching k and depth L, as DBoW2's TemplatedVocabulary and fbow build it (Nister & Stewenius's
// vocabulary tree; Galvez-Lopez & Tardos 2012 for binary words), trained offline, deterministic
// from a seed, then read-only.
//
// Training (Vocabulary::Train): the root holds every training descriptor; a node at depth < L
// with more than one distinct descriptor is split into at most k clusters by k-means++ seeding
// (probability proportional to the squared Hamming distance to the nearest chosen centre) and
// Lloyd iterations where a centre is the bitwise MAJORITY of its members (the k-medians of the
// Hamming space; a tie gives 0, as DBoW2). A node that holds at most k descriptors gets one child
// per distinct descriptor. Nodes that are not split are the leaves: the words, numbered 0..W-1
// in breadth-first order. Children of a node are contiguous, so Quantize compares a descriptor
// with k centres per level through the zm::simd Hamming kernel and descends to the FIRST nearest
// (ties to the lower child): L * k distances per descriptor.
//
// Weights: IDF from the training keyframes, idf(w) = ln(N / n_w), N keyframes, n_w of them with
// at least one descriptor in w (DBoW2's TF_IDF). Transform() gives a keyframe's bag: for each
// distinct word, tf * idf with tf = count / features, then L1-normalised (so the L1 score of
// inverted_index.h lies in [0, 1]). A word present in every training keyframe weighs 0 and is
// left out of bags (it says nothing about the place).
//
// Defaults k = 10, L = 4: at most 10^4 words. A map of a few thousand keyframes gives ~10^6
// training descriptors at 500 words per keyframe, so ~100 per word (enough for stable majority
// centres), while 10^4 words against 500 per keyframe keeps a word in a few % of keyframes: the
// posting lists of inverted_index.h stay short. L = 6 (ORB-SLAM's 10^6 words) needs far more
// training data than one building's map has. The tree takes ~0.5 MB (memory_bytes(): 44 bytes per
// node, 4 per word).
//
// Serialisation: ToBlob()/FromBlob() (little-endian, versioned header, CRC-32C of the body);
// FromBlob checks every size against the header and the limits before copying anything, then
// the tree's structure (children after their parent and in range, every leaf one word, every
// word one leaf, finite non-negative weights). Any damage is one kCorrupt error.
//
// Allocation: Train and FromBlob allocate; Quantize and Transform never do (BowVector has its
// capacity from construction). All state is const after construction: thread-safe to read.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "common/ids.h"
#include "common/status.h"
#include "mapdb/keyframe_payload.h"

namespace zm {

struct WordIdTag {};
// A leaf of the vocabulary tree, dense 0..word_count()-1.
using WordId = StrongId<WordIdTag, std::uint32_t>;

inline constexpr std::uint32_t kMaxVocabularyBranching = 32;    // k: stack scratch in Quantize
inline constexpr std::uint32_t kMaxVocabularyDepth = 8;         // L
inline constexpr std::uint32_t kMaxVocabularyNodes = 1u << 24;  // blob sanity limit (~0.7 GB)

struct VocabularyOptions {
  std::uint32_t branching = 10;       // k, in [2, kMaxVocabularyBranching]
  std::uint32_t depth = 4;            // L, in [1, kMaxVocabularyDepth]; k^L <= kMaxVocabularyNodes
  std::uint32_t max_iterations = 10;  // Lloyd iterations per split (stops earlier when stable)
  std::uint64_t seed = 0x5EED5EED5EEDull;  // k-means++ draws: same seed and data, same tree
};

// Checks the ranges above; names the field and the limit.
[[nodiscard]] Status ValidateVocabularyOptions(const VocabularyOptions& options);

struct BowEntry {
  WordId word;
  float weight = 0.0f;  // tf-idf, L1-normalised over the bag (> 0)
};

// A bag of words: entries sorted by word, words unique, weights > 0 summing to 1 (or empty).
// Capacity fixed at construction (max features per frame); refilling never allocates.
class BowVector {
 public:
  explicit BowVector(std::uint32_t capacity);

  [[nodiscard]] std::span<const BowEntry> entries() const { return {entries_.data(), size_}; }
  [[nodiscard]] std::uint32_t size() const { return size_; }
  [[nodiscard]] std::uint32_t capacity() const {
    return static_cast<std::uint32_t>(entries_.size());
  }
  void Clear() { size_ = 0; }

  // Sets the bag from (word, weight) pairs with words strictly increasing and weights finite and
  // > 0, then L1-normalises the weights. For bags not made by a Vocabulary (tests, imports).
  [[nodiscard]] Status Assign(std::span<const BowEntry> entries);

 private:
  friend class Vocabulary;
  std::vector<BowEntry> entries_;       // capacity slots; the first size_ are the bag
  std::vector<std::uint32_t> scratch_;  // word per feature during Transform
  std::uint32_t size_ = 0;
};

class Vocabulary {
 public:
  // Trains a vocabulary from the descriptors of `keyframe_sizes.size()` keyframes, stored one
  // keyframe after the other (sum of keyframe_sizes == descriptors.size(), every size >= 0, at
  // least one descriptor). Deterministic for the same options and input.
  [[nodiscard]] static Result<Vocabulary> Train(std::span<const Descriptor256> descriptors,
                                                std::span<const std::uint32_t> keyframe_sizes,
                                                const VocabularyOptions& options);

  // Rebuilds a vocabulary from ToBlob()'s bytes; kCorrupt with one line on any damage.
  [[nodiscard]] static Result<Vocabulary> FromBlob(std::span<const std::byte> blob);
  [[nodiscard]] std::vector<std::byte> ToBlob() const;

  // The word of one descriptor (32 bytes, any alignment). Never allocates.
  [[nodiscard]] WordId Quantize(const std::uint8_t* descriptor) const;

  // The L1-normalised tf-idf bag of n descriptors (n * 32 contiguous bytes). kOutOfRange when
  // n > out->capacity() (out left empty). Never allocates.
  [[nodiscard]] Status Transform(const std::uint8_t* descriptors, std::size_t n,
                                 BowVector* out) const;

  [[nodiscard]] std::uint32_t word_count() const { return static_cast<std::uint32_t>(idf_.size()); }
  [[nodiscard]] std::uint32_t node_count() const {
    return static_cast<std::uint32_t>(nodes_.size());
  }
  [[nodiscard]] std::uint32_t branching() const { return branching_; }
  [[nodiscard]] std::uint32_t depth() const { return depth_; }
  [[nodiscard]] std::uint32_t training_keyframes() const { return training_keyframes_; }
  [[nodiscard]] float idf(WordId w) const { return idf_[w.value]; }
  // Heap and object bytes this vocabulary holds (for the memory budget).
  [[nodiscard]] std::size_t memory_bytes() const;

  // Node structure, for tests that check where a descriptor lands.
  static constexpr std::uint32_t kNoWord = 0xFFFFFFFFu;
  struct Node {
    std::uint32_t first_child = 0;  // index of the first child; children are contiguous
    std::uint32_t child_count = 0;  // 0 for a leaf
    std::uint32_t word = kNoWord;   // the leaf's word, kNoWord for an inner node
  };
  [[nodiscard]] std::span<const Node> nodes() const { return nodes_; }
  [[nodiscard]] const std::uint8_t* centre(std::uint32_t node) const {
    return centres_.data() + std::size_t{node} * kDescriptorBytes;
  }

 private:
  Vocabulary() = default;

  std::uint32_t branching_ = 0;
  std::uint32_t depth_ = 0;
  std::uint32_t training_keyframes_ = 0;
  std::vector<Node> nodes_;            // breadth-first; nodes_[0] is the root
  std::vector<std::uint8_t> centres_;  // 32 bytes per node (the root's is unused zeros)
  std::vector<float> idf_;             // per word
};

}  // namespace zm
