// The inverted index over resident keyframes (lib/localization/inverted_index.h): the same top-k
// as a brute-force DBoW2 L1 score (1 - |q - d|_1 / 2 over whole vectors) on seeded random bags,
// Remove restores the previous state exactly, capacity bounds hold when full, errors name the
// limit, the work of Score grows with the resident set, and Add/Remove/Score never allocate.
#include "localization/inverted_index.h"

#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <random>
#include <vector>

#include "support/counting_allocator.h"

namespace zm {
namespace {

constexpr std::uint32_t kWords = 3000;
constexpr std::uint32_t kMaxWords = 200;

// A random bag of 20..kMaxWords distinct words with random positive weights, normalised.
void RandomBag(std::mt19937_64& rng, BowVector* bag) {
  std::uniform_int_distribution<std::uint32_t> count(20, kMaxWords);
  std::uniform_int_distribution<std::uint32_t> word(0, kWords - 1);
  std::uniform_real_distribution<float> weight(0.05f, 1.0f);
  std::vector<std::uint32_t> words;
  const std::uint32_t n = count(rng);
  while (words.size() < n) {
    words.push_back(word(rng));
    std::sort(words.begin(), words.end());
    words.erase(std::unique(words.begin(), words.end()), words.end());
  }
  std::vector<BowEntry> entries;
  for (const std::uint32_t w : words) entries.push_back(BowEntry{WordId{w}, weight(rng)});
  REQUIRE(bag->Assign(entries).ok());
}

// Half of a resident bag's words with new weights plus fresh words: a query that looks like it.
void NearCopy(std::mt19937_64& rng, const BowVector& of, BowVector* bag) {
  std::uniform_real_distribution<float> weight(0.05f, 1.0f);
  std::map<std::uint32_t, float> m;
  for (const BowEntry& e : of.entries()) {
    if (rng() % 2 == 0) m[e.word.value] = weight(rng);
  }
  for (int i = 0; i < 30; ++i) m[static_cast<std::uint32_t>(rng() % kWords)] = weight(rng);
  std::vector<BowEntry> entries;
  for (const auto& [w, x] : m) entries.push_back(BowEntry{WordId{w}, x});
  REQUIRE(bag->Assign(entries).ok());
}

double BruteL1(const BowVector& q, const BowVector& d) {
  std::map<std::uint32_t, std::pair<double, double>> m;
  for (const BowEntry& e : q.entries()) m[e.word.value].first = e.weight;
  for (const BowEntry& e : d.entries()) m[e.word.value].second = e.weight;
  double l1 = 0.0;
  for (const auto& [w, p] : m) l1 += std::abs(p.first - p.second);
  return 1.0 - 0.5 * l1;
}

struct Resident {
  std::uint32_t slot;
  const BowVector* bag;
};

// Brute-force top k (score > 0), best first, ties to the larger id (= slot + 1000 here).
std::vector<std::pair<double, std::uint32_t>> BruteTopK(const BowVector& q,
                                                        const std::vector<Resident>& resident,
                                                        std::size_t k) {
  std::vector<std::pair<double, std::uint32_t>> all;
  for (const Resident& r : resident) {
    const double s = BruteL1(q, *r.bag);
    if (s > 1e-6) all.emplace_back(s, r.slot);
  }
  std::sort(all.begin(), all.end(), [](const auto& a, const auto& b) {
    return a.first != b.first ? a.first > b.first : a.second > b.second;
  });
  if (all.size() > k) all.resize(k);
  return all;
}

void CheckAgainstBrute(InvertedIndex& index, const BowVector& q,
                       const std::vector<Resident>& resident, std::uint32_t k) {
  std::vector<IndexCandidate> out(k);
  const std::size_t n = index.Score(q, k, out);
  const auto brute = BruteTopK(q, resident, k);
  REQUIRE(n == brute.size());
  for (std::size_t i = 0; i < n; ++i) {
    CHECK(out[i].score == doctest::Approx(brute[i].first).epsilon(1e-5));
    // Same keyframe unless two brute scores are too close for float accumulation to order.
    const bool separated = (i == 0 || brute[i - 1].first - brute[i].first > 1e-4) &&
                           (i + 1 == n || brute[i].first - brute[i + 1].first > 1e-4);
    if (separated) CHECK(out[i].slot.value == brute[i].second);
    CHECK(out[i].id.value == 1000 + out[i].slot.value);
  }
}

TEST_CASE("inverted index: options and inputs are checked, the limit named") {
  CHECK(ValidateInvertedIndexOptions({kWords, 100, kMaxWords}).ok());
  CHECK(ValidateInvertedIndexOptions({0, 100, kMaxWords}).message().find("word_count") !=
        std::string::npos);
  CHECK(ValidateInvertedIndexOptions({kWords, 1u << 26, 512}).code() == StatusCode::kOutOfRange);

  InvertedIndex index({kWords, 4, 3});
  BowVector bag(8);
  REQUIRE(bag.Assign(std::vector<BowEntry>{{WordId{1}, 1.0f}, {WordId{5}, 2.0f}}).ok());
  CHECK(index.Add(SlotIndex{4}, KeyframeId{1}, bag).message() ==
        "inverted index slot 4 >= max_keyframes 4");
  REQUIRE(index.Add(SlotIndex{0}, KeyframeId{7}, bag).ok());
  CHECK(index.Add(SlotIndex{0}, KeyframeId{8}, bag).message() ==
        "inverted index slot 0 already holds keyframe 7");
  BowVector big(8);
  REQUIRE(
      big.Assign(std::vector<BowEntry>{
                     {WordId{1}, 1.0f}, {WordId{2}, 1.0f}, {WordId{3}, 1.0f}, {WordId{4}, 1.0f}})
          .ok());
  CHECK(index.Add(SlotIndex{1}, KeyframeId{9}, big).code() == StatusCode::kOutOfRange);
  BowVector out_of_vocabulary(8);
  REQUIRE(out_of_vocabulary.Assign(std::vector<BowEntry>{{WordId{kWords}, 1.0f}}).ok());
  CHECK(index.Add(SlotIndex{1}, KeyframeId{9}, out_of_vocabulary).code() ==
        StatusCode::kInvalidArgument);
  CHECK(index.Remove(SlotIndex{2}).code() == StatusCode::kNotFound);
  CHECK(bag.Assign(std::vector<BowEntry>{{WordId{5}, 1.0f}, {WordId{1}, 1.0f}}).code() ==
        StatusCode::kInvalidArgument);  // unsorted
  CHECK(index.resident() == 1);
  CHECK(index.postings() == 2);
}

TEST_CASE("inverted index: same top-k as a brute-force L1 score, Remove restores the state") {
  constexpr std::uint32_t kKeyframes = 300;
  std::mt19937_64 rng(26);
  std::vector<BowVector> bags;
  bags.reserve(kKeyframes);
  for (std::uint32_t i = 0; i < kKeyframes; ++i) {
    bags.emplace_back(kMaxWords + 40);
    RandomBag(rng, &bags.back());
  }
  std::vector<BowVector> queries;
  queries.reserve(20);
  for (int i = 0; i < 20; ++i) {
    queries.emplace_back(kMaxWords + 40);
    if (i % 2 == 0) {
      RandomBag(rng, &queries.back());
    } else {
      NearCopy(rng, bags[rng() % kKeyframes], &queries.back());
    }
  }

  InvertedIndex index({kWords, kKeyframes, kMaxWords + 40});
  std::vector<Resident> resident;
  for (std::uint32_t i = 0; i < kKeyframes; ++i) {
    REQUIRE(index.Add(SlotIndex{i}, KeyframeId{1000 + i}, bags[i]).ok());
    resident.push_back({i, &bags[i]});
  }
  for (const BowVector& q : queries) CheckAgainstBrute(index, q, resident, 10);

  // Scores before, then add and remove a third of the keyframes again: identical results.
  auto snapshot = [&] {
    std::vector<IndexCandidate> all;
    for (const BowVector& q : queries) {
      std::vector<IndexCandidate> out(kMaxIndexCandidates);
      const std::size_t n = index.Score(q, kMaxIndexCandidates, out);
      all.insert(all.end(), out.begin(), out.begin() + static_cast<std::ptrdiff_t>(n));
    }
    return all;
  };
  const std::uint64_t postings = index.postings();
  for (std::uint32_t i = 0; i < kKeyframes; i += 3) REQUIRE(index.Remove(SlotIndex{i}).ok());
  std::vector<Resident> fewer;
  for (const Resident& r : resident) {
    if (r.slot % 3 != 0) fewer.push_back(r);
  }
  for (const BowVector& q : queries) CheckAgainstBrute(index, q, fewer, 10);
  const auto before = snapshot();
  const std::uint64_t walked_fewer = index.last_postings_walked();
  for (std::uint32_t i = 0; i < kKeyframes; i += 3) {
    REQUIRE(index.Add(SlotIndex{i}, KeyframeId{1000 + i}, bags[i]).ok());
  }
  CHECK(index.postings() == postings);
  CHECK(index.last_postings_walked() == walked_fewer);
  (void)snapshot();
  CHECK(index.last_postings_walked() > walked_fewer);  // more resident, more postings walked
  for (std::uint32_t i = 0; i < kKeyframes; i += 3) REQUIRE(index.Remove(SlotIndex{i}).ok());
  const auto after = snapshot();
  REQUIRE(after.size() == before.size());
  for (std::size_t i = 0; i < after.size(); ++i) {
    CHECK(after[i].slot == before[i].slot);
    CHECK(after[i].score == before[i].score);  // bitwise: same words, same order of addition
  }

  for (std::uint32_t i = 0; i < kKeyframes; ++i) {
    if (index.contains(SlotIndex{i})) REQUIRE(index.Remove(SlotIndex{i}).ok());
  }
  CHECK(index.resident() == 0);
  CHECK(index.postings() == 0);
  std::vector<IndexCandidate> out(10);
  CHECK(index.Score(queries[0], 10, out) == 0);
}

TEST_CASE("inverted index: full to K_max x M in the worst block patterns, no allocation") {
  constexpr std::uint32_t kSlots = 64;
  constexpr std::uint32_t kM = 40;
  // Pattern 1: every keyframe its own words (one partly filled block per word).
  // Pattern 2: every keyframe the same words (long chains).
  for (const bool shared : {false, true}) {
    InvertedIndex index({kSlots * kM, kSlots, kM});
    std::vector<BowVector> bags;
    bags.reserve(kSlots);
    for (std::uint32_t s = 0; s < kSlots; ++s) {
      std::vector<BowEntry> e;
      for (std::uint32_t w = 0; w < kM; ++w) {
        e.push_back(BowEntry{WordId{shared ? w : s * kM + w}, 1.0f + static_cast<float>(w)});
      }
      bags.emplace_back(kM);
      REQUIRE(bags.back().Assign(e).ok());
    }
    std::vector<IndexCandidate> out(kMaxIndexCandidates);
    test::AllocationCounter news;
    test::MallocCounter mallocs;
    for (int round = 0; round < 3; ++round) {
      for (std::uint32_t s = 0; s < kSlots; ++s) {
        REQUIRE(index.Add(SlotIndex{s}, KeyframeId{1000 + s}, bags[s]).ok());
      }
      const std::size_t n = index.Score(bags[5], kMaxIndexCandidates, out);
      CHECK(n == (shared ? std::size_t{kMaxIndexCandidates} : 1u));
      CHECK(out[0].score == doctest::Approx(1.0f));
      if (!shared) CHECK(out[0].id.value == 1005);
      for (std::uint32_t s = 0; s < kSlots; s += 2) REQUIRE(index.Remove(SlotIndex{s}).ok());
      for (std::uint32_t s = 1; s < kSlots; s += 2) REQUIRE(index.Remove(SlotIndex{s}).ok());
    }
    CHECK(news.allocations() == 0);
    CHECK(mallocs.mallocs() == 0);
    CHECK(index.memory_bytes() > std::size_t{kSlots} * kM * 8);
    // Filled and emptied three times over, it holds what BytesFor says (the budget's figure).
    CHECK(index.memory_bytes() == InvertedIndex::BytesFor(index.options()));
  }
}

}  // namespace
}  // namespace zm
