// Prefetch and value-based eviction over whole-zone batches (the WorkingSet slices them in time).
#include "memory/predictive_policy.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace zm {
namespace {

std::size_t U(ZoneId z) { return static_cast<std::size_t>(z.value); }

}  // namespace

PredictivePolicy::PredictivePolicy(const MapIndex& index, PredictiveOptions options)
    : index_(index), options_(options), residency_(index) {
  const auto nz = static_cast<std::size_t>(index.zone_count());
  order_.assign(index.total_memberships(), kNoKf);
  last_used_.assign(nz, 0);
  adj_offsets_.assign(nz + 1, 0);
  for (std::size_t z = 0; z < nz; ++z) {
    adj_offsets_[z + 1] = adj_offsets_[z] +
        static_cast<std::uint32_t>(index.AdjacentZones(ZoneId{static_cast<std::int32_t>(z)}).size());
  }
  trans_.assign(adj_offsets_[nz], 0);
  sort_scratch_.reserve(index.max_zone_size());
}

std::uint32_t PredictivePolicy::Transitions(ZoneId from, ZoneId to) const {
  const auto adj = index_.AdjacentZones(from);
  for (std::size_t i = 0; i < adj.size(); ++i) {
    if (adj[i] == to) return trans_[adj_offsets_[U(from)] + i];
  }
  return 0;
}

std::uint32_t PredictivePolicy::Target(ZoneId z) const {
  return std::min(index_.ZoneSize(z), options_.k_max);
}

std::pair<std::int64_t, std::uint64_t> PredictivePolicy::Value(
    ZoneId z, std::span<const ZoneId> route) const {
  if (!route.empty()) {
    for (std::size_t i = route_cursor_; i < route.size(); ++i) {
      if (route[i] == z) return {-static_cast<std::int64_t>(i - route_cursor_), last_used_[U(z)]};
    }
    return {std::numeric_limits<std::int64_t>::min(), last_used_[U(z)]};
  }
  return {z_curr_ == kNoZone ? 0 : Transitions(z_curr_, z), last_used_[U(z)]};
}

ZoneId PredictivePolicy::PredictNext(std::span<const ZoneId> route) const {
  if (!route.empty()) {
    for (std::size_t i = route_cursor_ + 1; i < route.size(); ++i) {
      if (route[i] != z_curr_ && route[i].value >= 0 && route[i].value < index_.zone_count()) {
        return route[i];
      }
    }
    return kNoZone;
  }
  ZoneId best = kNoZone;
  std::int64_t best_score = -1;
  for (ZoneId a : index_.AdjacentZones(z_curr_)) {
    const std::int64_t score = 2 * static_cast<std::int64_t>(Transitions(z_curr_, a)) +
                               (a != z_prev_ ? 1 : 0);
    if (score > best_score) {  // adjacency is sorted: ties keep the smaller id
      best_score = score;
      best = a;
    }
  }
  return best;
}

bool PredictivePolicy::LoadSome(ZoneId z, bool is_current, const TickContext& ctx, Plan* plan) {
  const std::uint32_t target = Target(z);
  const auto held = static_cast<std::uint32_t>(residency_.held_members(z).size());
  if (held >= target) return true;
  KfIndex* order = order_.data() + index_.ZoneOffset(z);
  const auto members = index_.ZoneMembers(z);
  if (held == 0) {
    // Fix this activation's load order: nearest-first from where the robot is now.
    const Eigen::Vector3d p = ctx.pose.translation();
    sort_scratch_.clear();
    for (KfIndex k : members) sort_scratch_.emplace_back((index_.position(k) - p).squaredNorm(), k);
    std::sort(sort_scratch_.begin(), sort_scratch_.end());
    for (std::size_t i = 0; i < sort_scratch_.size(); ++i) order[i] = sort_scratch_[i].second;
  }
  std::span<const KfIndex> next(order + held, target - held);
  std::uint64_t k_pred = residency_.resident() + residency_.MarkAndCountNew(next);
  const auto mine = Value(z, ctx.route);
  while (k_pred > options_.k_max) {
    ZoneId victim = kNoZone;
    std::pair<std::int64_t, std::uint64_t> worst{};
    for (ZoneId a : residency_.active_zones()) {
      if (a == z || a == z_curr_) continue;
      const auto v = Value(a, ctx.route);
      if (victim == kNoZone || v < worst) {
        worst = v;
        victim = a;
      }
    }
    if (victim == kNoZone) break;
    if (!is_current && !(worst < mine)) break;  // prefetch never evicts something worth more
    k_pred -= residency_.Evict(victim, plan);
  }
  if (k_pred > options_.k_max) {
    // Not enough room even after the evictions allowed: take the prefix that fits.
    const std::uint32_t room = options_.k_max - std::min(options_.k_max, residency_.resident());
    std::uint32_t fresh = 0, m = 0;
    for (KfIndex k : next) {
      if (residency_.held(k) == 0) {
        if (fresh == room) break;
        ++fresh;
      }
      ++m;
    }
    if (m == 0) return false;
    next = next.first(m);
  }
  if (!residency_.active(z)) ++zone_loads_;
  residency_.Hold(z, next, plan);
  return true;
}

void PredictivePolicy::Start(const TickContext& ctx, Plan* plan) { PlanBeforeLocalize(ctx, plan); }

void PredictivePolicy::PlanBeforeLocalize(const TickContext& ctx, Plan* plan) {
  const ZoneId z = ctx.zone;
  if (z != kNoZone && z != z_curr_ && z.value >= 0 && z.value < index_.zone_count()) {
    if (z_curr_ != kNoZone) {
      const auto adj = index_.AdjacentZones(z_curr_);
      for (std::size_t i = 0; i < adj.size(); ++i) {
        if (adj[i] == z) ++trans_[adj_offsets_[U(z_curr_)] + i];
      }
    }
    z_prev_ = z_curr_;
    z_curr_ = z;
    last_used_[U(z)] = ++clock_;
    for (std::size_t i = route_cursor_; i < ctx.route.size(); ++i) {
      if (ctx.route[i] == z) {
        route_cursor_ = i;
        break;
      }
    }
  }
  if (z_curr_ == kNoZone) return;
  // The current zone's batch first, then the prefetch: the working set loads them in this order
  // (time-sliced, in the idle part of the ticks), so the next zone is resident by the time the
  // robot walks into it.
  LoadSome(z_curr_, /*is_current=*/true, ctx, plan);
  const bool current_held = residency_.held_members(z_curr_).size() >= Target(z_curr_);
  last_prefetch_ = kNoZone;
  if (options_.prefetch && current_held) {
    const ZoneId next = PredictNext(ctx.route);
    if (next != kNoZone && next != z_curr_) {
      if (LoadSome(next, /*is_current=*/false, ctx, plan)) last_prefetch_ = next;
    }
  }
}

}  // namespace zm
