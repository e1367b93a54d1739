// WorkingSet: pin, unload, queue, load (or load, unload for basic), with exact accounting; loads
// run to the end inside Apply, or time-sliced through StepLoads.
#include "memory/working_set.h"

#include <algorithm>
#include <cassert>
#include <string>

#include "common/clock.h"

namespace zm {
namespace {

using Clock = std::chrono::steady_clock;

bool Unlimited(const LoadSlice& s) {
  return s.deadline == Clock::time_point::max() &&
         s.max_bytes == std::numeric_limits<std::uint64_t>::max() &&
         s.max_keyframes == std::numeric_limits<std::uint32_t>::max() && s.interrupt == nullptr;
}

std::string BatchName(ZoneId zone) {
  return zone == kNoZone ? std::string("LoadKeyframes")
                         : "LoadZone(" + std::to_string(zone.value) + ")";
}

}  // namespace

WorkingSet::WorkingSet(const MapIndex& index, Arena& arena, KeyframeSource& source,
                       std::uint32_t k_max, bool sliced)
    : index_(index), arena_(arena), source_(source), k_max_(k_max), sliced_(sliced) {
  const std::size_t n = index.keyframe_count();
  const std::size_t refs = Plan::RefCapacity(index);
  refcount_.assign(n, 0);
  position_.assign(n, 0);
  payload_.assign(n, 0);
  owner_.assign(n, 0);
  pinned_.assign(refs, 0);
  // Owned entries are distinct pending keyframes (<= n); one plan batch adds <= refs more. Twice
  // the reference capacity leaves room for entries of cancelled keyframes until a compaction.
  ids_.reserve(2 * refs);
  ids_scratch_.reserve(2 * refs);
  // Live batches each own >= 1 pending keyframe; one plan adds at most its batch capacity.
  batches_.reserve(n + 2 * (static_cast<std::size_t>(index.zone_count()) + 2) + 1);
  batch_ids_.reserve(n);
  resident_.reserve(std::min<std::size_t>(n, arena.capacity()));
}

WorkingSet::~WorkingSet() { YieldSource(); }

bool WorkingSet::Wants(KeyframeId id) {
  const KfIndex k = index_.Find(id);
  return k != kNoKf && owner_[k] != 0;
}

void WorkingSet::Loaded(KeyframeId id, SlotIndex slot, std::uint32_t payload_bytes) {
  const KfIndex k = index_.Find(id);
  if (k == kNoKf || owner_[k] == 0) {
    // The source delivered something nobody asked for: give the slot back, count it.
    arena_.Release(slot);
    ++unexpected_loads_;
    return;
  }
  if (Batch* b = FindBatch(owner_[k]); b != nullptr) --b->remaining;
  owner_[k] = 0;
  --pending_count_;
  position_[k] = static_cast<std::uint32_t>(resident_.size());
  assert(resident_.size() < resident_.capacity());
  resident_.push_back(Resident{id, k, slot});
  payload_[k] = payload_bytes;
  resident_bytes_ += payload_bytes;
  ++step_loaded_;
  step_bytes_ += payload_bytes;
  // The invariant check after every single slot acquisition.
  const auto count = static_cast<std::uint32_t>(resident_.size());
  max_resident_seen_ = std::max(max_resident_seen_, count);
  apply_peak_ = std::max(apply_peak_, count);
  if (count > k_max_) ++over_budget_acquisitions_;
}

void WorkingSet::Drop(KfIndex k) {
  const std::uint32_t pos = position_[k];
  arena_.Release(resident_[pos].slot);
  resident_bytes_ -= payload_[k];
  payload_[k] = 0;
  resident_[pos] = resident_.back();
  position_[resident_[pos].index] = pos;
  resident_.pop_back();
}

WorkingSet::Batch* WorkingSet::FindBatch(std::uint32_t seq) {
  for (Batch& b : batches_) {
    if (b.seq == seq) return &b;
  }
  return nullptr;
}

void WorkingSet::Cancel(KfIndex k, TickTelemetry* t) {
  if (Batch* b = FindBatch(owner_[k]); b != nullptr) --b->remaining;
  owner_[k] = 0;
  --pending_count_;
  ++t->keyframes_cancelled;
}

void WorkingSet::Pin(const Plan& plan) {
  const auto acquires = plan.acquires();
  for (std::size_t i = 0; i < acquires.size(); ++i) {
    const KfIndex k = acquires[i];
    pinned_[i] = refcount_[k] > 0 ? 1 : 0;
    if (pinned_[i] != 0) ++refcount_[k];
  }
}

void WorkingSet::Unload(const Plan& plan, TickTelemetry* t) {
  const auto t0 = Clock::now();
  for (KfIndex k : plan.releases()) {
    // A keyframe nobody holds: its load failed (no slot: the device refused the memory) and
    // RetireHead dropped its references; the policy that planned it does not know. Nothing to do.
    if (refcount_[k] == 0) continue;
    if (--refcount_[k] != 0) continue;
    if (owner_[k] != 0) {
      Cancel(k, t);  // still queued: no slot to give back, just no longer wanted
    } else {
      Drop(k);
      ++t->keyframes_unloaded;
    }
  }
  t->unload_ms += MsSince(t0);
  DropDoneBatches();
}

void WorkingSet::Compact() {
  ids_scratch_.clear();
  for (Batch& b : batches_) {
    const auto begin = static_cast<std::uint32_t>(ids_scratch_.size());
    for (std::uint32_t i = std::max(b.begin, b.cursor); i < b.end; ++i) {
      if (owner_[ids_[i]] == b.seq) ids_scratch_.push_back(ids_[i]);
    }
    b.begin = begin;
    b.cursor = begin;
    b.end = static_cast<std::uint32_t>(ids_scratch_.size());
  }
  ids_.swap(ids_scratch_);  // equal capacities: swapping buffers allocates nothing
}

void WorkingSet::Enqueue(const Plan& plan) {
  const auto acquires = plan.acquires();
  std::size_t insert_at = 0;  // the plan's batches go to the front, in plan order
  for (const PlanBatch& pb : plan.batches()) {
    if (ids_.size() + (pb.end - pb.begin) > ids_.capacity()) Compact();
    assert(ids_.size() + (pb.end - pb.begin) <= ids_.capacity());
    Batch b;
    b.zone = pb.zone;
    b.seq = next_seq_;
    b.begin = static_cast<std::uint32_t>(ids_.size());
    b.cursor = b.begin;
    for (std::uint32_t i = pb.begin; i < pb.end; ++i) {
      if (pinned_[i] != 0) continue;
      const KfIndex k = acquires[i];
      if (refcount_[k]++ != 0) continue;  // already resident or queued
      owner_[k] = b.seq;
      ids_.push_back(k);
      ++b.remaining;
      ++pending_count_;
    }
    b.end = static_cast<std::uint32_t>(ids_.size());
    if (b.remaining == 0) continue;  // everything already held: no transaction at all
    if (++next_seq_ == 0) next_seq_ = 1;  // 0 means "not pending"
    assert(batches_.size() < batches_.capacity());
    batches_.insert(batches_.begin() + static_cast<std::ptrdiff_t>(insert_at++), b);
  }
}

void WorkingSet::DropDoneBatches() {
  std::size_t out = 0;
  for (std::size_t i = 0; i < batches_.size(); ++i) {
    if (batches_[i].remaining == 0) {
      // Nothing left to load (cancelled, or delivered by an overlapping zone's load).
      if (batches_[i].seq == in_flight_seq_) YieldSource();
      continue;
    }
    if (out != i) batches_[out] = batches_[i];
    ++out;
  }
  batches_.resize(out);  // shrinking never allocates
}

void WorkingSet::Prioritize(ZoneId z) {
  if (z == kNoZone) return;
  std::size_t front = 0;
  for (std::size_t i = 0; i < batches_.size(); ++i) {
    if (batches_[i].zone != z) continue;
    if (i != front) {
      std::rotate(batches_.begin() + static_cast<std::ptrdiff_t>(front),
                  batches_.begin() + static_cast<std::ptrdiff_t>(i),
                  batches_.begin() + static_cast<std::ptrdiff_t>(i + 1));
    }
    ++front;
  }
}

void WorkingSet::YieldSource() {
  if (in_flight_seq_ == 0) return;
  source_.AbortZoneLoad();
  in_flight_seq_ = 0;
}

std::uint32_t WorkingSet::Undelivered(const Batch& b, KeyframeId* first) {
  std::uint32_t missing = 0;
  for (std::uint32_t i = b.begin; i < b.end; ++i) {
    const KfIndex k = ids_[i];
    if (owner_[k] != b.seq) continue;
    if (missing++ == 0) *first = index_.id(k);
  }
  return missing;
}

void WorkingSet::RetireHead() {
  // Whatever the head still owns is dropped with it: its references are undone, so counts keep
  // matching slots (the policy's view no longer does: see the header).
  const Batch& b = batches_.front();
  for (std::uint32_t i = b.begin; i < b.end; ++i) {
    const KfIndex k = ids_[i];
    if (owner_[k] != b.seq) continue;
    owner_[k] = 0;
    refcount_[k] = 0;
    --pending_count_;
  }
  if (b.seq == in_flight_seq_) YieldSource();
  batches_.erase(batches_.begin());
}

Status WorkingSet::StepHead(TickTelemetry* t, std::uint32_t max_keyframes, bool* done) {
  Batch& b = batches_.front();
  const ZoneId zone = b.zone;
  *done = false;
  if (zone == kNoZone) {
    // A keyframe batch: the next owned ids, in plan order, one LoadKeyframes call.
    batch_ids_.clear();
    while (b.cursor < b.end && batch_ids_.size() < max_keyframes) {
      const KfIndex k = ids_[b.cursor++];
      if (owner_[k] == b.seq) batch_ids_.push_back(index_.id(k));
    }
    const bool last = b.cursor == b.end;
    if (batch_ids_.empty()) {
      *done = true;
      RetireHead();
      return Status::Ok();
    }
    const auto t0 = Clock::now();
    Result<LoadStats> stats = source_.LoadKeyframes(batch_ids_, arena_, *this);
    t->load_ms += MsSince(t0);
    if (stats.ok()) AccountLoad(*stats, t);
    std::uint32_t missing = 0;
    KeyframeId first{0};
    for (KeyframeId id : batch_ids_) {
      if (owner_[index_.Find(id)] == b.seq && missing++ == 0) first = id;
    }
    if (!stats.ok() || missing > 0 || last) {
      *done = true;
      RetireHead();  // undoes the references of whatever was not delivered
    }
    if (!stats.ok()) return stats.status().Annotate("loading keyframes");
    if (missing > 0) {
      return NotFound(std::to_string(missing) + " wanted keyframes (first: " +
                      std::to_string(first.value) + ") were not delivered by LoadKeyframes");
    }
    return Status::Ok();
  }

  const auto t0 = Clock::now();
  if (in_flight_seq_ != b.seq) {
    if (in_flight_seq_ != 0) {
      YieldSource();  // overtaken by a newer batch: its load restarts when it is the head again
      ++t->loads_preempted;
    }
    Result<LoadStats> begun = source_.BeginZoneLoad(zone, arena_, *this);
    if (!begun.ok()) {
      t->load_ms += MsSince(t0);
      *done = true;
      RetireHead();
      return begun.status().Annotate("loading zone " + std::to_string(zone.value));
    }
    in_flight_seq_ = b.seq;
    AccountLoad(*begun, t);
  }
  LoadBudget budget;
  budget.max_keyframes = max_keyframes;
  Result<ZoneLoadStep> step = source_.StepZoneLoad(budget);
  t->load_ms += MsSince(t0);
  if (!step.ok()) {
    in_flight_seq_ = 0;  // the source ended the load (and released the failing keyframe's slot)
    *done = true;
    RetireHead();
    return step.status().Annotate("loading zone " + std::to_string(zone.value));
  }
  AccountLoad(step->stats, t);
  if (!step->done) return Status::Ok();
  in_flight_seq_ = 0;
  *done = true;
  KeyframeId first{0};
  const std::uint32_t missing = Undelivered(batches_.front(), &first);
  RetireHead();
  if (missing > 0) {
    return NotFound(std::to_string(missing) + " wanted keyframes (first: " +
                    std::to_string(first.value) + ") were not delivered by " + BatchName(zone));
  }
  return Status::Ok();
}

void WorkingSet::AccountLoad(const LoadStats& stats, TickTelemetry* t) {
  t->db_transactions += stats.transactions;
  t->db_queries += stats.queries;
  t->db_blob_reads += stats.blob_reads;
  t->db_bytes_read += stats.bytes;
}

Status WorkingSet::AccountSearch(const Plan& plan, TickTelemetry* t) {
  t->db_transactions += plan.search.transactions;
  t->db_queries += plan.search.queries;
  t->db_blob_reads += plan.search.blob_reads;
  t->search_transactions += plan.search.transactions;
  t->search_queries += plan.search.queries;
  if (plan.search_error.ok()) return Status::Ok();
  return plan.search_error.Annotate("the policy's graph search");
}

Status WorkingSet::StepLoads(const LoadSlice& slice, TickTelemetry* telemetry) {
  const std::uint64_t refused_before = arena_.stats().refused;
  apply_peak_ = resident_count();
  const Status status = RunQueue(slice, telemetry);
  Snapshot(telemetry, refused_before);
  return status;
}

void WorkingSet::Snapshot(TickTelemetry* telemetry, std::uint64_t refused_before) {
  TickTelemetry& t = *telemetry;
  t.resident_keyframes = resident_count();
  t.resident_bytes = resident_bytes_;
  t.pending_keyframes = pending_count_;
  t.peak_resident_keyframes = std::max(t.peak_resident_keyframes, apply_peak_);
  t.over_budget = t.over_budget || t.peak_resident_keyframes > k_max_;
  t.refused_acquisitions += arena_.stats().refused - refused_before;
}

Status WorkingSet::RunQueue(const LoadSlice& slice, TickTelemetry* telemetry) {
  TickTelemetry& t = *telemetry;
  const bool unlimited = Unlimited(slice);
  const bool timed = slice.deadline != Clock::time_point::max();
  const auto estimate = [this] {
    return std::chrono::duration_cast<Clock::duration>(
        std::chrono::duration<double, std::milli>(keyframe_ms_estimate_));
  };
  std::uint32_t loaded = 0;
  std::uint64_t bytes = 0;
  Status status;
  for (;;) {
    DropDoneBatches();
    if (batches_.empty()) break;
    const ZoneId head = batches_.front().zone;
    if (slice.zone != kNoZone && head != kNoZone && head != slice.zone) break;
    if (loaded >= slice.max_keyframes) break;
    if (loaded >= slice.min_keyframes) {
      if (timed && Clock::now() + estimate() > slice.deadline) break;
      if (bytes + arena_.slot_bytes() > slice.max_bytes) break;
      if (slice.interrupt != nullptr && slice.interrupt->ShouldStop()) break;
    }
    // Unlimited: each batch in one call (one LoadZone-like step, one LoadKeyframes). Otherwise
    // one keyframe a call, so the clock is read between keyframes.
    const std::uint32_t chunk = unlimited ? std::numeric_limits<std::uint32_t>::max() : 1;
    step_loaded_ = 0;
    step_bytes_ = 0;
    const auto t0 = Clock::now();
    bool done = false;
    status = StepHead(&t, chunk, &done);
    if (step_loaded_ > 0) {
      const double per = MsSince(t0) / step_loaded_;
      keyframe_ms_estimate_ = std::max(per, keyframe_ms_estimate_ * 0.95);
    }
    loaded += step_loaded_;
    bytes += step_bytes_;
    t.keyframes_loaded += step_loaded_;
    if (!status.ok()) break;
  }
  return status;
}

Status WorkingSet::Apply(const Plan& plan, TickTelemetry* telemetry) {
  TickTelemetry& t = *telemetry;
  const std::uint64_t refused_before = arena_.stats().refused;
  apply_peak_ = resident_count();
  std::fill_n(pinned_.begin(), plan.acquires().size(), std::uint8_t{0});
  Status status;
  // Loads everything queued; an error drops only its own batch, the others still load.
  const auto load_all = [&] {
    while (loading()) {
      Status s = RunQueue(LoadSlice{}, &t);
      if (status.ok()) status = s;
    }
  };
  if (plan.order == PlanOrder::kUnloadThenLoad) {
    Pin(plan);
    Unload(plan, &t);
    Enqueue(plan);
    if (!sliced_) load_all();
  } else {
    Enqueue(plan);
    load_all();  // RTAB-Map retrieves, then transfers: never sliced
    Unload(plan, &t);
  }
  t.zones_loaded += static_cast<std::uint32_t>(plan.zones_loaded().size());
  t.zones_unloaded += static_cast<std::uint32_t>(plan.zones_unloaded().size());
  const Status searched = AccountSearch(plan, &t);
  if (status.ok() && !searched.ok()) status = searched;
  Snapshot(&t, refused_before);
  return status;
}

}  // namespace zm
