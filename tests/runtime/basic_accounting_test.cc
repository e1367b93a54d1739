// Database work in one unit (statements executed, transactions, blob reads), start-up and
// steady state apart, counted by hand on a tiny map and checked against what the loop reports
// (ticks.jsonl, LoopTotals, summary.json) and against what MapDb really executed. Plus basic's
// start-up: the map's recorded last working memory, and init_wm_with_all_nodes meaning what it
// says.
#include <doctest/doctest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "runtime/frames_file.h"
#include "runtime/summary.h"
#include "runtime/telemetry.h"
#include "runtime/tick_loop.h"
#include "support/test_building.h"

namespace zm {
namespace {

// Keyframes 1..6 on the x axis, 2 m apart (x = 0, 2, ..., 10), chained by neighbour links, one
// zone holding them all; `last_wm` recorded when given (as import-rtabmap does), `source` as
// written by the simulator or the importer. Frames: `frames` frames standing at node 2 (x = 2),
// 1 s apart, without features, so the localizer never proposes a hypothesis and never localizes:
// basic's work is then its local retrieval and its transfers alone, which can be counted by hand.
struct TinyMap {
  std::filesystem::path dir;
  std::string db, frames;

  TinyMap(const std::string& name, const std::vector<std::int64_t>* last_wm,
          const std::string& source, int frame_count = 5) {
    dir = std::filesystem::temp_directory_path() /
          ("zm_basic_accounting_" + std::to_string(getpid()) + "_" + name);
    std::filesystem::create_directories(dir);
    db = (dir / "map.db").string();
    frames = (dir / "frames.bin").string();
    // tests/support/test_building.h: one "room" of 6 keyframes 2 m apart, one corridor zone.
    test::BuildingSpec spec{.rooms = 1, .keyframes_per_room = 6};
    spec.keyframe_pose = [](int, int k) { return PoseFromXYYaw(2.0 * k, 0.0, 0.0); };
    spec.dense_payloads = false;
    spec.keypoint = {320, 240};
    spec.neighbour_links = true;
    spec.zones = test::BuildingSpec::Zones::kOneCorridor;
    spec.corridor_polygon = {{-1.0, -1.0}, {12.0, -1.0}, {12.0, 1.0}, {-1.0, 1.0}};
    spec.source = source;
    spec.last_working_memory = last_wm;
    (void)test::WriteBuilding(db, spec);

    auto fw = FrameWriter::Create(frames, test::kTestCamera, 1.0);
    REQUIRE(fw.ok());
    Frame f;
    for (int i = 0; i < frame_count; ++i) {
      f.index = static_cast<std::uint64_t>(i);
      f.stamp_s = static_cast<double>(i);
      f.odom = PoseFromXYYaw(2.0, 0.0, 0.0);
      REQUIRE(fw->Append(f).ok());
    }
    REQUIRE(fw->Finish().ok());
  }
  ~TinyMap() {
    std::error_code ec;
    std::filesystem::remove_all(dir, ec);
  }
};

LoopConfig Basic(std::uint64_t memory_thr, bool all_nodes) {
  LoopConfig c;
  c.policy.kind = PolicyKind::kBasic;
  c.map.memory_thr_keyframes = memory_thr;
  c.policy.basic.init_wm_with_all_nodes = all_nodes;
  c.localizer.reserve_features = 8;
  c.loop.rate_hz = 1.0;
  return c;
}

struct Opened {
  std::unique_ptr<MapDb> db;
  std::unique_ptr<FrameSource> frames;
  Result<std::unique_ptr<TickLoop>> loop = Internal("not created");
};

Opened Open(const TinyMap& m, const LoopConfig& c) {
  Opened o;
  auto db = MapDb::Open(m.db);
  REQUIRE_MESSAGE(db.ok(), db.status().ToString());
  o.db = std::move(db).value();
  auto fr = OpenReplaySource(m.frames);
  REQUIRE_MESSAGE(fr.ok(), fr.status().ToString());
  o.frames = std::move(fr).value();
  o.loop = TickLoop::Create(c, *o.db, *o.frames);
  return o;
}

TEST_CASE("basic's database work by hand: start-up, then searches and loads, one unit") {
  // Recorded last working memory {1, 2}; MemoryThr 3; the robot stands at node 2.
  //
  // Start-up: WM = {1, 2}, one LoadKeyframes batch, 4 statements a node (row, payload, links,
  // calibration), each its own transaction: 8 statements, 8 transactions, 0 blob reads.
  // lastLoc = 2, local map L = {1, 2}.
  //
  // Tick 0, after localizing (nothing: no features): local retrieval around x = 2, quota 2.
  //   first pass from 2: its LTM neighbour 3 is read (weight, links: 2 statements) -> local [3];
  //                 from 1: no LTM neighbour;
  //   second pass from 3, limit 2 - 1 + 1 = 2: 3 and 4 read (4 statements) -> local [3, 4];
  //   load 3, 4 (8 statements); |WM| = 4 > 3: transfer retrieved + 1 = 3 nodes, but only 1 is
  //   not immunized (3, 4 retrieved; 2 is lastLoc): 1 leaves. L = {2}.
  //   22 statements in the tick: 8 start-up + 6 searching + 8 loading.
  // Tick 1: from 2, LTM neighbour 1 read (2) -> local [1]; second pass from 1 reads 1 again
  //   (2), nothing new; load 1 (4); |WM| = 4: transfer 2: 3 and 4 (same whole-second age, by
  //   id). 8 statements.
  // Ticks 2, 3, 4 repeat ticks 0 (without start-up) and 1: 14, 8, 14.
  const std::vector<std::int64_t> last_wm{1, 2};
  TinyMap m("hand", &last_wm, "sim tiny");
  Opened o = Open(m, Basic(3, /*all_nodes=*/false));
  REQUIRE_MESSAGE(o.loop.ok(), o.loop.status().ToString());
  TickLoop& loop = **o.loop;
  const std::uint64_t executed_before = o.db->total_queries();
  const std::uint64_t transactions_before = o.db->total_transactions();
  TelemetryWriter telemetry;
  const std::string ticks_path = (m.dir / "ticks.jsonl").string();
  REQUIRE(telemetry.Open(ticks_path).ok());

  const std::uint32_t want_statements[] = {22, 8, 14, 8, 14};
  const std::uint32_t want_search[] = {6, 4, 6, 4, 6};
  const std::uint32_t want_loaded[] = {4, 1, 2, 1, 2};
  const std::uint32_t want_unloaded[] = {1, 2, 1, 2, 1};
  for (int i = 0; i < 5; ++i) {
    CAPTURE(i);
    REQUIRE(loop.Tick().value());
    const TickRecord& r = loop.last_record();
    CHECK(r.startup == (i == 0));
    CHECK(r.highest_hypothesis == 0);
    CHECK(r.db_queries == want_statements[i]);
    CHECK(r.db_transactions == want_statements[i]);  // every statement autocommits
    CHECK(r.search_queries == want_search[i]);
    CHECK(r.search_transactions == want_search[i]);
    CHECK(r.db_blob_reads == 0);
    CHECK(r.keyframes_loaded == want_loaded[i]);
    CHECK(r.keyframes_unloaded == want_unloaded[i]);
    CHECK(r.startup_db_queries == (i == 0 ? 8U : 0U));
    CHECK(r.startup_db_transactions == (i == 0 ? 8U : 0U));
    CHECK(telemetry.Write(r));
  }
  CHECK_FALSE(loop.Tick().value());
  telemetry.Close();

  // Totals: start-up apart, the steady state the rest; and all of it really executed.
  const LoopTotals& t = loop.totals();
  CHECK(t.startup.keyframes_loaded == 2);
  CHECK(t.startup.db_queries == 8);
  CHECK(t.startup.db_transactions == 8);
  CHECK(t.startup.db_blob_reads == 0);
  CHECK(t.db_queries == 8 + 58);
  CHECK(t.db_transactions == 8 + 58);
  CHECK(t.search_queries == 26);
  CHECK(t.search_transactions == 26);
  CHECK(t.db_blob_reads == 0);
  CHECK(SteadyDbWork(t).queries == 58);
  CHECK(o.db->total_queries() - executed_before == t.db_queries);
  CHECK(o.db->total_transactions() - transactions_before == t.db_transactions);
  CHECK(t.step_errors == 0);

  const nlohmann::json s = LoopSummary(loop, false);
  CHECK(s["startup"]["db_queries"] == 8);
  CHECK(s["startup"]["db_transactions"] == 8);
  CHECK(s["startup"]["db_blob_reads"] == 0);
  CHECK(s["steady_state"]["db_queries"] == 58);
  CHECK(s["steady_state"]["db_transactions"] == 58);
  CHECK(s["db_queries"] == 66);
  CHECK(s["search_queries"] == 26);
  CHECK(s["search_transactions"] == 26);

  std::ifstream in(ticks_path);
  std::string line;
  std::vector<nlohmann::json> lines;
  while (std::getline(in, line)) lines.push_back(nlohmann::json::parse(line));
  REQUIRE(lines.size() == 5);
  CHECK(lines[0]["db_queries"] == 22);
  CHECK(lines[0]["search_queries"] == 6);
  CHECK(lines[0]["startup_db"]["queries"] == 8);
  CHECK(lines[0]["startup_db"]["transactions"] == 8);
  CHECK(lines[1]["db_queries"] == 8);
  CHECK(lines[1]["db_transactions"] == 8);
  CHECK(lines[1]["db_blob_reads"] == 0);
  CHECK_FALSE(lines[1].contains("startup_db"));
}

TEST_CASE("semantic's zone load counts its blob reads in the same unit") {
  TinyMap m("semantic", nullptr, "sim tiny", 2);
  LoopConfig c = Basic(6, false);
  c.policy.kind = PolicyKind::kSemantic;
  Opened o = Open(m, c);
  REQUIRE_MESSAGE(o.loop.ok(), o.loop.status().ToString());
  TickLoop& loop = **o.loop;
  while (loop.Tick().value()) {
  }
  // Start-up: the zone, one statement over zone_member, one transaction, one blob read a
  // keyframe (6); nothing after.
  const LoopTotals& t = loop.totals();
  CHECK(t.startup.db_queries == 1);
  CHECK(t.startup.db_transactions == 1);
  CHECK(t.startup.db_blob_reads == 6);
  CHECK(t.db_blob_reads == 6);
  CHECK(t.search_queries == 0);
  CHECK(SteadyDbWork(t).queries == 0);
  CHECK(LoopSummary(loop, false)["startup"]["db_blob_reads"] == 6);
}

TEST_CASE("basic's start-up: the recorded last working memory, or every node when asked") {
  const std::vector<std::int64_t> last_wm{1, 2};
  TinyMap m("startup", &last_wm, "rtabmap:/x/rtabmap.db v0.23.1", 1);
  SUBCASE("init_wm_with_all_nodes = false: the map's last working memory") {
    Opened o = Open(m, Basic(3, false));
    REQUIRE_MESSAGE(o.loop.ok(), o.loop.status().ToString());
    REQUIRE((*o.loop)->Tick().value());
    CHECK((*o.loop)->totals().startup.keyframes_loaded == 2);
    CHECK((*o.loop)->totals().startup.db_queries == 2 * 4);
  }
  SUBCASE("init_wm_with_all_nodes = true: every node") {
    Opened o = Open(m, Basic(3, true));
    REQUIRE_MESSAGE(o.loop.ok(), o.loop.status().ToString());
    REQUIRE((*o.loop)->Tick().value());
    CHECK((*o.loop)->totals().startup.keyframes_loaded == 6);
    CHECK((*o.loop)->totals().startup.db_queries == 6 * 4);
  }
}

TEST_CASE("basic's start-up on maps that record no last working memory") {
  SUBCASE("built without memory management (the simulator's): every node") {
    TinyMap m("sim", nullptr, "sim tiny", 1);
    Opened o = Open(m, Basic(3, false));
    REQUIRE_MESSAGE(o.loop.ok(), o.loop.status().ToString());
    REQUIRE((*o.loop)->Tick().value());
    CHECK((*o.loop)->totals().startup.keyframes_loaded == 6);
  }
  SUBCASE("an RTAB-Map import from before the record: refused, naming the fix") {
    TinyMap m("old_import", nullptr, "rtabmap:/x/rtabmap.db v0.23.1", 1);
    Opened o = Open(m, Basic(3, false));
    REQUIRE_FALSE(o.loop.ok());
    CHECK(o.loop.status().code() == StatusCode::kFailedPrecondition);
    CHECK(o.loop.status().message().find("import-rtabmap") != std::string::npos);
    CHECK(o.loop.status().message().find("init_wm_with_all_nodes") != std::string::npos);
    Opened all = Open(m, Basic(3, true));  // asking for every node needs no record
    CHECK(all.loop.ok());
  }
}

}  // namespace
}  // namespace zm
