// Plan: what a memory policy decided for one step, carried out by WorkingSet::Apply.
//
// A plan is a list of keyframe references to drop (releases) and batches of references to take
// (acquires). A reference is one holder's claim on a keyframe: for the zone policies one active
// zone, for basic/radius the single residency flag. A keyframe is resident while it has at
// least one reference. Each acquire batch names the zone it comes from (one LoadZone call = one
// transaction) or kNoZone (one LoadKeyframes call, RTAB-Map's per-keyframe pattern).
//
// Invariants:
//   - the buffers are reserved once (Reserve) from the map size; a policy never pushes more than
//     that, so building a plan never allocates (asserted);
//   - order is kUnloadThenLoad for every bounded policy; only basic uses kLoadThenUnload
//     (RTAB-Map retrieves, then transfers);
//   - `search` is database work the policy already did while planning (basic's graph searches
//     read through its LtmGraph); the WorkingSet only accounts it, so a plan that loads nothing
//     but searched is not empty().
#pragma once

#include <algorithm>
#include <cassert>
#include <cstdint>
#include <span>
#include <vector>

#include "common/ids.h"
#include "common/status.h"
#include "mapdb/map_db.h"
#include "memory/map_index.h"

namespace zm {

struct PlanBatch {
  ZoneId zone = kNoZone;      // kNoZone: per-keyframe load
  std::uint32_t begin = 0;    // into acquires()
  std::uint32_t end = 0;
};

enum class PlanOrder : std::uint8_t { kUnloadThenLoad, kLoadThenUnload };

class Plan {
 public:
  // Buffer sizes that no policy's plan exceeds for this map: every reference of every zone, or
  // every keyframe, whichever is larger (start-up of basic/unbounded loads every keyframe).
  static std::size_t RefCapacity(const MapIndex& index) {
    return std::max<std::size_t>(index.total_memberships(), index.keyframe_count()) + 1;
  }

  Plan() = default;
  explicit Plan(const MapIndex& index) { Reserve(index); }
  // The only allocating call.
  void Reserve(const MapIndex& index) {
    const std::size_t refs = RefCapacity(index);
    const std::size_t zones = static_cast<std::size_t>(index.zone_count()) + 2;
    releases_.reserve(refs);
    acquires_.reserve(refs);
    batches_.reserve(zones * 2);
    zones_loaded_.reserve(zones * 2);
    zones_unloaded_.reserve(zones * 2);
  }
  void Clear() noexcept {
    releases_.clear();
    acquires_.clear();
    batches_.clear();
    zones_loaded_.clear();
    zones_unloaded_.clear();
    order = PlanOrder::kUnloadThenLoad;
    search = LoadStats{};
    search_error = Status::Ok();
  }

  void Release(KfIndex k) { Push(releases_, k); }
  // Starts a batch; the following Acquire() calls belong to it.
  void BeginBatch(ZoneId zone) {
    Push(batches_, PlanBatch{zone, Size(acquires_), Size(acquires_)});
  }
  void Acquire(KfIndex k) {
    assert(!batches_.empty() && "Acquire() needs a BeginBatch() first");
    Push(acquires_, k);
    batches_.back().end = Size(acquires_);
  }
  // Zone-level notes for telemetry and tests (a zone load may be partial).
  void NoteZoneLoaded(ZoneId z) { Push(zones_loaded_, z); }
  void NoteZoneUnloaded(ZoneId z) { Push(zones_unloaded_, z); }

  [[nodiscard]] std::span<const KfIndex> releases() const { return releases_; }
  [[nodiscard]] std::span<const KfIndex> acquires() const { return acquires_; }
  [[nodiscard]] std::span<const PlanBatch> batches() const { return batches_; }
  [[nodiscard]] std::span<const ZoneId> zones_loaded() const { return zones_loaded_; }
  [[nodiscard]] std::span<const ZoneId> zones_unloaded() const { return zones_unloaded_; }
  [[nodiscard]] bool empty() const {
    return releases_.empty() && acquires_.empty() && search.queries == 0 && search_error.ok();
  }

  PlanOrder order = PlanOrder::kUnloadThenLoad;
  // What the policy's own graph searches read from the database while it planned this step
  // (basic: each admitted long-term-memory node's weight and links, two statements, two
  // autocommit transactions; basic-baseline.md §3.1). Executed, not estimated.
  LoadStats search;
  // The first read of those searches that failed (the search went on without that node); the
  // WorkingSet reports it from Apply.
  Status search_error;

 private:
  template <class T>
  static void Push(std::vector<T>& v, const T& x) {
    assert(v.size() < v.capacity() && "plan capacity exceeded: Reserve() from the MapIndex");
    v.push_back(x);
  }
  template <class T>
  static std::uint32_t Size(const std::vector<T>& v) {
    return static_cast<std::uint32_t>(v.size());
  }

  std::vector<KfIndex> releases_;
  std::vector<KfIndex> acquires_;
  std::vector<PlanBatch> batches_;
  std::vector<ZoneId> zones_loaded_;
  std::vector<ZoneId> zones_unloaded_;
};

}  // namespace zm
