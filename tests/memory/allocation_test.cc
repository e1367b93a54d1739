// Invariant 2 of docs/design.md: no heap allocation per tick once warm. Proven for every
// policy (semantic is the one the design requires) over many ticks of a walk through zones,
// including the WorkingSet's Apply and the fake source (call logging off).
#include <doctest/doctest.h>

#include <random>

#include "memory/memory_test_util.h"
#include "support/counting_allocator.h"

namespace zm {
namespace {

TEST_CASE("no allocation per tick once warm / for every policy") {
  // 12 zones of 15 keyframes on a 3 x 4 grid of rooms, chained by neighbour links, adjacent
  // rooms overlapping by one keyframe.
  test::MapSpec s;
  std::vector<int> walk;
  for (int z = 0; z < 12; ++z) {
    std::vector<std::int64_t> members;
    for (int i = 0; i < 15; ++i) {
      s.positions.emplace_back(30.0 * (z % 4) + 2.0 * (i % 5), 30.0 * (z / 4) + 2.0 * (i / 5), 0.0);
      const auto id = static_cast<std::int64_t>(s.positions.size());
      members.push_back(id);
      if (id > 1) s.links.emplace_back(id - 1, id, LinkKind::kNeighbor);
    }
    if (z > 0) members.push_back(members.front() - 1);
    s.zones.push_back(members);
  }
  s.adjacency.resize(12);
  for (int z = 0; z + 1 < 12; ++z) s.adjacency[static_cast<std::size_t>(z)].push_back(ZoneId{z + 1});
  std::mt19937 rng(1);
  int z = 0;
  for (int i = 0; i < 1500; ++i) {
    if (rng() % 4 == 0) z = std::clamp(z + static_cast<int>(rng() % 3) - 1, 0, 11);
    walk.push_back(rng() % 10 == 0 ? -1 : z);
  }
  std::vector<ZoneId> future;
  for (int w : walk) future.push_back(w < 0 ? kNoZone : ZoneId{w});

  for (const char* name : {"semantic", "predictive", "oracle", "radius", "basic", "unbounded"}) {
    CAPTURE(name);
    PolicyOptions o;
    o.kind = *ParsePolicyKind(name);
    o.k_max = 45;
    o.radius.map_radius_m = 20;
    o.radius.update_distance_m = 5;
    o.oracle.future = future;
    o.basic.init_wm_with_all_nodes = true;
    const std::uint32_t slots = std::string(name) == "basic" || std::string(name) == "unbounded" ? 180 : 45;
    // basic reads its long-term-memory nodes through the harness's SourceLtmGraph (the fake).
    test::Harness h(s, slots, 45, [&](const MapIndex& index, LtmGraph& graph) {
      auto p = MakePolicy(index, o, &graph);
      REQUIRE(p.ok());
      return std::move(p).value();
    });
    h.source.log_calls = false;
    h.verify_slots = false;
    auto pos = [&](int zone, std::size_t i) {
      const KfIndex k = h.index.ZoneMembers(ZoneId{std::max(zone, 0)})[i % 15];
      return h.index.position(k);
    };
    h.Start(test::At(0, walk[0], pos(walk[0], 0)));
    std::size_t i = 1;
    for (; i < 300; ++i) h.Tick(test::At(i, walk[i], pos(walk[i], i)));
    test::AllocationCounter counter;
    std::uint64_t moved = 0;
    for (; i < walk.size(); ++i) {
      TickContext c = test::At(i, walk[i], pos(walk[i], i), static_cast<double>(i) * 0.5);
      c.highest_hypothesis = h.index.id(h.index.ZoneMembers(ZoneId{std::max(walk[i], 0)})[i % 15]);
      c.localized_on = h.ws.IsResident(h.index.Find(c.highest_hypothesis)) ? c.highest_hypothesis : KeyframeId{0};
      auto t = h.Tick(c);
      moved += t.keyframes_loaded + t.keyframes_unloaded;
    }
    CHECK(counter.allocations() == 0);
    if (std::string(name) != "unbounded") CHECK(moved > 0);
  }
}

}  // namespace
}  // namespace zm
