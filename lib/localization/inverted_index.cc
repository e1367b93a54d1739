// Inverted index over the resident keyframes' bags, DBoW2 L1 score (see inverted_index.h).
#include "localization/inverted_index.h"

#include <algorithm>
#include <array>
#include <bit>
#include <cassert>
#include <string>

namespace zm {
namespace {

std::uint32_t StrideShift(std::uint32_t max_words) {
  return static_cast<std::uint32_t>(std::bit_width(std::bit_ceil(max_words) - 1));
}

std::uint64_t BlockBound(const InvertedIndexOptions& o) {
  const std::uint64_t postings = std::uint64_t{o.max_keyframes} * o.max_words_per_keyframe;
  return (postings + kPostingsPerBlock - 1) / kPostingsPerBlock +
         std::min<std::uint64_t>(o.word_count, postings);
}

// Strict "a ranks before b": higher score, then larger keyframe id, then larger slot.
bool Before(const IndexCandidate& a, const IndexCandidate& b) {
  if (a.score != b.score) return a.score > b.score;
  if (a.id != b.id) return a.id > b.id;
  return a.slot > b.slot;
}

}  // namespace

Status ValidateInvertedIndexOptions(const InvertedIndexOptions& o) {
  if (o.word_count == 0) return InvalidArgument("inverted index word_count 0 < 1");
  if (o.max_keyframes == 0) return InvalidArgument("inverted index max_keyframes 0 < 1");
  if (o.max_words_per_keyframe == 0) {
    return InvalidArgument("inverted index max_words_per_keyframe 0 < 1");
  }
  const std::uint64_t refs = std::uint64_t{o.max_keyframes}
                             << StrideShift(o.max_words_per_keyframe);
  const std::uint64_t positions = BlockBound(o) * kPostingsPerBlock;
  if (refs > 0xFFFFFFFFull || positions > 0xFFFFFFFFull) {
    return OutOfRange("inverted index of " + std::to_string(o.max_keyframes) + " keyframes x " +
                      std::to_string(o.max_words_per_keyframe) +
                      " words overflows 32-bit posting references (limit 2^32)");
  }
  return Status::Ok();
}

InvertedIndex::InvertedIndex(const InvertedIndexOptions& options) : options_(options) {
  assert(ValidateInvertedIndexOptions(options).ok());
  shift_ = StrideShift(options.max_words_per_keyframe);
  blocks_.resize(BlockBound(options));
  for (std::size_t b = 0; b < blocks_.size(); ++b) {
    blocks_[b].next = b + 1 < blocks_.size() ? static_cast<std::uint32_t>(b + 1) : kNone;
  }
  free_block_ = blocks_.empty() ? kNone : 0;
  words_.resize(options.word_count);
  direct_.resize(std::size_t{options.max_keyframes} << shift_);
  slot_size_.assign(options.max_keyframes, kEmptySlot);
  slot_id_.resize(options.max_keyframes);
  accumulator_.assign(options.max_keyframes, 0.0f);
  touched_.resize(options.max_keyframes);
}

Status InvertedIndex::Add(SlotIndex slot, KeyframeId id, const BowVector& bag) {
  if (slot.value >= options_.max_keyframes) {
    return OutOfRange("inverted index slot " + std::to_string(slot.value) + " >= max_keyframes " +
                      std::to_string(options_.max_keyframes));
  }
  if (slot_size_[slot.value] != kEmptySlot) {
    return InvalidArgument("inverted index slot " + std::to_string(slot.value) +
                           " already holds keyframe " + std::to_string(slot_id_[slot.value].value));
  }
  const std::span<const BowEntry> entries = bag.entries();
  if (entries.size() > options_.max_words_per_keyframe) {
    return OutOfRange("bag of keyframe " + std::to_string(id.value) + " has " +
                      std::to_string(entries.size()) + " words > max_words_per_keyframe " +
                      std::to_string(options_.max_words_per_keyframe));
  }
  for (std::size_t i = 0; i < entries.size(); ++i) {
    if (entries[i].word.value >= options_.word_count ||
        (i > 0 && !(entries[i - 1].word < entries[i].word))) {
      return InvalidArgument("bag of keyframe " + std::to_string(id.value) + ": word " +
                             std::to_string(entries[i].word.value) +
                             " repeated, unsorted or >= word_count " +
                             std::to_string(options_.word_count));
    }
  }
  const std::uint32_t base = slot.value << shift_;
  for (std::uint32_t i = 0; i < entries.size(); ++i) {
    WordList& list = words_[entries[i].word.value];
    if (list.tail == kNone || list.count % kPostingsPerBlock == 0) {
      // The tail is full (or there is none): chain a block from the pool. BlockBound() makes
      // running out impossible.
      const std::uint32_t b = free_block_;
      assert(b != kNone);
      free_block_ = blocks_[b].next;
      blocks_[b].next = kNone;
      blocks_[b].prev = list.tail;
      if (list.tail != kNone) {
        blocks_[list.tail].next = b;
      } else {
        list.head = b;
      }
      list.tail = b;
    }
    const std::uint32_t position = list.tail * kPostingsPerBlock + list.count % kPostingsPerBlock;
    At(position) = Posting{base | i, entries[i].weight};
    direct_[base | i] = DirectEntry{entries[i].word.value, position};
    ++list.count;
  }
  slot_size_[slot.value] = static_cast<std::uint32_t>(entries.size());
  slot_id_[slot.value] = id;
  ++resident_;
  postings_ += entries.size();
  return Status::Ok();
}

Status InvertedIndex::Remove(SlotIndex slot) {
  if (!contains(slot)) {
    return NotFound("inverted index slot " + std::to_string(slot.value) + " holds no keyframe");
  }
  const std::uint32_t base = slot.value << shift_;
  const std::uint32_t n = slot_size_[slot.value];
  for (std::uint32_t i = 0; i < n; ++i) {
    const DirectEntry entry = direct_[base | i];
    WordList& list = words_[entry.word];
    const std::uint32_t last = list.tail * kPostingsPerBlock + (list.count - 1) % kPostingsPerBlock;
    if (last != entry.position) {  // swap-remove: the word's last posting fills the hole
      const Posting moved = At(last);
      At(entry.position) = moved;
      direct_[moved.ref].position = entry.position;
    }
    --list.count;
    if (list.count % kPostingsPerBlock == 0) {  // the tail block emptied: back to the pool
      const std::uint32_t b = list.tail;
      list.tail = blocks_[b].prev;
      if (list.tail != kNone) {
        blocks_[list.tail].next = kNone;
      } else {
        list.head = kNone;
      }
      blocks_[b].prev = kNone;
      blocks_[b].next = free_block_;
      free_block_ = b;
    }
  }
  slot_size_[slot.value] = kEmptySlot;
  slot_id_[slot.value] = KeyframeId{};
  --resident_;
  postings_ -= n;
  return Status::Ok();
}

std::size_t InvertedIndex::Score(const BowVector& query, std::uint32_t k,
                                 std::span<IndexCandidate> out) {
  std::uint32_t touched = 0;
  std::uint64_t walked = 0;
  for (const BowEntry& q : query.entries()) {
    if (q.word.value >= options_.word_count) continue;
    const WordList& list = words_[q.word.value];
    std::uint32_t remaining = list.count;
    for (std::uint32_t b = list.head; b != kNone; b = blocks_[b].next) {
      const std::uint32_t m = std::min(remaining, kPostingsPerBlock);
      const Posting* postings = blocks_[b].postings;
      for (std::uint32_t j = 0; j < m; ++j) {
        const std::uint32_t s = postings[j].ref >> shift_;
        float& acc = accumulator_[s];
        if (acc == 0.0f) touched_[touched++] = s;  // weights are > 0: non-zero once touched
        acc += std::min(q.weight, postings[j].weight);
      }
      remaining -= m;
      walked += m;
    }
  }
  last_walked_ = walked;

  const std::size_t limit =
      std::min<std::size_t>({k, std::size_t{kMaxIndexCandidates}, out.size()});
  std::array<IndexCandidate, kMaxIndexCandidates> best;
  std::size_t size = 0;
  for (std::uint32_t t = 0; t < touched; ++t) {
    const std::uint32_t s = touched_[t];
    const IndexCandidate c{SlotIndex{s}, slot_id_[s], accumulator_[s]};
    accumulator_[s] = 0.0f;
    if (limit == 0 || (size == limit && !Before(c, best[size - 1]))) continue;
    std::size_t at = size < limit ? size++ : size - 1;
    while (at > 0 && Before(c, best[at - 1])) {
      best[at] = best[at - 1];
      --at;
    }
    best[at] = c;
  }
  std::copy_n(best.begin(), size, out.begin());
  return size;
}

std::size_t InvertedIndex::BytesFor(const InvertedIndexOptions& o) {
  // The constructor's sizes, one for one.
  const std::size_t slots = o.max_keyframes;
  return sizeof(InvertedIndex) + BlockBound(o) * sizeof(Block) + o.word_count * sizeof(WordList) +
         (slots << StrideShift(o.max_words_per_keyframe)) * sizeof(DirectEntry) +
         slots *
             (sizeof(std::uint32_t) + sizeof(KeyframeId) + sizeof(float) + sizeof(std::uint32_t));
}

std::size_t InvertedIndex::memory_bytes() const {
  return sizeof(InvertedIndex) + blocks_.capacity() * sizeof(Block) +
         words_.capacity() * sizeof(WordList) + direct_.capacity() * sizeof(DirectEntry) +
         slot_size_.capacity() * sizeof(std::uint32_t) + slot_id_.capacity() * sizeof(KeyframeId) +
         accumulator_.capacity() * sizeof(float) + touched_.capacity() * sizeof(std::uint32_t);
}

}  // namespace zm
