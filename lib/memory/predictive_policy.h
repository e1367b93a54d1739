// PredictivePolicy (beyond the paper, which lists it as future work): Algorithm 1's zone
// batches plus prefetch and value-based eviction.
//
//   - current zone first: up to min(|zone|, k_max) of its keyframes, nearest-first from the pose
//     when its loading starts (the order decides which part is taken when room is short);
//   - then, once the current zone is held, the next zone is prefetched: the zone after the
//     current one on the planned route when one is given, else the adjacent zone with the most
//     transitions seen so far from the current one (ties: not the zone we came from, then the
//     smaller id);
//   - to make room it evicts the zone whose next use on the route is farthest (not on the
//     route = never), or without a route the least likely one (fewest transitions from the
//     current zone, then least recently entered). Prefetch only evicts zones worth less than
//     the zone it brings in; the current zone is never evicted; when room is still short it
//     takes the nearest prefix that fits, completed later when room frees up.
//
// Both come out as whole-zone batches of one plan, current zone first. Time slicing is the
// WorkingSet's (LoadSliceOptions): it loads the batches in the idle part of the ticks, so the
// prefetched zone is resident when the robot enters it (issue 14). A zone held by the plan may
// therefore still be loading: held() counts it, the WorkingSet's resident set does not yet.
//
// Invariants: resident <= k_max at every instant (unload before load); no allocation after
// construction.
#pragma once

#include <cstdint>
#include <span>
#include <utility>
#include <vector>

#include "memory/policy.h"
#include "memory/zone_residency.h"

namespace zm {

class PredictivePolicy final : public MemoryPolicy {
 public:
  PredictivePolicy(const MapIndex& index, PredictiveOptions options);
  [[nodiscard]] std::string_view name() const override { return "predictive"; }
  void Start(const TickContext& ctx, Plan* plan) override;
  void PlanBeforeLocalize(const TickContext& ctx, Plan* plan) override;
  void PlanAfterLocalize(const TickContext& /*ctx*/, Plan* /*plan*/) override {}
  [[nodiscard]] std::uint64_t zone_loads() const override { return zone_loads_; }

  [[nodiscard]] ZoneId current_zone() const { return z_curr_; }
  [[nodiscard]] ZoneId last_prefetch() const { return last_prefetch_; }
  [[nodiscard]] const ZoneResidency& residency() const { return residency_; }
  [[nodiscard]] std::uint32_t Transitions(ZoneId from, ZoneId to) const;

 private:
  // Value of keeping z (larger = keep): (route rank or transition count, last entry).
  std::pair<std::int64_t, std::uint64_t> Value(ZoneId z, std::span<const ZoneId> route) const;
  ZoneId PredictNext(std::span<const ZoneId> route) const;
  // Holds the rest of z (what fits); returns false if it could not make room for any of it.
  bool LoadSome(ZoneId z, bool is_current, const TickContext& ctx, Plan* plan);
  std::uint32_t Target(ZoneId z) const;

  const MapIndex& index_;
  PredictiveOptions options_;
  ZoneResidency residency_;
  std::vector<KfIndex> order_;               // per zone segment: load order (nearest-first)
  std::vector<std::uint64_t> last_used_;     // per zone
  std::vector<std::uint32_t> adj_offsets_;   // per zone: into trans_ (AdjacentZones order)
  std::vector<std::uint32_t> trans_;         // transition counts along adjacency
  std::vector<std::pair<double, KfIndex>> sort_scratch_;
  ZoneId z_curr_ = kNoZone;
  ZoneId z_prev_ = kNoZone;
  ZoneId last_prefetch_ = kNoZone;
  std::size_t route_cursor_ = 0;
  std::uint64_t clock_ = 0;
  std::uint64_t zone_loads_ = 0;
};

}  // namespace zm
