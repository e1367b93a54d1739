// WorkingSet::Apply: pin, unload, load (or load, unload for basic), with exact accounting.
#include "memory/working_set.h"

#include <algorithm>
#include <chrono>
#include <string>

namespace zm {
namespace {

using Clock = std::chrono::steady_clock;
double MsSince(Clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}

}  // namespace

WorkingSet::WorkingSet(const MapIndex& index, Arena& arena, KeyframeSource& source,
                       std::uint32_t k_max)
    : index_(index), arena_(arena), source_(source), k_max_(k_max) {
  const std::size_t n = index.keyframe_count();
  refcount_.assign(n, 0);
  position_.assign(n, 0);
  payload_.assign(n, 0);
  pending_.assign(n, 0);
  pinned_.assign(Plan::RefCapacity(index), 0);
  batch_ids_.reserve(n);
  resident_.reserve(std::min<std::size_t>(n, arena.capacity()));
}

bool WorkingSet::Wants(KeyframeId id) {
  const KfIndex k = index_.Find(id);
  return k != kNoKf && pending_[k] != 0;
}

void WorkingSet::Loaded(KeyframeId id, SlotIndex slot, std::uint32_t payload_bytes) {
  const KfIndex k = index_.Find(id);
  if (k == kNoKf || pending_[k] == 0) {
    // The source delivered something nobody asked for: give the slot back, count it.
    arena_.Release(slot);
    ++unexpected_loads_;
    return;
  }
  pending_[k] = 0;
  position_[k] = static_cast<std::uint32_t>(resident_.size());
  assert(resident_.size() < resident_.capacity());
  resident_.push_back(Resident{id, k, slot});
  payload_[k] = payload_bytes;
  resident_bytes_ += payload_bytes;
  ++batch_loaded_;
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
    assert(refcount_[k] > 0 && "release of a keyframe nobody holds");
    if (refcount_[k] == 0) continue;
    if (--refcount_[k] == 0) {
      Drop(k);
      ++t->keyframes_unloaded;
    }
  }
  t->unload_ms += MsSince(t0);
}

Status WorkingSet::Load(const Plan& plan, TickTelemetry* t) {
  const auto acquires = plan.acquires();
  for (const PlanBatch& b : plan.batches()) {
    std::uint32_t wanted = 0;
    batch_ids_.clear();
    for (std::uint32_t i = b.begin; i < b.end; ++i) {
      if (pinned_[i] != 0) continue;
      const KfIndex k = acquires[i];
      if (refcount_[k]++ == 0) {
        pending_[k] = 1;
        ++wanted;
        batch_ids_.push_back(index_.id(k));
      }
    }
    if (wanted == 0) continue;  // everything already resident: no transaction at all
    batch_loaded_ = 0;
    const auto t0 = Clock::now();
    Result<LoadStats> stats = b.zone == kNoZone
                                  ? source_.LoadKeyframes(batch_ids_, arena_, *this)
                                  : source_.LoadZone(b.zone, arena_, *this);
    t->load_ms += MsSince(t0);
    t->keyframes_loaded += batch_loaded_;
    if (stats.ok()) AccountLoad(*stats, t);
    if (batch_loaded_ > 0) {
      const double per = MsSince(t0) / batch_loaded_;
      load_ms_per_keyframe_ =
          load_ms_per_keyframe_ == 0.0 ? per : 0.8 * load_ms_per_keyframe_ + 0.2 * per;
    }
    // Whatever is still pending was not delivered: undo its references.
    std::uint32_t missing = 0;
    KeyframeId first_missing{0};
    for (std::uint32_t i = b.begin; i < b.end; ++i) {
      const KfIndex k = acquires[i];
      if (pinned_[i] == 0 && pending_[k] != 0) {
        if (missing == 0) first_missing = index_.id(k);
        ++missing;
        --refcount_[k];
      }
    }
    for (std::uint32_t i = b.begin; i < b.end; ++i) pending_[acquires[i]] = 0;
    if (!stats.ok()) {
      return stats.status().Annotate(b.zone == kNoZone
                                         ? "loading keyframes"
                                         : "loading zone " + std::to_string(b.zone.value));
    }
    if (missing > 0) {
      return NotFound(std::to_string(missing) + " wanted keyframes (first: " +
                      std::to_string(first_missing.value) + ") were not delivered by " +
                      (b.zone == kNoZone ? std::string("LoadKeyframes")
                                         : "LoadZone(" + std::to_string(b.zone.value) + ")"));
    }
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

Status WorkingSet::Apply(const Plan& plan, TickTelemetry* telemetry) {
  TickTelemetry& t = *telemetry;
  const std::uint64_t refused_before = arena_.stats().refused;
  apply_peak_ = resident_count();
  std::fill_n(pinned_.begin(), plan.acquires().size(), std::uint8_t{0});
  Status status;
  if (plan.order == PlanOrder::kUnloadThenLoad) {
    Pin(plan);
    Unload(plan, &t);
    status = Load(plan, &t);
  } else {
    status = Load(plan, &t);
    Unload(plan, &t);
  }
  t.zones_loaded += static_cast<std::uint32_t>(plan.zones_loaded().size());
  t.zones_unloaded += static_cast<std::uint32_t>(plan.zones_unloaded().size());
  const Status searched = AccountSearch(plan, &t);
  if (status.ok() && !searched.ok()) status = searched;
  t.resident_keyframes = resident_count();
  t.resident_bytes = resident_bytes_;
  t.peak_resident_keyframes = std::max(t.peak_resident_keyframes, apply_peak_);
  t.over_budget = t.over_budget || t.peak_resident_keyframes > k_max_;
  t.refused_acquisitions += arena_.stats().refused - refused_before;
  return status;
}

}  // namespace zm
