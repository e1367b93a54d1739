// zonemap public API, way 1: bring your own keyframe store.
//
// The host (a SLAM system such as RTAB-Map) keeps its keyframes in its own memory and its own
// database. It tells zonemap what it has (ids, poses, zone memberships, optionally links) once,
// then calls zonemap once per tick with its pose; zonemap answers with the keyframe ids to
// unload, then the ids to load. zonemap never touches the host's keyframes: it only keeps a
// reference count per keyframe id.
//
//   zonemap::HostMap map;                                  // metadata only
//   map.keyframes.push_back({.id = {17}, .pose = pose17}); // ... every keyframe
//   map.zone_file = "zones.geojson";                       // or zone_names + memberships
//   zonemap::ManagerOptions opt;
//   opt.policy = "semantic";
//   opt.memory_thr_keyframes = 300;                        // or a profile's byte budget
//   auto mgr = zonemap::ZoneManager::Create(map, opt);     // everything allocated here
//   for (;;) {                                             // one tick
//     auto a = (*mgr)->Update({.stamp_s = t, .pose = pose});
//     for (zonemap::KeyframeId id : a->unload) host.Unload(id);   // first every unload,
//     for (zonemap::KeyframeId id : a->load) host.Load(id);       // then the loads, in order
//     ... localize on the host's resident keyframes ...
//     auto b = (*mgr)->AfterLocalization({.highest_hypothesis = h, .localized_on = l});
//     ... carry b out the same way (non-empty only for the basic policy) ...
//   }
//
// The budget invariant: for the bounded policies (semantic, predictive, radius, oracle) a host
// that starts empty and carries out every answer in order (all of `unload`, then `load` in
// order) never holds more than k_max() of the keyframes zonemap manages, at any instant. Each
// Answer states its own peak so a host can check. basic (RTAB-Map's retrieval and transfer)
// and unbounded are not bounded by design: basic may sit above MemoryThr, as RTAB-Map does.
//
// Policies: semantic (the paper's Algorithm 1: zone-level LRU), predictive (route prefetch,
// farthest-next-use eviction; SetRoute), radius (Autoware-style distance tiles), oracle (the
// Belady bound; needs the zone of every future tick), basic (RTAB-Map's default memory
// management; needs AfterLocalization every tick), unbounded (everything resident).
//
// Threading: a ZoneManager is not thread-safe; call it from one thread (the host's tick).
#pragma once

#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "zonemap/status.h"
#include "zonemap/types.h"

namespace zonemap {

// One of the host's keyframes, as zonemap needs to know it (metadata only, never its data).
struct KeyframeInfo {
  KeyframeId id;             // unique, not 0
  Pose pose;                 // map frame
  std::int32_t weight = 0;   // RTAB-Map's node weight (basic's transfer order); -1 intermediate
  std::uint64_t bytes = 0;   // its size in the host's memory; needed only for a byte budget
};

// A link between two keyframes (LinkKind: zonemap/types.h).
struct KeyframeLink {
  KeyframeId from;
  KeyframeId to;
  LinkKind kind = LinkKind::kNeighbor;
};

struct ZoneMembership {
  ZoneId zone;
  KeyframeId keyframe;
};

// The host's map. Zones come one of two ways:
//   - zone_names + memberships: the host's own zones (zone i is zone_names[i]); the zone of a
//     pose is then the zone of the nearest keyframe (ManagerOptions::nearest_keyframe_zone_m),
//     unless the host passes its own in TickInput::zone;
//   - zone_file: a GeoJSON FeatureCollection of polygons (name, kind, floor; docs/zones.md) or
//     the paper's keyframe lists; zonemap assigns the keyframes to the zones (a keyframe within
//     doorway_band_m of another zone joins it too) and finds the zone of a pose by polygon, with
//     the profile's boundary hysteresis.
struct HostMap {
  std::vector<KeyframeInfo> keyframes;
  // Optional. basic searches the link graph (RTAB-Map's retrieval); predictive derives zone
  // adjacency from links between zones. Links to unknown ids are dropped (and counted).
  std::vector<KeyframeLink> links;
  std::vector<std::string> zone_names;
  std::vector<ZoneMembership> memberships;
  std::string zone_file;
  double doorway_band_m = 0.5;
};

struct ManagerOptions {
  // A device profile (a name such as "orin-nano-8gb", searched like zonemapd's, or a path to a
  // .toml file): its [policy], [map], [device], [model] and zone hysteresis are used. Empty (the
  // default, the same as MapLoopOptions::profile) = no profile: every module's defaults, no
  // device memory (a count budget only: memory_thr_keyframes, else every keyframe). Not "host":
  // a profile name is searched where an installed library's user has none (docs/api.md), and
  // the host profile's 25 GiB byte share would need every KeyframeInfo::bytes even for a count
  // budget.
  std::string profile;
  // Overrides (empty / 0 = the profile's): the policy name, and MemoryThr as a keyframe count
  // and/or a byte share. K_max = min(count, (share - overhead) / largest keyframe bytes, map
  // size): the same derivation as zonemapd's (docs/runtime.md). A byte budget needs
  // KeyframeInfo::bytes.
  std::string policy;
  std::uint64_t memory_thr_keyframes = 0;
  std::uint64_t map_share_bytes = 0;
  // Zones from memberships: a pose takes the zones of its nearest keyframe within this radius
  // (staying in the current zone if that keyframe is in it); farther than that, it keeps the
  // current zone.
  double nearest_keyframe_zone_m = 5.0;
  // The oracle policy only: the zone of every tick from the first Update on (kNoZone allowed).
  std::vector<ZoneId> oracle_future;
};

struct TickInput {
  double stamp_s = 0.0;   // seconds; must increase (basic ages keyframes by it)
  Pose pose;              // the host's current pose estimate, map frame
  ZoneId zone = kNoZone;  // the host's own zone for this pose; kNoZone = zonemap decides
};

// What the host's localization found this tick (the basic policy's inputs; RTAB-Map's
// Loop/Highest_hypothesis_id and the accepted loop-closure or proximity node).
struct LocalizationInput {
  KeyframeId highest_hypothesis;  // best-ranked resident keyframe for this frame; 0 = none
  KeyframeId localized_on;        // keyframe the frame was localized on; 0 = not localized
};

// A load batch: load[begin, end) all come from `zone` (one transaction if the host's store has
// transactions), or kNoZone for per-keyframe retrieval (basic, radius, unbounded).
struct LoadBatch {
  ZoneId zone = kNoZone;
  std::uint32_t begin = 0;
  std::uint32_t end = 0;
};

// zonemap's answer for one step. The spans point into the ZoneManager and stay valid until the
// next Update/AfterLocalization call on it.
struct Answer {
  std::span<const KeyframeId> unload;    // carry these out first (any order among them)
  std::span<const KeyframeId> load;      // then these, in order
  std::span<const LoadBatch> batches;    // `load` grouped by the zone it comes from
  ZoneId zone = kNoZone;                 // the current zone after this step
  bool startup = false;                  // the first Update: the policy's start-up load
  std::uint32_t resident_before = 0;     // keyframes resident before the answer
  std::uint32_t resident_after = 0;      // ... and after carrying it out
  std::uint32_t peak = 0;                // highest count at any instant of carrying it out in
                                         // order: max(before, after), <= k_max() if bounded()
};

struct ManagerStats {
  std::uint64_t updates = 0;
  std::uint64_t keyframes_loaded = 0;
  std::uint64_t keyframes_unloaded = 0;
  std::uint64_t zone_loads = 0;          // zone batches the policy started (partial ones too)
  std::uint32_t peak_resident = 0;       // highest count at any instant, over every answer
  std::uint64_t over_budget_steps = 0;   // answers whose peak exceeded k_max (basic only)
};

class ZoneManager {
 public:
  // Builds the index over the host's map (zones annotated from zone_file if given), derives
  // K_max (DeriveBudget, the one derivation zonemapd uses too) and makes the policy.
  // Cost: O(N log N) in keyframes plus the zone annotation (a grid lookup per keyframe);
  // allocates everything the manager will ever need: about 100 bytes per keyframe (the index,
  // reference counts and answer buffers, counted from their array sizes), 8 per membership and
  // 16 per link, plus the policy's own arrays, all sized from N and the zone count. Errors name
  // the offending id, file, key or limit: duplicate or zero keyframe ids, a membership naming an
  // unknown keyframe or zone, no zones at all, a bad zone file, a bad profile, an unknown
  // policy, a byte budget without keyframe sizes.
  [[nodiscard]] static Result<std::unique_ptr<ZoneManager>> Create(const HostMap& map,
                                                                   const ManagerOptions& options);
  ~ZoneManager();
  ZoneManager(const ZoneManager&) = delete;
  ZoneManager& operator=(const ZoneManager&) = delete;

  // One tick, before the host localizes: the zone of the pose (the host's, or polygon lookup
  // with hysteresis, or the nearest keyframe's), then the policy's plan (semantic, predictive,
  // radius and oracle decide here; the first call is the start-up load), as the net answer.
  // Cost: the zone lookup (constant time, ~20 ns) plus the policy's decision (semantic 0.01-0.2
  // µs, radius up to ~6 µs; docs/memory.md) plus O(keyframes in the answer): a steady tick
  // (Update + AfterLocalization) ~0.2 µs whatever the map size, ~6 ns more per id in the answer
  // (zm_api_bench, docs/api.md). Allocates nothing (after the first call). Bad input is
  // kInvalidArgument and changes nothing: a non-finite pose value or an unknown zone id, then
  // zonemapd's input gate (a stamp not finite, beyond 2^32 s or not greater than the last
  // accepted one; | |q| - 1 | above the profile's [input] quaternion_tolerance; a pose beyond the
  // map's extent + [input] max_distance_from_map_m; docs/api.md).
  [[nodiscard]] Result<Answer> Update(const TickInput& input);

  // The same tick, after the host localized: basic's retrieval around the highest hypothesis
  // and the pose, and its transfer (RTAB-Map runs both after its likelihood step); an empty
  // answer for every other policy. Call it after every Update when the policy is basic.
  // Cost: basic's decision (1.5-6 µs on maps of 1,000-100,000 keyframes with a working memory
  // near MemoryThr, docs/memory.md) plus O(answer); its transfer scans the working memory,
  // which starts as the whole map and drains a few keyframes a tick (up to ~0.7 ms a tick on
  // 100,000 keyframes until then; docs/api.md). Allocates nothing. kFailedPrecondition before the first Update; an unknown id
  // is kInvalidArgument.
  [[nodiscard]] Result<Answer> AfterLocalization(const LocalizationInput& input);

  // The planned zone sequence (predictive prefetch and eviction follow it, from the current
  // zone's place on it); replaces the previous one. Cost O(route). Allocates only when the route
  // is longer than any before (the buffer is reserved for 4 x zone_count() at Create). Unknown
  // zone ids are kInvalidArgument.
  [[nodiscard]] Status SetRoute(std::span<const ZoneId> route);

  // Queries: O(1) unless stated, no allocation unless stated.
  [[nodiscard]] std::string_view policy() const;
  [[nodiscard]] std::uint32_t k_max() const;  // MemoryThr in keyframes
  [[nodiscard]] bool bounded() const;         // the policy keeps resident <= k_max() always
  [[nodiscard]] std::uint32_t keyframe_count() const;
  [[nodiscard]] std::uint32_t resident_count() const;
  [[nodiscard]] bool IsResident(KeyframeId id) const;  // O(log N)
  [[nodiscard]] ZoneId current_zone() const;
  [[nodiscard]] std::int32_t zone_count() const;
  [[nodiscard]] std::string_view zone_name(ZoneId zone) const;  // empty for an unknown id
  [[nodiscard]] ZoneId FindZone(std::string_view name) const;  // O(log Z); kNoZone if absent
  // Every (zone, keyframe) membership, as given or as zonemap annotated them from the zone
  // file (e.g. to store them beside the host's map). Allocates the returned vector.
  [[nodiscard]] std::vector<ZoneMembership> Memberships() const;
  [[nodiscard]] ManagerStats stats() const;

 private:
  struct Impl;
  explicit ZoneManager(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace zonemap
