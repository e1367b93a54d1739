// Hierarchical k-majority vocabulary over 256-bit descriptors (see vocabulary.h).
#include "localization/vocabulary.h"

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstring>
#include <string>

#include "simd/crc32c.h"
#include "simd/hamming.h"

namespace zm {
namespace {

static_assert(std::endian::native == std::endian::little,
              "the vocabulary blob is little-endian and read with memcpy");
static_assert(kDescriptorBytes == simd::kHammingBytes);

constexpr std::uint32_t kBlobMagic = 0x42564D5Au;  // "ZMVB"
constexpr std::uint16_t kBlobVersion = 1;
constexpr std::size_t kBlobHeaderBytes = 32;
constexpr std::size_t kBlobNodeBytes = 12;  // first_child, child_count, word (u32 each)

// splitmix64: a tiny, portable, seeded generator (std:: distributions differ between standard
// libraries; the tree must not).
class SplitMix64 {
 public:
  explicit SplitMix64(std::uint64_t seed) : state_(seed) {}
  std::uint64_t Next() {
    std::uint64_t z = (state_ += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
  }
  std::uint64_t Below(std::uint64_t n) { return Next() % n; }  // n > 0; bias < n / 2^64

 private:
  std::uint64_t state_;
};

std::uint32_t Distance(const std::uint8_t* a, const std::uint8_t* b) {
  std::uint32_t d = 0;
  simd::HammingOneToMany(a, b, 1, &d);
  return d;
}

// Index of the first nearest of `count` contiguous centres (the rule Quantize uses).
std::uint32_t Nearest(const std::uint8_t* d, const std::uint8_t* centres, std::uint32_t count) {
  simd::BestTwo best;
  simd::BestTwoMatches(d, 1, centres, count, &best);
  return best.best_index;
}

// Scratch shared by every split of one training run (sized once for all descriptors).
struct TrainScratch {
  std::vector<std::uint32_t> assignment;  // cluster per element of the current range
  std::vector<std::uint32_t> nearest_d;   // k-means++: distance to the nearest chosen centre
  std::vector<std::uint32_t> sorted;      // partitioned copy of a range
  std::vector<std::uint8_t> centres;      // k * 32
  std::vector<std::uint32_t> bit_counts;  // k * 256 majority counters
  std::vector<std::uint32_t> members;     // k
};

// Clusters descriptors[idx[0..n)] into at most k clusters (see the file comment of the header).
// Writes the centres to s->centres and each element's cluster to s->assignment; returns the
// number of clusters (1 means: do not split).
std::uint32_t Cluster(std::span<const Descriptor256> descriptors, const std::uint32_t* idx,
                      std::uint32_t n, std::uint32_t k, std::uint32_t max_iterations,
                      SplitMix64* rng, TrainScratch* s) {
  auto desc = [&](std::uint32_t i) { return descriptors[idx[i]].data(); };
  std::uint8_t* centres = s->centres.data();
  std::uint32_t count = 0;
  if (n <= k) {
    // Few descriptors: one cluster per distinct descriptor (DBoW2 does the same).
    for (std::uint32_t i = 0; i < n; ++i) {
      bool seen = false;
      for (std::uint32_t c = 0; c < count && !seen; ++c) {
        seen = std::memcmp(centres + c * kDescriptorBytes, desc(i), kDescriptorBytes) == 0;
      }
      if (!seen) std::memcpy(centres + (count++) * kDescriptorBytes, desc(i), kDescriptorBytes);
    }
  } else {
    // k-means++ seeding: the next centre is drawn with probability proportional to D(x)^2.
    std::memcpy(centres, desc(static_cast<std::uint32_t>(rng->Below(n))), kDescriptorBytes);
    count = 1;
    for (std::uint32_t i = 0; i < n; ++i) s->nearest_d[i] = Distance(desc(i), centres);
    while (count < k) {
      std::uint64_t total = 0;
      for (std::uint32_t i = 0; i < n; ++i) {
        total += std::uint64_t{s->nearest_d[i]} * s->nearest_d[i];
      }
      if (total == 0) break;  // every descriptor is a centre already: fewer clusters
      const std::uint64_t r = rng->Below(total);
      std::uint64_t acc = 0;
      std::uint32_t pick = n - 1;
      for (std::uint32_t i = 0; i < n; ++i) {
        acc += std::uint64_t{s->nearest_d[i]} * s->nearest_d[i];
        if (acc > r) {
          pick = i;
          break;
        }
      }
      std::uint8_t* c = centres + count * kDescriptorBytes;
      std::memcpy(c, desc(pick), kDescriptorBytes);
      ++count;
      for (std::uint32_t i = 0; i < n; ++i) {
        s->nearest_d[i] = std::min(s->nearest_d[i], Distance(desc(i), c));
      }
    }
  }
  if (count <= 1) return count;

  // Lloyd iterations with majority centres; the loop ends on an assignment made from the final
  // centres, so every element's cluster is its nearest centre (what Quantize will find).
  for (std::uint32_t i = 0; i < n; ++i) s->assignment[i] = Nearest(desc(i), centres, count);
  if (n > k) {
    for (std::uint32_t it = 0; it < max_iterations; ++it) {
      std::fill_n(s->bit_counts.begin(), std::size_t{count} * 256, 0u);
      std::fill_n(s->members.begin(), count, 0u);
      for (std::uint32_t i = 0; i < n; ++i) {
        const std::uint32_t c = s->assignment[i];
        ++s->members[c];
        std::uint32_t* bits = s->bit_counts.data() + std::size_t{c} * 256;
        const std::uint8_t* d = desc(i);
        for (std::uint32_t b = 0; b < 256; ++b) {
          bits[b] += (static_cast<std::uint32_t>(d[b >> 3]) >> (b & 7u)) & 1u;
        }
      }
      for (std::uint32_t c = 0; c < count; ++c) {
        if (s->members[c] == 0) continue;  // an emptied cluster keeps its centre
        const std::uint32_t* bits = s->bit_counts.data() + std::size_t{c} * 256;
        std::uint8_t* centre = centres + c * kDescriptorBytes;
        std::memset(centre, 0, kDescriptorBytes);
        for (std::uint32_t b = 0; b < 256; ++b) {
          if (2 * bits[b] > s->members[c]) {
            centre[b >> 3] |= static_cast<std::uint8_t>(1u << (b & 7u));
          }
        }
      }
      bool changed = false;
      for (std::uint32_t i = 0; i < n; ++i) {
        const std::uint32_t c = Nearest(desc(i), centres, count);
        changed = changed || c != s->assignment[i];
        s->assignment[i] = c;
      }
      if (!changed) break;
    }
  }
  // Drop clusters nobody is nearest to (keeps each element's first-nearest index order).
  std::fill_n(s->members.begin(), count, 0u);
  for (std::uint32_t i = 0; i < n; ++i) ++s->members[s->assignment[i]];
  std::array<std::uint32_t, kMaxVocabularyBranching> remap{};
  std::uint32_t kept = 0;
  for (std::uint32_t c = 0; c < count; ++c) {
    if (s->members[c] == 0) continue;
    if (kept != c) {
      std::memmove(centres + kept * kDescriptorBytes, centres + c * kDescriptorBytes,
                   kDescriptorBytes);
    }
    remap[c] = kept++;
  }
  for (std::uint32_t i = 0; i < n; ++i) s->assignment[i] = remap[s->assignment[i]];
  return kept;
}

template <class T>
void Put(std::vector<std::byte>* out, std::size_t at, T v) {
  std::memcpy(out->data() + at, &v, sizeof(T));
}
template <class T>
T Get(std::span<const std::byte> in, std::size_t at) {
  T v;
  std::memcpy(&v, in.data() + at, sizeof(T));
  return v;
}

}  // namespace

Status ValidateVocabularyOptions(const VocabularyOptions& o) {
  if (o.branching < 2 || o.branching > kMaxVocabularyBranching) {
    return InvalidArgument("vocabulary branching " + std::to_string(o.branching) + " outside [2, " +
                           std::to_string(kMaxVocabularyBranching) + "]");
  }
  if (o.depth < 1 || o.depth > kMaxVocabularyDepth) {
    return InvalidArgument("vocabulary depth " + std::to_string(o.depth) + " outside [1, " +
                           std::to_string(kMaxVocabularyDepth) + "]");
  }
  std::uint64_t nodes = 1;
  std::uint64_t level = 1;
  for (std::uint32_t l = 0; l < o.depth; ++l) {
    level *= o.branching;
    nodes += level;
  }
  if (nodes > kMaxVocabularyNodes) {
    return InvalidArgument("vocabulary of branching " + std::to_string(o.branching) +
                           " and depth " + std::to_string(o.depth) + " may have " +
                           std::to_string(nodes) + " nodes > limit " +
                           std::to_string(kMaxVocabularyNodes));
  }
  if (o.max_iterations < 1) return InvalidArgument("vocabulary max_iterations 0 < 1");
  return Status::Ok();
}

BowVector::BowVector(std::uint32_t capacity) : entries_(capacity), scratch_(capacity) {}

Status BowVector::Assign(std::span<const BowEntry> entries) {
  size_ = 0;
  if (entries.size() > entries_.size()) {
    return OutOfRange("bag of " + std::to_string(entries.size()) + " words > capacity " +
                      std::to_string(entries_.size()));
  }
  double sum = 0.0;
  for (std::size_t i = 0; i < entries.size(); ++i) {
    if (i > 0 && !(entries[i - 1].word < entries[i].word)) {
      return InvalidArgument("bag words not strictly increasing at entry " + std::to_string(i));
    }
    if (!(entries[i].weight > 0.0f) || !std::isfinite(entries[i].weight)) {
      return InvalidArgument("bag weight of entry " + std::to_string(i) + " not finite and > 0");
    }
    sum += static_cast<double>(entries[i].weight);
  }
  for (std::size_t i = 0; i < entries.size(); ++i) {
    entries_[i] =
        BowEntry{entries[i].word, static_cast<float>(static_cast<double>(entries[i].weight) / sum)};
  }
  size_ = static_cast<std::uint32_t>(entries.size());
  return Status::Ok();
}

Result<Vocabulary> Vocabulary::Train(std::span<const Descriptor256> descriptors,
                                     std::span<const std::uint32_t> keyframe_sizes,
                                     const VocabularyOptions& options) {
  ZM_RETURN_IF_ERROR(ValidateVocabularyOptions(options));
  if (descriptors.empty()) return InvalidArgument("vocabulary training set has 0 descriptors");
  if (descriptors.size() >= 0xFFFFFFFFull) {
    return OutOfRange("vocabulary training set of " + std::to_string(descriptors.size()) +
                      " descriptors > limit 4294967294");
  }
  std::uint64_t sum = 0;
  for (const std::uint32_t s : keyframe_sizes) sum += s;
  if (keyframe_sizes.empty() || sum != descriptors.size()) {
    return InvalidArgument("vocabulary keyframe sizes sum to " + std::to_string(sum) + " over " +
                           std::to_string(keyframe_sizes.size()) + " keyframes, descriptors " +
                           std::to_string(descriptors.size()));
  }

  Vocabulary v;
  v.branching_ = options.branching;
  v.depth_ = options.depth;
  v.training_keyframes_ = static_cast<std::uint32_t>(keyframe_sizes.size());
  const auto n = static_cast<std::uint32_t>(descriptors.size());
  const std::uint32_t k = options.branching;

  std::vector<std::uint32_t> idx(n);
  for (std::uint32_t i = 0; i < n; ++i) idx[i] = i;
  TrainScratch s;
  s.assignment.resize(n);
  s.nearest_d.resize(n);
  s.sorted.resize(n);
  s.centres.resize(std::size_t{k} * kDescriptorBytes);
  s.bit_counts.resize(std::size_t{k} * 256);
  s.members.resize(k);

  struct Pending {
    std::uint32_t node, begin, end, level;
  };
  std::vector<Pending> queue{{0, 0, n, 0}};  // breadth-first: nodes are appended in BFS order
  v.nodes_.push_back(Node{});
  v.centres_.resize(kDescriptorBytes, 0);
  SplitMix64 rng(options.seed);
  for (std::size_t q = 0; q < queue.size(); ++q) {
    const Pending p = queue[q];
    if (p.level >= options.depth) continue;  // a leaf
    const std::uint32_t m = p.end - p.begin;
    const std::uint32_t clusters =
        Cluster(descriptors, idx.data() + p.begin, m, k, options.max_iterations, &rng, &s);
    if (clusters <= 1) continue;  // nothing to separate: a leaf
    // Partition the range by cluster (stable), append the children contiguously.
    std::array<std::uint32_t, kMaxVocabularyBranching + 1> start{};
    for (std::uint32_t i = 0; i < m; ++i) ++start[s.assignment[i] + 1];
    for (std::uint32_t c = 0; c < clusters; ++c) start[c + 1] += start[c];
    std::array<std::uint32_t, kMaxVocabularyBranching + 1> fill = start;
    for (std::uint32_t i = 0; i < m; ++i) s.sorted[fill[s.assignment[i]]++] = idx[p.begin + i];
    std::copy_n(s.sorted.begin(), m, idx.begin() + p.begin);
    const auto first = static_cast<std::uint32_t>(v.nodes_.size());
    v.nodes_[p.node].first_child = first;
    v.nodes_[p.node].child_count = clusters;
    for (std::uint32_t c = 0; c < clusters; ++c) {
      v.nodes_.push_back(Node{});
      const std::uint8_t* centre = s.centres.data() + std::size_t{c} * kDescriptorBytes;
      v.centres_.insert(v.centres_.end(), centre, centre + kDescriptorBytes);
      queue.push_back(Pending{first + c, p.begin + start[c], p.begin + start[c + 1], p.level + 1});
    }
  }
  v.nodes_.shrink_to_fit();  // memory_bytes() then reports what the tree needs, not growth slack
  v.centres_.shrink_to_fit();
  std::uint32_t words = 0;
  for (Node& node : v.nodes_) {
    if (node.child_count == 0) node.word = words++;
  }

  // IDF over the training keyframes: n_w = keyframes with at least one descriptor in w.
  std::vector<std::uint32_t> keyframes_with(words, 0);
  std::vector<std::uint32_t> last_keyframe(words, 0xFFFFFFFFu);
  std::size_t at = 0;
  for (std::uint32_t kf = 0; kf < keyframe_sizes.size(); ++kf) {
    for (std::uint32_t i = 0; i < keyframe_sizes[kf]; ++i, ++at) {
      const WordId w = v.Quantize(descriptors[at].data());
      if (last_keyframe[w.value] != kf) {
        last_keyframe[w.value] = kf;
        ++keyframes_with[w.value];
      }
    }
  }
  v.idf_.resize(words);
  const double total = static_cast<double>(keyframe_sizes.size());
  for (std::uint32_t w = 0; w < words; ++w) {
    v.idf_[w] = keyframes_with[w] == 0
                    ? 0.0f
                    : static_cast<float>(std::log(total / static_cast<double>(keyframes_with[w])));
  }
  return v;
}

WordId Vocabulary::Quantize(const std::uint8_t* descriptor) const {
  std::uint32_t node = 0;
  while (nodes_[node].child_count != 0) {
    const Node& n = nodes_[node];
    node = n.first_child + Nearest(descriptor, centre(n.first_child), n.child_count);
  }
  return WordId{nodes_[node].word};
}

Status Vocabulary::Transform(const std::uint8_t* descriptors, std::size_t n, BowVector* out) const {
  out->size_ = 0;
  if (n > out->entries_.size()) {
    return OutOfRange("bag of words from " + std::to_string(n) + " descriptors > capacity " +
                      std::to_string(out->entries_.size()));
  }
  std::uint32_t* words = out->scratch_.data();
  for (std::size_t i = 0; i < n; ++i) words[i] = Quantize(descriptors + i * kDescriptorBytes).value;
  std::sort(words, words + n);
  double sum = 0.0;
  std::uint32_t size = 0;
  for (std::size_t i = 0; i < n;) {
    std::size_t j = i;
    while (j < n && words[j] == words[i]) ++j;
    const float w = static_cast<float>(j - i) / static_cast<float>(n) * idf_[words[i]];
    if (w > 0.0f) {
      out->entries_[size++] = BowEntry{WordId{words[i]}, w};
      sum += static_cast<double>(w);
    }
    i = j;
  }
  if (sum <= 0.0) return Status::Ok();  // only words seen everywhere: an empty bag
  for (std::uint32_t i = 0; i < size; ++i) {
    out->entries_[i].weight =
        static_cast<float>(static_cast<double>(out->entries_[i].weight) / sum);
  }
  out->size_ = size;
  return Status::Ok();
}

std::size_t Vocabulary::memory_bytes() const {
  return sizeof(Vocabulary) + nodes_.capacity() * sizeof(Node) + centres_.capacity() +
         idf_.capacity() * sizeof(float);
}

std::vector<std::byte> Vocabulary::ToBlob() const {
  const std::size_t body =
      nodes_.size() * (kBlobNodeBytes + kDescriptorBytes) + idf_.size() * sizeof(float);
  std::vector<std::byte> out(kBlobHeaderBytes + body);
  std::size_t at = kBlobHeaderBytes;
  for (const Node& n : nodes_) {
    Put(&out, at, n.first_child);
    Put(&out, at + 4, n.child_count);
    Put(&out, at + 8, n.word);
    at += kBlobNodeBytes;
  }
  std::memcpy(out.data() + at, centres_.data(), centres_.size());
  at += centres_.size();
  std::memcpy(out.data() + at, idf_.data(), idf_.size() * sizeof(float));
  Put(&out, 0, kBlobMagic);
  Put(&out, 4, kBlobVersion);
  Put(&out, 6, std::uint16_t{0});
  Put(&out, 8, branching_);
  Put(&out, 12, depth_);
  Put(&out, 16, node_count());
  Put(&out, 20, word_count());
  Put(&out, 24, training_keyframes_);
  Put(&out, 28, simd::Crc32c(out.data() + kBlobHeaderBytes, body));
  return out;
}

Result<Vocabulary> Vocabulary::FromBlob(std::span<const std::byte> blob) {
  auto corrupt = [](const std::string& what) { return Corrupt("vocabulary blob: " + what); };
  if (blob.size() < kBlobHeaderBytes) {
    return corrupt(std::to_string(blob.size()) + " bytes < " + std::to_string(kBlobHeaderBytes) +
                   "-byte header");
  }
  if (Get<std::uint32_t>(blob, 0) != kBlobMagic) return corrupt("bad magic (not a vocabulary)");
  const auto version = Get<std::uint16_t>(blob, 4);
  if (version != kBlobVersion) {
    return FailedPrecondition("vocabulary blob: version " + std::to_string(version) +
                              ", this build reads version " + std::to_string(kBlobVersion));
  }
  const auto branching = Get<std::uint32_t>(blob, 8);
  const auto depth = Get<std::uint32_t>(blob, 12);
  const auto node_count = Get<std::uint32_t>(blob, 16);
  const auto word_count = Get<std::uint32_t>(blob, 20);
  const auto training_keyframes = Get<std::uint32_t>(blob, 24);
  const auto crc = Get<std::uint32_t>(blob, 28);
  if (branching < 2 || branching > kMaxVocabularyBranching || depth < 1 ||
      depth > kMaxVocabularyDepth) {
    return corrupt("branching " + std::to_string(branching) + " / depth " + std::to_string(depth) +
                   " outside [2, " + std::to_string(kMaxVocabularyBranching) + "] / [1, " +
                   std::to_string(kMaxVocabularyDepth) + "]");
  }
  if (node_count < 1 || node_count > kMaxVocabularyNodes || word_count < 1 ||
      word_count > node_count) {
    return corrupt(std::to_string(node_count) + " nodes, " + std::to_string(word_count) +
                   " words: need 1 <= words <= nodes <= " + std::to_string(kMaxVocabularyNodes));
  }
  const std::uint64_t expected = kBlobHeaderBytes +
                                 std::uint64_t{node_count} * (kBlobNodeBytes + kDescriptorBytes) +
                                 std::uint64_t{word_count} * sizeof(float);
  if (blob.size() != expected) {
    return corrupt(std::to_string(blob.size()) + " bytes, header says " + std::to_string(expected) +
                   " (truncated or trailing data)");
  }
  if (simd::Crc32c(blob.data() + kBlobHeaderBytes, blob.size() - kBlobHeaderBytes) != crc) {
    return corrupt("body checksum mismatch");
  }

  Vocabulary v;
  v.branching_ = branching;
  v.depth_ = depth;
  v.training_keyframes_ = training_keyframes;
  v.nodes_.resize(node_count);
  std::size_t at = kBlobHeaderBytes;
  for (Node& n : v.nodes_) {
    n.first_child = Get<std::uint32_t>(blob, at);
    n.child_count = Get<std::uint32_t>(blob, at + 4);
    n.word = Get<std::uint32_t>(blob, at + 8);
    at += kBlobNodeBytes;
  }
  v.centres_.resize(std::size_t{node_count} * kDescriptorBytes);
  std::memcpy(v.centres_.data(), blob.data() + at, v.centres_.size());
  at += v.centres_.size();
  v.idf_.resize(word_count);
  std::memcpy(v.idf_.data(), blob.data() + at, v.idf_.size() * sizeof(float));

  // Structure: a tree rooted at 0 (each other node the child of exactly one earlier node), no
  // deeper than `depth`, each leaf one word and each word one leaf.
  std::vector<std::uint32_t> level(node_count, 0);
  std::vector<std::uint8_t> has_parent(node_count, 0);
  std::vector<std::uint8_t> word_seen(word_count, 0);
  for (std::uint32_t i = 0; i < node_count; ++i) {
    const Node& n = v.nodes_[i];
    if (i > 0 && has_parent[i] == 0) return corrupt("node " + std::to_string(i) + " has no parent");
    if (n.child_count == 0) {
      if (n.word >= word_count || word_seen[n.word] != 0) {
        return corrupt("leaf " + std::to_string(i) + " has word " + std::to_string(n.word) +
                       " (duplicate or >= " + std::to_string(word_count) + ")");
      }
      word_seen[n.word] = 1;
      continue;
    }
    if (n.word != kNoWord || n.child_count > branching || n.first_child <= i ||
        std::uint64_t{n.first_child} + n.child_count > node_count || level[i] >= depth) {
      return corrupt("inner node " + std::to_string(i) + " has children [" +
                     std::to_string(n.first_child) + ", +" + std::to_string(n.child_count) +
                     ") outside (node, " + std::to_string(node_count) + "), more than " +
                     std::to_string(branching) + ", or deeper than " + std::to_string(depth));
    }
    for (std::uint32_t c = n.first_child; c < n.first_child + n.child_count; ++c) {
      if (has_parent[c] != 0) return corrupt("node " + std::to_string(c) + " has two parents");
      has_parent[c] = 1;
      level[c] = level[i] + 1;
    }
  }
  for (std::uint32_t w = 0; w < word_count; ++w) {
    if (word_seen[w] == 0) return corrupt("word " + std::to_string(w) + " has no leaf");
    if (!std::isfinite(v.idf_[w]) || v.idf_[w] < 0.0f) {
      return corrupt("idf of word " + std::to_string(w) + " not finite and >= 0");
    }
  }
  return v;
}

}  // namespace zm
