// The localizer with a vocabulary (Localizer::UseVocabulary): the frame's bag of words scores
// the resident keyframes through an inverted index that Localize keeps equal to the resident
// set it is handed. On the synthetic corridor it localizes as the binary-word scorer does; the
// index follows the resident set (keyframes leave with their zone, a slot reused by another
// keyframe is re-indexed); the index's work grows with the resident set; only resident
// keyframes are hypotheses or matches (invariant 4); a warm tick allocates nothing.
#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <set>
#include <vector>

#include "localization/camera.h"
#include "localization/localizer.h"
#include "localization/vocabulary.h"
#include "support/counting_allocator.h"
#include "synthetic_world.h"

namespace zm {
namespace {

using test::KeyframeStore;
using test::World;

KeyframeStore MakeKeyframes(World& world) {
  KeyframeStore store;
  for (int i = 0; i <= 40; ++i) {
    const Pose3 pose = PoseFromXYYaw(i, 0.0, 0.0);
    store.Add(KeyframeId{i + 1}, pose, world.Observe(pose));
  }
  return store;
}

// The store's keyframes, each in its own slot (slot = position), as the arena would hold them.
std::vector<ResidentKeyframe> InSlots(std::vector<ResidentKeyframe> kfs, std::uint32_t first = 0) {
  for (std::size_t i = 0; i < kfs.size(); ++i) kfs[i].slot = SlotIndex{first + static_cast<std::uint32_t>(i)};
  return kfs;
}

Vocabulary TrainOn(const std::vector<ResidentKeyframe>& kfs) {
  std::vector<Descriptor256> all;
  std::vector<std::uint32_t> sizes;
  for (const ResidentKeyframe& kf : kfs) {
    for (std::uint32_t f = 0; f < kf.view.feature_count; ++f) {
      Descriptor256 d;
      std::copy_n(kf.view.descriptors + 32 * std::size_t{f}, 32, d.begin());
      all.push_back(d);
    }
    sizes.push_back(kf.view.feature_count);
  }
  VocabularyOptions o;
  o.branching = 8;
  o.depth = 3;
  auto v = Vocabulary::Train(all, sizes, o);
  REQUIRE(v.ok());
  return std::move(v).value();
}

TEST_CASE("vocabulary likelihood: localizes along the corridor, hypotheses at the right place") {
  World world({});
  const KeyframeStore store = MakeKeyframes(world);
  const std::vector<ResidentKeyframe> resident = InSlots(store.all());
  const Vocabulary vocab = TrainOn(resident);
  Localizer loc(LocalizerConfig{}, world.camera());
  REQUIRE(loc.UseVocabulary(&vocab, 64).ok());
  std::uint32_t accepted = 0;
  std::uint32_t near = 0;
  const int frames = 40;
  for (int k = 0; k < frames; ++k) {
    const Pose3 truth = PoseFromXYYaw(0.5 + 0.9 * k, 0.2, 0.05);
    const Frame frame = test::MakeFrame(static_cast<std::uint64_t>(k), 0.1 * k, truth, world.Observe(truth));
    const LocalizeResult r = loc.Localize(frame, truth, resident);
    if (k == 0) CHECK(r.index_added == resident.size());
    if (k > 0) CHECK(r.index_added == 0);
    if (r.accepted) {
      ++accepted;
      CHECK((r.t_map_body.translation() - truth.translation()).norm() < 0.2);
    }
    if (r.highest_hypothesis.value > 0 &&
        std::abs(static_cast<double>(r.highest_hypothesis.value - 1) - truth.translation().x()) < 3.0) {
      ++near;
    }
    CHECK(r.postings_walked > 0);
    CHECK(r.highest_likelihood <= 1.0f);
  }
  MESSAGE("vocabulary: " << accepted << " of " << frames << " accepted, hypothesis within 3 m in "
                         << near);
  CHECK(accepted * 4 >= frames * 3);
  CHECK(near * 4 >= frames * 3);
}

TEST_CASE("vocabulary likelihood: the index follows the resident set, and its work grows with it") {
  World world({});
  const KeyframeStore store = MakeKeyframes(world);
  const std::vector<ResidentKeyframe> all = InSlots(store.all());
  const Vocabulary vocab = TrainOn(all);
  Localizer loc(LocalizerConfig{}, world.camera());
  REQUIRE(loc.UseVocabulary(&vocab, 64).ok());
  const Pose3 truth = PoseFromXYYaw(30.2, 0.1, 0.0);
  const Frame frame = test::MakeFrame(0, 0.0, truth, world.Observe(truth));

  LocalizeResult r = loc.Localize(frame, truth, all);
  const std::uint64_t walked_all = r.postings_walked;
  CHECK(r.index_added == all.size());
  // Only the first ten keyframes stay (x in [0, 9]): 31 leave; the frame's place is gone.
  const std::vector<ResidentKeyframe> first(all.begin(), all.begin() + 10);
  r = loc.Localize(frame, truth, first);
  CHECK(r.index_removed == all.size() - 10);
  CHECK(r.index_added == 0);
  CHECK_FALSE(r.accepted);
  const std::uint64_t walked_ten = r.postings_walked;
  MESSAGE("postings walked: 41 resident " << walked_all << ", 10 resident " << walked_ten);
  CHECK(walked_all > 2 * walked_ten);
  // Invariant 4: the hypothesis is one of the resident.
  if (r.highest_hypothesis.value != 0) CHECK(r.highest_hypothesis.value <= 10);
  // The place comes back: re-indexed, and localized again.
  r = loc.Localize(frame, truth, all);
  CHECK(r.index_added == all.size() - 10);
  CHECK(r.accepted);
  // Another keyframe in slot 0: the slot is re-indexed (one out, one in).
  std::vector<ResidentKeyframe> swapped = all;
  swapped[0].id = KeyframeId{1000};
  r = loc.Localize(frame, truth, swapped);
  CHECK(r.index_removed == 1);
  CHECK(r.index_added == 1);
  // Nothing resident: the index empties.
  r = loc.Localize(frame, truth, {});
  CHECK(r.index_removed == all.size());
  CHECK(loc.index_memory_bytes() > 0);
}

TEST_CASE("vocabulary likelihood: it reserves what the memory budget counts for it") {
  World world({});
  const KeyframeStore store = MakeKeyframes(world);
  const std::vector<ResidentKeyframe> all = InSlots(store.all());
  const Vocabulary vocab = TrainOn(all);
  LocalizerConfig config;
  Localizer loc(config, world.camera());
  CHECK(loc.index_memory_bytes() == 0);  // no vocabulary, nothing reserved for one
  for (const std::uint32_t slots : {64U, 1000U}) {
    REQUIRE(loc.UseVocabulary(&vocab, slots).ok());
    CHECK(loc.index_memory_bytes() ==
          VocabularyIndexBytes(vocab.word_count(), slots, config.word_features));
  }
  // Ticks over the resident set reserve nothing more.
  const Pose3 truth = PoseFromXYYaw(12.3, 0.0, 0.0);
  (void)loc.Localize(test::MakeFrame(0, 0.0, truth, world.Observe(truth)), truth, all);
  CHECK(loc.index_memory_bytes() ==
        VocabularyIndexBytes(vocab.word_count(), 1000, config.word_features));
}

TEST_CASE("vocabulary likelihood: a warm tick allocates nothing, through PnP") {
  World world({});
  const KeyframeStore store = MakeKeyframes(world);
  const std::vector<ResidentKeyframe> resident = InSlots(store.all());
  const Vocabulary vocab = TrainOn(resident);
  Localizer loc(LocalizerConfig{}, world.camera());
  REQUIRE(loc.UseVocabulary(&vocab, 64).ok());
  const Pose3 truth = PoseFromXYYaw(12.3, 0.0, 0.0);
  const Frame frame = test::MakeFrame(0, 0.0, truth, world.Observe(truth));
  (void)loc.Localize(frame, truth, resident);  // warm-up: indexes everything
  test::AllocationCounter allocs;
  const LocalizeResult r = loc.Localize(frame, truth, resident);
  CHECK(allocs.allocations() == 0);
  CHECK(r.accepted);
}

TEST_CASE("vocabulary likelihood: bad arguments are values") {
  World world({});
  Localizer loc(LocalizerConfig{}, world.camera());
  CHECK(loc.UseVocabulary(nullptr, 64).code() == StatusCode::kInvalidArgument);
  CHECK_FALSE(loc.has_vocabulary());
  LocalizerConfig c;
  c.min_likelihood = 1.5f;
  CHECK(ValidateLocalizerConfig(c, world.camera()).message() ==
        "localizer min_likelihood must be in [0, 1]");
}

}  // namespace
}  // namespace zm
