// The inverted index over the RESIDENT keyframes' bags of words: for each word, the postings
// (keyframe slot, tf-idf weight) of the resident keyframes that contain it. It is what makes the
// loop-closure search cost what RTAB-Map's does: Score() walks, for every word of the query bag,
// that word's postings, so its cost grows with the resident set (sum of the query words' posting
// lengths ~ query words * resident keyframes * P(word in a keyframe)). Evicting a zone removes its
// keyframes' postings; the memory policy therefore sets the tick's likelihood time.
//
// Score: DBoW2's L1 score between L1-normalised tf-idf bags, s(q, d) = 1 - |q - d|_1 / 2, in
// [0, 1]. For non-negative vectors of unit L1 norm, |q - d|_1 = 2 - 2 * sum_w min(q_w, d_w), so
// s(q, d) = sum over the COMMON words of min(q_w, d_w): only the postings of the query's words
// are read. Chosen over RTAB-Map's likelihood (sum over common words of n_wi * log(N / n_w) /
// n_i with N the working-memory size, recomputed each tick) because (a) with the vocabulary's
// fixed IDF a keyframe's score does not change when OTHER keyframes are loaded or evicted, so
// the memory policy changes which keyframes compete, not how each is scored; (b) weights are
// fixed when a keyframe is added, so Score only adds; (c) the score is bounded, comparable
// across frames. The cost shape (postings walked per resident keyframe) is the same.
//
// Storage, reserved once from K_max (max_keyframes) and max words per keyframe (M), so Add,
// Remove and Score never allocate:
//   - postings live in fixed blocks of kPostingsPerBlock from one pool, chained per word (head to
//     tail, doubly linked). Bound: a word with n postings uses ceil(n / B) <= n / B + 1 blocks,
//     so K_max * M / B + min(W, K_max * M) blocks always suffice: Add can never run out;
//   - a per-slot direct table (M entries per slot: word, posting position) lets Remove find each
//     of its postings in O(1) and fill the hole with the word's last posting (swap-remove);
//   - Score accumulates into a per-slot array with a list of touched slots (reset after), then
//     keeps the top k by a bounded insertion (ties: larger keyframe id first, as RTAB-Map's
//     argmax and the localizer's), so the result does not depend on posting order.
// Memory: ~8 bytes per posting in blocks + 8 per direct entry (K_max x M of each, M rounded up to
// a power of two for the direct table) + ~280 per word (its spare block) + 16 per slot;
// memory_bytes() reports it (K_max 3200, M 500, W 10^4: 29 MB, bench/localization_bench.cc).
//
// Slots are the arena's slot indices (dense, < K_max): the runtime adds a keyframe when its zone
// is loaded into slots and removes it when evicted. Not thread-safe (one tick thread).
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "arena/arena.h"
#include "common/ids.h"
#include "common/status.h"
#include "localization/vocabulary.h"

namespace zm {

inline constexpr std::uint32_t kPostingsPerBlock = 32;
inline constexpr std::uint32_t kMaxIndexCandidates = 64;  // top-k limit of Score

struct InvertedIndexOptions {
  std::uint32_t word_count = 0;                // the vocabulary's word_count()
  std::uint32_t max_keyframes = 0;             // K_max: slots are < this
  std::uint32_t max_words_per_keyframe = 500;  // M: a bag larger than this is refused (Kp 500)
};

// Checks every count > 0 and that K_max * M fits the 32-bit posting references.
[[nodiscard]] Status ValidateInvertedIndexOptions(const InvertedIndexOptions& options);

struct IndexCandidate {
  SlotIndex slot;
  KeyframeId id;
  float score = 0.0f;  // DBoW2 L1 score in (0, 1]
};

class InvertedIndex {
 public:
  // options must satisfy ValidateInvertedIndexOptions (asserted); allocates everything here.
  explicit InvertedIndex(const InvertedIndexOptions& options);

  // Indexes keyframe `id` held in `slot` with its bag. Errors (nothing changed): slot >= K_max,
  // slot already indexed, bag larger than M, a word >= word_count.
  [[nodiscard]] Status Add(SlotIndex slot, KeyframeId id, const BowVector& bag);
  // Drops the keyframe in `slot`; kNotFound when the slot holds none.
  [[nodiscard]] Status Remove(SlotIndex slot);

  // The best min(k, kMaxIndexCandidates, out.size()) resident keyframes for `query`, best first,
  // written to out; returns how many (only keyframes sharing a word with the query score > 0).
  // Words >= word_count in the query are ignored (they have no postings).
  [[nodiscard]] std::size_t Score(const BowVector& query, std::uint32_t k,
                                  std::span<IndexCandidate> out);

  [[nodiscard]] std::uint32_t resident() const { return resident_; }
  [[nodiscard]] std::uint64_t postings() const { return postings_; }
  // Postings walked by the last Score() (the work that grows with the resident set).
  [[nodiscard]] std::uint64_t last_postings_walked() const { return last_walked_; }
  [[nodiscard]] bool contains(SlotIndex slot) const {
    return slot.value < options_.max_keyframes && slot_size_[slot.value] != kEmptySlot;
  }
  // The object and everything it reserved (capacities): equals BytesFor(options()).
  [[nodiscard]] std::size_t memory_bytes() const;
  // What an index with these options reserves, before building one (the memory budget's).
  [[nodiscard]] static std::size_t BytesFor(const InvertedIndexOptions& options);
  [[nodiscard]] const InvertedIndexOptions& options() const { return options_; }

 private:
  static constexpr std::uint32_t kNone = 0xFFFFFFFFu;
  static constexpr std::uint32_t kEmptySlot = 0xFFFFFFFFu;

  struct Posting {
    std::uint32_t ref = 0;  // slot << shift_ | entry index in the slot's direct table
    float weight = 0.0f;
  };
  struct Block {
    std::uint32_t next = kNone;
    std::uint32_t prev = kNone;
    Posting postings[kPostingsPerBlock];
  };
  struct WordList {
    std::uint32_t head = kNone;  // first block
    std::uint32_t tail = kNone;  // last block (the only one not full)
    std::uint32_t count = 0;     // postings
  };
  struct DirectEntry {
    std::uint32_t word = 0;
    std::uint32_t position = 0;  // block * kPostingsPerBlock + offset
  };

  [[nodiscard]] Posting& At(std::uint32_t position) {
    return blocks_[position / kPostingsPerBlock].postings[position % kPostingsPerBlock];
  }

  InvertedIndexOptions options_;
  std::uint32_t shift_ = 0;  // log2 of the direct table stride (M rounded up to a power of 2)
  std::vector<Block> blocks_;
  std::uint32_t free_block_ = kNone;  // singly linked through Block::next
  std::vector<WordList> words_;
  std::vector<DirectEntry> direct_;       // max_keyframes << shift_
  std::vector<std::uint32_t> slot_size_;  // entries per slot, kEmptySlot when not indexed
  std::vector<KeyframeId> slot_id_;
  std::vector<float> accumulator_;      // per slot, zero between Score calls
  std::vector<std::uint32_t> touched_;  // slots with a non-zero accumulator
  std::uint32_t resident_ = 0;
  std::uint64_t postings_ = 0;
  std::uint64_t last_walked_ = 0;
};

}  // namespace zm
