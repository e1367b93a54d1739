// Test helpers for lib/memory: small hand-made maps (keyframe id i+1 at positions[i]) and a
// Harness that wires MapIndex + Arena + FakeKeyframeSource + WorkingSet + a policy and checks
// the working-set invariants after every Apply. The fake source also plays the database for
// basic's graph searches: it holds the spec's links and weights, read through a SourceLtmGraph.
#pragma once

#include <doctest/doctest.h>

#include <functional>
#include <memory>
#include <tuple>
#include <variant>
#include <vector>

#include "memory/ltm_graph.h"
#include "memory/map_index.h"
#include "memory/plan.h"
#include "memory/policy.h"
#include "memory/working_set.h"
#include "support/fake_keyframe_source.h"

namespace zm::test {

struct MapSpec {
  std::vector<Eigen::Vector3d> positions;           // keyframe id = index + 1
  std::vector<std::vector<std::int64_t>> zones;     // member ids per zone
  std::vector<std::tuple<std::int64_t, std::int64_t, LinkKind>> links;
  std::vector<std::int32_t> weights;                // empty = all 0
  std::vector<std::vector<ZoneId>> adjacency;
};

// Keyframes on the x axis, 1 m apart, zones of consecutive ids of the given sizes.
inline MapSpec LineMap(const std::vector<int>& zone_sizes) {
  MapSpec s;
  std::int64_t next = 1;
  for (int size : zone_sizes) {
    std::vector<std::int64_t> z;
    for (int i = 0; i < size; ++i) {
      s.positions.emplace_back(static_cast<double>(next - 1), 0.0, 0.0);
      z.push_back(next++);
    }
    s.zones.push_back(z);
  }
  return s;
}

inline std::vector<LinkRecord> Links(const MapSpec& s) {
  std::vector<LinkRecord> links;
  for (auto [a, b, t] : s.links) {
    LinkRecord l;
    l.from = KeyframeId{a};
    l.to = KeyframeId{b};
    l.type = t;
    links.push_back(l);
  }
  return links;
}

inline MapIndex BuildIndex(const MapSpec& s) {
  std::vector<KeyframeMeta> kfs;
  for (std::size_t i = 0; i < s.positions.size(); ++i) {
    KeyframeMeta m;
    m.id = KeyframeId{static_cast<std::int64_t>(i + 1)};
    m.pose = Pose3::Identity();
    m.pose.translation() = s.positions[i];
    m.weight = s.weights.empty() ? 0 : s.weights[i];
    m.payload_bytes = 100;
    kfs.push_back(m);
  }
  const std::vector<LinkRecord> links = Links(s);
  std::vector<ZoneMember> members;
  for (std::size_t z = 0; z < s.zones.size(); ++z) {
    for (std::int64_t id : s.zones[z]) {
      members.push_back({ZoneId{static_cast<std::int32_t>(z)}, KeyframeId{id}});
    }
  }
  MapIndexInput in;
  in.keyframes = kfs;
  in.links = links;
  in.members = members;
  in.zone_count = static_cast<std::int32_t>(s.zones.size());
  in.zone_adjacency = s.adjacency;
  auto r = MapIndex::Build(in);
  REQUIRE(r.ok());
  return std::move(r).value();
}

inline Arena MakeArena(std::uint32_t slots) {
  auto r = Arena::Create({.memory_thr_keyframes = slots, .budget_bytes = 0, .slot_bytes = 128,
                          .lock = false, .prefault = false});
  REQUIRE(std::holds_alternative<Arena>(r));
  return std::move(std::get<Arena>(r));
}

inline std::vector<std::vector<KeyframeId>> ZoneIds(const MapSpec& s) {
  std::vector<std::vector<KeyframeId>> out;
  for (const auto& z : s.zones) {
    std::vector<KeyframeId> ids;
    for (auto id : z) ids.push_back(KeyframeId{id});
    out.push_back(ids);
  }
  return out;
}

inline std::vector<std::int64_t> Ids(const MapIndex& index, std::span<const KfIndex> ks) {
  std::vector<std::int64_t> out;
  for (KfIndex k : ks) out.push_back(index.id(k).value);
  return out;
}

inline std::vector<std::int64_t> Ids(std::span<const KeyframeId> ids) {
  std::vector<std::int64_t> out;
  for (KeyframeId id : ids) out.push_back(id.value);
  return out;
}

inline std::vector<std::int32_t> Zones(std::span<const ZoneId> zs) {
  std::vector<std::int32_t> out;
  for (ZoneId z : zs) out.push_back(z.value);
  return out;
}

inline TickContext At(std::uint64_t tick, std::int32_t zone, Eigen::Vector3d p = {0, 0, 0},
                      double now_s = -1.0) {
  TickContext c;
  c.tick = tick;
  c.now_s = now_s < 0 ? static_cast<double>(tick) : now_s;
  c.zone = zone < 0 ? kNoZone : ZoneId{zone};
  c.pose = Pose3::Identity();
  c.pose.translation() = p;
  return c;
}

// Everything wired together. Plans of the last step are kept for inspection.
class Harness {
 public:
  using Factory = std::function<std::unique_ptr<MemoryPolicy>(const MapIndex&)>;
  // For a policy that reads long-term-memory nodes (basic): it gets `graph`, over the fake.
  using GraphFactory = std::function<std::unique_ptr<MemoryPolicy>(const MapIndex&, LtmGraph&)>;
  // sliced: the WorkingSet only queues loads; the test steps them (Step, Drain).
  Harness(const MapSpec& spec, std::uint32_t arena_slots, std::uint32_t k_max, const Factory& make,
          bool sliced = false)
      : Harness(spec, arena_slots, k_max,
                GraphFactory([&make](const MapIndex& i, LtmGraph&) { return make(i); }), sliced) {}
  Harness(const MapSpec& spec, std::uint32_t arena_slots, std::uint32_t k_max,
          const GraphFactory& make, bool sliced = false)
      : index(BuildIndex(spec)),
        arena(MakeArena(arena_slots)),
        source(ZoneIds(spec), 100),
        ws(index, arena, source, k_max, sliced),
        graph(index, source),
        before(index),
        after(index),
        policy(make(index, graph)) {
    source.set_links(Links(spec));
    for (std::size_t i = 0; i < spec.weights.size(); ++i) {
      source.set_weight(KeyframeId{static_cast<std::int64_t>(i + 1)}, spec.weights[i]);
    }
  }

  TickTelemetry Start(const TickContext& ctx) {
    TickTelemetry t;
    before.Clear();
    after.Clear();
    policy->Start(ctx, &before);
    ApplyChecked(before, &t);
    return t;
  }
  TickTelemetry Tick(const TickContext& ctx) {
    TickTelemetry t;
    before.Clear();
    policy->PlanBeforeLocalize(ctx, &before);
    ApplyChecked(before, &t);
    after.Clear();
    policy->PlanAfterLocalize(ctx, &after);
    ApplyChecked(after, &t);
    return t;
  }
  // Time-sliced loads: one slice, then the same checks as after an Apply.
  TickTelemetry Step(const LoadSlice& slice) {
    TickTelemetry t;
    Status s = ws.StepLoads(slice, &t);
    REQUIRE_MESSAGE(s.ok(), s.ToString());
    Check();
    return t;
  }
  TickTelemetry Drain() { return Step(LoadSlice{}); }
  // Keyframe ids resident now, sorted.
  std::vector<std::int64_t> ResidentIds() const {
    std::vector<std::int64_t> out;
    for (const auto& r : ws.resident()) out.push_back(r.id.value);
    std::sort(out.begin(), out.end());
    return out;
  }

  MapIndex index;
  Arena arena;
  FakeKeyframeSource source;
  WorkingSet ws;
  SourceLtmGraph graph;
  Plan before;
  Plan after;
  std::unique_ptr<MemoryPolicy> policy;
  bool verify_slots = true;  // per-Apply slot/refcount checks (off in long runs)

 private:
  void ApplyChecked(const Plan& plan, TickTelemetry* t) {
    Status s = ws.Apply(plan, t);
    REQUIRE_MESSAGE(s.ok(), s.ToString());
    Check();
  }
  void Check() {
    // Working-set invariants: slots hold what the fake wrote; counts match the arena.
    REQUIRE(ws.resident_count() == arena.in_use());
    if (!verify_slots) return;
    for (const auto& r : ws.resident()) {
      CHECK(FakeKeyframeSource::SlotHolds(arena, r.slot, r.id));
      CHECK(ws.refcount(r.index) > 0);
    }
  }
};

}  // namespace zm::test
