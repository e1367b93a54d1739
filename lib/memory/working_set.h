// WorkingSet: the resident keyframes. Holds id -> slot and a per-keyframe reference count
// (number of active zones holding it for the zone policies, 0/1 for basic and radius), and
// carries out a Plan through a KeyframeSource into the Arena.
//
// Apply(plan) for kUnloadThenLoad:
//   1. pin: an acquire of a keyframe that is already resident only bumps its count, so a
//      keyframe shared by an evicted zone and the incoming zone is never dropped and re-read;
//   2. release every reference (slot returned to the arena when the count reaches 0);
//   3. per batch: count the references, then one LoadZone (zone batch, one transaction) or one
//      LoadKeyframes (kNoZone batch) for the keyframes that became wanted. The source asks
//      Wants(id) before reading each payload and calls Loaded(id, slot) after.
// kLoadThenUnload (basic only) does 3 then 2.
//
// Invariants:
//   - a keyframe is resident iff its count > 0, and then it owns exactly one arena slot;
//   - resident_count() after every single slot acquisition is recorded in max_resident_seen();
//     for the bounded policies it never exceeds k_max (the arena capacity makes it physical);
//   - after construction nothing allocates: resident() is a dense array updated by swap-remove.
//   - after an error from the source the working set stays self-consistent (counts match
//     slots), but the policy's view no longer matches: restart the policy.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "arena/arena.h"
#include "common/status.h"
#include "mapdb/map_db.h"
#include "memory/map_index.h"
#include "memory/plan.h"

namespace zm {

// What one tick did to memory. Counts add up over the Apply() calls of a tick; resident and
// over-budget fields are snapshots taken at the end of each Apply().
struct TickTelemetry {
  std::uint32_t resident_keyframes = 0;    // after the last Apply of the tick
  std::uint64_t resident_bytes = 0;        // payload bytes of the resident keyframes
  std::uint32_t peak_resident_keyframes = 0;  // highest count at any instant during the tick
  std::uint32_t keyframes_loaded = 0;
  std::uint32_t keyframes_unloaded = 0;
  std::uint32_t zones_loaded = 0;          // zone batches started (partial loads count)
  std::uint32_t zones_unloaded = 0;
  // Database work in one unit for every policy, LoadStats' definitions: SQL statements
  // executed, transactions (an autocommit statement is one), incremental blob reads. Loads and
  // the policy's own graph searches (basic) both count; the search_* fields say how much of it
  // was searching.
  std::uint32_t db_transactions = 0;
  std::uint32_t db_queries = 0;            // SQL statements executed
  std::uint32_t db_blob_reads = 0;         // payloads read through a blob handle (zone loads)
  std::uint32_t search_queries = 0;        // of db_queries: basic's graph-search statements
  std::uint32_t search_transactions = 0;   // of db_transactions: the same searches'
  std::uint64_t db_bytes_read = 0;         // payload bytes loaded
  double load_ms = 0.0;                    // wall time inside the source's load calls
  double unload_ms = 0.0;                  // wall time releasing slots
  bool over_budget = false;                // peak_resident_keyframes > k_max at some instant
  std::uint64_t refused_acquisitions = 0;  // arena TryAcquire refusals during the tick
};

class WorkingSet final : private LoadSink {
 public:
  // k_max is the policy budget (MemoryThr) used for the over-budget flag. The arena's capacity
  // may be larger (basic, unbounded) or equal (the bounded policies). Allocates once here.
  WorkingSet(const MapIndex& index, Arena& arena, KeyframeSource& source, std::uint32_t k_max);
  ~WorkingSet() override = default;
  WorkingSet(const WorkingSet&) = delete;
  WorkingSet& operator=(const WorkingSet&) = delete;

  // Carries out `plan`, adding what happened to *telemetry. No allocation once constructed.
  Status Apply(const Plan& plan, TickTelemetry* telemetry);

  struct Resident {
    KeyframeId id;
    KfIndex index = kNoKf;
    SlotIndex slot;
  };
  // The resident keyframes, dense, unordered. Valid until the next Apply.
  [[nodiscard]] std::span<const Resident> resident() const { return resident_; }
  [[nodiscard]] bool IsResident(KfIndex k) const { return refcount_[k] > 0; }
  [[nodiscard]] std::uint32_t refcount(KfIndex k) const { return refcount_[k]; }
  // Only meaningful while IsResident(k).
  [[nodiscard]] SlotIndex slot(KfIndex k) const { return resident_[position_[k]].slot; }
  [[nodiscard]] std::uint32_t resident_count() const {
    return static_cast<std::uint32_t>(resident_.size());
  }
  [[nodiscard]] std::uint64_t resident_bytes() const { return resident_bytes_; }
  [[nodiscard]] std::uint32_t k_max() const { return k_max_; }
  // Highest resident count ever observed, checked after every single slot acquisition.
  [[nodiscard]] std::uint32_t max_resident_seen() const { return max_resident_seen_; }
  // Slot acquisitions that took the count above k_max (0 for the bounded policies).
  [[nodiscard]] std::uint64_t over_budget_acquisitions() const { return over_budget_acquisitions_; }
  // Moving average of load wall time per keyframe (ms); 0 until something was loaded. Feeds
  // TickContext::load_ms_per_keyframe for the predictive policy's time slice.
  [[nodiscard]] double load_ms_per_keyframe() const { return load_ms_per_keyframe_; }

 private:
  bool Wants(KeyframeId id) override;
  void Loaded(KeyframeId id, SlotIndex slot, std::uint32_t payload_bytes) override;

  // Adds one load's LoadStats to the tick's database work (every load path calls it).
  static void AccountLoad(const LoadStats& stats, TickTelemetry* t);
  // Adds the plan's own searches (already executed by the policy) to the tick's database work;
  // returns the first search read that failed.
  static Status AccountSearch(const Plan& plan, TickTelemetry* t);
  void Pin(const Plan& plan);
  void Unload(const Plan& plan, TickTelemetry* t);
  Status Load(const Plan& plan, TickTelemetry* t);
  void Drop(KfIndex k);

  const MapIndex& index_;
  Arena& arena_;
  KeyframeSource& source_;
  std::uint32_t k_max_;
  std::vector<std::uint32_t> refcount_;  // per keyframe
  std::vector<std::uint32_t> position_;  // per keyframe: index into resident_ while resident
  std::vector<std::uint32_t> payload_;   // per keyframe: bytes of the resident payload
  std::vector<std::uint8_t> pending_;    // per keyframe: wanted by the batch being loaded
  std::vector<std::uint8_t> pinned_;     // per acquire entry of the current plan
  std::vector<KeyframeId> batch_ids_;    // scratch for LoadKeyframes
  std::vector<Resident> resident_;       // reserved to the arena capacity (or N)
  std::uint64_t resident_bytes_ = 0;
  std::uint32_t max_resident_seen_ = 0;
  std::uint32_t apply_peak_ = 0;
  std::uint64_t over_budget_acquisitions_ = 0;
  std::uint32_t batch_loaded_ = 0;
  std::uint32_t unexpected_loads_ = 0;
  double load_ms_per_keyframe_ = 0.0;
};

}  // namespace zm
