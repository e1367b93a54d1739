// MapIndex: id order and lookup, zone CSR both ways with overlaps, links both ways, adjacency,
// radius queries equal to brute force, and clear errors for bad metadata.
#include "memory/map_index.h"

#include <doctest/doctest.h>

#include <random>
#include <set>

#include "memory/memory_test_util.h"
#include "memory/policy.h"

namespace zm {
namespace {

TEST_CASE("map index: lookup / zones both ways / links both ways / adjacency") {
  test::MapSpec s = test::LineMap({3, 3});
  s.zones[1].push_back(3);  // keyframe 3 in both zones
  s.zones[1].push_back(3);  // duplicate member: ignored
  s.links = {{1, 2, LinkKind::kNeighbor}, {2, 1, LinkKind::kNeighbor}, {2, 5, LinkKind::kGlobalClosure},
             {1, 99, LinkKind::kLandmark}};
  s.adjacency = {{ZoneId{1}}, {}};
  MapIndex m = test::BuildIndex(s);
  CHECK(m.keyframe_count() == 6);
  CHECK(m.Find(KeyframeId{4}) == 3);
  CHECK(m.Find(KeyframeId{42}) == kNoKf);
  CHECK(m.ZoneSize(ZoneId{1}) == 4);
  CHECK(m.total_memberships() == 7);
  CHECK(m.max_zone_size() == 4);
  CHECK(m.ZonesOf(m.Find(KeyframeId{3})).size() == 2);
  CHECK(m.Edges(m.Find(KeyframeId{2})).size() == 2);  // 1 (deduplicated) and 5
  CHECK(m.Edges(m.Find(KeyframeId{5})).size() == 1);
  CHECK(m.dropped_links() == 1);  // the landmark
  REQUIRE(m.AdjacentZones(ZoneId{1}).size() == 1);  // symmetrised
  CHECK(m.AdjacentZones(ZoneId{1})[0] == ZoneId{0});
}

TEST_CASE("map index: bad metadata gives errors naming the thing") {
  test::MapSpec s = test::LineMap({2});
  std::vector<KeyframeMeta> kfs(2);
  kfs[0].id = KeyframeId{1};
  kfs[1].id = KeyframeId{1};
  MapIndexInput in;
  in.keyframes = kfs;
  auto r = MapIndex::Build(in);
  REQUIRE_FALSE(r.ok());
  CHECK(r.status().message().find("keyframe id 1 appears twice") != std::string::npos);
  kfs[1].id = KeyframeId{2};
  std::vector<ZoneMember> members{{ZoneId{0}, KeyframeId{7}}};
  in.members = members;
  in.zone_count = 1;
  r = MapIndex::Build(in);
  REQUIRE_FALSE(r.ok());
  CHECK(r.status().message().find("keyframe 7") != std::string::npos);
  members[0] = {ZoneId{3}, KeyframeId{1}};
  r = MapIndex::Build(in);
  REQUIRE_FALSE(r.ok());
  CHECK(r.status().message().find("zone 3") != std::string::npos);
}

TEST_CASE("map index: ForEachWithin equals brute force") {
  std::mt19937 rng(2);
  test::MapSpec s;
  for (int i = 0; i < 500; ++i) {
    s.positions.emplace_back(static_cast<double>(rng() % 3000) / 10.0,
                             static_cast<double>(rng() % 2000) / 10.0, static_cast<double>(rng() % 30) / 10.0);
  }
  MapIndex m = test::BuildIndex(s);
  for (int q = 0; q < 50; ++q) {
    const Eigen::Vector3d c(static_cast<double>(rng() % 3000) / 10.0, static_cast<double>(rng() % 2000) / 10.0, 1.0);
    const double r = static_cast<double>(rng() % 400) / 10.0;
    std::set<KfIndex> got, want;
    m.ForEachWithin(c, r, [&](KfIndex k, double d) {
      got.insert(k);
      CHECK(d <= r);
    });
    for (KfIndex k = 0; k < m.keyframe_count(); ++k) {
      if ((m.position(k) - c).norm() <= r) want.insert(k);
    }
    CHECK(got == want);
  }
}

TEST_CASE("MakePolicy: every name / and a clear error for an unknown one") {
  MapIndex m = test::BuildIndex(test::LineMap({2, 2}));
  for (const char* name : {"semantic", "basic", "radius", "predictive", "oracle", "unbounded"}) {
    PolicyOptions o;
    o.kind = *ParsePolicyKind(name);
    o.k_max = 4;
    auto p = MakePolicy(m, o);
    REQUIRE(p.ok());
    CHECK((*p)->name() == name);
  }
  // An unknown name is refused where it is parsed (once: profile, --policy, the API's options).
  auto lru = ParsePolicyKind("lru");
  REQUIRE_FALSE(lru.ok());
  CHECK(lru.status().message().find("unknown memory policy 'lru'") != std::string::npos);
  PolicyOptions o;
  o.kind = PolicyKind::kSemantic;
  o.k_max = 0;
  CHECK_FALSE(MakePolicy(m, o).ok());
}

}  // namespace
}  // namespace zm
