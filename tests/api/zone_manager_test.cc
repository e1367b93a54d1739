// zonemap::ZoneManager (bring your own keyframe store): a host that carries every answer out in
// order never holds more than K_max keyframes with a bounded policy, never unloads what it does
// not hold nor loads what it holds, and agrees with zonemap about what is resident; zones from
// memberships or a zone file; the errors a host can make; and no allocation in a warm tick.
#include "zonemap/zone_manager.h"

#include <doctest/doctest.h>

#include <algorithm>
#include <set>

#include "api/api_test_util.h"
#include "support/counting_allocator.h"

namespace zonemap {
namespace {

using zm::test::kKeyframesPerRoom;
using zm::test::kRooms;

// The host: a set of resident ids, and the checks it makes while carrying an answer out.
struct Host {
  std::set<std::int64_t> resident;
  std::uint32_t peak = 0;
  void Carry(const Answer& a, std::uint32_t k_max, bool bounded) {
    CHECK(a.resident_before == resident.size());
    for (KeyframeId id : a.unload) CHECK(resident.erase(id.value) == 1);
    for (KeyframeId id : a.load) {
      CHECK(resident.insert(id.value).second);
      peak = std::max(peak, static_cast<std::uint32_t>(resident.size()));
      if (bounded) CHECK(resident.size() <= k_max);
    }
    CHECK(a.resident_after == resident.size());
    CHECK(a.peak <= std::max(a.resident_before, a.resident_after));
    // Batches cover the loads exactly, in order.
    std::uint32_t next = 0;
    for (const LoadBatch& b : a.batches) {
      CHECK(b.begin == next);
      CHECK(b.end > b.begin);
      next = b.end;
    }
    CHECK(next == a.load.size());
  }
};

// Rooms of the synthetic building as host zones (memberships, no geometry).
HostMap MembershipMap(const zm::test::ApiScenario& s) {
  HostMap map;
  map.keyframes = s.keyframes;
  for (int r = 0; r < kRooms; ++r) map.zone_names.push_back("room" + std::to_string(r));
  for (const KeyframeInfo& k : s.keyframes) {
    const auto room = static_cast<std::int32_t>((k.id.value - 1) / kKeyframesPerRoom);
    map.memberships.push_back({ZoneId{room}, k.id});
    // The first keyframe of a room is also in the previous room: a doorway.
    if (room > 0 && (k.id.value - 1) % kKeyframesPerRoom == 0) {
      map.memberships.push_back({ZoneId{room - 1}, k.id});
    }
    if (k.id.value > 1) map.links.push_back({{k.id.value - 1}, k.id, LinkKind::kNeighbor});
  }
  return map;
}

TEST_CASE("zone manager: every policy's answers keep the host's store within the contract") {
  zm::test::ApiScenario s;
  zm::test::BuildApiScenario(&s, 300, "policies");
  std::vector<ZoneId> future;
  for (const char* policy : {"semantic", "predictive", "oracle", "radius", "basic", "unbounded"}) {
    CAPTURE(policy);
    ManagerOptions o;
    o.policy = policy;
    o.memory_thr_keyframes = 3 * kKeyframesPerRoom;
    if (std::string(policy) == "oracle") o.oracle_future = future;
    auto mgr = ZoneManager::Create(MembershipMap(s), o);
    REQUIRE_MESSAGE(mgr.ok(), mgr.status().ToString());
    ZoneManager& m = **mgr;
    CHECK(m.policy() == policy);
    const bool unbounded = std::string(policy) == "unbounded";
    CHECK(m.k_max() == (unbounded ? s.keyframes.size() : 3 * kKeyframesPerRoom));
    CHECK(m.bounded() == (std::string(policy) != "basic" && std::string(policy) != "unbounded"));
    CHECK(m.zone_count() == kRooms);
    Host host;
    std::uint64_t loads = 0;
    for (std::size_t t = 0; t < s.patrol.size(); ++t) {
      auto a = m.Update({.stamp_s = s.stamps[t], .pose = s.patrol[t], .zone = kNoZone});
      REQUIRE_MESSAGE(a.ok(), a.status().ToString());
      CHECK(a->startup == (t == 0));
      host.Carry(*a, m.k_max(), m.bounded());
      if (std::string(policy) == "semantic") future.push_back(a->zone);
      // Localized on the nearest resident keyframe (basic retrieves around it).
      LocalizationInput loc;
      const auto nearest = static_cast<std::int64_t>(s.patrol[t].x / 0.5) + 1;
      if (host.resident.count(nearest) != 0) loc = {{nearest}, {nearest}};
      auto b = m.AfterLocalization(loc);
      REQUIRE_MESSAGE(b.ok(), b.status().ToString());
      if (std::string(policy) != "basic") CHECK((b->load.empty() && b->unload.empty()));
      host.Carry(*b, m.k_max(), m.bounded());
      loads += a->load.size() + b->load.size();
      CHECK(m.resident_count() == host.resident.size());
    }
    for (const KeyframeInfo& k : s.keyframes) CHECK(m.IsResident(k.id) == (host.resident.count(k.id.value) == 1));
    const ManagerStats st = m.stats();
    CHECK(st.updates == s.patrol.size());
    CHECK(st.keyframes_loaded == loads);
    CHECK(st.peak_resident == std::max(host.peak, m.resident_count()));
    if (m.bounded()) {
      CHECK(st.peak_resident <= m.k_max());
      CHECK(st.over_budget_steps == 0);
      CHECK(st.keyframes_unloaded > 0);  // the patrol crosses more rooms than fit
    }
    if (std::string(policy) == "semantic") CHECK(st.zone_loads > kRooms);
    if (std::string(policy) == "basic") CHECK(st.over_budget_steps > 0);  // RTAB-Map's start-up WM
  }
}

TEST_CASE("zone manager: a doorway keyframe in both zones is never unloaded and reloaded") {
  zm::test::ApiScenario s;
  zm::test::BuildApiScenario(&s, 1, "doorway");
  ManagerOptions o;
  o.memory_thr_keyframes = kKeyframesPerRoom + 1;  // one room (and its doorway) at a time
  auto mgr = ZoneManager::Create(MembershipMap(s), o);
  REQUIRE(mgr.ok());
  ZoneManager& m = **mgr;
  // Keyframe 21 (first of room 1) is in rooms 0 and 1. Room 0, then room 1 (given by the host).
  auto a = m.Update({.stamp_s = 0, .pose = zm::test::XYYaw(3, 5, 0), .zone = ZoneId{0}});
  REQUIRE(a.ok());
  CHECK(a->load.size() == kKeyframesPerRoom + 1);
  auto b = m.Update({.stamp_s = 1, .pose = zm::test::XYYaw(13, 5, 0), .zone = ZoneId{1}});
  REQUIRE(b.ok());
  std::set<std::int64_t> unloaded, loaded;
  for (KeyframeId id : b->unload) unloaded.insert(id.value);
  for (KeyframeId id : b->load) loaded.insert(id.value);
  CHECK(unloaded.size() == kKeyframesPerRoom);
  CHECK(unloaded.count(21) == 0);
  CHECK(loaded.count(21) == 0);
  CHECK(m.IsResident({21}));
  REQUIRE(b->batches.size() == 1);
  CHECK(b->batches[0].zone == ZoneId{1});
  CHECK(b->peak <= m.k_max());
}

TEST_CASE("zone manager: zones from a zone file are annotated and looked up by polygon") {
  zm::test::ApiScenario s;
  zm::test::BuildApiScenario(&s, 1, "zonefile");
  HostMap map;
  map.keyframes = s.keyframes;
  map.zone_file = s.zones;
  map.doorway_band_m = 0.0;
  ManagerOptions o;
  o.memory_thr_keyframes = 2 * kKeyframesPerRoom;
  auto mgr = ZoneManager::Create(map, o);
  REQUIRE_MESSAGE(mgr.ok(), mgr.status().ToString());
  ZoneManager& m = **mgr;
  CHECK(m.zone_count() == kRooms);
  CHECK(m.FindZone("room3") == ZoneId{3});
  CHECK(m.zone_name(ZoneId{3}) == "room3");
  CHECK(m.FindZone("attic") == kNoZone);
  CHECK(m.zone_name(ZoneId{99}).empty());
  const std::vector<ZoneMembership> members = m.Memberships();
  CHECK(members.size() == s.keyframes.size());
  for (const ZoneMembership& z : members) {
    CHECK(z.zone.value == static_cast<std::int32_t>((z.keyframe.value - 1) / kKeyframesPerRoom));
  }
  auto a = m.Update({.stamp_s = 0, .pose = zm::test::XYYaw(35, 5, 0)});
  REQUIRE(a.ok());
  CHECK(a->zone == ZoneId{3});
  CHECK(m.current_zone() == ZoneId{3});
  CHECK(a->load.size() == kKeyframesPerRoom);
  // Just across the boundary (0.2 m, inside the 0.5 m hysteresis): still room 3.
  auto b = m.Update({.stamp_s = 1, .pose = zm::test::XYYaw(40.2, 5, 0)});
  REQUIRE(b.ok());
  CHECK(b->zone == ZoneId{3});
  auto c = m.Update({.stamp_s = 2, .pose = zm::test::XYYaw(42, 5, 0)});
  REQUIRE(c.ok());
  CHECK(c->zone == ZoneId{4});
  CHECK(c->load.size() == kKeyframesPerRoom);
  CHECK(c->unload.empty());  // two rooms fit
}

TEST_CASE("zone manager: a byte budget from a profile needs the keyframes' sizes") {
  zm::test::ApiScenario s;
  zm::test::BuildApiScenario(&s, 1, "bytes");
  HostMap map = MembershipMap(s);
  ManagerOptions o;
  o.map_share_bytes = 60000;  // about 12 keyframes of up to ~4.6 KB
  auto mgr = ZoneManager::Create(map, o);
  REQUIRE_MESSAGE(mgr.ok(), mgr.status().ToString());
  std::uint64_t largest = 0;
  for (const KeyframeInfo& k : s.keyframes) largest = std::max(largest, k.bytes);
  CHECK((*mgr)->k_max() == o.map_share_bytes / largest);
  for (KeyframeInfo& k : map.keyframes) k.bytes = 0;
  auto no_sizes = ZoneManager::Create(map, o);
  REQUIRE_FALSE(no_sizes.ok());
  CHECK(no_sizes.status().code() == StatusCode::kInvalidArgument);
  CHECK(no_sizes.status().message().find("KeyframeInfo::bytes") != std::string::npos);
  o.map_share_bytes = 0;
  o.memory_thr_keyframes = 30;
  CHECK(ZoneManager::Create(map, o).ok());  // a count budget needs no sizes
}

TEST_CASE("zone manager: a profile gives the budget and the policy, overrides win") {
  zm::test::ApiScenario s;
  zm::test::BuildApiScenario(&s, 1, "profile");
  ManagerOptions o;
  o.profile = "orin-nano-8gb";  // semantic, a 3.98 GiB share: the whole small map fits
  auto mgr = ZoneManager::Create(MembershipMap(s), o);
  REQUIRE_MESSAGE(mgr.ok(), mgr.status().ToString());
  CHECK((*mgr)->policy() == "semantic");
  CHECK((*mgr)->k_max() == s.keyframes.size());
  o.policy = "radius";
  o.memory_thr_keyframes = 50;
  auto over = ZoneManager::Create(MembershipMap(s), o);
  REQUIRE(over.ok());
  CHECK((*over)->policy() == "radius");
  CHECK((*over)->k_max() == 50);
  o.profile = "no-such-profile";
  auto missing = ZoneManager::Create(MembershipMap(s), o);
  REQUIRE_FALSE(missing.ok());
  CHECK(missing.status().code() == StatusCode::kNotFound);
}

TEST_CASE("zone manager: bad input is one clear error and changes nothing") {
  zm::test::ApiScenario s;
  zm::test::BuildApiScenario(&s, 1, "errors");
  ManagerOptions o;
  o.memory_thr_keyframes = 40;
  auto expect = [&](const HostMap& map, const ManagerOptions& opt, StatusCode code,
                    const std::string& text) {
    auto r = ZoneManager::Create(map, opt);
    REQUIRE_FALSE(r.ok());
    CHECK(r.status().code() == code);
    CHECK_MESSAGE(r.status().message().find(text) != std::string::npos, r.status().message());
  };
  HostMap map = MembershipMap(s);
  map.keyframes.push_back(map.keyframes.front());
  expect(map, o, StatusCode::kInvalidArgument, "appears twice");
  map = MembershipMap(s);
  map.keyframes[3].id = {0};
  expect(map, o, StatusCode::kInvalidArgument, "id 0");
  map = MembershipMap(s);
  map.keyframes[3].pose.qw = std::nan("");
  expect(map, o, StatusCode::kInvalidArgument, "keyframe 4 pose");
  map = MembershipMap(s);
  map.memberships.push_back({ZoneId{kRooms}, {1}});
  expect(map, o, StatusCode::kInvalidArgument, "zone 8");
  map = MembershipMap(s);
  map.memberships.push_back({ZoneId{0}, {9999}});
  expect(map, o, StatusCode::kInvalidArgument, "9999");
  map = MembershipMap(s);
  map.zone_file = s.zones;
  expect(map, o, StatusCode::kInvalidArgument, "one way");
  map = MembershipMap(s);
  map.zone_names.clear();
  map.memberships.clear();
  expect(map, o, StatusCode::kFailedPrecondition, "no zones");
  map = MembershipMap(s);
  map.zone_names.clear();
  map.memberships.clear();
  map.zone_file = s.dir.string() + "/missing.geojson";
  expect(map, o, StatusCode::kNotFound, "missing.geojson");
  ManagerOptions bad = o;
  bad.policy = "lru";
  expect(MembershipMap(s), bad, StatusCode::kInvalidArgument, "unknown memory policy 'lru'");

  auto mgr = ZoneManager::Create(MembershipMap(s), o);
  REQUIRE(mgr.ok());
  ZoneManager& m = **mgr;
  auto early = m.AfterLocalization({});
  CHECK(early.status().code() == StatusCode::kFailedPrecondition);
  REQUIRE(m.Update({.stamp_s = 5, .pose = zm::test::XYYaw(3, 5, 0)}).ok());
  const std::uint32_t resident = m.resident_count();
  CHECK(m.Update({.stamp_s = 4, .pose = zm::test::XYYaw(33, 5, 0)}).status().code() ==
        StatusCode::kInvalidArgument);
  Pose skew = zm::test::XYYaw(33, 5, 0);
  skew.qw = 3.0;
  auto q = m.Update({.stamp_s = 6, .pose = skew});
  CHECK(q.status().code() == StatusCode::kInvalidArgument);
  CHECK(q.status().message().find("quaternion") != std::string::npos);
  CHECK(m.Update({.stamp_s = 6, .pose = zm::test::XYYaw(33, 5, 0), .zone = ZoneId{kRooms}})
            .status().code() == StatusCode::kInvalidArgument);
  CHECK(m.AfterLocalization({.highest_hypothesis = {9999}, .localized_on = {}}).status().code() ==
        StatusCode::kInvalidArgument);
  const ZoneId bad_route[] = {ZoneId{1}, ZoneId{-3}};
  CHECK(m.SetRoute(bad_route).code() == StatusCode::kInvalidArgument);
  CHECK(m.resident_count() == resident);
  CHECK(m.current_zone() == ZoneId{0});
  CHECK(m.stats().updates == 1);
}

TEST_CASE("zone manager: the input gate's rules, as zonemapd applies them") {
  zm::test::ApiScenario s;
  zm::test::BuildApiScenario(&s, 1, "gate");
  ManagerOptions o;
  o.memory_thr_keyframes = 40;
  auto mgr = ZoneManager::Create(MembershipMap(s), o);
  REQUIRE(mgr.ok());
  ZoneManager& m = **mgr;
  auto refused = [&](const TickInput& in, const std::string& reason) {
    auto r = m.Update(in);
    REQUIRE_FALSE(r.ok());
    CHECK(r.status().code() == StatusCode::kInvalidArgument);
    CHECK_MESSAGE(r.status().message().find(reason) != std::string::npos, r.status().message());
  };
  REQUIRE(m.Update({.stamp_s = 5, .pose = zm::test::XYYaw(3, 5, 0)}).ok());
  // Stamps: an equal one is refused too (issue 25: was accepted), and beyond 2^32 s.
  refused({.stamp_s = 5, .pose = zm::test::XYYaw(3, 5, 0)}, "stamp_not_increasing");
  refused({.stamp_s = 1e300, .pose = zm::test::XYYaw(3, 5, 0)}, "stamp_out_of_range");
  refused({.stamp_s = std::nan(""), .pose = zm::test::XYYaw(3, 5, 0)}, "stamp_out_of_range");
  // Quaternions: within [input] quaternion_tolerance (0.01) of unit; 1.02 was accepted before.
  Pose q = zm::test::XYYaw(3, 5, 0);
  q.qw *= 1.02;
  q.qz *= 1.02;
  refused({.stamp_s = 6, .pose = q}, "quaternion_not_unit");
  Pose zero = zm::test::XYYaw(3, 5, 0);
  zero.qw = zero.qx = zero.qy = zero.qz = 0.0;
  refused({.stamp_s = 6, .pose = zero}, "quaternion_not_unit");
  // Positions: within the keyframes' extent + [input] max_distance_from_map_m (50 m).
  refused({.stamp_s = 6, .pose = zm::test::XYYaw(1e4, 5, 0)}, "position_outside_map");
  CHECK(m.stats().updates == 1);  // nothing refused moved the clock
  Pose near_unit = zm::test::XYYaw(4, 5, 0);
  near_unit.qw *= 1.005;
  near_unit.qz *= 1.005;
  CHECK(m.Update({.stamp_s = 6, .pose = near_unit}).ok());
  CHECK(m.stats().updates == 2);
}

TEST_CASE("zone manager: a warm Update and AfterLocalization allocate nothing") {
  zm::test::ApiScenario s;
  zm::test::BuildApiScenario(&s, 400, "alloc");
  for (const char* policy : {"semantic", "predictive", "radius", "basic"}) {
    CAPTURE(policy);
    ManagerOptions o;
    o.policy = policy;
    o.memory_thr_keyframes = 2 * kKeyframesPerRoom;
    auto mgr = ZoneManager::Create(MembershipMap(s), o);
    REQUIRE(mgr.ok());
    ZoneManager& m = **mgr;
    const ZoneId route[] = {ZoneId{0}, ZoneId{1}, ZoneId{2}, ZoneId{3}};
    REQUIRE(m.SetRoute(route).ok());
    auto tick = [&](std::size_t t) {
      auto a = m.Update({.stamp_s = s.stamps[t], .pose = s.patrol[t]});
      REQUIRE(a.ok());
      const auto nearest = static_cast<std::int64_t>(s.patrol[t].x / 0.5) + 1;
      LocalizationInput loc;
      if (m.IsResident({nearest})) loc = {{nearest}, {nearest}};
      REQUIRE(m.AfterLocalization(loc).ok());
    };
    std::size_t t = 0;
    for (; t < 100; ++t) tick(t);
    const std::uint64_t changed_before = m.stats().keyframes_loaded;
    zm::test::AllocationCounter counter;
    for (; t < s.patrol.size(); ++t) tick(t);
    CHECK(counter.allocations() == 0);
    CHECK(m.stats().keyframes_loaded > changed_before);  // the window did load
  }
}

}  // namespace
}  // namespace zonemap
