// The basic baseline's database work, done for real and counted in one unit (issue 17 §5,
// basic-baseline.md §3.1, §11): LoadKeyframes reads per node its row, payload, links and
// calibration (4 statements, 4 autocommit transactions), ReadGraphNodes per node its weight and
// links (2 and 2); both fail on bad data they read (so the statements are not just counted),
// and ReadGraphNodes allocates nothing once warm.
#include <doctest/doctest.h>
#include <sqlite3.h>

#include <algorithm>
#include <cstring>

#include "mapdb/map_db.h"
#include "mapdb/mapdb_test_util.h"
#include "support/counting_allocator.h"
#include "support/test_util.h"

namespace zm {
namespace {

using test::Sql;

using test::BuildMap;
using test::MakeArena;
using test::RecordingSink;
using test::TempDir;

LinkRecord Link(std::int64_t from, std::int64_t to, LinkType type) {
  LinkRecord l;
  l.from = KeyframeId{from};
  l.to = KeyframeId{to};
  l.type = type;
  l.transform = PoseFromXYYaw(static_cast<double>(to - from), 0.0, 0.0);
  l.information[0] = static_cast<double>(from * 100 + to);
  return l;
}

// The 12-keyframe test map with links 1-2, 2-3 (neighbours), 5->2 (a closure stored 5->2) and
// a camera.
struct GraphMap {
  TempDir dir;
  std::string path = dir.File("map.db");
  test::BuiltMap built = BuildMap(path);
  GraphMap() {
    auto w = MapDbWriter::OpenExisting(path);
    REQUIRE(w.ok());
    const std::vector<LinkRecord> links = {Link(1, 2, LinkType::kNeighbor),
                                           Link(2, 3, LinkType::kNeighbor),
                                           Link(5, 2, LinkType::kGlobalClosure)};
    REQUIRE((*w)->InsertLinks(links).ok());
    REQUIRE(
        (*w)->SetCamera({.fx = 500, .fy = 500, .cx = 320, .cy = 240, .width = 640, .height = 480})
            .ok());
    REQUIRE((*w)->Finish().ok());
  }
};

// Records what ReadGraphNodes delivers into storage reserved up front (no allocation).
class GraphRecorder final : public GraphNodeSink {
 public:
  GraphRecorder() {
    nodes.reserve(64);
    links.reserve(64);
  }
  void Node(KeyframeId id, std::int32_t weight) override { nodes.emplace_back(id.value, weight); }
  void Link(const LinkRecord& l) override { links.push_back(l); }
  void Clear() {
    nodes.clear();
    links.clear();
  }
  std::vector<std::pair<std::int64_t, std::int32_t>> nodes;
  std::vector<LinkRecord> links;
};

TEST_CASE(
    "per-keyframe loads read row, payload, links and calibration: 4 statements, 4 transactions "
    "each") {
  GraphMap g;
  auto db = MapDb::Open(g.path);
  REQUIRE(db.ok());
  Arena arena = MakeArena(16, (*db)->metadata().largest_payload_bytes);
  RecordingSink sink;
  const std::vector<KeyframeId> ids = {KeyframeId{9}, KeyframeId{3}, KeyframeId{12}, KeyframeId{3}};
  auto st = (*db)->LoadKeyframes(ids, arena, sink);
  REQUIRE_MESSAGE(st.ok(), st.status().ToString());
  CHECK(st->keyframes == 3);
  CHECK(st->skipped == 1);  // the second 3 is resident by then: no statement at all
  CHECK(st->queries == 4 * 3);
  CHECK(st->transactions == 4 * 3);
  CHECK(st->blob_reads == 0);
  for (const auto& e : sink.loaded()) {
    const auto& want = g.built.payloads.at(e.id.value);
    CHECK(std::memcmp(arena.Slot(e.slot).data(), want.data(), want.size()) == 0);
  }
  CHECK((*db)->total_queries() == 12);
  CHECK((*db)->total_transactions() == 12);
  // Each statement was its own transaction: nothing is held afterwards.
  CHECK(test::TryWrite(g.path) == SQLITE_OK);
}

TEST_CASE("per-keyframe loads really read the links: a damaged link of the node fails its load") {
  GraphMap g;
  Sql(g.path,
      "UPDATE link SET information=substr(information, 1, 100) WHERE from_id=5 AND to_id=2");
  auto db = MapDb::Open(g.path);
  REQUIRE(db.ok());
  Arena arena = MakeArena(16, (*db)->metadata().largest_payload_bytes);
  RecordingSink sink;
  const KeyframeId two[] = {KeyframeId{2}};
  auto st = (*db)->LoadKeyframes(two, arena, sink);
  REQUIRE_FALSE(st.ok());
  INFO(st.status().ToString());
  CHECK(st.status().code() == StatusCode::kCorrupt);
  CHECK(st.status().message().find("link 5->2") != std::string::npos);
  CHECK(st.status().message().find("information blob") != std::string::npos);
  CHECK(arena.in_use() == 0);  // the payload had landed; its slot went back
  CHECK(sink.loaded().empty());
  const KeyframeId nine[] = {KeyframeId{9}};  // no damaged link: loads
  CHECK((*db)->LoadKeyframes(nine, arena, sink).ok());
  const KeyframeId missing[] = {KeyframeId{99}};
  auto nf = (*db)->LoadKeyframes(missing, arena, sink);
  CHECK(nf.status().code() == StatusCode::kNotFound);
  CHECK(nf.status().message().find("keyframe 99") != std::string::npos);
}

TEST_CASE(
    "graph-search point queries: each node's weight and links, 2 statements, 2 transactions") {
  GraphMap g;
  auto db = MapDb::Open(g.path);
  REQUIRE(db.ok());
  GraphRecorder rec;
  const std::vector<KeyframeId> ids = {KeyframeId{2}, KeyframeId{7}, KeyframeId{5}};
  auto st = (*db)->ReadGraphNodes(ids, &rec);
  REQUIRE_MESSAGE(st.ok(), st.status().ToString());
  CHECK(st->queries == 6);
  CHECK(st->transactions == 6);
  CHECK(st->keyframes == 0);
  CHECK(st->bytes == 0);
  // BuildMap gives keyframe i the weight i % 3.
  CHECK(rec.nodes == std::vector<std::pair<std::int64_t, std::int32_t>>{{2, 2}, {7, 1}, {5, 2}});
  // Links of 2 (both directions, as stored), then none for 7, then the closure for 5.
  std::vector<std::pair<std::int64_t, std::int64_t>> ends;
  for (const auto& l : rec.links) ends.emplace_back(l.from.value, l.to.value);
  std::sort(ends.begin(), ends.begin() + 3);
  CHECK(ends == std::vector<std::pair<std::int64_t, std::int64_t>>{{1, 2}, {2, 3}, {5, 2}, {5, 2}});
  const auto closure = std::find_if(rec.links.begin(), rec.links.end(),
                                    [](const LinkRecord& l) { return l.from.value == 5; });
  REQUIRE(closure != rec.links.end());
  CHECK(closure->type == LinkType::kGlobalClosure);
  CHECK(closure->information[0] == 502.0);
  CHECK(closure->transform.isApprox(PoseFromXYYaw(-3.0, 0.0, 0.0)));

  SUBCASE("without a sink the statements still run and count") {
    auto counted = (*db)->ReadGraphNodes(ids, nullptr);
    REQUIRE(counted.ok());
    CHECK(counted->queries == 6);
  }
  SUBCASE("an id that is not in the map is NotFound, naming it") {
    const KeyframeId bad[] = {KeyframeId{3}, KeyframeId{99}};
    auto nf = (*db)->ReadGraphNodes(bad, &rec);
    CHECK(nf.status().code() == StatusCode::kNotFound);
    CHECK(nf.status().message().find("keyframe 99") != std::string::npos);
  }
  CHECK(test::TryWrite(g.path) == SQLITE_OK);
}

TEST_CASE("graph-search point queries fail on a damaged link and allocate nothing once warm") {
  GraphMap g;
  auto db = MapDb::Open(g.path);
  REQUIRE(db.ok());
  GraphRecorder rec;
  const std::vector<KeyframeId> ids = {KeyframeId{1}, KeyframeId{2}, KeyframeId{3}, KeyframeId{5},
                                       KeyframeId{11}};
  REQUIRE((*db)->ReadGraphNodes(ids, &rec).ok());  // warm-up
  const std::int64_t sqlite_before = sqlite3_memory_used();
  {
    test::AllocationCounter counter;
    for (int i = 0; i < 50; ++i) {
      rec.Clear();
      auto st = (*db)->ReadGraphNodes(ids, &rec);
      REQUIRE(st.ok());
    }
    CHECK(counter.allocations() == 0);
  }
  CHECK(sqlite3_memory_used() == sqlite_before);
  CHECK(rec.links.size() == 1 + 3 + 1 + 1);

  db->reset();
  Sql(g.path, "UPDATE link SET transform=x'00' WHERE from_id=2 AND to_id=3");
  auto damaged = MapDb::Open(g.path);
  REQUIRE(damaged.ok());
  const KeyframeId three[] = {KeyframeId{3}};
  auto st = (*damaged)->ReadGraphNodes(three, &rec);
  CHECK(st.status().code() == StatusCode::kCorrupt);
  CHECK(st.status().message().find("link 2->3: transform blob is 1 bytes") != std::string::npos);
}

TEST_CASE(
    "a map without the link_to index reads links the same, opening it to write adds the index") {
  GraphMap g;
  Sql(g.path, "DROP INDEX link_to");
  {
    auto db = MapDb::Open(g.path);
    REQUIRE(db.ok());
    GraphRecorder rec;
    const KeyframeId two[] = {KeyframeId{2}};
    REQUIRE((*db)->ReadGraphNodes(two, &rec).ok());
    CHECK(rec.links.size() == 3);
  }
  auto w = MapDbWriter::OpenExisting(g.path);
  REQUIRE(w.ok());
  REQUIRE((*w)->Finish().ok());
  w->reset();
  sqlite3* raw = nullptr;
  REQUIRE(sqlite3_open(g.path.c_str(), &raw) == SQLITE_OK);
  sqlite3_stmt* s = nullptr;
  REQUIRE(sqlite3_prepare_v2(
              raw, "SELECT count(*) FROM sqlite_master WHERE type='index' AND name='link_to'", -1,
              &s, nullptr) == SQLITE_OK);
  REQUIRE(sqlite3_step(s) == SQLITE_ROW);
  CHECK(sqlite3_column_int(s, 0) == 1);
  sqlite3_finalize(s);
  sqlite3_close(raw);
}

}  // namespace
}  // namespace zm
