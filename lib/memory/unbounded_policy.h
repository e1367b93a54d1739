// UnboundedPolicy: every keyframe resident from start-up (one per-keyframe batch), nothing
// ever unloaded. The accuracy ceiling; its arena must hold the whole map.
#pragma once

#include "memory/policy.h"

namespace zm {

class UnboundedPolicy final : public MemoryPolicy {
 public:
  explicit UnboundedPolicy(const MapIndex& index) : index_(index) {}
  [[nodiscard]] std::string_view name() const override { return "unbounded"; }
  void Start(const TickContext& /*ctx*/, Plan* plan) override {
    plan->BeginBatch(kNoZone);
    for (KfIndex k = 0; k < index_.keyframe_count(); ++k) plan->Acquire(k);
  }
  void PlanBeforeLocalize(const TickContext& /*ctx*/, Plan* /*plan*/) override {}
  void PlanAfterLocalize(const TickContext& /*ctx*/, Plan* /*plan*/) override {}
  // No budget: everything stays resident.
  void ChangeBudget(std::uint32_t /*k_max*/, const TickContext& /*ctx*/, Plan* /*plan*/) override {}

 private:
  const MapIndex& index_;
};

}  // namespace zm
