// Where a tick's time goes (issue 26): the five stages of every tick (TickRecord::stage_ms) sum
// to at most the tick's time, the run's statistics of each reach summary.json's `stages`, and the
// closures accepted beside the frames localized. On a map the localizer really closes loops on
// (rooms_map.h), so the verify and memory stages do work; the pixel path (features, quantize,
// likelihood) is tests/harness/run_test.cc's. Camera frames whose image cannot be used are
// counted (images_refused) and run on odometry, in the frame scratch the budget counted.
#include <doctest/doctest.h>

#include <numeric>
#include <random>

#include "rooms_map.h"
#include "runtime/frame_source.h"
#include "runtime/summary.h"
#include "runtime/tick_loop.h"

namespace zm {
namespace {

using test::RoomsMap;

// Camera frames of 160 x 120 along the rooms' corridor: the first image is not a JPEG, the
// others are (noise: whatever ORB finds there).
class CameraFrames final : public FrameSource {
 public:
  static constexpr std::uint32_t kWidth = 160, kHeight = 120;
  explicit CameraFrames(std::uint64_t frames) : frames_(frames) {
    std::vector<std::uint8_t> rgb(std::size_t{kWidth} * kHeight * 3);
    std::mt19937 rng(5);
    for (auto& v : rgb) v = static_cast<std::uint8_t>(rng());
    auto jpeg = EncodeJpegRgb(rgb, kWidth, kHeight, 90);
    REQUIRE(jpeg.ok());
    jpeg_ = std::move(jpeg).value();
  }
  Result<bool> Next(Frame* frame) override {
    if (next_ == frames_) return false;
    frame->index = next_;
    frame->stamp_s = 0.5 * static_cast<double>(next_);
    frame->odom = PoseFromXYYaw(1.0 + 0.5 * static_cast<double>(next_), 5.0, 0.0);
    frame->descriptors.clear();
    frame->keypoints.clear();
    frame->colour_codec = ImageCodec::kJpeg;
    if (next_ == 0) {
      frame->colour.assign(64, std::byte{0x5a});
    } else {
      frame->colour.assign(jpeg_.begin(), jpeg_.end());
    }
    ++next_;
    return true;
  }
  [[nodiscard]] std::uint32_t max_features() const override { return 0; }
  [[nodiscard]] Images images() const override {
    return {.max_colour_bytes = static_cast<std::uint32_t>(jpeg_.size()),
            .width = kWidth,
            .height = kHeight};
  }

 private:
  std::uint64_t frames_;
  std::uint64_t next_ = 0;
  std::vector<std::byte> jpeg_;
};

// A semantic loop at MemoryThr k_max over the rooms map and `frames` (both outlive it).
struct SemanticLoop {
  std::unique_ptr<MapDb> db;
  std::unique_ptr<TickLoop> loop;
  SemanticLoop(const RoomsMap& map, FrameSource& frames, std::uint64_t k_max) {
    auto opened = MapDb::Open(map.db());
    REQUIRE(opened.ok());
    db = std::move(opened).value();
    LoopConfig c;
    c.policy.kind = PolicyKind::kSemantic;
    c.map.memory_thr_keyframes = k_max;
    c.localizer.reserve_features = 64;
    auto made = TickLoop::Create(c, *db, frames);
    REQUIRE_MESSAGE(made.ok(), made.status().ToString());
    loop = std::move(made).value();
  }
};

TEST_CASE("stage times sum to at most the tick time, and the summary has every stage") {
  RoomsMap map(3, 8, "stages");
  StagedFrameSource frames(64);
  SemanticLoop semantic(map, frames, 16);
  TickLoop& l = *semantic.loop;

  std::uint64_t localized = 0;
  for (int i = 0; i < 40; ++i) {
    // Every fourth frame unrecognisable: no candidate, the tick on odometry.
    frames.staging() = map.FrameAt(0.5 * i, 1.0 + 0.7 * i, i % 4 != 3);
    frames.Stage();
    REQUIRE(l.Tick().value());
    const TickRecord& r = l.last_record();
    const double stages = std::accumulate(std::begin(r.stage_ms), std::end(r.stage_ms), 0.0);
    CHECK(stages <= r.tick_ms + 1e-9);  // the stages leave out reading the frame and recording
    for (double ms : r.stage_ms) CHECK(ms >= 0.0);
    CHECK(r.stage_ms[static_cast<int>(LoopStage::kMemory)] > 0.0);
    CHECK(r.stage_ms[static_cast<int>(LoopStage::kFeatures)] == 0.0);  // features came with it
    CHECK_FALSE(r.has_image);
    CHECK_FALSE(r.vocabulary);
    if (r.loop_closure) {
      ++localized;
      CHECK(r.stage_ms[static_cast<int>(LoopStage::kVerify)] > 0.0);  // matching and PnP
    }
  }
  const LoopTotals& t = l.totals();
  CHECK(localized > 20);
  CHECK(t.frames_localized == localized);
  CHECK(t.closures_accepted == localized);  // at most one a frame
  CHECK(t.images_refused == 0);
  for (const StreamingStats& s : t.stage_ms) CHECK(s.count() == t.tick_ms.count());

  const RunSummary s = LoopSummary(l, false);
  const auto verify = static_cast<std::size_t>(LoopStage::kVerify);
  CHECK(s.stages[verify].p50_ms == doctest::Approx(t.stage_ms[verify].Quantile(0.5)));
  CHECK(s.stages[verify].p99_ms >= s.stages[verify].p50_ms);
  CHECK(s.frames_localized == localized);
  const nlohmann::json j = ToJson(s);
  for (int i = 0; i < kLoopStageCount; ++i) {
    const char* name = LoopStageName(static_cast<LoopStage>(i));
    CHECK_MESSAGE(j["stages"][name]["p50_ms"].is_number(), name);
    CHECK_MESSAGE(j["stages"][name]["p99_ms"].is_number(), name);
  }
  CHECK(j["stages"]["memory"]["p50_ms"].get<double>() > 0.0);
  CHECK(j["closures_accepted"] == localized);
  CHECK(j["images_refused"] == 0);
  CHECK_FALSE(j.contains("frame_scratch"));  // no images, no front-end
}

TEST_CASE("a camera frame whose image cannot be used is counted, and its tick runs on odometry") {
  RoomsMap map(2, 5, "images");
  CameraFrames frames(4);
  SemanticLoop semantic(map, frames, 10);
  TickLoop& l = *semantic.loop;
  REQUIRE(l.front_end() != nullptr);
  // The front-end's region is the budget's, to the byte.
  CHECK(l.budget().frame_scratch_bytes > 0);
  CHECK(l.front_end()->extractor().scratch_stats().capacity_bytes ==
        l.budget().frame_scratch_bytes);

  REQUIRE(l.Tick().value());
  const TickRecord& bad = l.last_record();
  CHECK(bad.has_image);
  CHECK(bad.image_refused);
  CHECK(bad.features == 0);
  CHECK_FALSE(bad.loop_closure);
  CHECK(bad.pose.isApprox(PoseFromXYYaw(1.0, 5.0, 0.0)));  // odometry (no correction yet)
  CHECK_FALSE(bad.stalled);                                // a refused image is not a failed step
  for (int i = 1; i < 4; ++i) {
    REQUIRE(l.Tick().value());
    CHECK_FALSE(l.last_record().image_refused);
    CHECK(l.last_record().stage_ms[static_cast<int>(LoopStage::kFeatures)] > 0.0);
  }
  const LoopTotals& t = l.totals();
  CHECK(t.images_refused == 1);
  CHECK(t.first_image_error.message().find("frame 0") != std::string::npos);
  const RunSummary s = LoopSummary(l, false);
  CHECK(s.images_refused == 1);
  REQUIRE(s.first_image_error.has_value());
  CHECK(s.first_image_error->find("frame 0: colour image") != std::string::npos);
  REQUIRE(s.frame_scratch.has_value());
  CHECK(s.frame_scratch->capacity_bytes == s.frame_scratch_bytes);
  CHECK(s.frame_scratch->overflows == 0);
  CHECK(s.stages[static_cast<std::size_t>(LoopStage::kFeatures)].p50_ms > 0.0);
}

}  // namespace
}  // namespace zm
