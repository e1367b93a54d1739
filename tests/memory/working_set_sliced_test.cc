// WorkingSet with time-sliced loads (issue 14 §2): a slice keeps its budget (keyframes, bytes,
// deadline, interrupt) and always makes its minimum progress; only complete keyframes are
// resident, so a zone being loaded is usable keyframe by keyframe; a newer zone preempts an
// unfinished load, which resumes later without re-reading; evicting a zone mid-load cancels its
// queued keyframes; an error drops its own batch only; and every zone policy keeps resident <=
// K_max and its own bookkeeping when loads lag behind its plans.
#include <doctest/doctest.h>

#include <random>
#include <thread>

#include "memory/memory_test_util.h"
#include "memory/predictive_policy.h"
#include "memory/radius_policy.h"
#include "memory/semantic_policy.h"
#include "memory/working_set.h"

namespace zm {
namespace {

using V = std::vector<std::int64_t>;
using Clock = std::chrono::steady_clock;

struct SlicedRig {
  SlicedRig(const test::MapSpec& s, std::uint32_t slots, std::uint32_t k_max)
      : index(test::BuildIndex(s)),
        arena(test::MakeArena(slots)),
        source(test::ZoneIds(s), 100),
        ws(index, arena, source, k_max, /*sliced=*/true),
        plan(index) {}
  KfIndex K(std::int64_t id) const { return index.Find(KeyframeId{id}); }
  void Batch(ZoneId zone, std::initializer_list<std::int64_t> ids) {
    plan.BeginBatch(zone);
    for (std::int64_t id : ids) plan.Acquire(K(id));
  }
  TickTelemetry Apply() {
    TickTelemetry t;
    const Status s = ws.Apply(plan, &t);
    REQUIRE_MESSAGE(s.ok(), s.ToString());
    plan.Clear();
    return t;
  }
  TickTelemetry Step(const LoadSlice& slice) {
    TickTelemetry t;
    const Status s = ws.StepLoads(slice, &t);
    REQUIRE_MESSAGE(s.ok(), s.ToString());
    return t;
  }
  V Resident() const {
    V out;
    for (const auto& r : ws.resident()) {
      CHECK(test::FakeKeyframeSource::SlotHolds(arena, r.slot, r.id));  // complete, its own bytes
      out.push_back(r.id.value);
    }
    std::sort(out.begin(), out.end());
    return out;
  }
  MapIndex index;
  Arena arena;
  test::FakeKeyframeSource source;
  WorkingSet ws;
  Plan plan;
};

LoadSlice Keyframes(std::uint32_t n) {
  LoadSlice s;
  s.max_keyframes = n;
  return s;
}

TEST_CASE("sliced: Apply only queues / a slice keeps its keyframe, byte and time budgets") {
  SlicedRig r(test::LineMap({10}), 10, 10);
  r.Batch(ZoneId{0}, {1, 2, 3, 4, 5, 6, 7, 8, 9, 10});
  TickTelemetry t = r.Apply();
  CHECK(t.keyframes_loaded == 0);
  CHECK(t.pending_keyframes == 10);
  CHECK(r.source.begin_calls == 0);  // nothing read inside the tick's Apply
  CHECK(r.ws.loading_zone() == ZoneId{0});

  t = r.Step(Keyframes(3));
  CHECK(t.keyframes_loaded == 3);
  CHECK(t.db_transactions == 1);
  CHECK(t.pending_keyframes == 7);
  CHECK(r.source.transaction_open());  // one read transaction held across the steps
  // Usable keyframe by keyframe: exactly the delivered ones are resident, each complete.
  CHECK(r.Resident() == V{1, 2, 3});
  CHECK(r.ws.IsPending(r.K(4)));
  CHECK_FALSE(r.ws.IsResident(r.K(4)));
  CHECK(r.ws.refcount(r.K(4)) == 1);

  // Bytes: a keyframe counts as a whole slot (128 bytes) until it lands, so 300 bytes = 2.
  LoadSlice bytes;
  bytes.max_bytes = 300;
  t = r.Step(bytes);
  CHECK(t.keyframes_loaded == 2);
  CHECK(t.db_transactions == 0);  // the same transaction
  bytes.max_bytes = 0;
  CHECK(r.Step(bytes).keyframes_loaded == 0);
  bytes.min_keyframes = 1;  // progress whatever the budget
  CHECK(r.Step(bytes).keyframes_loaded == 1);

  // A deadline already past: nothing starts, unless the slice must make progress.
  LoadSlice late;
  late.deadline = Clock::now() - std::chrono::seconds(1);
  CHECK(r.Step(late).keyframes_loaded == 0);
  late.min_keyframes = 2;
  CHECK(r.Step(late).keyframes_loaded == 2);
  CHECK(r.ws.pending_count() == 2);
  CHECK(r.ws.keyframe_ms_estimate() >= 0.0);

  t = r.Step(LoadSlice{});
  CHECK(t.keyframes_loaded == 2);
  CHECK_FALSE(r.ws.loading());
  CHECK_FALSE(r.source.transaction_open());
  CHECK(r.source.begin_calls == 1);
  CHECK(r.source.aborts == 0);
  CHECK(r.Resident() == V{1, 2, 3, 4, 5, 6, 7, 8, 9, 10});
}

// Forwards to the fake and makes every keyframe of a zone step take at least `delay`, as a
// keyframe decoded into its slot does (milliseconds, not microseconds).
class SlowSource final : public KeyframeSource {
 public:
  SlowSource(test::FakeKeyframeSource& inner, std::chrono::milliseconds delay)
      : inner_(inner), delay_(delay) {}
  Result<LoadStats> LoadZone(ZoneId z, Arena& a, LoadSink& s) override {
    return inner_.LoadZone(z, a, s);
  }
  Result<LoadStats> LoadKeyframes(std::span<const KeyframeId> ids, Arena& a, LoadSink& s) override {
    return inner_.LoadKeyframes(ids, a, s);
  }
  Result<LoadStats> BeginZoneLoad(ZoneId z, Arena& a, LoadSink& s) override {
    return inner_.BeginZoneLoad(z, a, s);
  }
  Result<ZoneLoadStep> StepZoneLoad(const LoadBudget& budget) override {
    std::this_thread::sleep_for(delay_);
    return inner_.StepZoneLoad(budget);
  }
  void AbortZoneLoad() override { inner_.AbortZoneLoad(); }
  [[nodiscard]] ZoneId ZoneLoadInFlight() const override { return inner_.ZoneLoadInFlight(); }
  Result<LoadStats> ReadGraphNodes(std::span<const KeyframeId> ids, GraphNodeSink* s) override {
    return inner_.ReadGraphNodes(ids, s);
  }

 private:
  test::FakeKeyframeSource& inner_;
  std::chrono::milliseconds delay_;
};

TEST_CASE(
    "sliced: the clock is read between keyframes / a slow keyframe keeps the next from "
    "starting past the deadline") {
  const test::MapSpec spec = test::LineMap({6});
  const MapIndex index = test::BuildIndex(spec);
  Arena arena = test::MakeArena(6);
  test::FakeKeyframeSource fake(test::ZoneIds(spec), 100);
  SlowSource slow(fake, std::chrono::milliseconds(20));
  WorkingSet ws(index, arena, slow, 6, /*sliced=*/true);
  Plan plan(index);
  plan.BeginBatch(ZoneId{0});
  for (KfIndex k = 0; k < 6; ++k) plan.Acquire(k);
  TickTelemetry t;
  REQUIRE(ws.Apply(plan, &t).ok());
  CHECK(ws.keyframe_ms_estimate() == 0.0);  // nothing measured yet
  LoadSlice first;
  first.max_keyframes = 1;
  REQUIRE(ws.StepLoads(first, &t).ok());
  CHECK(ws.keyframe_ms_estimate() >= 20.0);  // what that keyframe really took
  // 10 ms left: the next keyframe is expected to take >= 20 ms, so it does not start...
  LoadSlice tight;
  tight.deadline = Clock::now() + std::chrono::milliseconds(10);
  t = {};
  REQUIRE(ws.StepLoads(tight, &t).ok());
  CHECK(t.keyframes_loaded == 0);
  // ... whatever the byte budget says, which would let every one of them start.
  tight.max_bytes = 1ull << 40;
  REQUIRE(ws.StepLoads(tight, &t).ok());
  CHECK(t.keyframes_loaded == 0);
  CHECK(ws.pending_count() == 5);
  REQUIRE(ws.StepLoads(LoadSlice{}, &t).ok());
  CHECK(ws.pending_count() == 0);
}

TEST_CASE("sliced: an interrupt (a frame waiting) ends the slice between two keyframes") {
  struct StopAfter final : SliceInterrupt {
    int polls = 0;
    int allowed = 0;
    bool ShouldStop() override { return ++polls > allowed; }
  };
  SlicedRig r(test::LineMap({6}), 6, 6);
  r.Batch(ZoneId{0}, {1, 2, 3, 4, 5, 6});
  r.Apply();
  StopAfter stop;
  stop.allowed = 2;
  LoadSlice s;
  s.interrupt = &stop;
  CHECK(r.Step(s).keyframes_loaded == 2);
  CHECK(stop.polls == 3);  // polled before each keyframe
  stop.polls = 0;
  stop.allowed = 0;
  CHECK(r.Step(s).keyframes_loaded == 0);
  CHECK(r.Resident() == V{1, 2});
}

TEST_CASE("sliced: a newer zone preempts an unfinished load, which resumes without re-reading") {
  SlicedRig r(test::LineMap({6, 6}), 12, 12);
  r.Batch(ZoneId{0}, {1, 2, 3, 4, 5, 6});
  r.Apply();
  r.Step(Keyframes(2));
  r.Batch(ZoneId{1}, {7, 8, 9, 10, 11, 12});
  r.Apply();
  CHECK(r.ws.loading_zone() == ZoneId{1});  // the newest batch first
  TickTelemetry t = r.Step(Keyframes(3));
  CHECK(t.loads_preempted == 1);
  CHECK(r.source.aborts == 1);  // zone 0's transaction ended
  CHECK(t.db_transactions == 1);
  CHECK(r.Resident() == V{1, 2, 7, 8, 9});
  t = r.Step(LoadSlice{});
  CHECK(t.keyframes_loaded == 7);
  CHECK(r.source.begin_calls == 3);  // zone 0, zone 1, zone 0 again: a new transaction
  REQUIRE(r.source.calls.size() == 3);
  CHECK(r.source.calls.back().zone == ZoneId{0});
  CHECK(test::Ids(r.source.calls.back().loaded) == V{3, 4, 5, 6});  // 1 and 2 not re-read
  CHECK(r.source.keyframes_loaded == 12);
  CHECK(r.ws.max_resident_seen() == 12);
}

TEST_CASE("sliced: evicting a zone mid-load cancels its queue and frees its slots first") {
  SlicedRig r(test::LineMap({6, 6}), 6, 6);
  r.Batch(ZoneId{0}, {1, 2, 3, 4, 5, 6});
  r.Apply();
  r.Step(Keyframes(2));
  for (std::int64_t id = 1; id <= 6; ++id) r.plan.Release(r.K(id));
  r.Batch(ZoneId{1}, {7, 8, 9, 10, 11, 12});
  TickTelemetry t = r.Apply();
  CHECK(t.keyframes_unloaded == 2);
  CHECK(t.keyframes_cancelled == 4);
  CHECK(t.pending_keyframes == 6);
  CHECK(r.source.aborts == 1);  // nothing of zone 0 is wanted any more: its load ends at once
  CHECK_FALSE(r.source.transaction_open());
  CHECK(r.arena.in_use() == 0);
  r.Step(LoadSlice{});
  CHECK(r.Resident() == V{7, 8, 9, 10, 11, 12});
  CHECK(r.ws.max_resident_seen() <= 6);
  CHECK(r.arena.stats().refused == 0);
  CHECK(r.ws.refcount(r.K(3)) == 0);
}

TEST_CASE("sliced: an error drops its own batch, the rest of the queue still loads") {
  SlicedRig r(test::LineMap({5, 5}), 10, 10);
  r.source.fail_on = KeyframeId{3};
  r.Batch(ZoneId{0}, {1, 2, 3, 4, 5});
  r.Batch(ZoneId{1}, {6, 7, 8, 9, 10});
  r.Apply();
  TickTelemetry t;
  const Status st = r.ws.StepLoads(Keyframes(100), &t);
  CHECK(st.code() == StatusCode::kCorrupt);
  CHECK(st.message().find("loading zone 0") != std::string::npos);
  CHECK(t.keyframes_loaded == 2);
  CHECK(r.Resident() == V{1, 2});  // delivered before the error: kept
  CHECK(r.ws.refcount(r.K(4)) == 0);
  CHECK_FALSE(r.ws.IsPending(r.K(4)));
  CHECK_FALSE(r.source.transaction_open());
  CHECK(r.arena.in_use() == 2);  // the failing keyframe's slot went back
  CHECK(r.ws.loading_zone() == ZoneId{1});
  r.Step(LoadSlice{});
  CHECK(r.Resident() == V{1, 2, 6, 7, 8, 9, 10});
  CHECK(r.ws.pending_count() == 0);
}

TEST_CASE("sliced: a keyframe batch loads one keyframe a call, in plan order") {
  SlicedRig r(test::LineMap({4}), 4, 4);
  r.Batch(kNoZone, {4, 1, 3});
  r.Apply();
  const TickTelemetry t = r.Step(Keyframes(2));
  CHECK(t.keyframes_loaded == 2);
  CHECK(t.db_transactions == 8);  // RTAB-Map's 4 autocommit statements per keyframe
  REQUIRE(r.source.calls.size() == 2);
  CHECK(test::Ids(r.source.calls[0].loaded) == V{4});
  CHECK(test::Ids(r.source.calls[1].loaded) == V{1});
  r.Step(LoadSlice{});
  CHECK(r.Resident() == V{1, 3, 4});
}

TEST_CASE("sliced: a keyframe shared by two queued zones is read once, by whichever comes first") {
  test::MapSpec s;
  for (int i = 0; i < 4; ++i) s.positions.emplace_back(i, 0, 0);
  s.zones = {{1, 2, 3}, {2, 3, 4}};
  SlicedRig r(s, 4, 4);
  r.Batch(ZoneId{1}, {2, 3});
  r.Apply();
  r.Batch(ZoneId{0}, {1, 2, 3});  // 2 and 3 are queued already: only 1 is new
  r.Apply();
  r.Step(LoadSlice{});
  CHECK(r.Resident() == V{1, 2, 3});
  CHECK(r.source.begin_calls == 1);  // zone 0's load delivered 2 and 3: zone 1 needed none
  CHECK(r.source.keyframes_loaded == 3);
}

TEST_CASE("sliced property: every zone policy / loads behind its plans / never above K_max") {
  std::mt19937 rng(14);
  for (const char* name : {"semantic", "predictive", "oracle", "radius"}) {
    CAPTURE(name);
    for (int trial = 0; trial < 12; ++trial) {
      const int zones = 3 + static_cast<int>(rng() % 6);
      const int n = 12 + static_cast<int>(rng() % 50);
      test::MapSpec s;
      for (int i = 0; i < n; ++i) s.positions.emplace_back(rng() % 60, rng() % 60, 0);
      s.zones.resize(static_cast<std::size_t>(zones));
      for (int i = 1; i <= n; ++i) {
        const int copies = 1 + static_cast<int>(rng() % 2);  // overlaps
        for (int c = 0; c < copies; ++c) s.zones[rng() % s.zones.size()].push_back(i);
      }
      for (auto& z : s.zones) {
        std::sort(z.begin(), z.end());
        z.erase(std::unique(z.begin(), z.end()), z.end());
      }
      s.adjacency.resize(static_cast<std::size_t>(zones));
      for (int z = 0; z + 1 < zones; ++z)
        s.adjacency[static_cast<std::size_t>(z)].push_back(ZoneId{z + 1});
      std::vector<int> walk;
      for (int i = 0; i < 80; ++i)
        walk.push_back(static_cast<int>(rng() % static_cast<std::uint32_t>(zones + 1)) - 1);
      std::vector<ZoneId> future;
      for (int w : walk) future.push_back(w < 0 ? kNoZone : ZoneId{w});
      const auto k_max = static_cast<std::uint32_t>(1 + rng() % static_cast<std::uint32_t>(n));
      PolicyOptions o;
      o.kind = *ParsePolicyKind(name);
      o.k_max = k_max;
      o.oracle.future = future;
      o.radius.tile_m = 10;
      o.radius.map_radius_m = 15;
      o.radius.update_distance_m = 5;
      test::Harness h(
          s, k_max, k_max,
          [&](const MapIndex& index) {
            auto p = MakePolicy(index, o);
            REQUIRE(p.ok());
            return std::move(p).value();
          },
          /*sliced=*/true);
      const auto held_by_policy = [&](KfIndex k) -> std::uint32_t {
        if (const auto* p = dynamic_cast<const SemanticPolicy*>(h.policy.get()))
          return p->residency().held(k);
        if (const auto* p = dynamic_cast<const PredictivePolicy*>(h.policy.get()))
          return p->residency().held(k);
        return h.ws.refcount(k);  // radius: 0/1 flags, checked through the totals below
      };
      const auto check = [&] {
        REQUIRE(h.ws.max_resident_seen() <= k_max);
        REQUIRE(h.arena.stats().refused == 0);
        std::uint32_t held = 0;
        for (KfIndex k = 0; k < h.index.keyframe_count(); ++k) {
          REQUIRE(h.ws.refcount(k) == held_by_policy(k));
          if (h.ws.refcount(k) > 0) ++held;
          REQUIRE_FALSE((h.ws.IsPending(k) && h.ws.IsResident(k)));
        }
        REQUIRE(h.ws.resident_count() + h.ws.pending_count() == held);
        REQUIRE(held <= k_max);
        if (const auto* p = dynamic_cast<const RadiusPolicy*>(h.policy.get()))
          REQUIRE(p->resident() == held);
      };
      auto pos = [&](int zone) {
        const auto members = h.index.ZoneMembers(ZoneId{std::max(zone, 0)});
        return members.empty() ? Eigen::Vector3d::Zero()
                               : h.index.position(members[rng() % members.size()]);
      };
      h.Start(test::At(0, walk[0], pos(walk[0])));
      check();
      for (std::size_t i = 1; i < walk.size(); ++i) {
        h.Tick(test::At(i, walk[i], pos(walk[i])));
        check();
        // Loads lag: zero to three keyframes between two plans, sometimes the robot's zone only.
        LoadSlice slice = Keyframes(static_cast<std::uint32_t>(rng() % 4));
        if (rng() % 3 == 0) h.ws.Prioritize(walk[i] < 0 ? kNoZone : ZoneId{walk[i]});
        h.Step(slice);
        check();
      }
      h.Drain();
      check();
      CHECK(h.ws.pending_count() == 0);
    }
  }
}

}  // namespace
}  // namespace zm
