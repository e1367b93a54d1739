// The decide step: one tick's memory decision, the one implementation that zonemapd's tick loop
// (TickLoop) and the public API's host path (zonemap::ZoneManager) both drive.
//
//   Before(stamp, pose[, zone])   the pose's small-displacement flag (RGBD/LinearUpdate and
//                                 RGBD/AngularUpdate against the last kept pose), the zone of the
//                                 pose (the caller's, else polygons with hysteresis, else the
//                                 nearest keyframe's), then the policy's plan before
//                                 localization: on the first call its start-up load
//                                 (MemoryPolicy::Start), afterwards PlanBeforeLocalize;
//   After(hypothesis, localized)  what localization found, then PlanAfterLocalize (basic's
//                                 retrieval and transfer; empty for the other policies);
//   ChangeBudget(k_max)           MemoryPolicy::ChangeBudget on the last tick's context;
//   SetRoute(zones)               the planned route, and MemoryPolicy::RouteChanged.
//
// Each returns the Plan, which the caller carries out in the plan's order (unload, then load)
// with its own residency: TickLoop's WorkingSet (arena slots from the map database) or
// ZoneManager's ExternalWorkingSet (the host's keyframes, by reference count). The plan stays
// valid until the next call.
//
// Allocates only in the constructor (the plan's buffers are reserved from the map's size); every
// call after it allocates nothing.
#pragma once

#include <chrono>
#include <cstdint>
#include <memory>
#include <span>

#include "common/ids.h"
#include "geometry/pose.h"
#include "memory/map_index.h"
#include "memory/plan.h"
#include "memory/policy.h"
#include "zones/zone_index.h"

namespace zm {

struct DecideOptions {
  double small_displacement_m = 0.1;    // RGBD/LinearUpdate
  double small_displacement_rad = 0.1;  // RGBD/AngularUpdate
  // Zones without polygons (no ZoneIndex): a pose takes the zones of its nearest keyframe within
  // this radius (staying in the current zone while that keyframe is in it); beyond it, or with
  // no keyframe in any zone, the current zone stays.
  double nearest_keyframe_zone_m = 5.0;
};

// RGBD/LinearUpdate and RGBD/AngularUpdate: `now` moved less than both thresholds from
// `last_kept`, the last pose that was not a small displacement.
[[nodiscard]] bool IsSmallDisplacement(const Pose3& last_kept, const Pose3& now,
                                       double linear_m, double angular_rad);

class DecideStep {
 public:
  // Wall time of Before()'s parts, when asked for (the tick loop's step timers).
  struct Times {
    double pose_ms = 0.0;
    double zone_ms = 0.0;
    double plan_ms = 0.0;
  };

  // `index` and `zones` (null: zones by nearest keyframe) must outlive the step; so must
  // `route`, the route planned before the first tick (the policy starts with it: no
  // RouteChanged).
  DecideStep(const MapIndex& index, std::unique_ptr<MemoryPolicy> policy,
             const DecideOptions& options, const ZoneIndex* zones,
             std::span<const ZoneId> route = {});

  // One tick before localization. `given_zone` (not kNoZone) is the caller's own zone for the
  // pose and skips the lookup; `times` (may be null) receives the parts' wall time.
  const Plan& Before(double now_s, const Pose3& pose, ZoneId given_zone = kNoZone,
                     Times* times = nullptr);
  // The same tick after localization (0 = none for either id).
  const Plan& After(KeyframeId highest_hypothesis, KeyframeId localized_on);
  // MemoryThr changes to k_max (already clamped by the caller), between ticks.
  const Plan& ChangeBudget(std::uint32_t k_max);
  // Replaces the planned zone sequence (`route` must stay valid until replaced) and tells the
  // policy (predictive follows it).
  void SetRoute(std::span<const ZoneId> route);
  // The same route at a new address (its buffer was re-reserved): the policy is not told.
  void RebindRoute(std::span<const ZoneId> route) { ctx_.route = route; }

  // The zone of the pose looked up as Before() does (no state changes).
  [[nodiscard]] ZoneId LookUpZone(const Pose3& pose) const;
  [[nodiscard]] std::uint64_t ticks() const { return ticks_; }  // Before() calls so far
  [[nodiscard]] bool started() const { return ticks_ > 0; }
  [[nodiscard]] ZoneId zone() const { return ctx_.zone; }
  [[nodiscard]] const TickContext& context() const { return ctx_; }
  [[nodiscard]] const Plan& plan() const { return plan_; }
  [[nodiscard]] const MemoryPolicy& policy() const { return *policy_; }

 private:
  const MapIndex& index_;
  std::unique_ptr<MemoryPolicy> policy_;
  DecideOptions options_;
  const ZoneIndex* zones_;
  Plan plan_;
  TickContext ctx_;
  Pose3 last_kept_ = Pose3::Identity();
  bool have_kept_ = false;
  std::uint64_t ticks_ = 0;
};

}  // namespace zm
