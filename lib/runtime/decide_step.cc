// The decide step (see decide_step.h).
#include "runtime/decide_step.h"

#include <algorithm>
#include <limits>
#include <utility>

namespace zm {
namespace {

using Clock = std::chrono::steady_clock;

double MsBetween(Clock::time_point a, Clock::time_point b) {
  return std::chrono::duration<double, std::milli>(b - a).count();
}

}  // namespace

bool IsSmallDisplacement(const Pose3& last_kept, const Pose3& now, double linear_m,
                         double angular_rad) {
  const Pose3 delta = last_kept.inverse() * now;
  const double angle = Eigen::AngleAxisd(delta.linear()).angle();
  return delta.translation().norm() < linear_m && angle < angular_rad;
}

DecideStep::DecideStep(const MapIndex& index, std::unique_ptr<MemoryPolicy> policy,
                       const DecideOptions& options, const ZoneIndex* zones,
                       std::span<const ZoneId> route)
    : index_(index), policy_(std::move(policy)), options_(options), zones_(zones) {
  plan_.Reserve(index_);
  ctx_.route = route;
}

ZoneId DecideStep::LookUpZone(const Pose3& pose) const {
  const ZoneId current = ctx_.zone;
  if (zones_ != nullptr) return zones_->GetZone(pose, current);
  // Zones from memberships: the zones of the nearest keyframe, staying in the current one while
  // that keyframe is in it (a doorway keyframe in both zones does not flip the zone).
  KfIndex best = kNoKf;
  double best_d = std::numeric_limits<double>::infinity();
  index_.ForEachWithin(pose.translation(), options_.nearest_keyframe_zone_m,
                       [&](KfIndex k, double d) {
                         if (d < best_d || (d == best_d && k < best)) {
                           best_d = d;
                           best = k;
                         }
                       });
  if (best == kNoKf) return current;
  const auto of = index_.ZonesOf(best);
  if (of.empty()) return current;
  if (std::find(of.begin(), of.end(), current) != of.end()) return current;
  return of.front();
}

const Plan& DecideStep::Before(double now_s, const Pose3& pose, ZoneId given_zone, Times* times) {
  const Clock::time_point t0 = times != nullptr ? Clock::now() : Clock::time_point{};
  const bool small =
      have_kept_ && IsSmallDisplacement(last_kept_, pose, options_.small_displacement_m,
                                        options_.small_displacement_rad);
  if (!small) {
    last_kept_ = pose;
    have_kept_ = true;
  }
  const Clock::time_point t1 = times != nullptr ? Clock::now() : Clock::time_point{};
  const ZoneId zone = given_zone != kNoZone ? given_zone : LookUpZone(pose);
  const Clock::time_point t2 = times != nullptr ? Clock::now() : Clock::time_point{};

  ctx_.tick = ticks_;
  ctx_.now_s = now_s;
  ctx_.pose = pose;
  ctx_.zone = zone;
  ctx_.small_displacement = small;
  ctx_.highest_hypothesis = KeyframeId{0};
  ctx_.localized_on = KeyframeId{0};
  plan_.Clear();
  if (ticks_ == 0) {
    policy_->Start(ctx_, &plan_);
  } else {
    policy_->PlanBeforeLocalize(ctx_, &plan_);
  }
  ++ticks_;
  if (times != nullptr) {
    const Clock::time_point t3 = Clock::now();
    times->pose_ms = MsBetween(t0, t1);
    times->zone_ms = MsBetween(t1, t2);
    times->plan_ms = MsBetween(t2, t3);
  }
  return plan_;
}

const Plan& DecideStep::After(KeyframeId highest_hypothesis, KeyframeId localized_on) {
  ctx_.highest_hypothesis = highest_hypothesis;
  ctx_.localized_on = localized_on;
  plan_.Clear();
  policy_->PlanAfterLocalize(ctx_, &plan_);
  return plan_;
}

const Plan& DecideStep::ChangeBudget(std::uint32_t k_max) {
  plan_.Clear();
  policy_->ChangeBudget(k_max, ctx_, &plan_);
  return plan_;
}

void DecideStep::SetRoute(std::span<const ZoneId> route) {
  ctx_.route = route;
  policy_->RouteChanged(ctx_);
}

}  // namespace zm
