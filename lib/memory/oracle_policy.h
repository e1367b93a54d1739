// OraclePolicy: Belady's MIN over zones. Algorithm 1 with the eviction choice replaced by
// "the active zone whose next entry lies farthest in the future (never = infinitely far)",
// given the whole future zone sequence. With equal-size, non-overlapping zones this makes the
// fewest possible zone loads of any policy, prefetching or not; reports use it as the lower
// bound. (With unequal sizes or overlaps MIN is a strong heuristic, not a proven bound.)
//
// The future is the per-tick zone sequence; kNoZone entries and repeats are dropped, as the
// policy only acts on zone changes. If the observed zone differs from the expected next one,
// the cursor resynchronises on the next occurrence of the observed zone.
#pragma once

#include <vector>

#include "memory/semantic_policy.h"

namespace zm {

class OraclePolicy final : public SemanticPolicy {
 public:
  OraclePolicy(const MapIndex& index, const OracleOptions& options);
  [[nodiscard]] std::string_view name() const override { return "oracle"; }

 protected:
  ZoneId SelectUnloadZone(ZoneId z_new) override;
  void OnEnter(ZoneId z) override;

 private:
  std::size_t NextUse(ZoneId z);

  std::vector<ZoneId> seq_;               // compressed future
  std::vector<std::size_t> next_same_;    // per position: next position of the same zone
  std::vector<std::size_t> next_use_;     // per zone: a position of its next entry (lazy)
  std::size_t cursor_ = kNever;           // position of the current zone; kNever before start
  static constexpr std::size_t kNever = static_cast<std::size_t>(-1);
};

}  // namespace zm
