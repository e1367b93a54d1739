// LtmGraph: basic's long-term-memory reads over the real map database (SourceLtmGraph over
// MapDb) give what the MapIndex holds, cost two statements and two transactions a node, and
// leave basic's decisions exactly as they are over the MapIndex; a failed read is reported,
// never hidden. Builds a small database in a temporary file.
#include "memory/ltm_graph.h"

#include <doctest/doctest.h>
#include <unistd.h>

#include <algorithm>
#include <filesystem>
#include <random>
#include <tuple>
#include <variant>

#include "memory/basic_policy.h"
#include "memory/working_set.h"
#include "support/test_building.h"

namespace zm {
namespace {

// 8 rooms of 12 keyframes chained by neighbour links, 20 random loop closures (some stored
// twice, once each way, as RTAB-Map stores every edge), weights 0..3 and a few intermediate
// nodes (-1).
struct TestMap {
  std::filesystem::path dir;
  std::string path;
  std::unique_ptr<MapDb> db;
  std::vector<KeyframeMeta> keyframes;
  std::vector<LinkRecord> links;
  std::unique_ptr<MapIndex> index;

  TestMap() {
    dir = std::filesystem::temp_directory_path() / ("zm_ltm_graph_" + std::to_string(getpid()));
    std::filesystem::create_directories(dir);
    path = (dir / "map.db").string();
    // tests/support/test_building.h: rooms 25 m apart, each a 4 x 3 grid of keyframes 2 m apart.
    test::BuildingSpec spec{.rooms = 8, .keyframes_per_room = 12, .seed = 5};
    spec.keyframe_pose = [](int room, int k) {
      return PoseFromXYYaw(25.0 * room + 2.0 * (k % 4), 2.0 * (k / 4), 0.0);
    };
    spec.dense_payloads = false;
    spec.random_weights = true;
    spec.neighbour_links = true;
    spec.random_closures = 20;
    spec.zones = test::BuildingSpec::Zones::kNone;
    spec.camera = false;
    (void)test::WriteBuilding(path, spec);
    auto opened = MapDb::Open(path);
    REQUIRE_MESSAGE(opened.ok(), opened.status().ToString());
    db = std::move(opened).value();
    auto kfs = db->Keyframes();
    auto ls = db->Links();
    REQUIRE(kfs.ok());
    REQUIRE(ls.ok());
    keyframes = *kfs;
    links = *ls;
    MapIndexInput in;
    in.keyframes = keyframes;
    in.links = links;
    auto built = MapIndex::Build(in);
    REQUIRE(built.ok());
    index = std::make_unique<MapIndex>(std::move(built).value());
  }
  ~TestMap() {
    db.reset();
    std::error_code ec;
    std::filesystem::remove_all(dir, ec);
  }
};

std::vector<std::tuple<KfIndex, LinkKind>> Sorted(std::span<const GraphEdge> edges) {
  std::vector<std::tuple<KfIndex, LinkKind>> out;
  for (const GraphEdge& e : edges) out.emplace_back(e.to, e.type);
  std::sort(out.begin(), out.end());
  return out;
}

Arena MakeArena(std::uint32_t slots, std::uint64_t slot_bytes) {
  auto r = Arena::Create({.memory_thr_keyframes = slots,
                          .budget_bytes = 0,
                          .slot_bytes = slot_bytes,
                          .lock = false,
                          .prefault = false});
  REQUIRE(std::holds_alternative<Arena>(r));
  return std::move(std::get<Arena>(r));
}

TEST_CASE(
    "SourceLtmGraph over MapDb reads each node's weight and links: 2 statements, 2 transactions") {
  TestMap m;
  SourceLtmGraph db_graph(*m.index, *m.db);
  IndexLtmGraph ram_graph(*m.index);
  for (KfIndex k = 0; k < m.index->keyframe_count(); ++k) {
    CAPTURE(m.index->id(k).value);
    const std::uint64_t executed = m.db->total_queries();
    const std::uint64_t transactions = m.db->total_transactions();
    LoadStats from_db, from_ram;
    LtmNode a, b;
    REQUIRE(db_graph.Read(k, &a, &from_db).ok());
    REQUIRE(ram_graph.Read(k, &b, &from_ram).ok());
    CHECK(a.weight == m.index->weight(k));
    CHECK(a.weight == b.weight);
    CHECK(Sorted(a.edges) == Sorted(b.edges));  // closures stored both ways come back once
    CHECK(from_db.queries == 2);
    CHECK(from_db.transactions == 2);
    CHECK(m.db->total_queries() - executed == 2);  // executed, not estimated
    CHECK(m.db->total_transactions() - transactions == 2);
    CHECK(from_ram.queries == 2);  // the stand-in counts what it did not execute
  }
}

// One working set + basic policy over the map database, reading LTM through `graph`.
struct BasicRun {
  Arena arena;
  WorkingSet ws;
  std::unique_ptr<BasicPolicy> policy;
  Plan plan;
  BasicRun(TestMap& m, LtmGraph* graph, const BasicOptions& o)
      : arena(MakeArena(m.index->keyframe_count(), m.db->metadata().largest_payload_bytes)),
        ws(*m.index, arena, *m.db, o.memory_thr),
        policy(std::make_unique<BasicPolicy>(*m.index, o, graph)),
        plan(*m.index) {}
  TickTelemetry Step(const TickContext& c, bool start) {
    TickTelemetry t;
    plan.Clear();
    if (start) {
      policy->Start(c, &plan);
    } else {
      policy->PlanAfterLocalize(c, &plan);
    }
    const Status s = ws.Apply(plan, &t);
    REQUIRE_MESSAGE(s.ok(), s.ToString());
    return t;
  }
};

TEST_CASE("basic decides the same reading LTM from the map database as from the MapIndex") {
  TestMap m;
  BasicOptions o;
  o.memory_thr = 20;
  for (std::int64_t i = 1; i <= 20; ++i) o.initial_wm.push_back(KeyframeId{i});
  SourceLtmGraph db_graph(*m.index, *m.db);
  BasicRun on_db(m, &db_graph, o);
  BasicRun on_ram(m, nullptr, o);  // IndexLtmGraph
  std::mt19937 rng(3);
  TickContext c;
  c.pose = PoseFromXYYaw(0, 0, 0);
  on_db.Step(c, true);
  on_ram.Step(c, true);
  std::uint64_t searched = 0, retrieved = 0;
  double x = 0.0;
  for (std::uint64_t t = 1; t <= 400; ++t) {
    CAPTURE(t);
    x = std::clamp(x + static_cast<double>(static_cast<int>(rng() % 7) - 3), 0.0, 185.0);
    c.tick = t;
    c.now_s = 0.5 * static_cast<double>(t);
    c.pose = PoseFromXYYaw(x, 2.0, 0.0);
    c.highest_hypothesis = KeyframeId{0};
    if (rng() % 4 != 0) {
      const auto r = on_db.ws.resident();
      c.highest_hypothesis = r[rng() % r.size()].id;
    }
    c.localized_on = rng() % 3 == 0 ? c.highest_hypothesis : KeyframeId{0};
    c.small_displacement = rng() % 5 == 0;
    const std::uint64_t executed = m.db->total_queries();
    const std::uint64_t transactions = m.db->total_transactions();
    const TickTelemetry a = on_db.Step(c, false);
    // Every statement the database executed for this tick is in its telemetry, searches included.
    CHECK(m.db->total_queries() - executed == a.db_queries);
    CHECK(m.db->total_transactions() - transactions == a.db_transactions);
    const TickTelemetry b = on_ram.Step(c, false);
    const auto& ra = on_db.policy->last_tick();
    const auto& rb = on_ram.policy->last_tick();
    REQUIRE(ra.retrieved == rb.retrieved);
    REQUIRE(ra.transferred == rb.transferred);
    CHECK(a.search_queries == b.search_queries);
    CHECK(a.db_queries == b.db_queries);
    searched += a.search_queries;
    retrieved += ra.retrieved.size();
  }
  CHECK(searched > 500);  // the run really searched the database
  CHECK(retrieved > 100);
}

// Fails the read of one node; everything else goes to the MapIndex.
class FailingGraph final : public LtmGraph {
 public:
  FailingGraph(const MapIndex& index, KeyframeId fail) : ram_(index), index_(index), fail_(fail) {}
  Status Read(KfIndex k, LtmNode* node, LoadStats* stats) override {
    if (index_.id(k) == fail_)
      return IoError("disk I/O error reading keyframe " + std::to_string(fail_.value));
    return ram_.Read(k, node, stats);
  }

 private:
  IndexLtmGraph ram_;
  const MapIndex& index_;
  KeyframeId fail_;
};

TEST_CASE("a failed LTM read: the search goes on without the node and Apply reports it") {
  TestMap m;
  BasicOptions o;
  o.memory_thr = 20;
  for (std::int64_t i = 1; i <= 10; ++i) o.initial_wm.push_back(KeyframeId{i});
  FailingGraph graph(*m.index, KeyframeId{11});
  BasicRun run(m, &graph, o);
  TickContext c;
  c.pose = PoseFromXYYaw(0, 0, 0);
  run.Step(c, true);
  c.tick = 1;
  c.now_s = 1.0;
  c.highest_hypothesis = KeyframeId{10};  // its neighbour 11 is in LTM and cannot be read
  run.plan.Clear();
  run.policy->PlanAfterLocalize(c, &run.plan);
  TickTelemetry t;
  const Status s = run.ws.Apply(run.plan, &t);
  CHECK(s.code() == StatusCode::kIoError);
  CHECK(s.message().find("keyframe 11") != std::string::npos);
  CHECK(s.message().find("graph search") != std::string::npos);
  for (KfIndex k : run.policy->last_tick().retrieved) CHECK(m.index->id(k) != KeyframeId{11});
  CHECK(run.ws.resident_count() == 10 + run.policy->last_tick().retrieved.size());
}

}  // namespace
}  // namespace zm
