// The tick loop against a small synthetic building: a row of square rooms (one zone each),
// keyframes along the corridor through them, and a patrol that walks back and forth so zones
// are loaded and evicted many times. Checks the design's invariants at the level of the loop:
//   1. resident <= K_max at every tick (and at every instant, via the working set's peak);
//   2. no heap allocation in a warm tick, its idle part included, for every policy;
//   3. one transaction per zone load, unload before load;
//   4. the localizer only sees resident keyframes;
// plus time-sliced loads (issue 14 §2: the in-tick and idle budgets are kept, the idle part
// stops for a waiting frame and at the frame's due time), deterministic replay and the basic
// policy's measured overshoot. Budgets are given in bytes here, never in time, so what a tick
// loads does not depend on the machine.
#include "runtime/tick_loop.h"

#include <doctest/doctest.h>

#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <random>
#include <set>

#include "runtime/frame_source.h"
#include "runtime/line_protocol.h"
#include "runtime/frames_file.h"
#include "support/counting_allocator.h"

namespace zm {
namespace {

constexpr int kRooms = 8;
constexpr double kRoomM = 10.0;
constexpr int kKeyframesPerRoom = 20;

struct Scenario {
  std::filesystem::path dir;
  std::string db, frames;
  ~Scenario() {
    std::error_code ec;
    std::filesystem::remove_all(dir, ec);
  }
};

std::vector<std::byte> Payload(std::int64_t id, std::mt19937& rng) {
  constexpr std::uint32_t kFeatures = 40;
  std::vector<Descriptor256> desc(kFeatures);
  for (auto& d : desc)
    for (auto& b : d) b = static_cast<std::uint8_t>(rng());
  std::vector<float> pts(3 * kFeatures), kps(2 * kFeatures);
  for (auto& f : pts) f = static_cast<float>(rng() % 1000) * 0.01f;
  for (auto& f : kps) f = static_cast<float>(rng() % 640);
  std::vector<std::byte> dense(2000 + rng() % 500);
  for (auto& b : dense) b = static_cast<std::byte>(rng());
  auto r = EncodePayload(
      PayloadParts{KeyframeId{id}, desc, pts, kps, DenseFormat::kOpaque, dense, 0});
  REQUIRE(r.ok());
  return std::move(r).value();
}

// Builds map.db (rooms along x, zones annotated) and frames.bin (a back-and-forth patrol).
void Build(Scenario* s, int patrol_frames) {
  s->dir = std::filesystem::temp_directory_path() /
           ("zm_loop_test_" + std::to_string(::getpid()) + "_" + std::to_string(patrol_frames));
  std::filesystem::create_directories(s->dir);
  s->db = (s->dir / "map.db").string();
  s->frames = (s->dir / "frames.bin").string();
  std::mt19937 rng(7);
  auto w = MapDbWriter::Create(s->db, true);
  REQUIRE(w.ok());
  std::vector<std::vector<std::byte>> payloads;
  std::vector<KeyframeRecord> recs;
  std::vector<ZoneMember> members;
  std::vector<ZoneRecord> zones;
  std::int64_t id = 1;
  for (int room = 0; room < kRooms; ++room) {
    ZoneRecord z;
    z.id = ZoneId{room};
    z.name = "room" + std::to_string(room);
    z.kind = "room";
    const double x0 = room * kRoomM;
    z.polygon = {{x0, 0.0}, {x0 + kRoomM, 0.0}, {x0 + kRoomM, kRoomM}, {x0, kRoomM}};
    zones.push_back(z);
    for (int k = 0; k < kKeyframesPerRoom; ++k, ++id) {
      payloads.push_back(Payload(id, rng));
      KeyframeMeta m;
      m.id = KeyframeId{id};
      m.pose = PoseFromXYYaw(x0 + 0.25 + 0.5 * k, 5.0, 0.0, 0.0);
      m.payload_bytes = static_cast<std::uint32_t>(payloads.back().size());
      members.push_back({z.id, m.id});
      recs.push_back({m, {}});
    }
  }
  for (std::size_t i = 0; i < recs.size(); ++i) recs[i].payload = payloads[i];
  REQUIRE((*w)->InsertKeyframes(recs).ok());
  REQUIRE((*w)->ReplaceZones(zones, members).ok());
  REQUIRE((*w)->SetCamera({.fx = 320, .fy = 320, .cx = 320, .cy = 240, .width = 640, .height = 480}).ok());
  REQUIRE((*w)->Finish().ok());

  auto fw = FrameWriter::Create(s->frames, {.fx = 320, .fy = 320, .cx = 320, .cy = 240, .width = 640, .height = 480}, 2.0);
  REQUIRE(fw.ok());
  Frame f;
  const double length = kRooms * kRoomM - 1.0;
  for (int i = 0; i < patrol_frames; ++i) {
    // Triangle wave over the corridor: every room is left and re-entered several times.
    const double phase = std::fmod(i * 1.7, 2.0 * length);
    const double x = 0.5 + (phase < length ? phase : 2.0 * length - phase);
    f.index = static_cast<std::uint64_t>(i);
    f.stamp_s = 0.5 * i;
    f.odom = PoseFromXYYaw(x, 5.0, phase < length ? 0.0 : M_PI, 0.0);
    f.descriptors.assign(30, Descriptor256{});
    for (auto& d : f.descriptors)
      for (auto& b : d) b = static_cast<std::uint8_t>(rng());
    f.keypoints.assign(60, 100.0f);
    REQUIRE(fw->Append(f).ok());
  }
  REQUIRE(fw->Finish().ok());
}

LoopConfig Config(const std::string& policy, std::uint64_t k_max) {
  LoopConfig c;
  c.policy.policy = policy;
  c.map.memory_thr_keyframes = k_max;
  c.policy.basic.init_wm_with_all_nodes = true;
  c.zones.hysteresis_m = 0.5;
  c.localizer.reserve_features = 64;
  c.loop.rate_hz = 2.0;
  return c;
}

struct Run {
  std::unique_ptr<MapDb> db;
  std::unique_ptr<FrameSource> frames;
  std::unique_ptr<TickLoop> loop;
  // What a driver does for one frame: the tick, then its idle part (on the frames' clock).
  bool Step() {
    auto more = loop->Tick();
    REQUIRE_MESSAGE(more.ok(), more.status().ToString());
    if (!more.value()) return false;
    (void)loop->Idle();
    return true;
  }
};

// The largest payload's slot in this map (every slot of the arena has this size).
std::uint64_t SlotBytes(const Scenario& s) {
  auto db = MapDb::Open(s.db);
  REQUIRE(db.ok());
  const std::uint64_t largest = (*db)->metadata().largest_payload_bytes;
  return (largest + 63) / 64 * 64;
}

// Time-sliced loads counted in keyframes through the byte budgets (a keyframe counts as a whole
// slot until it lands): `in_tick` keyframes in a tick's slice, `idle` in each idle part.
LoopConfig Sliced(LoopConfig c, const Scenario& s, std::uint32_t in_tick, std::uint32_t idle) {
  const std::uint64_t slot = SlotBytes(s);
  c.loads.sliced = true;
  c.loads.tick_ms = 0.0;  // no time limit: bytes only
  c.loads.tick_bytes = in_tick * slot;
  c.loads.idle_ms = 0.0;  // up to the next frame's due time, 500 ms away at 2 Hz
  c.loads.idle_bytes = idle * slot;
  return c;
}

Run Open(const Scenario& s, const LoopConfig& c) {
  Run r;
  auto db = MapDb::Open(s.db);
  REQUIRE_MESSAGE(db.ok(), db.status().ToString());
  r.db = std::move(db).value();
  auto fr = OpenReplaySource(s.frames);
  REQUIRE_MESSAGE(fr.ok(), fr.status().ToString());
  r.frames = std::move(fr).value();
  auto loop = TickLoop::Create(c, *r.db, *r.frames);
  REQUIRE_MESSAGE(loop.ok(), loop.status().ToString());
  r.loop = std::move(loop).value();
  return r;
}

TEST_CASE("semantic unsliced: resident never exceeds K_max, zone loads are single transactions") {
  Scenario s;
  Build(&s, 200);
  const std::uint64_t k_max = 3 * kKeyframesPerRoom;  // three rooms fit
  LoopConfig c = Config("semantic", k_max);
  c.loads.sliced = false;  // every load in the tick that plans it (before issue 14)
  Run r = Open(s, c);
  std::uint64_t ticks = 0;
  for (;;) {
    auto more = r.loop->Tick();
    REQUIRE(more.ok());
    if (!more.value()) break;
    ++ticks;
    const TickRecord& rec = r.loop->last_record();
    CHECK(rec.resident_keyframes <= k_max);
    CHECK_FALSE(rec.over_budget);
    CHECK(rec.db_transactions <= 1);  // at most one zone enters per tick here
    if (rec.keyframes_loaded > 0) CHECK(rec.db_transactions == 1);
    CHECK(rec.pending_keyframes == 0);
  }
  CHECK(ticks == 200);
  const LoopTotals& t = r.loop->totals();
  CHECK(t.zone_loads > kRooms);  // rooms were evicted and re-entered
  CHECK(t.keyframes_unloaded > 0);
  CHECK(t.peak_resident_keyframes <= k_max);
  CHECK(r.loop->working_set().max_resident_seen() <= k_max);
  CHECK(r.loop->arena().capacity() == k_max);
  CHECK(r.loop->arena().stats().refused == 0);
  CHECK(t.over_budget_ticks == 0);
  CHECK(t.step_errors == 0);
}

TEST_CASE("time-sliced: each tick and each idle part keep their budget / resident <= K_max") {
  Scenario s;
  Build(&s, 200);
  const std::uint32_t k_max = 3 * kKeyframesPerRoom;
  Run r = Open(s, Sliced(Config("semantic", k_max), s, /*in_tick=*/2, /*idle=*/5));
  std::set<std::int64_t> resident;
  std::uint32_t idle_loaded = 0;
  std::uint32_t most_pending = 0;
  for (;;) {
    auto more = r.loop->Tick();
    REQUIRE(more.ok());
    if (!more.value()) break;
    const TickRecord& rec = r.loop->last_record();
    CAPTURE(rec.tick);
    CHECK(rec.resident_keyframes <= k_max);
    CHECK_FALSE(rec.over_budget);
    CHECK(rec.idle_keyframes_loaded == idle_loaded);  // the idle part before this tick
    CHECK(rec.late_ms == 0.0);  // 500 ms of idle on the frames' clock: never used up here
    if (!rec.startup) CHECK(rec.keyframes_loaded <= 2);
    most_pending = std::max(most_pending, rec.pending_keyframes);
    // The localizer saw complete keyframes only: what it matched is resident, not pending.
    resident.clear();
    for (const auto& k : r.loop->working_set().resident()) resident.insert(k.id.value);
    if (rec.highest_hypothesis != 0) CHECK(resident.count(rec.highest_hypothesis) == 1);
    if (rec.matched_keyframe != 0) CHECK(resident.count(rec.matched_keyframe) == 1);
    const TickLoop::IdleReport idle = r.loop->Idle();
    CHECK(idle.keyframes_loaded <= 5);
    CHECK(idle.late_ms == 0.0);
    idle_loaded = idle.keyframes_loaded;
  }
  const LoopTotals& t = r.loop->totals();
  CHECK(most_pending > 0);  // loads did span ticks
  CHECK(t.idle_keyframes_loaded > 0);
  CHECK(t.peak_resident_keyframes <= k_max);
  CHECK(r.loop->working_set().max_resident_seen() <= k_max);
  CHECK(r.loop->arena().stats().refused == 0);
  // One transaction per zone batch begun: a zone load, plus a restart for each preempted one
  // (a batch evicted before it began costs none).
  CHECK(t.db_transactions <= t.zone_loads + t.loads_preempted);
  CHECK(t.db_transactions > 0);
  CHECK(t.step_errors == 0);
  CHECK(t.late_ticks == 0);
}

TEST_CASE("time-sliced: the idle part ends at the next frame's due time") {
  Scenario s;
  Build(&s, 20);
  Run r = Open(s, Sliced(Config("semantic", 2 * kKeyframesPerRoom), s, 1, 1000));
  REQUIRE(r.loop->Tick().value());  // start-up: the first room, loaded to the end
  CHECK(r.loop->last_record().pending_keyframes == 0);
  while (r.loop->working_set().pending_count() == 0) REQUIRE(r.loop->Tick().value());
  // A room was entered and 1 of its keyframes loaded in the tick; the frame is already due.
  const std::uint32_t pending = r.loop->working_set().pending_count();
  TickLoop::IdleReport idle = r.loop->Idle(std::chrono::steady_clock::now());
  CHECK(idle.keyframes_loaded == 0);
  CHECK(idle.late_ms == 0.0);
  CHECK(r.loop->working_set().pending_count() == pending);
  idle = r.loop->Idle();  // the frames' clock: 500 ms after the tick started
  CHECK(idle.keyframes_loaded == pending);
  CHECK(idle.pending_keyframes == 0);
}

TEST_CASE("time-sliced: the idle part stops when a frame is waiting at the source") {
  Scenario s;
  Build(&s, 1);
  int fds[2];
  REQUIRE(::pipe(fds) == 0);
  Frame f;
  f.descriptors.assign(3, Descriptor256{});
  f.keypoints.assign(6, 1.0f);
  const auto send = [&](int i, double x) {
    f.stamp_s = i;
    f.odom = PoseFromXYYaw(x, 5.0, 0.0);
    const std::string line = FormatFrameLine(f) + "\n";
    REQUIRE(::write(fds[1], line.data(), line.size()) == static_cast<ssize_t>(line.size()));
  };
  LineFrameSource source(fds[0], 16);
  auto db = MapDb::Open(s.db);
  REQUIRE(db.ok());
  auto loop = TickLoop::Create(Sliced(Config("semantic", 2 * kKeyframesPerRoom), s, 1, 1000),
                               *db.value(), source);
  REQUIRE(loop.ok());
  TickLoop& l = *loop.value();
  send(0, 5.0);
  REQUIRE(l.Tick().value());  // start-up in room 0
  send(1, 15.0);
  send(2, 15.5);
  REQUIRE(l.Tick().value());  // room 1 entered: 1 keyframe in the tick, the rest queued
  REQUIRE(l.working_set().pending_count() > 0);
  CHECK(source.FrameWaiting());  // frame 2 is in the buffer already
  CHECK(l.Idle().keyframes_loaded == 0);
  REQUIRE(l.Tick().value());
  CHECK_FALSE(source.FrameWaiting());  // nothing more written yet
  const TickLoop::IdleReport idle = l.Idle();
  CHECK(idle.keyframes_loaded > 0);
  CHECK(idle.pending_keyframes == 0);
  ::close(fds[1]);
  ::close(fds[0]);
}

TEST_CASE("a warm semantic tick allocates nothing") {
  Scenario s;
  Build(&s, 240);
  Run r = Open(s, Config("semantic", 3 * kKeyframesPerRoom));
  for (int i = 0; i < 80; ++i) REQUIRE(r.Step());  // one full sweep: warm
  const std::uint64_t loads_before = r.loop->totals().zone_loads;
  test::AllocationCounter counter;
  for (int i = 0; i < 150; ++i) REQUIRE(r.Step());
  CHECK(counter.allocations() == 0);
  CHECK(r.loop->totals().zone_loads > loads_before);  // the window did load and evict zones
}

TEST_CASE("the localizer only ever sees resident keyframes") {
  Scenario s;
  Build(&s, 120);
  Run r = Open(s, Config("semantic", 2 * kKeyframesPerRoom));
  std::set<std::int64_t> resident;
  for (;;) {
    auto more = r.loop->Tick();
    REQUIRE(more.ok());
    if (!more.value()) break;
    resident.clear();
    for (const auto& k : r.loop->working_set().resident()) resident.insert(k.id.value);
    const TickRecord& rec = r.loop->last_record();
    if (rec.highest_hypothesis != 0) CHECK(resident.count(rec.highest_hypothesis) == 1);
    if (rec.matched_keyframe != 0) CHECK(resident.count(rec.matched_keyframe) == 1);
    (void)r.loop->Idle();
  }
}

TEST_CASE("replay is deterministic") {
  Scenario s;
  Build(&s, 100);
  auto trace = [&](const std::string& policy) {
    // Loads time-sliced with byte budgets: the idle part is never cut short by its deadline
    // here, so what each tick loads is the same in every run.
    Run r = Open(s, Sliced(Config(policy, 2 * kKeyframesPerRoom), s, 2, 6));
    std::vector<std::uint64_t> out;
    while (r.Step()) {
      const TickRecord& rec = r.loop->last_record();
      out.push_back((static_cast<std::uint64_t>(rec.zone.value + 1) << 48) ^
                    (std::uint64_t{rec.resident_keyframes} << 24) ^ rec.keyframes_loaded ^
                    (std::uint64_t{rec.keyframes_unloaded} << 12) ^
                    (std::uint64_t{rec.idle_keyframes_loaded} << 36) ^ rec.loop_closure);
    }
    return out;
  };
  for (const char* policy : {"semantic", "basic", "predictive"}) {
    CAPTURE(policy);
    CHECK(trace(policy) == trace(policy));
  }
}

TEST_CASE("basic exceeds MemoryThr at start-up and the loop measures by how much") {
  Scenario s;
  Build(&s, 60);
  const std::uint64_t k_max = 2 * kKeyframesPerRoom;
  Run r = Open(s, Config("basic", k_max));
  while (r.loop->Tick().value()) {
  }
  const LoopTotals& t = r.loop->totals();
  // InitWMWithAllNodes: every keyframe resident at start, shed one net node per tick.
  CHECK(t.peak_resident_keyframes == kRooms * kKeyframesPerRoom);
  CHECK(t.over_budget_ticks == 60);
  CHECK(t.max_over_budget_keyframes == kRooms * kKeyframesPerRoom - k_max);
  CHECK(t.longest_over_budget_run == 60);
  CHECK_FALSE(r.loop->bounded());
}

TEST_CASE("the start-up load is reported apart from the steady-state tick times") {
  Scenario s;
  Build(&s, 30);
  Run r = Open(s, Config("basic", 2 * kKeyframesPerRoom));
  REQUIRE(r.loop->Tick().value());
  CHECK(r.loop->last_record().startup);
  const LoopTotals& t = r.loop->totals();
  // basic's start-up: its whole initial working memory (every node of a map built without
  // memory management), in the first tick, not in the tick-time statistics.
  CHECK(t.startup.keyframes_loaded == kRooms * kKeyframesPerRoom);
  CHECK(t.startup.tick_ms > 0.0);
  CHECK(t.tick_ms.count() == 0);
  while (r.loop->Tick().value()) CHECK_FALSE(r.loop->last_record().startup);
  CHECK(t.tick_ms.count() == 29);
  CHECK(t.tick_ms.max() >= t.tick_ms.Quantile(0.99));
}

TEST_CASE("every warm tick allocates nothing, for every policy, sliced loads included") {
  Scenario s;
  Build(&s, 300);
  for (const char* policy : {"semantic", "basic", "radius", "predictive", "oracle", "unbounded"}) {
    CAPTURE(policy);
    // Small slices (1 keyframe in a tick, 2 in its idle part; a room is 20), so zone loads span
    // ticks and are preempted, cancelled and resumed inside the counted window.
    LoopConfig c = Sliced(Config(policy, 3 * kKeyframesPerRoom), s, 1, 2);
    c.policy.radius.map_radius_m = 15.0;
    c.policy.radius.update_distance_m = 5.0;
    Run r;
    auto db = MapDb::Open(s.db);
    REQUIRE(db.ok());
    r.db = std::move(db).value();
    auto fr = OpenReplaySource(s.frames);
    REQUIRE(fr.ok());
    r.frames = std::move(fr).value();
    LoopPlanInputs plan;
    if (std::string(policy) == "oracle") plan.oracle_future.assign(300, ZoneId{0});
    auto loop = TickLoop::Create(c, *r.db, *r.frames, std::move(plan));
    REQUIRE_MESSAGE(loop.ok(), loop.status().ToString());
    r.loop = std::move(loop).value();
    for (int i = 0; i < 100; ++i) REQUIRE(r.Step());  // warm: a full sweep
    const std::uint64_t idle_before = r.loop->totals().idle_keyframes_loaded;
    test::AllocationCounter counter;
    for (int i = 0; i < 150; ++i) REQUIRE(r.Step());
    CHECK(counter.allocations() == 0);
    const bool zone_policy = std::string(policy) != "basic" && std::string(policy) != "unbounded";
    if (zone_policy) CHECK(r.loop->totals().idle_keyframes_loaded > idle_before);
    // The small slices made loads lag: zones were left (or evicted) before they finished.
    if (zone_policy) CHECK(r.loop->totals().keyframes_cancelled > 0);
  }
}

TEST_CASE("the live line protocol drives the loop and bad lines are skipped") {
  Scenario s;
  Build(&s, 1);
  int fds[2];
  REQUIRE(::pipe(fds) == 0);
  std::string input = "# comment\nnot a frame\n";
  Frame f;
  f.odom = PoseFromXYYaw(5.0, 5.0, 0.0);
  f.descriptors.assign(3, Descriptor256{});
  f.keypoints.assign(6, 1.0f);
  for (int i = 0; i < 5; ++i) {
    f.stamp_s = i;
    f.odom.translation().x() = 5.0 + 10.0 * i;  // one room per frame
    input += FormatFrameLine(f) + "\n";
  }
  input += "frame 1 2\n";
  REQUIRE(::write(fds[1], input.data(), input.size()) == static_cast<ssize_t>(input.size()));
  ::close(fds[1]);
  LineFrameSource source(fds[0], 16);
  auto db = MapDb::Open(s.db);
  REQUIRE(db.ok());
  auto loop = TickLoop::Create(Config("semantic", 2 * kKeyframesPerRoom), *db.value(), source);
  REQUIRE(loop.ok());
  int ticks = 0;
  while (loop.value()->Tick().value()) ++ticks;
  ::close(fds[0]);
  CHECK(ticks == 5);
  CHECK(source.malformed_lines() == 2);
  CHECK(loop.value()->last_record().zone == ZoneId{4});
  CHECK(loop.value()->totals().zone_loads == 5);
  CHECK(loop.value()->last_record().resident_keyframes <= 2 * kKeyframesPerRoom);
}

}  // namespace
}  // namespace zm
