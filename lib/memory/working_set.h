// WorkingSet: the resident keyframes. Holds id -> slot and a per-keyframe reference count
// (number of active zones holding it for the zone policies, 0/1 for basic and radius), and
// carries out a Plan through a KeyframeSource into the Arena.
//
// Apply(plan) for kUnloadThenLoad:
//   1. pin: an acquire of a keyframe that is already held (resident, or queued to load) only
//      bumps its count, so a keyframe shared by an evicted zone and the incoming zone is never
//      dropped and re-read;
//   2. release every reference: a resident keyframe's slot goes back to the arena when its
//      count reaches 0, a queued one is simply no longer wanted (cancelled);
//   3. queue each acquire batch: the keyframes that became wanted are "pending", owned by the
//      batch; the plan's batches go to the FRONT of the load queue, in plan order (the newest
//      decision is the most urgent: the zone the robot just entered comes before a zone it left).
//   Unsliced (the default): the queue is then loaded to the end inside Apply, one LoadZone-like
//   transaction per zone batch (Begin + one unlimited step) and one LoadKeyframes per keyframe
//   batch: exactly the pre-slicing behaviour.
//   Sliced (LoadSliceOptions::sliced, what the tick loop uses): Apply only queues; StepLoads()
//   loads within a LoadSlice (a deadline, bytes, a stop poll), one keyframe at a time, checking
//   the clock between keyframes, so a load spreads over the idle time of several ticks.
// kLoadThenUnload (basic only) queues, loads to the end, then releases.
//
// The load queue (sliced): the head batch is the only one the source works on. A zone batch is
// one time-sliced zone load (BeginZoneLoad, StepZoneLoad one keyframe a call), its read
// transaction held across steps and ticks; a keyframe batch (kNoZone) is one LoadKeyframes call
// per keyframe, in the plan's order (radius: nearest tiles first). When a newer batch overtakes
// the head (a new zone preempts an unfinished load), the head's zone load is aborted; its
// undelivered keyframes stay pending and its load restarts (a new transaction) when it is the
// head again, skipping what already arrived. A batch whose keyframes were all cancelled or
// delivered by another zone's load (overlaps) is dropped without a transaction.
//
// Invariants:
//   - a keyframe is resident iff it owns exactly one arena slot; count > 0 iff resident or
//     pending; pending keyframes own no slot, so resident <= the policy's planned union <= k_max
//     at every instant, however far behind the loads are;
//   - the localizer's view (resident()) only ever holds complete, validated keyframes: a slot
//     enters it in Loaded(), after the source checked the payload; a zone being loaded is
//     usable keyframe by keyframe;
//   - resident_count() after every single slot acquisition is recorded in max_resident_seen();
//     for the bounded policies it never exceeds k_max (the arena capacity makes it physical);
//   - after construction nothing allocates (error messages aside): resident(), the queue and its
//     keyframe lists are fixed-capacity arrays updated in place;
//   - after an error from the source the working set stays self-consistent (counts match slots;
//     the failed batch's pending keyframes are dropped), but the policy's view no longer
//     matches: restart the policy.
#pragma once

#include <chrono>
#include <cstdint>
#include <limits>
#include <span>
#include <vector>

#include "arena/arena.h"
#include "common/status.h"
#include "mapdb/map_db.h"
#include "memory/map_index.h"
#include "memory/plan.h"

namespace zm {

// How loads are spread over time ([loads] in a profile, read once; docs/memory.md). Time-sliced
// loads spend two budgets per tick: a small in-tick slice right after the plan, so that the zone
// the robot just entered starts loading at once, and the idle part of the tick, between its end
// and the next frame's due time. The clock is checked between keyframes.
struct LoadSliceOptions {
  bool sliced = true;                           // false: every load finishes in the tick that plans it
  double tick_ms = 2.0;                         // in-tick slice; 0 = no time limit (bytes only)
  std::uint64_t tick_bytes = 32ull << 20;       // in-tick slice; 0 = no byte limit
  double idle_ms = 0.0;                         // idle slice per tick; 0 = up to the next frame's due time
  std::uint64_t idle_bytes = 0;                 // idle slice per tick; 0 = no byte limit
  double margin_ms = 5.0;                       // the idle slice ends this long before the next frame is due
};

// Polled between two keyframes of a slice: true ends the slice (e.g. a frame is waiting).
class SliceInterrupt {
 public:
  virtual ~SliceInterrupt() = default;
  [[nodiscard]] virtual bool ShouldStop() = 0;
};

// The budget of one StepLoads() call. A keyframe is started only if it is expected to end by
// the deadline (the slowest recent keyframe, keyframe_ms_estimate(), is the expectation) and
// could not take the slice past max_bytes (a keyframe counts as a whole slot until it lands).
// min_keyframes are loaded whatever the budget, so that a slice always makes progress.
struct LoadSlice {
  using Clock = std::chrono::steady_clock;
  Clock::time_point deadline = Clock::time_point::max();
  std::uint64_t max_bytes = std::numeric_limits<std::uint64_t>::max();
  std::uint32_t max_keyframes = std::numeric_limits<std::uint32_t>::max();
  std::uint32_t min_keyframes = 0;
  // Load only while the head batch is a keyframe batch or a batch of `zone` (the robot's zone);
  // kNoZone = any batch.
  ZoneId zone = kNoZone;
  SliceInterrupt* interrupt = nullptr;  // may be null
};

// What one tick did to memory. Counts add up over the Apply()/StepLoads() calls of a tick;
// resident and over-budget fields are snapshots taken at the end of each call.
struct TickTelemetry {
  std::uint32_t resident_keyframes = 0;    // after the last call of the tick
  std::uint64_t resident_bytes = 0;        // payload bytes of the resident keyframes
  std::uint32_t pending_keyframes = 0;     // queued, not yet loaded, after the last call
  std::uint32_t peak_resident_keyframes = 0;  // highest count at any instant during the tick
  std::uint32_t keyframes_loaded = 0;
  std::uint32_t keyframes_unloaded = 0;
  std::uint32_t keyframes_cancelled = 0;   // pending keyframes released before they loaded
  std::uint32_t zones_loaded = 0;          // zone batches started (partial loads count)
  std::uint32_t zones_unloaded = 0;
  std::uint32_t loads_preempted = 0;       // in-flight zone loads overtaken by a newer batch
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
  using Clock = std::chrono::steady_clock;

  // k_max is the policy budget (MemoryThr) used for the over-budget flag. The arena's capacity
  // may be larger (basic, unbounded) or equal (the bounded policies). `sliced`: Apply queues
  // loads and StepLoads carries them out (see above); otherwise Apply loads everything.
  // Allocates once here.
  WorkingSet(const MapIndex& index, Arena& arena, KeyframeSource& source, std::uint32_t k_max,
             bool sliced = false);
  ~WorkingSet() override;
  WorkingSet(const WorkingSet&) = delete;
  WorkingSet& operator=(const WorkingSet&) = delete;

  // Carries out `plan` (releases at once, loads queued or done, see above), adding what
  // happened to *telemetry. No allocation once constructed.
  Status Apply(const Plan& plan, TickTelemetry* telemetry);

  // Loads queued keyframes within `slice`, head batch first, one keyframe at a time. An error
  // drops the head batch (its pending keyframes are no longer held) and is returned; the rest
  // of the queue stays. No allocation.
  Status StepLoads(const LoadSlice& slice, TickTelemetry* telemetry);
  // Loads the whole queue (StepLoads without limits).
  Status FinishLoads(TickTelemetry* telemetry) { return StepLoads(LoadSlice{}, telemetry); }
  // Moves the batches of zone z to the front of the queue (the robot is in z: its zone first).
  void Prioritize(ZoneId z);
  // Ends the source's in-flight zone load, if ours, keeping its batch queued (it restarts, as a
  // new transaction, at the next step). For a caller that must read through the same source in
  // between (a source allows one load at a time).
  void YieldSource();

  [[nodiscard]] bool sliced() const { return sliced_; }
  // Something is queued to load.
  [[nodiscard]] bool loading() const { return !batches_.empty(); }
  [[nodiscard]] std::uint32_t pending_count() const { return pending_count_; }
  // The zone of the head batch (kNoZone for a keyframe batch, or when nothing is queued).
  [[nodiscard]] ZoneId loading_zone() const { return batches_.empty() ? kNoZone : batches_.front().zone; }
  [[nodiscard]] std::size_t queued_batches() const { return batches_.size(); }
  [[nodiscard]] bool IsPending(KfIndex k) const { return owner_[k] != 0; }
  // The slowest recent keyframe load, decaying 5 % per keyframe loaded since (ms; 0 until the
  // first): what a slice expects the next keyframe to take.
  [[nodiscard]] double keyframe_ms_estimate() const { return keyframe_ms_estimate_; }

  struct Resident {
    KeyframeId id;
    KfIndex index = kNoKf;
    SlotIndex slot;
  };
  // The resident keyframes, dense, unordered. Valid until the next Apply or StepLoads.
  [[nodiscard]] std::span<const Resident> resident() const { return resident_; }
  [[nodiscard]] bool IsResident(KfIndex k) const { return refcount_[k] > 0 && owner_[k] == 0; }
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

 private:
  // One queued acquire batch: its keyframes are ids_[begin, end); those still owned by it
  // (owner_[k] == seq) are its `remaining` pending keyframes.
  struct Batch {
    ZoneId zone = kNoZone;
    std::uint32_t seq = 0;
    std::uint32_t begin = 0;
    std::uint32_t end = 0;
    std::uint32_t remaining = 0;
    std::uint32_t cursor = 0;  // keyframe batches: next position to load
  };

  bool Wants(KeyframeId id) override;
  void Loaded(KeyframeId id, SlotIndex slot, std::uint32_t payload_bytes) override;

  // Adds one load's LoadStats to the tick's database work (every load path calls it).
  static void AccountLoad(const LoadStats& stats, TickTelemetry* t);
  // Adds the plan's own searches (already executed by the policy) to the tick's database work;
  // returns the first search read that failed.
  static Status AccountSearch(const Plan& plan, TickTelemetry* t);
  void Pin(const Plan& plan);
  void Unload(const Plan& plan, TickTelemetry* t);
  void Enqueue(const Plan& plan);
  Batch* FindBatch(std::uint32_t seq);
  void Cancel(KfIndex k, TickTelemetry* t);
  void DropDoneBatches();
  void Compact();
  // The head batch's keyframes still owned by it: the load ended without them.
  std::uint32_t Undelivered(const Batch& b, KeyframeId* first);
  void RetireHead();
  Status StepHead(TickTelemetry* t, std::uint32_t max_keyframes, bool* done);
  // The body of StepLoads (also Apply's when unsliced), without the end-of-call snapshot.
  Status RunQueue(const LoadSlice& slice, TickTelemetry* t);
  void Snapshot(TickTelemetry* t, std::uint64_t refused_before);
  void Drop(KfIndex k);

  const MapIndex& index_;
  Arena& arena_;
  KeyframeSource& source_;
  std::uint32_t k_max_;
  bool sliced_;
  std::vector<std::uint32_t> refcount_;  // per keyframe
  std::vector<std::uint32_t> position_;  // per keyframe: index into resident_ while resident
  std::vector<std::uint32_t> payload_;   // per keyframe: bytes of the resident payload
  std::vector<std::uint32_t> owner_;     // per keyframe: seq of the batch loading it; 0 = none
  std::vector<std::uint8_t> pinned_;     // per acquire entry of the current plan
  std::vector<KfIndex> ids_;             // keyframe lists of the queued batches
  std::vector<KfIndex> ids_scratch_;     // compaction buffer (same capacity)
  std::vector<Batch> batches_;           // the load queue, head first
  std::vector<KeyframeId> batch_ids_;    // scratch for LoadKeyframes
  std::vector<Resident> resident_;       // reserved to the arena capacity (or N)
  std::uint32_t next_seq_ = 1;
  std::uint32_t pending_count_ = 0;
  std::uint32_t in_flight_seq_ = 0;      // batch whose zone load the source has in flight; 0 = none
  std::uint64_t resident_bytes_ = 0;
  std::uint32_t max_resident_seen_ = 0;
  std::uint32_t apply_peak_ = 0;
  std::uint64_t over_budget_acquisitions_ = 0;
  std::uint32_t step_loaded_ = 0;
  std::uint64_t step_bytes_ = 0;
  std::uint32_t unexpected_loads_ = 0;
  double keyframe_ms_estimate_ = 0.0;
};

}  // namespace zm
