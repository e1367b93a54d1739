// FakeKeyframeSource: a KeyframeSource with no database, for memory-policy and WorkingSet
// tests. Zones and payload sizes are given up front; a load asks the sink Wants() for each
// member (zones in id order, like MapDb; keyframe lists in the given order), acquires a slot, fills it with a recognisable pattern (the
// keyframe id's 8 bytes repeated) and calls Loaded(). It counts calls, transactions, queries
// and bytes exactly as the contract says (a zone load = 1 transaction, 1 query; a per-keyframe
// load = 5 point queries per keyframe, no transaction) and logs every call.
//
// A full arena makes the load fail with kResourceExhausted, as MapDb does.
#pragma once

#include <algorithm>
#include <cstring>
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
    if (zone.value < 0 || static_cast<std::size_t>(zone.value) >= zones_.size()) {
      return NotFound("zone " + std::to_string(zone.value));
    }
    LoadStats s;
    s.transactions = 1;
    s.queries = 1;
    if (log_calls) calls.push_back(Call{zone, {}});
    ZM_RETURN_IF_ERROR(LoadList(zones_[static_cast<std::size_t>(zone.value)], arena, sink, &s));
    Account(s);
    return s;
  }

  Result<LoadStats> LoadKeyframes(std::span<const KeyframeId> ids, Arena& arena,
                                  LoadSink& sink) override {
    ++load_keyframes_calls;
    LoadStats s;
    if (log_calls) calls.push_back(Call{kNoZone, {}});
    ZM_RETURN_IF_ERROR(LoadList(ids, arena, sink, &s));
    s.queries = 5 * s.keyframes;
    Account(s);
    return s;
  }

  // True if `slot` holds the pattern written for `id`.
  static bool SlotHolds(const Arena& arena, SlotIndex slot, KeyframeId id) {
    auto bytes = arena.Slot(slot);
    std::int64_t v = 0;
    std::memcpy(&v, bytes.data(), sizeof v);
    return v == id.value;
  }

  bool log_calls = true;  // false: no allocation per call (allocation-counting tests)
  std::vector<Call> calls;
  std::uint64_t load_zone_calls = 0;
  std::uint64_t load_keyframes_calls = 0;
  std::uint64_t transactions = 0;
  std::uint64_t queries = 0;
  std::uint64_t keyframes_loaded = 0;
  std::uint64_t bytes_read = 0;

 private:
  Status LoadList(std::span<const KeyframeId> ids, Arena& arena, LoadSink& sink, LoadStats* s) {
    for (KeyframeId id : ids) {
      if (!sink.Wants(id)) {
        ++s->skipped;
        continue;
      }
      auto slot = arena.TryAcquire();
      if (!slot) {
        return ResourceExhausted("arena full (" + std::to_string(arena.capacity()) +
                                 " slots) loading keyframe " + std::to_string(id.value));
      }
      auto bytes = arena.Slot(*slot);
      for (std::size_t i = 0; i + sizeof(id.value) <= bytes.size(); i += sizeof(id.value)) {
        std::memcpy(bytes.data() + i, &id.value, sizeof(id.value));
      }
      sink.Loaded(id, *slot, bytes_);
      if (log_calls) calls.back().loaded.push_back(id);
      ++s->keyframes;
      s->bytes += bytes_;
    }
    return Status::Ok();
  }
  void Account(const LoadStats& s) {
    transactions += s.transactions;
    queries += s.queries;
    keyframes_loaded += s.keyframes;
    bytes_read += s.bytes;
  }

  std::vector<std::vector<KeyframeId>> zones_;
  std::uint32_t bytes_;
};

}  // namespace zm::test
