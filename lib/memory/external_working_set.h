// ExternalWorkingSet: the WorkingSet's residency bookkeeping for keyframes that live in someone
// else's memory (the public API's "bring your own keyframe store", include/zonemap/).
//
// It holds the same per-keyframe reference counts as WorkingSet (the number of active zones
// holding a keyframe for the zone policies, 0/1 for basic and radius) but no arena and no
// KeyframeSource: Apply(plan) does not load anything, it turns the plan into the NET change a
// host must carry out, as two lists of keyframe ids:
//   unloads()  keyframes resident before the plan and not after it;
//   loads()    keyframes not resident before and resident after, grouped per plan batch
//              (load_batches(): the zone it came from, or kNoZone for per-keyframe batches).
// A keyframe released by an evicted zone and acquired again by the incoming zone (a doorway
// shared by both) is in neither list, exactly as WorkingSet's pin keeps it in its slot.
//
// The host carries the answer out in order: every unload, then the loads. Resident counts then
// go before -> before - |unloads| -> after, so the highest count at any instant of carrying it
// out is max(before, after) (peak_during_apply()). That is never above the plan's own peak, so
// for the bounded policies, whose plans never take the count above K_max, neither is the
// answer: max_resident_seen() records it after every Apply (tests/memory/ check it against
// WorkingSet on the same plans).
//
// Invariants:
//   - a keyframe is resident iff its count > 0; resident_count() is the number of them;
//   - final counts = counts before + acquires - releases, whatever the plan's order: the order
//     only decides which intermediate states a plan passes through, and the net answer never
//     passes through any state but before, the unloads' removals and the loads' additions;
//   - a release of a keyframe nobody holds at that point of the plan (in the plan's own order)
//     is a policy bug: Apply returns kInternal and leaves the counts as they were;
//   - everything is sized at construction from the MapIndex; Apply allocates nothing.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "common/status.h"
#include "memory/map_index.h"
#include "memory/plan.h"

namespace zm {

class ExternalWorkingSet {
 public:
  // One net load batch: loads()[begin, end) came from plan batch `zone`.
  struct LoadBatch {
    ZoneId zone = kNoZone;
    std::uint32_t begin = 0;
    std::uint32_t end = 0;
  };

  explicit ExternalWorkingSet(const MapIndex& index);
  ExternalWorkingSet(const ExternalWorkingSet&) = delete;
  ExternalWorkingSet& operator=(const ExternalWorkingSet&) = delete;

  // Applies `plan` to the counts and fills unloads()/loads()/load_batches(). On error nothing
  // changes (the lists are empty). No allocation.
  [[nodiscard]] Status Apply(const Plan& plan);

  // The net change of the last Apply; valid until the next one.
  [[nodiscard]] std::span<const KfIndex> unloads() const { return unloads_; }
  [[nodiscard]] std::span<const KfIndex> loads() const { return loads_; }
  [[nodiscard]] std::span<const LoadBatch> load_batches() const { return batches_; }
  // Resident count before the last Apply, and the highest count while carrying it out in order.
  [[nodiscard]] std::uint32_t resident_before() const { return before_; }
  [[nodiscard]] std::uint32_t peak_during_apply() const { return peak_; }

  [[nodiscard]] bool IsResident(KfIndex k) const { return refcount_[k] > 0; }
  [[nodiscard]] std::uint32_t refcount(KfIndex k) const { return refcount_[k]; }
  [[nodiscard]] std::uint32_t resident_count() const { return resident_; }
  // Highest resident count at any instant of carrying out every answer so far.
  [[nodiscard]] std::uint32_t max_resident_seen() const { return max_seen_; }

 private:
  // Marks k as touched by this Apply and remembers its count before it.
  void Touch(KfIndex k);
  [[nodiscard]] Status ApplyReleases(const Plan& plan);
  void ApplyAcquires(const Plan& plan);

  const MapIndex& index_;
  std::vector<std::uint32_t> refcount_;  // per keyframe
  std::vector<std::uint32_t> before_count_;  // per keyframe: count before this Apply (if touched)
  std::vector<std::uint32_t> touched_;   // per keyframe: epoch of the Apply that touched it
  std::uint32_t epoch_ = 0;
  std::vector<KfIndex> unloads_;         // reserved to N
  std::vector<KfIndex> loads_;           // reserved to N
  std::vector<LoadBatch> batches_;       // reserved to the plan's batch capacity
  std::uint32_t resident_ = 0;
  std::uint32_t before_ = 0;
  std::uint32_t peak_ = 0;
  std::uint32_t max_seen_ = 0;
};

}  // namespace zm
