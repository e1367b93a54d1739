// The visual vocabulary (lib/localization/vocabulary.h): deterministic training, descriptors of
// one cluster in one word with the majority as its centre, Quantize = greedy nearest descent,
// IDF from the training keyframes, L1-normalised bags, the blob round trip and its refusals, no
// allocation in Quantize/Transform.
#include "localization/vocabulary.h"

#include <doctest/doctest.h>

#include <bit>
#include <cmath>
#include <cstring>
#include <random>
#include <set>
#include <vector>

#include "simd/crc32c.h"
#include "support/counting_allocator.h"

namespace zm {
namespace {

Descriptor256 RandomDescriptor(std::mt19937_64& rng) {
  Descriptor256 d;
  for (std::size_t i = 0; i < d.size(); i += 8) {
    const std::uint64_t v = rng();
    std::memcpy(d.data() + i, &v, 8);
  }
  return d;
}

Descriptor256 Flip(Descriptor256 d, std::mt19937_64& rng, int bits) {
  for (int i = 0; i < bits; ++i) {
    const auto b = static_cast<std::size_t>(rng() % 256);
    d[b / 8] = static_cast<std::uint8_t>(d[b / 8] ^ (1u << (b % 8)));
  }
  return d;
}

std::uint32_t Hamming(const std::uint8_t* a, const std::uint8_t* b) {
  std::uint32_t d = 0;
  for (std::size_t i = 0; i < kDescriptorBytes; ++i) {
    d += static_cast<std::uint32_t>(std::popcount(static_cast<unsigned>(a[i] ^ b[i])));
  }
  return d;
}

// 8 well-separated bases; keyframe j holds 5 noisy copies (<= 6 flipped bits) of bases j and
// j + 1 (mod 8), so each base is seen in exactly 2 of the 8 keyframes.
struct ClusteredSet {
  std::vector<Descriptor256> bases;
  std::vector<Descriptor256> descriptors;
  std::vector<std::uint32_t> base_of;  // per descriptor
  std::vector<std::uint32_t> keyframe_sizes;
};

ClusteredSet MakeClusteredSet() {
  std::mt19937_64 rng(7);
  ClusteredSet s;
  for (int b = 0; b < 8; ++b) s.bases.push_back(RandomDescriptor(rng));
  for (std::uint32_t kf = 0; kf < 8; ++kf) {
    for (const std::uint32_t b : {kf, (kf + 1) % 8}) {
      for (int i = 0; i < 5; ++i) {
        s.descriptors.push_back(Flip(s.bases[b], rng, 6));
        s.base_of.push_back(b);
      }
    }
    s.keyframe_sizes.push_back(10);
  }
  return s;
}

// Random descriptors in `keyframes` keyframes of `per` each.
std::vector<Descriptor256> RandomSet(std::uint64_t seed, std::size_t n) {
  std::mt19937_64 rng(seed);
  std::vector<Descriptor256> out(n);
  for (auto& d : out) d = RandomDescriptor(rng);
  return out;
}

Vocabulary TrainRandom(const std::vector<Descriptor256>& set, std::uint32_t keyframes,
                       VocabularyOptions options = {}) {
  std::vector<std::uint32_t> sizes(keyframes, static_cast<std::uint32_t>(set.size() / keyframes));
  auto v = Vocabulary::Train(set, sizes, options);
  REQUIRE(v.ok());
  return std::move(v).value();
}

TEST_CASE("vocabulary: options are checked, the field and the limit named") {
  VocabularyOptions o;
  CHECK(ValidateVocabularyOptions(o).ok());
  o.branching = 1;
  CHECK(ValidateVocabularyOptions(o).message().find("branching 1") != std::string::npos);
  o = {};
  o.depth = 9;
  CHECK(ValidateVocabularyOptions(o).message().find("depth 9") != std::string::npos);
  o = {};
  o.branching = 32;
  o.depth = 8;
  CHECK(ValidateVocabularyOptions(o).message().find("nodes > limit") != std::string::npos);

  const std::vector<Descriptor256> set = RandomSet(1, 20);
  const std::vector<std::uint32_t> wrong{10, 5};
  const auto bad = Vocabulary::Train(set, wrong, {});
  REQUIRE_FALSE(bad.ok());
  CHECK(bad.status().message().find("sum to 15") != std::string::npos);
  CHECK_FALSE(Vocabulary::Train({}, {}, {}).ok());
}

TEST_CASE("vocabulary: training is deterministic for a seed") {
  const std::vector<Descriptor256> set = RandomSet(3, 600);
  VocabularyOptions o;
  o.branching = 5;
  o.depth = 3;
  const Vocabulary a = TrainRandom(set, 20, o);
  const Vocabulary b = TrainRandom(set, 20, o);
  CHECK(a.ToBlob() == b.ToBlob());
  CHECK(a.word_count() > 25);
  CHECK(a.word_count() <= 125);
  // Training ends each split on an assignment to the final centres, so the descriptors that made
  // a leaf quantize to it: every word is reached by the training set.
  std::set<std::uint32_t> reached;
  for (const Descriptor256& d : set) reached.insert(a.Quantize(d.data()).value);
  CHECK(reached.size() == a.word_count());
  o.seed += 1;
  const Vocabulary c = TrainRandom(set, 20, o);
  CHECK(c.ToBlob() != a.ToBlob());  // the seed matters (k-means++ draws)
}

TEST_CASE("vocabulary: a cluster's descriptors share one word whose centre is their majority") {
  const ClusteredSet s = MakeClusteredSet();
  VocabularyOptions o;
  o.branching = 8;
  o.depth = 1;
  auto trained = Vocabulary::Train(s.descriptors, s.keyframe_sizes, o);
  REQUIRE(trained.ok());
  const Vocabulary& v = trained.value();
  CHECK(v.word_count() == 8);
  std::vector<std::uint32_t> word_of_base(8, Vocabulary::kNoWord);
  for (std::size_t i = 0; i < s.descriptors.size(); ++i) {
    const WordId w = v.Quantize(s.descriptors[i].data());
    if (word_of_base[s.base_of[i]] == Vocabulary::kNoWord) word_of_base[s.base_of[i]] = w.value;
    CHECK(word_of_base[s.base_of[i]] == w.value);
  }
  CHECK(std::set<std::uint32_t>(word_of_base.begin(), word_of_base.end()).size() == 8);
  // Each base is the bitwise majority of its 10 noisy copies (6 flips each), hence the centre.
  for (std::uint32_t b = 0; b < 8; ++b) {
    for (std::uint32_t n = 0; n < v.node_count(); ++n) {
      if (v.nodes()[n].word == word_of_base[b]) {
        CHECK(std::memcmp(v.centre(n), s.bases[b].data(), kDescriptorBytes) == 0);
      }
    }
    // Seen in 2 of 8 training keyframes: idf = ln(8 / 2).
    CHECK(v.idf(WordId{word_of_base[b]}) == doctest::Approx(std::log(4.0)).epsilon(1e-6));
  }
}

TEST_CASE("vocabulary: Quantize is the greedy nearest-child descent (first nearest on ties)") {
  const std::vector<Descriptor256> set = RandomSet(5, 400);
  VocabularyOptions o;
  o.branching = 4;
  o.depth = 3;
  const Vocabulary v = TrainRandom(set, 10, o);
  const std::vector<Descriptor256> queries = RandomSet(6, 200);
  for (const Descriptor256& q : queries) {
    std::uint32_t node = 0;
    while (v.nodes()[node].child_count != 0) {
      const Vocabulary::Node& n = v.nodes()[node];
      std::uint32_t best = n.first_child;
      for (std::uint32_t c = n.first_child; c < n.first_child + n.child_count; ++c) {
        if (Hamming(q.data(), v.centre(c)) < Hamming(q.data(), v.centre(best))) best = c;
      }
      node = best;
    }
    CHECK(v.Quantize(q.data()).value == v.nodes()[node].word);
  }
  // Training descriptors: a node with at most k distinct descriptors has one child per
  // descriptor, so a depth-1 vocabulary over 3 descriptors maps each to its own word.
  const std::vector<Descriptor256> three = RandomSet(8, 3);
  const std::vector<std::uint32_t> one{3};
  auto tiny = Vocabulary::Train(three, one, o);
  REQUIRE(tiny.ok());
  CHECK(tiny->word_count() == 3);
  std::set<std::uint32_t> words;
  for (const auto& d : three) words.insert(tiny->Quantize(d.data()).value);
  CHECK(words.size() == 3);
}

TEST_CASE("vocabulary: Transform gives a sorted, unique, L1-normalised tf-idf bag") {
  const ClusteredSet s = MakeClusteredSet();
  VocabularyOptions o;
  o.branching = 8;
  o.depth = 1;
  auto v = Vocabulary::Train(s.descriptors, s.keyframe_sizes, o);
  REQUIRE(v.ok());
  BowVector bag(64);
  // Keyframe 0: 5 copies of base 0 and 5 of base 1, same idf: two words of weight 1/2.
  REQUIRE(v->Transform(s.descriptors[0].data(), 10, &bag).ok());
  REQUIRE(bag.size() == 2);
  CHECK(bag.entries()[0].word < bag.entries()[1].word);
  CHECK(bag.entries()[0].weight == doctest::Approx(0.5));
  CHECK(bag.entries()[1].weight == doctest::Approx(0.5));
  // 3 copies of one base + 7 of another: weights 0.3 / 0.7.
  std::vector<Descriptor256> mix(s.descriptors.begin() + 2, s.descriptors.begin() + 12);
  REQUIRE(v->Transform(mix[0].data(), mix.size(), &bag).ok());
  REQUIRE(bag.size() == 2);
  float sum = 0.0f;
  for (const BowEntry& e : bag.entries()) sum += e.weight;
  CHECK(sum == doctest::Approx(1.0f));
  BowVector small(4);
  const Status too_many = v->Transform(s.descriptors[0].data(), 10, &small);
  CHECK(too_many.code() == StatusCode::kOutOfRange);
  CHECK(small.size() == 0);

  {  // warm Quantize and Transform allocate nothing
    test::AllocationCounter news;
    test::MallocCounter mallocs;
    for (std::size_t r = 0; r < 10; ++r) {
      REQUIRE(v->Transform(s.descriptors[0].data(), 10, &bag).ok());
      CHECK(v->Quantize(s.descriptors[r].data()).value < v->word_count());
    }
    CHECK(news.allocations() == 0);
    CHECK(mallocs.mallocs() == 0);
  }
}

TEST_CASE("vocabulary: blob round trip is identical, memory footprint is reported") {
  const std::vector<Descriptor256> set = RandomSet(9, 500);
  VocabularyOptions o;
  o.branching = 6;
  o.depth = 3;
  const Vocabulary v = TrainRandom(set, 25, o);
  const std::vector<std::byte> blob = v.ToBlob();
  auto back = Vocabulary::FromBlob(blob);
  REQUIRE(back.ok());
  CHECK(back->ToBlob() == blob);
  CHECK(back->word_count() == v.word_count());
  CHECK(back->training_keyframes() == 25);
  for (const Descriptor256& q : RandomSet(10, 100)) {
    CHECK(back->Quantize(q.data()) == v.Quantize(q.data()));
  }
  CHECK(v.memory_bytes() >= v.node_count() * (kDescriptorBytes + sizeof(Vocabulary::Node)));
}

TEST_CASE("vocabulary: truncated, padded or corrupt blobs are refused with one clear error") {
  const std::vector<Descriptor256> set = RandomSet(11, 300);
  VocabularyOptions o;
  o.branching = 4;
  o.depth = 2;
  const std::vector<std::byte> blob = TrainRandom(set, 10, o).ToBlob();

  for (std::size_t n = 0; n < blob.size(); n += (n < 64 ? 1 : 37)) {  // every header prefix
    const auto r = Vocabulary::FromBlob(std::span(blob.data(), n));
    REQUIRE_FALSE(r.ok());
    CHECK(r.status().code() == StatusCode::kCorrupt);
  }
  const auto short_header = Vocabulary::FromBlob(std::span(blob.data(), 10));
  CHECK(short_header.status().message() == "vocabulary blob: 10 bytes < 32-byte header");
  std::vector<std::byte> padded = blob;
  padded.push_back(std::byte{0});
  CHECK(Vocabulary::FromBlob(padded).status().message().find("trailing") != std::string::npos);

  std::vector<std::byte> flipped = blob;
  flipped[blob.size() / 2] ^= std::byte{0x10};
  CHECK(Vocabulary::FromBlob(flipped).status().message() ==
        "vocabulary blob: body checksum mismatch");

  std::vector<std::byte> magic = blob;
  magic[0] = std::byte{'X'};
  CHECK(Vocabulary::FromBlob(magic).status().code() == StatusCode::kCorrupt);
  std::vector<std::byte> version = blob;
  version[4] = std::byte{9};
  CHECK(Vocabulary::FromBlob(version).status().code() == StatusCode::kFailedPrecondition);

  // A structural lie with a valid checksum: the root's first child pointing back at the root.
  std::vector<std::byte> cyclic = blob;
  const std::uint32_t zero = 0;
  std::memcpy(cyclic.data() + 32, &zero, 4);
  const std::uint32_t crc = simd::Crc32c(cyclic.data() + 32, cyclic.size() - 32);
  std::memcpy(cyclic.data() + 28, &crc, 4);
  const auto r = Vocabulary::FromBlob(cyclic);
  REQUIRE_FALSE(r.ok());
  CHECK(r.status().code() == StatusCode::kCorrupt);
  CHECK(r.status().message().find("inner node 0") != std::string::npos);
}

}  // namespace
}  // namespace zm
