// FakeKeyframeSource: a KeyframeSource with no database, for memory-policy and WorkingSet
// tests. Zones and payload sizes are given up front; a load asks the sink Wants() for each
// member (zones in id order, like MapDb; keyframe lists in the given order), acquires a slot,
// fills it with a recognisable pattern (the keyframe id's 8 bytes repeated) and calls Loaded().
// It follows MapDb's contract (lib/mapdb/map_db.h), counts included:
//   - a zone load (one call, or time-sliced: BeginZoneLoad, StepZoneLoad within a LoadBudget,
//     AbortZoneLoad) = 1 transaction, 1 query, 1 blob read per keyframe delivered; at most one
//     in flight, other loads refused meanwhile; transaction_open() says whether its
//     transaction is held (it is from Begin to the step that finishes, or an error, or Abort);
//   - a per-keyframe load = 4 queries and 4 transactions per keyframe delivered (row, payload,
//     links, calibration, each autocommit);
//   - ReadGraphNodes = 2 queries and 2 transactions per node: the weight (set_weight, default
//     0) and the links given to set_links() that touch the node.
// It logs every load call (log_calls). A full arena fails the load with kResourceExhausted, as
// MapDb does; fail_on = an id makes the load fail with kCorrupt on that keyframe (its slot
// released, like a payload failing validation), to test errors in the middle of a load.
#pragma once

#include <algorithm>
#include <chrono>
#include <cstring>
#include <map>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "mapdb/map_db.h"

namespace zm::test {

class FakeKeyframeSource final : public KeyframeSource {
 public:
  struct Call {
    ZoneId zone = kNoZone;           // kNoZone for LoadKeyframes
    std::vector<KeyframeId> loaded;  // what was delivered, in order
  };

  // zones[z] = member ids of zone z; payload_bytes(id) = bytes_per_keyframe.
  FakeKeyframeSource(std::vector<std::vector<KeyframeId>> zones, std::uint32_t bytes_per_keyframe)
      : zones_(std::move(zones)), bytes_(bytes_per_keyframe) {
    for (auto& z : zones_) std::sort(z.begin(), z.end());
  }

  Result<LoadStats> LoadZone(ZoneId zone, Arena& arena, LoadSink& sink) override {
    ++load_zone_calls;
    auto begin = Begin(zone, arena, sink);
    if (!begin.ok()) return begin.status();
    LoadStats s = *begin;
    auto step = StepZoneLoad(LoadBudget{});
    if (!step.ok()) return step.status();
    s += step->stats;
    return s;
  }

  Result<LoadStats> LoadKeyframes(std::span<const KeyframeId> ids, Arena& arena,
                                  LoadSink& sink) override {
    ++load_keyframes_calls;
    ZM_RETURN_IF_ERROR(RefuseInFlight());
    LoadStats s;
    if (log_calls) calls.push_back(Call{kNoZone, {}});
    for (KeyframeId id : ids) {
      if (!sink.Wants(id)) {
        ++s.skipped;
        continue;
      }
      ZM_RETURN_IF_ERROR(Deliver(id, arena, sink, &s));
    }
    s.queries = 4 * s.keyframes;
    s.transactions = 4 * s.keyframes;
    Account(s);
    return s;
  }

  Result<LoadStats> BeginZoneLoad(ZoneId zone, Arena& arena, LoadSink& sink) override {
    ++begin_calls;
    return Begin(zone, arena, sink);
  }

  Result<ZoneLoadStep> StepZoneLoad(const LoadBudget& budget) override {
    ++step_calls;
    if (!cursor_) return FailedPrecondition("no zone load in flight (BeginZoneLoad first)");
    Cursor& c = *cursor_;
    const std::vector<KeyframeId>& members = zones_[static_cast<std::size_t>(c.zone.value)];
    const bool timed = budget.deadline != std::chrono::steady_clock::time_point::max();
    ZoneLoadStep step;
    std::uint32_t loaded = 0;
    std::uint64_t bytes = 0;
    for (; c.next < members.size(); ++c.next) {
      if (loaded > 0 && (loaded >= budget.max_keyframes ||
                         (timed && std::chrono::steady_clock::now() >= budget.deadline) ||
                         bytes + bytes_ > budget.max_bytes)) {
        break;
      }
      const KeyframeId id = members[c.next];
      if (!c.sink->Wants(id)) {
        ++step.stats.skipped;
        continue;
      }
      Status st = Deliver(id, *c.arena, *c.sink, &step.stats);
      if (!st.ok()) {
        Account(step.stats);
        AbortZoneLoad();
        return st;
      }
      ++step.stats.blob_reads;
      ++loaded;
      bytes += bytes_;
    }
    if (c.next == members.size()) {
      step.done = true;
      cursor_.reset();
    }
    Account(step.stats);
    return step;
  }

  void AbortZoneLoad() override {
    if (cursor_) ++aborts;
    cursor_.reset();
  }

  [[nodiscard]] ZoneId ZoneLoadInFlight() const override {
    return cursor_ ? cursor_->zone : kNoZone;
  }

  Result<LoadStats> ReadGraphNodes(std::span<const KeyframeId> ids, GraphNodeSink* sink) override {
    ZM_RETURN_IF_ERROR(RefuseInFlight());
    LoadStats s;
    for (KeyframeId id : ids) {
      s.queries += 2;
      s.transactions += 2;
      if (sink == nullptr) continue;
      const auto w = weights_.find(id);
      sink->Node(id, w == weights_.end() ? 0 : w->second);
      for (const LinkRecord& l : links_) {
        if (l.from == id || l.to == id) sink->Link(l);
      }
    }
    Account(s);
    return s;
  }

  void set_links(std::vector<LinkRecord> links) { links_ = std::move(links); }
  void set_weight(KeyframeId id, std::int32_t weight) { weights_[id] = weight; }
  [[nodiscard]] bool transaction_open() const { return cursor_.has_value(); }

  // True if `slot` holds the pattern written for `id`.
  static bool SlotHolds(const Arena& arena, SlotIndex slot, KeyframeId id) {
    auto bytes = arena.Slot(slot);
    std::int64_t v = 0;
    std::memcpy(&v, bytes.data(), sizeof v);
    return v == id.value;
  }

  bool log_calls = true;  // false: no allocation per call (allocation-counting tests)
  std::optional<KeyframeId> fail_on;  // a load reaching this keyframe fails (kCorrupt)
  std::vector<Call> calls;
  std::uint64_t load_zone_calls = 0;
  std::uint64_t load_keyframes_calls = 0;
  std::uint64_t begin_calls = 0;  // BeginZoneLoad calls (LoadZone does not count here)
  std::uint64_t step_calls = 0;   // StepZoneLoad calls, LoadZone's own included
  std::uint64_t aborts = 0;       // loads ended by AbortZoneLoad or by an error
  std::uint64_t transactions = 0;
  std::uint64_t queries = 0;
  std::uint64_t blob_reads = 0;
  std::uint64_t keyframes_loaded = 0;
  std::uint64_t bytes_read = 0;

 private:
  struct Cursor {
    ZoneId zone;
    Arena* arena;
    LoadSink* sink;
    std::size_t next = 0;  // index of the next member to handle
  };

  Status RefuseInFlight() const {
    if (!cursor_) return Status::Ok();
    return FailedPrecondition("the load of zone " + std::to_string(cursor_->zone.value) +
                              " is in flight (one load at a time)");
  }

  Result<LoadStats> Begin(ZoneId zone, Arena& arena, LoadSink& sink) {
    ZM_RETURN_IF_ERROR(RefuseInFlight());
    if (zone.value < 0 || static_cast<std::size_t>(zone.value) >= zones_.size()) {
      return NotFound("zone " + std::to_string(zone.value));
    }
    LoadStats s;
    s.transactions = 1;
    s.queries = 1;
    if (log_calls) calls.push_back(Call{zone, {}});
    cursor_ = Cursor{zone, &arena, &sink, 0};
    Account(s);
    return s;
  }

  Status Deliver(KeyframeId id, Arena& arena, LoadSink& sink, LoadStats* s) {
    auto slot = arena.TryAcquire();
    if (!slot) {
      return ResourceExhausted("arena full (" + std::to_string(arena.capacity()) +
                               " slots) loading keyframe " + std::to_string(id.value));
    }
    auto bytes = arena.Slot(*slot);
    for (std::size_t i = 0; i + sizeof(id.value) <= bytes.size(); i += sizeof(id.value)) {
      std::memcpy(bytes.data() + i, &id.value, sizeof(id.value));
    }
    if (fail_on && *fail_on == id) {
      arena.Release(*slot);
      return Corrupt("keyframe " + std::to_string(id.value) + ": payload checksum mismatch (fake)");
    }
    sink.Loaded(id, *slot, bytes_);
    if (log_calls) calls.back().loaded.push_back(id);
    ++s->keyframes;
    s->bytes += bytes_;
    return Status::Ok();
  }

  void Account(const LoadStats& s) {
    transactions += s.transactions;
    queries += s.queries;
    blob_reads += s.blob_reads;
    keyframes_loaded += s.keyframes;
    bytes_read += s.bytes;
  }

  std::vector<std::vector<KeyframeId>> zones_;
  std::uint32_t bytes_;
  std::optional<Cursor> cursor_;
  std::vector<LinkRecord> links_;
  std::map<KeyframeId, std::int32_t> weights_;
};

}  // namespace zm::test
