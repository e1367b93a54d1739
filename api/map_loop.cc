// MapLoop: the public complete path as a thin facade over what zonemapd runs: LoadProfile +
// ApplyOverrides, MapDb::Open, the input gate (input_gate.h: Process's frames, and a replay's
// through GatedFrameSource), TickLoop::Create/Tick/last_record/totals. The only new piece is a
// FrameSource fed by the caller (Process), which copies one frame into the loop's reserved Frame
// without allocating.
#include "zonemap/map_loop.h"

#include <cmath>
#include <limits>
#include <string>
#include <utility>

#include "convert.h"
#include "mapdb/map_db.h"
#include "runtime/frame_source.h"
#include "runtime/input_gate.h"
#include "runtime/profile.h"
#include "runtime/summary.h"
#include "runtime/tick_loop.h"

namespace zonemap {

// The public header states the defaults in plain C++ (it may include nothing of the core's); the
// parameters are declared once in the core, and these keep the two the same.
// Clang 14 cannot evaluate libstdc++ 12's std::string constructor in a constant expression;
// GCC, which builds every target for aarch64, checks it.
#if !defined(__clang__)
static_assert(MapLoopOptions{}.max_features == zm::kMaxFeaturesParam.default_value,
              "MapLoopOptions::max_features must default to runtime/frame_source.h's");
#endif

using internal::FromPose3;
using internal::ToPose3;

namespace {

// Hands the loop the one frame Process() was given. Next() after it: end of input (Process
// drives exactly one tick per frame).
class PushFrameSource final : public zm::FrameSource {
 public:
  explicit PushFrameSource(std::uint32_t max_features) : max_features_(max_features) {}
  void Set(const FrameInput* frame, const zm::Pose3* odom) {
    frame_ = frame;
    odom_ = odom;
  }
  zm::Result<bool> Next(zm::Frame* out) override {
    if (frame_ == nullptr) return false;
    out->index = next_index_++;
    out->stamp_s = frame_->stamp_s;
    out->odom = *odom_;
    out->descriptors.clear();  // capacity reserved by the loop for max_features: no allocation
    out->keypoints.clear();
    for (const Feature& f : frame_->features) {
      zm::Descriptor256 d;
      for (std::size_t i = 0; i < d.size(); ++i) d[i] = f.descriptor[i];
      out->descriptors.push_back(d);
      out->keypoints.push_back(f.u);
      out->keypoints.push_back(f.v);
    }
    frame_ = nullptr;
    return true;
  }
  [[nodiscard]] std::uint32_t max_features() const override { return max_features_; }

 private:
  std::uint32_t max_features_;
  const FrameInput* frame_ = nullptr;
  const zm::Pose3* odom_ = nullptr;
  std::uint64_t next_index_ = 0;
};

TickOutput ToOutput(const zm::TickRecord& r) {
  TickOutput o;
  o.tick = r.tick;
  o.stamp_s = r.stamp_s;
  o.pose = FromPose3(r.pose);
  o.correction = FromPose3(r.correction);
  o.zone = r.zone;
  o.startup = r.startup;
  o.loop_closure = r.loop_closure;
  o.matched = KeyframeId{r.matched_keyframe};
  o.inliers = r.inliers;
  o.resident_keyframes = r.resident_keyframes;
  o.keyframes_loaded = r.keyframes_loaded;
  o.keyframes_unloaded = r.keyframes_unloaded;
  o.over_budget = r.over_budget;
  o.stalled = r.stalled;
  o.tick_ms = r.tick_ms;
  return o;
}

}  // namespace

struct MapLoop::Impl {
  zm::Profile profile;
  std::unique_ptr<zm::MapDb> db;
  std::unique_ptr<zm::FrameSource> replay;
  std::unique_ptr<zm::GatedFrameSource> gated_replay;  // the replay through the gate
  std::unique_ptr<PushFrameSource> push;
  std::unique_ptr<zm::TickLoop> loop;
  std::optional<zm::InputGate> gate;  // Process()'s frames
  std::uint64_t rejected = 0;         // Process() calls refused (syntax or gate)
};

MapLoop::MapLoop(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
MapLoop::~MapLoop() = default;

Result<std::unique_ptr<MapLoop>> MapLoop::Open(const MapLoopOptions& options) {
  auto impl = std::make_unique<Impl>();
  Impl& m = *impl;
  if (options.db_path.empty()) {
    return Status(StatusCode::kInvalidArgument, "MapLoopOptions::db_path is empty");
  }
  if (options.max_features == 0) {
    return Status(StatusCode::kInvalidArgument, "MapLoopOptions::max_features must be > 0");
  }
  {
    auto p = internal::ProfileOrDefaults(options.profile);
    if (!p.ok()) return p.status();
    m.profile = std::move(p).value();
  }
  zm::ProfileOverrides ov;
  if (!options.policy.empty()) ov.policy = options.policy;
  if (!options.memory_thr.empty()) ov.memory_thr = options.memory_thr;
  if (zm::Status s = zm::ApplyOverrides(ov, m.profile); !s.ok()) return s;
  {
    auto db = zm::MapDb::Open(options.db_path);
    if (!db.ok()) return db.status();
    m.db = std::move(db).value();
  }
  zm::FrameSource* source = nullptr;
  if (!options.frames_path.empty()) {
    auto r = zm::OpenReplaySource(options.frames_path);
    if (!r.ok()) return r.status();
    m.replay = std::move(r).value();
    m.gated_replay = std::make_unique<zm::GatedFrameSource>(*m.replay);
    source = m.gated_replay.get();
  } else {
    m.push = std::make_unique<PushFrameSource>(options.max_features);
    source = m.push.get();
  }
  {
    auto loop = zm::TickLoop::Create(m.profile, *m.db, *source);
    if (!loop.ok()) return loop.status();
    m.loop = std::move(loop).value();
  }
  // The gate over the map's extent, with the loop's correction (zonemapd's rules).
  const zm::MapExtent extent = zm::ExtentOf(m.loop->map_index());
  if (m.gated_replay) {
    m.gated_replay->Attach(m.profile.input, extent, &m.loop->map_from_odom());
  } else {
    m.gate.emplace(m.profile.input, extent);
  }
  return std::unique_ptr<MapLoop>(new MapLoop(std::move(impl)));
}

Result<TickOutput> MapLoop::Process(const FrameInput& frame) {
  Impl& m = *impl_;
  if (!m.push) {
    return Status(StatusCode::kFailedPrecondition,
                  "Process() on a replay loop (MapLoopOptions::frames_path): call Step()");
  }
  auto reject = [&](std::string why) {
    ++m.rejected;
    return Status(StatusCode::kInvalidArgument, std::move(why));
  };
  // Syntax (the line parser's part for zonemapd): finite numbers, the feature reserve.
  if (frame.features.size() > m.push->max_features()) {
    return reject("frame has " + std::to_string(frame.features.size()) +
                  " features; max_features is " + std::to_string(m.push->max_features()));
  }
  for (const Feature& f : frame.features) {
    if (!std::isfinite(f.u) || !std::isfinite(f.v)) return reject("a keypoint is not finite");
  }
  auto odom = ToPose3(frame.odom, "frame odometry pose");
  if (!odom.ok()) return reject(odom.status().message());
  // Sanity: the input gate, zonemapd's rules.
  zm::RejectReason why = zm::RejectReason::kSyntax;
  if (!m.gate->AcceptFrame(frame.stamp_s, odom->pose, odom->quaternion_norm,
                           m.loop->map_from_odom(), &why)) {
    return reject("frame refused (" + std::string(zm::RejectReasonName(why)) +
                  "): " + zm::RejectRule(why) + " (stamp_s " + std::to_string(frame.stamp_s) +
                  ", quaternion norm " + std::to_string(odom->quaternion_norm) + ")");
  }
  m.push->Set(&frame, &odom->pose);
  auto more = m.loop->Tick();
  m.push->Set(nullptr, nullptr);
  if (!more.ok()) return more.status();
  if (!*more) return Status(StatusCode::kInternal, "the tick loop did not take the frame");
  return ToOutput(m.loop->last_record());
}

Result<std::optional<TickOutput>> MapLoop::Step() {
  Impl& m = *impl_;
  if (!m.replay) {
    return Status(StatusCode::kFailedPrecondition,
                  "Step() needs a frames file (MapLoopOptions::frames_path); use Process()");
  }
  auto more = m.loop->Tick();
  if (!more.ok()) return more.status();
  if (!*more) return std::optional<TickOutput>();
  return std::optional<TickOutput>(ToOutput(m.loop->last_record()));
}

std::string_view MapLoop::policy() const { return impl_->loop->policy().name(); }
std::uint32_t MapLoop::k_max() const { return impl_->loop->k_max(); }
bool MapLoop::bounded() const { return impl_->loop->bounded(); }
std::uint64_t MapLoop::slot_bytes() const { return impl_->loop->slot_bytes(); }
std::uint32_t MapLoop::resident_count() const {
  return impl_->loop->working_set().resident_count();
}
std::string_view MapLoop::zone_name(ZoneId zone) const {
  const zm::ZoneSet& zones = impl_->loop->zone_set();
  if (zone.value < 0 || static_cast<std::size_t>(zone.value) >= zones.size()) return {};
  return zones.zone(zm::ZoneId{zone.value}).name;
}
std::string_view MapLoop::profile_path() const { return impl_->profile.source; }

LoopStats MapLoop::stats() const {
  // The run summary zonemapd and the harness write (runtime/summary.h), projected onto the
  // public struct: one derivation of every figure.
  const zm::RunSummary t = zm::LoopSummary(*impl_->loop, false);
  LoopStats s;
  s.ticks = t.ticks;
  s.loop_closures = t.closures_accepted;
  s.keyframes_loaded = t.keyframes_loaded;
  s.keyframes_unloaded = t.keyframes_unloaded;
  s.zone_loads = t.zone_loads;
  s.db_transactions = t.db_transactions;
  s.db_bytes_read = t.db_bytes_read;
  s.peak_resident_keyframes = static_cast<std::uint32_t>(t.peak_resident_keyframes);
  s.over_budget_ticks = t.over_budget_ticks;
  s.stalled_ticks = t.stalled_ticks;
  s.rejected_frames =
      impl_->rejected + (impl_->gated_replay ? impl_->gated_replay->rejects().total : 0);
  s.tick_ms_mean = t.tick_ms.mean;
  s.tick_ms_p50 = t.tick_ms.p50;
  s.tick_ms_p99 = t.tick_ms.p99;
  s.tick_ms_max = t.tick_ms.max;
  return s;
}

}  // namespace zonemap
