// Algorithm 1 with union counting and the oversize-zone fallback.
#include "memory/semantic_policy.h"

#include <algorithm>
#include <cassert>
#include <limits>

namespace zm {

SemanticPolicy::SemanticPolicy(const MapIndex& index, SemanticOptions options)
    : index_(index), k_max_(options.k_max), residency_(index) {
  last_used_.assign(static_cast<std::size_t>(index.zone_count()), 0);
  nearest_.reserve(index.max_zone_size());
  chosen_.reserve(std::min(index.max_zone_size(), k_max_));
}

void SemanticPolicy::Start(const TickContext& ctx, Plan* plan) {
  // Only the initial zone: never the whole map.
  PlanBeforeLocalize(ctx, plan);
}

void SemanticPolicy::PlanBeforeLocalize(const TickContext& ctx, Plan* plan) {
  const ZoneId z_new = ctx.zone;
  if (z_new == kNoZone || z_new == z_curr_) return;  // outside every zone: keep the current one
  if (z_new.value < 0 || z_new.value >= index_.zone_count()) return;
  OnEnter(z_new);
  if (!residency_.active(z_new)) Enter(ctx, z_new, plan);
  last_used_[static_cast<std::size_t>(z_new.value)] = ++clock_;
  z_curr_ = z_new;
}

ZoneId SemanticPolicy::SelectUnloadZone(ZoneId z_new) {
  ZoneId victim = kNoZone;
  std::uint64_t oldest = std::numeric_limits<std::uint64_t>::max();
  for (ZoneId z : residency_.active_zones()) {
    if (z == z_new) continue;
    const std::uint64_t t = last_used_[static_cast<std::size_t>(z.value)];
    if (t < oldest || (t == oldest && z < victim)) {
      oldest = t;
      victim = z;
    }
  }
  return victim;
}

void SemanticPolicy::Enter(const TickContext& ctx, ZoneId z_new, Plan* plan) {
  const auto members = index_.ZoneMembers(z_new);
  // K_pred from metadata only: the union of A plus the members of z_new nobody holds yet.
  std::uint64_t k_pred = residency_.resident() + residency_.MarkAndCountNew(members);
  while (k_pred > k_max_ && !residency_.active_zones().empty()) {
    const ZoneId z_old = SelectUnloadZone(z_new);
    if (z_old == kNoZone) break;
    k_pred -= residency_.Evict(z_old, plan);  // unload strictly before load (plan order)
  }
  ++zone_loads_;
  if (k_pred <= k_max_) {
    residency_.Hold(z_new, members, plan);
    return;
  }
  // A is empty and z_new alone exceeds the budget: nearest-first up to K_max.
  const Eigen::Vector3d p = ctx.pose.translation();
  nearest_.clear();
  for (KfIndex k : members) nearest_.emplace_back((index_.position(k) - p).squaredNorm(), k);
  const auto take = static_cast<std::ptrdiff_t>(k_max_);
  std::nth_element(nearest_.begin(), nearest_.begin() + take, nearest_.end());
  std::sort(nearest_.begin(), nearest_.begin() + take);
  chosen_.clear();
  for (std::ptrdiff_t i = 0; i < take; ++i) chosen_.push_back(nearest_[static_cast<std::size_t>(i)].second);
  residency_.Hold(z_new, chosen_, plan);
  assert(residency_.resident() <= k_max_);
}


void SemanticPolicy::ChangeBudget(std::uint32_t k_max, const TickContext& ctx, Plan* plan) {
  k_max_ = k_max;
  while (residency_.resident() > k_max_) {
    const ZoneId victim = SelectUnloadZone(z_curr_);  // never the current zone
    if (victim == kNoZone) break;
    residency_.Evict(victim, plan);
  }
  if (residency_.resident() <= k_max_ || z_curr_ == kNoZone || !residency_.active(z_curr_)) return;
  // Only the current zone is left and it alone is over the new budget: the oversize rule of
  // Enter, nearest-first to the pose. Evict + Hold of a subset of what it holds: the WorkingSet
  // pins the kept keyframes (their references are bumped before the releases), so nothing is
  // read and nothing new is ever resident.
  const Eigen::Vector3d p = ctx.pose.translation();
  nearest_.clear();
  for (KfIndex k : residency_.held_members(z_curr_)) {
    nearest_.emplace_back((index_.position(k) - p).squaredNorm(), k);
  }
  const auto take = static_cast<std::ptrdiff_t>(std::min<std::size_t>(k_max_, nearest_.size()));
  std::nth_element(nearest_.begin(), nearest_.begin() + take, nearest_.end());
  std::sort(nearest_.begin(), nearest_.begin() + take);
  chosen_.clear();
  for (std::ptrdiff_t i = 0; i < take; ++i) chosen_.push_back(nearest_[static_cast<std::size_t>(i)].second);
  residency_.Evict(z_curr_, plan);
  residency_.Hold(z_curr_, chosen_, plan);
  assert(residency_.resident() <= k_max_);
}

}  // namespace zm
