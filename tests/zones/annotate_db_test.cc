// Annotation of a real map database: memberships and zones written in one transaction and read
// back by the run-time reader; an error (unknown keyframe id) leaves the previous zones intact.
#include <doctest/doctest.h>

#include "mapdb/mapdb_test_util.h"
#include "zones/adjacency.h"
#include "zones/annotate.h"
#include "zones_test_util.h"

namespace zm {
namespace {

using test::MakeSet;
using test::MakeZone;
using test::Rect;

// Ten keyframes along y = 2.5 from x = 0.5 to 9.5, linked in a chain.
void BuildLine(const std::string& path) {
  auto w = MapDbWriter::Create(path);
  REQUIRE_MESSAGE(w.ok(), w.status().ToString());
  std::vector<std::vector<std::byte>> payloads;
  std::vector<KeyframeRecord> recs;
  for (int i = 1; i <= 10; ++i) payloads.push_back(test::MakePayload(i, 4, 0));
  for (int i = 1; i <= 10; ++i) {
    KeyframeRecord r;
    r.meta = test::KeyframeAt(i, i - 0.5, 2.5);
    r.payload = payloads[static_cast<std::size_t>(i - 1)];
    recs.push_back(r);
  }
  REQUIRE((*w)->InsertKeyframes(recs).ok());
  std::vector<LinkRecord> links;
  for (int i = 1; i < 10; ++i) {
    LinkRecord l;
    l.from = KeyframeId{i};
    l.to = KeyframeId{i + 1};
    links.push_back(l);
  }
  REQUIRE((*w)->InsertLinks(links).ok());
  REQUIRE((*w)->Finish().ok());
}

TEST_CASE("AnnotateDatabase writes zones and memberships the reader sees") {
  test::TempDir dir;
  const std::string db = dir.File("map.db");
  BuildLine(db);
  const ZoneSet set = MakeSet({MakeZone("A", Rect(0, 0, 5, 5)), MakeZone("B", Rect(5, 0, 10, 5))});
  auto report = AnnotateDatabase(db, set, {.band_m = 0.6});
  REQUIRE_MESSAGE(report.ok(), report.status().ToString());
  CHECK(report->counts == std::vector<std::uint32_t>{6, 6});  // keyframes 5 and 6 in both

  auto map = MapDb::Open(db);
  REQUIRE_MESSAGE(map.ok(), map.status().ToString());
  auto zones = (*map)->Zones();
  REQUIRE(zones.ok());
  REQUIRE(zones->size() == 2);
  CHECK((*zones)[1].name == "B");
  CHECK((*zones)[1].polygon.size() == 4);
  auto sizes = (*map)->ZoneSizes();
  REQUIRE(sizes.ok());
  CHECK(*sizes == std::vector<std::uint32_t>{6, 6});
  auto members = (*map)->ZoneMembers();
  REQUIRE(members.ok());
  CHECK(members->size() == 12);
  CHECK((*map)->metadata().zone_count == 2);

  // Round trip into a ZoneSet and the adjacency graph from the stored pose graph.
  auto back = ZoneSetFromRecords(*zones, *members);
  REQUIRE(back.ok());
  auto links = (*map)->Links();
  REQUIRE(links.ok());
  const ZoneGraph g = BuildAdjacency(*back, *members, *links);
  REQUIRE(g.edges().size() == 1);
  CHECK(g.edges()[0].touching);
  CHECK(g.edges()[0].links > 0);
}

TEST_CASE("AnnotateDatabase with an unknown keyframe id fails and keeps the old zones") {
  test::TempDir dir;
  const std::string db = dir.File("map.db");
  BuildLine(db);
  const ZoneSet set = MakeSet({MakeZone("A", Rect(0, 0, 10, 5))});
  REQUIRE(AnnotateDatabase(db, set, {}).ok());

  auto lists = ParseZoneJson(R"({"zones":{"L1":[1,2],"H1":[3,77]}})", "paper.json");
  REQUIRE(lists.ok());
  auto bad = AnnotateDatabase(db, *lists, {});
  REQUIRE_FALSE(bad.ok());
  CHECK(bad.status().message().find("paper.json: feature 1 (\"H1\"): keyframe id 77") == 0);

  auto map = MapDb::Open(db);
  REQUIRE(map.ok());
  auto zones = (*map)->Zones();
  REQUIRE(zones.ok());
  REQUIRE(zones->size() == 1);
  CHECK((*zones)[0].name == "A");
  CHECK(*(*map)->ZoneSizes() == std::vector<std::uint32_t>{10});
}

TEST_CASE("AnnotateDatabase on a missing database is a clear error") {
  const ZoneSet set = MakeSet({MakeZone("A", Rect(0, 0, 10, 5))});
  auto r = AnnotateDatabase("/nonexistent/map.db", set, {});
  REQUIRE_FALSE(r.ok());
  CHECK(r.status().message().find("/nonexistent/map.db") != std::string::npos);
}

}  // namespace
}  // namespace zm
