// SemanticPolicy: the paper's Algorithm 1 (docs/design.md), zone-level LRU.
//
//   z_new = GetZone(x_t); if z_new is none or z_new == z_curr: keep everything.
//   if z_new not in A: K_pred = |union of S_z over A| + |S_z_new not already held|
//     while K_pred > K_max: evict the least recently entered zone of A (K_pred drops by the
//       keyframes no other remaining zone, nor z_new, holds)
//     load S_z_new as one batch (one transaction).
//   z_curr = z_new.
//
// Where the paper is silent: overlaps are counted as unions (ZoneResidency); a pose outside
// every zone keeps the current zone; a zone larger than K_max, once A is empty, is loaded
// nearest-first to the current pose up to K_max. Start-up loads only the initial zone (the
// paper's authors had to add this: RTAB-Map loaded ~800 keyframes at once).
//
// Invariants: the predicted count never exceeds k_max after a step (so neither does the
// WorkingSet, which unloads before it loads); no allocation after construction.
#pragma once

#include <cstdint>
#include <utility>
#include <vector>

#include "memory/policy.h"
#include "memory/zone_residency.h"

namespace zm {

class SemanticPolicy : public MemoryPolicy {
 public:
  SemanticPolicy(const MapIndex& index, SemanticOptions options);

  [[nodiscard]] std::string_view name() const override { return "semantic"; }
  void Start(const TickContext& ctx, Plan* plan) override;
  void PlanBeforeLocalize(const TickContext& ctx, Plan* plan) override;
  void PlanAfterLocalize(const TickContext& /*ctx*/, Plan* /*plan*/) override {}
  [[nodiscard]] std::uint64_t zone_loads() const override { return zone_loads_; }
  // Evicts other zones (SelectUnloadZone's order) until it fits; if the current zone alone is
  // larger, keeps its k_max members nearest to ctx.pose (releases only).
  void ChangeBudget(std::uint32_t k_max, const TickContext& ctx, Plan* plan) override;

  [[nodiscard]] ZoneId current_zone() const { return z_curr_; }
  [[nodiscard]] const ZoneResidency& residency() const { return residency_; }

 protected:
  // Which active zone to unload to make room for z_new (never z_new itself; A is non-empty).
  virtual ZoneId SelectUnloadZone(ZoneId z_new);
  // Called when the robot enters z (a change of current zone), before any load decision.
  virtual void OnEnter(ZoneId /*z*/) {}

  const MapIndex& index_;
  std::uint32_t k_max_;
  ZoneResidency residency_;
  std::vector<std::uint64_t> last_used_;  // per zone: LRU stamp of the last entry

 private:
  void Enter(const TickContext& ctx, ZoneId z_new, Plan* plan);

  ZoneId z_curr_ = kNoZone;
  std::uint64_t clock_ = 0;
  std::uint64_t zone_loads_ = 0;
  std::vector<std::pair<double, KfIndex>> nearest_;  // scratch, max zone size
  std::vector<KfIndex> chosen_;                      // scratch, k_max
};

}  // namespace zm
