// DeriveBudget: the one derivation of K_max (style.md §14), worked by hand.
#include "runtime/budget.h"

#include <doctest/doctest.h>

#include "arena/frame_scratch.h"
#include "localization/frame_scratch_size.h"
#include "localization/localizer.h"

namespace zm {
namespace {

BudgetInputs Orin(std::uint64_t slot, std::uint64_t keyframes) {
  BudgetInputs in;
  in.device = {.name = "orin", .power_mode = "", .memory_bytes = 8ULL << 30,
               .os_reserve_bytes = 1792ULL << 20};
  in.model = {.name = "qwen3-vl-2b", .weights_bytes = 1'900'000'000, .kv_cache_bytes = 0};
  in.map.headroom_bytes = 512ULL << 20;
  in.map.overhead_bytes = 256ULL << 20;
  in.largest_keyframe_bytes = slot;
  in.keyframe_count = keyframes;
  return in;
}

TEST_CASE("share = device - OS - model - headroom, K_max = (share - overhead) / slot") {
  const BudgetInputs in = Orin(2'000'000, 10'000);
  Result<Budget> b = DeriveBudget(in);
  REQUIRE(b.ok());
  const std::uint64_t share = (8ULL << 30) - (1792ULL << 20) - 1'900'000'000ULL - (512ULL << 20);
  CHECK(b->map_share_bytes == share);
  CHECK(b->keyframe_bytes == share - (256ULL << 20));
  CHECK(b->k_max == (share - (256ULL << 20)) / 2'000'000);  // 1,868 slots of 2 MB
  CHECK(b->arena_slots == b->k_max);
  CHECK(b->bounded);
}

TEST_CASE("the count, the bytes and the map size: the tightest wins") {
  BudgetInputs in = Orin(2'000'000, 10'000);
  in.map.memory_thr_keyframes = 500;
  CHECK(DeriveBudget(in)->k_max == 500);
  in.keyframe_count = 120;  // a small map: everything fits
  CHECK(DeriveBudget(in)->k_max == 120);
  in.map.memory_thr_keyframes = 0;
  in.device.memory_bytes = 0;  // no device, no count: the whole map
  CHECK(DeriveBudget(in)->k_max == 120);
}

TEST_CASE("basic and unbounded: the arena holds the whole map, residency is measured not capped") {
  BudgetInputs in = Orin(2'000'000, 10'000);
  in.bounded_policy = false;
  Result<Budget> b = DeriveBudget(in);
  REQUIRE(b.ok());
  CHECK(b->arena_slots == 10'000);
  CHECK(b->k_max < 10'000);
  CHECK_FALSE(b->bounded);
  in.unbounded_policy = true;
  b = DeriveBudget(in);
  CHECK(b->k_max == 10'000);
  CHECK(b->map_share_bytes == 0);
}

TEST_CASE("localization is counted: the vocabulary, the index over the slots, the frame scratch") {
  BudgetInputs in = Orin(2'000'000, 10'000);
  const Budget plain = DeriveBudget(in).value();
  CHECK(plain.vocabulary_bytes == 0);  // a map without a vocabulary, frames with features
  CHECK(plain.index_bytes == 0);
  CHECK(plain.frame_scratch_bytes == 0);

  in.localization = {.vocabulary_bytes = 527'008,
                     .vocabulary_words = 9'960,
                     .word_features = 500,
                     .image_width = 640,
                     .image_height = 480};
  Result<Budget> b = DeriveBudget(in);
  REQUIRE(b.ok());
  const std::uint64_t scratch = FrameScratch::ReservedBytes(FrameScratchBytesFor(640, 480));
  CHECK(scratch >= 8ULL * 640 * 480 + (2ULL << 20));
  CHECK(b->vocabulary_bytes == 527'008);
  CHECK(b->frame_scratch_bytes == scratch);
  CHECK(b->keyframe_bytes == plain.keyframe_bytes - 527'008 - scratch);
  // Each keyframe costs its slot and its postings: K_max is the most that fit with the index.
  const auto cost = [](std::uint64_t k) {
    return k * 2'000'000 + VocabularyIndexBytes(9'960, static_cast<std::uint32_t>(k), 500);
  };
  CHECK(cost(b->k_max) <= b->keyframe_bytes);
  CHECK(cost(b->k_max + 1) > b->keyframe_bytes);
  CHECK(b->k_max < plain.k_max);
  CHECK(b->index_bytes == VocabularyIndexBytes(9'960, b->arena_slots, 500));

  // basic: K_max the same way, the index over its whole-map arena.
  in.bounded_policy = false;
  b = DeriveBudget(in);
  REQUIRE(b.ok());
  CHECK(b->arena_slots == 10'000);
  CHECK(b->index_bytes == VocabularyIndexBytes(9'960, 10'000, 500));
  CHECK(cost(b->k_max) <= b->keyframe_bytes);

  // A profile's own scratch size is what the region reserves (to the page).
  in.bounded_policy = true;
  in.localization.scratch_bytes = 5'000'001;
  CHECK(DeriveBudget(in)->frame_scratch_bytes == FrameScratch::ReservedBytes(5'000'001));

  // Too little left beside the vocabulary and the scratch: named.
  in.map.map_share_bytes = (256ULL << 20) + 527'008 + 1;
  const Result<Budget> none = DeriveBudget(in);
  REQUIRE_FALSE(none.ok());
  CHECK(none.status().message().find("frame scratch") != std::string::npos);
}

TEST_CASE("a run's options become budget inputs by the policy's name") {
  const BudgetInputs orin = Orin(2'000'000, 10'000);
  for (const char* bounded : {"semantic", "predictive", "radius", "oracle"}) {
    const BudgetInputs in = BudgetInputsFor(orin.device, orin.model, orin.map,
                                            *ParsePolicyKind(bounded), 2'000'000, 10'000);
    CHECK_MESSAGE(in.bounded_policy, bounded);
    CHECK_FALSE(in.unbounded_policy);
    CHECK(in.largest_keyframe_bytes == 2'000'000);
    CHECK(in.keyframe_count == 10'000);
  }
  const BudgetInputs basic =
      BudgetInputsFor(orin.device, orin.model, orin.map, PolicyKind::kBasic, 2'000'000, 10'000);
  CHECK_FALSE(basic.bounded_policy);
  CHECK_FALSE(basic.unbounded_policy);
  const BudgetInputs unbounded =
      BudgetInputsFor(orin.device, orin.model, orin.map, PolicyKind::kUnbounded, 2'000'000, 10'000);
  CHECK_FALSE(unbounded.bounded_policy);
  CHECK(unbounded.unbounded_policy);
  CHECK(DeriveBudget(unbounded)->k_max == 10'000);
}

TEST_CASE("errors name the quantity and the limit") {
  BudgetInputs in = Orin(2'000'000, 10'000);
  in.map.slot_bytes = 4096;
  Result<Budget> b = DeriveBudget(in);
  REQUIRE_FALSE(b.ok());
  CHECK(b.status().message().find("map.slot_bytes 4096") != std::string::npos);
  CHECK(b.status().message().find("2000000") != std::string::npos);

  in = Orin(2'000'000, 10'000);
  in.model.weights_bytes = 7ULL << 30;
  b = DeriveBudget(in);
  REQUIRE_FALSE(b.ok());
  CHECK(b.status().message().find("no map share left") != std::string::npos);

  in = Orin(2'000'000, 10'000);
  in.map.map_share_bytes = 200ULL << 20;  // below the overhead
  CHECK(DeriveBudget(in).status().message().find("map.overhead_bytes") != std::string::npos);

  in = Orin(0, 10'000);
  CHECK(DeriveBudget(in).status().message().find("slot size is unknown") != std::string::npos);
  CHECK_FALSE(DeriveBudget(Orin(2'000'000, 0)).ok());
}

}  // namespace
}  // namespace zm
