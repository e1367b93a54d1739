// basic = RTAB-Map's retrieval/transfer: small examples worked out by hand from rules 1-12 of
// basic-baseline.md (transfer count and order, whole-second ages, immunization, retrieval
// limits, start-up overshoot).
#include "memory/basic_policy.h"

#include <doctest/doctest.h>

#include <algorithm>
#include <random>

#include "memory/memory_test_util.h"

namespace zm {
namespace {

using test::Harness;
using test::Ids;
using V = std::vector<std::int64_t>;

// Basic reading its long-term-memory nodes from the fake source (the harness's SourceLtmGraph).
Harness::GraphFactory Basic(BasicOptions o) {
  return [o](const MapIndex& index, LtmGraph& graph) {
    return std::make_unique<BasicPolicy>(index, o, &graph);
  };
}

BasicPolicy& Policy(Harness& h) { return *static_cast<BasicPolicy*>(h.policy.get()); }

TickContext Ctx(std::uint64_t tick, double now_s, double x, std::int64_t highest = 0,
                std::int64_t localized = 0) {
  TickContext c = test::At(tick, -1, {x, 0, 0}, now_s);
  c.highest_hypothesis = KeyframeId{highest};
  c.localized_on = KeyframeId{localized};
  return c;
}

test::MapSpec Spread(int n, double spacing) {
  test::MapSpec s;
  for (int i = 0; i < n; ++i) s.positions.emplace_back(spacing * i, 0, 0);
  return s;
}

TEST_CASE("basic: InitWMWithAllNodes with N > MemoryThr takes N - MemoryThr ticks to come down") {
  // 10 isolated nodes, 50 m apart, MemoryThr 6; the robot stays far from all of them.
  test::MapSpec s = Spread(10, 50);
  BasicOptions o;
  o.memory_thr = 6;
  o.init_wm_with_all_nodes = true;
  Harness h(s, 10, 6, Basic(o));
  auto t = h.Start(Ctx(0, 100.0, 1000));  // lastLoc = node 10 (nearest to x=1000)
  CHECK(t.keyframes_loaded == 10);
  CHECK(t.over_budget);
  CHECK(Policy(h).last_localization() == h.index.Find(KeyframeId{10}));
  int over_ticks = 0;
  std::vector<std::int64_t> order;
  for (std::uint64_t i = 1; i <= 8; ++i) {
    t = h.Tick(Ctx(i, 100.0 + static_cast<double>(i), 1000));
    over_ticks += t.over_budget ? 1 : 0;
    for (auto id : Ids(h.index, Policy(h).last_tick().transferred)) order.push_back(id);
    CHECK(t.keyframes_unloaded <= 1);  // never in bulk: retrieved (0) + 1 per tick
  }
  CHECK(over_ticks == 4);        // N - MemoryThr ticks above the threshold
  CHECK(order == V{1, 2, 3, 4});  // (weight, floor(age), id): equal ages, smallest id first
  CHECK(Policy(h).wm_size() == 6);
  CHECK(h.ws.resident_count() == 6);
}

TEST_CASE("basic: ages are truncated to whole seconds / ties broken by id") {
  // WM {1,2,3} chained 1-2-3, MemoryThr 2, node 4 in LTM (so not all nodes are in WM).
  test::MapSpec s = Spread(4, 20);
  s.links = {{1, 2, LinkKind::kNeighbor}, {2, 3, LinkKind::kNeighbor}, {3, 4, LinkKind::kNeighbor}};
  s.positions[3] = {500, 0, 0};
  BasicOptions o;
  o.memory_thr = 2;
  o.initial_wm = {KeyframeId{1}, KeyframeId{2}, KeyframeId{3}};
  SUBCASE("refreshed within the same second: id 1 still goes first") {
    Harness h(s, 4, 2, Basic(o));
    h.Start(Ctx(0, 100.0, 40));          // lastLoc = 3, L = {1,2,3}
    h.Tick(Ctx(1, 100.7, 0));            // near = {1}: age(1) = 100.7 -> 100
    CHECK(h.policy->name() == "basic");
    CHECK(Ids(h.index, Policy(h).last_tick().transferred) == V{1});
  }
  SUBCASE("refreshed in a later second: id 2 goes first") {
    Harness h(s, 4, 2, Basic(o));
    h.Start(Ctx(0, 100.0, 40));
    h.Tick(Ctx(1, 101.2, 0));            // age(1) = 101.2 -> 101 > 100
    CHECK(Ids(h.index, Policy(h).last_tick().transferred) == V{2});
  }
  SUBCASE("TransferSortingByWeightId ignores ages") {
    o.transfer_sorting_by_weight_id = true;
    Harness h(s, 4, 2, Basic(o));
    h.Start(Ctx(0, 100.0, 40));
    h.Tick(Ctx(1, 105.0, 0));
    CHECK(Ids(h.index, Policy(h).last_tick().transferred) == V{1});
  }
}

TEST_CASE("basic: weight orders the transfer before age") {
  test::MapSpec s = Spread(4, 50);
  s.weights = {3, 0, 1, 0};
  BasicOptions o;
  o.memory_thr = 1;
  o.init_wm_with_all_nodes = true;
  Harness h(s, 4, 1, Basic(o));
  h.Start(Ctx(0, 10.0, 150));  // lastLoc = 4 (x = 150)
  std::vector<std::int64_t> order;
  for (std::uint64_t i = 1; i <= 4; ++i) {
    h.Tick(Ctx(i, 10.0 + static_cast<double>(i), 1000));
    for (auto id : Ids(h.index, Policy(h).last_tick().transferred)) order.push_back(id);
  }
  CHECK(order == V{2, 3, 1});  // weights 0, 1, 3; node 4 is lastLoc (immunized)
  CHECK(Policy(h).wm_size() == 1);
}

// A chain 1-2-...-20, 15 m apart; WM starts as {1..5}, MemoryThr 5.
test::MapSpec Chain() {
  test::MapSpec s = Spread(20, 15);
  for (int i = 1; i < 20; ++i) s.links.emplace_back(i, i + 1, LinkKind::kNeighbor);
  return s;
}

TEST_CASE("basic: local and hypothesis retrieval / immunization / WM may stay above MemoryThr") {
  BasicOptions o;
  o.memory_thr = 5;
  for (int i = 1; i <= 5; ++i) o.initial_wm.push_back(KeyframeId{i});
  Harness h(Chain(), 20, 5, Basic(o));
  h.Start(Ctx(0, 0.0, 0));  // lastLoc = 1, L = {1..5}
  CHECK(Policy(h).local_map_size() == 5);
  // Robot at node 5 (x = 60), highest hypothesis 5, localized on 5.
  const std::uint64_t executed_before = h.source.queries;
  auto t = h.Tick(Ctx(1, 10.0, 60, 5, 5));
  const auto& r = Policy(h).last_tick();
  // Local: 5's LTM neighbour 6 (first pass; 6 read), then the one-hop expansion from 6 with
  // the limit 2 - 1 + 1 = 2 reads 6 and 7 and adds 7: local = [6, 7]. The time search from 5
  // reads 6 and 7 too; the load limit 2 + |local| = 4 takes the two not in WM.
  CHECK(r.local_retrieved == 2);
  CHECK(Ids(h.index, r.retrieved) == V{6, 7});
  CHECK(r.max_local_imm == 1);
  // Search statements: local 2 + 4, time 4, space 4 (2 per LTM node read).
  CHECK(r.search_queries == 14);
  CHECK(t.search_queries == 14);
  // One unit for loads and searches: 4 statements per loaded node (row, payload, links,
  // calibration) + the searches' 14, each statement its own (autocommit) transaction.
  CHECK(t.db_queries == 8 + 14);
  CHECK(t.db_transactions == 8 + 14);
  CHECK(t.search_transactions == 14);
  CHECK(h.source.queries - executed_before == 8 + 14);  // what the fake database executed
  // Everything in WM was immunized (time search + local + retrieved + lastLoc): nothing to
  // transfer although |WM| = 7 > 5.
  CHECK(r.transferred.empty());
  CHECK(Policy(h).wm_size() == 7);
  CHECK(t.over_budget);
  CHECK(Policy(h).local_map_size() == 7);  // localized and retrieved: L = WM component of 5
  // Then the robot leaves: one node per tick, oldest whole-second age first (1..4 at 0 s).
  t = h.Tick(Ctx(2, 20.0, 1000));
  CHECK(Ids(h.index, Policy(h).last_tick().transferred) == V{1});
  t = h.Tick(Ctx(3, 21.0, 1000));
  CHECK(Ids(h.index, Policy(h).last_tick().transferred) == V{2});
  t = h.Tick(Ctx(4, 22.0, 1000));
  CHECK(Policy(h).last_tick().transferred.empty());
  CHECK(h.ResidentIds() == V{3, 4, 5, 6, 7});
  CHECK_FALSE(t.over_budget);
}

TEST_CASE("basic: at most MaxRetrieved + |local| loaded per tick") {
  // 1 (WM, at x=0) has LTM neighbours 2, 3, 4. 10 (WM, far) has LTM neighbours 11, 12 and a
  // loop closure to LTM node 13.
  test::MapSpec s;
  for (int i = 1; i <= 13; ++i) s.positions.emplace_back(i == 1 ? 0.0 : 500.0 + i, 0, 0);
  s.links = {{1, 2, LinkKind::kNeighbor},  {1, 3, LinkKind::kNeighbor},
             {1, 4, LinkKind::kNeighbor},  {10, 11, LinkKind::kNeighbor},
             {10, 12, LinkKind::kNeighbor}, {10, 13, LinkKind::kGlobalClosure}};
  BasicOptions o;
  o.memory_thr = 100;
  o.initial_wm = {KeyframeId{1}, KeyframeId{10}};
  Harness h(s, 13, 100, Basic(o));
  h.Start(Ctx(0, 0.0, 0));
  auto t = h.Tick(Ctx(1, 1.0, 0, /*highest=*/10));
  const auto& r = Policy(h).last_tick();
  // local = [4, 3] (descending id, quota 2); time search from 10 = [12, 11]; the space search
  // adds 13, which the limit 2 + 2 = 4 leaves in LTM.
  CHECK(r.local_retrieved == 2);
  CHECK(Ids(h.index, r.retrieved) == V{4, 3, 12, 11});
  CHECK(t.keyframes_loaded == 4);
  CHECK(r.search_queries == 12);
  CHECK_FALSE(h.ws.IsResident(h.index.Find(KeyframeId{13})));
  // Retrieved nodes become candidates from the next tick: they are resident now.
  CHECK(h.ResidentIds() == V{1, 3, 4, 10, 11, 12});
}

TEST_CASE("basic: small displacement reuses the previous highest hypothesis") {
  BasicOptions o;
  o.memory_thr = 50;
  o.initial_wm = {KeyframeId{10}};
  Harness h(Chain(), 20, 50, Basic(o));
  h.Start(Ctx(0, 0.0, 135));  // node 10 at x = 135
  h.Tick(Ctx(1, 1.0, 1000, 10, 10));  // retrieves 11 and 9 around 10
  CHECK(Ids(h.index, Policy(h).last_tick().retrieved) == V{11, 9});
  TickContext c = Ctx(2, 2.0, 1000, 0, 0);
  c.small_displacement = true;  // no detection ran: the last hypothesis (10) is reused
  h.Tick(c);
  CHECK(Ids(h.index, Policy(h).last_tick().retrieved) == V{12, 8});
}

TEST_CASE("basic: memory management off and everything in WM means no retrieval") {
  BasicOptions o;
  o.memory_thr = 0;
  o.init_wm_with_all_nodes = true;
  Harness h(Chain(), 20, 20, Basic(o));
  h.Start(Ctx(0, 0.0, 0));
  auto t = h.Tick(Ctx(1, 1.0, 0, 3, 3));
  CHECK(t.search_queries == 0);
  CHECK(t.keyframes_loaded == 0);
  CHECK(t.keyframes_unloaded == 0);
}


TEST_CASE("basic: the second local pass admits MaxLocalRetrieved - |local| + 1 LTM nodes") {
  // A chain 1-2-3-4, 50 m apart; WM = {1}; the robot stays at node 1; no hypothesis.
  // First pass, from 1 (WM): its LTM neighbour 2 joins local (2 read: 2 statements).
  // Second pass, from 2 (LTM): the search reads 2 itself, which counts against its limit, so
  // RTAB-Map asks for _maxLocalRetrieved - |local| + 1 = 2 - 1 + 1 = 2 (Rtabmap.cpp, RETRIEVAL
  // 2/3): 2 and then 3 are read (4 statements) and 3 joins local. With 2 - 1 = 1 the search
  // would stop at 2 itself: local = [2], 1 node retrieved, 4 statements.
  test::MapSpec s = Spread(4, 50);
  s.links = {{1, 2, LinkKind::kNeighbor}, {2, 3, LinkKind::kNeighbor}, {3, 4, LinkKind::kNeighbor}};
  BasicOptions o;
  o.memory_thr = 10;
  o.initial_wm = {KeyframeId{1}};
  Harness h(s, 4, 10, Basic(o));
  h.Start(Ctx(0, 0.0, 0));
  const auto t = h.Tick(Ctx(1, 1.0, 0));
  const auto& r = Policy(h).last_tick();
  CHECK(r.local_retrieved == 2);
  CHECK(Ids(h.index, r.retrieved) == V{2, 3});  // load limit MaxRetrieved + |local| = 4
  CHECK(t.search_queries == 2 + 4);
  CHECK(t.search_transactions == 2 + 4);
  CHECK(t.db_queries == 2 + 4 + 2 * 4);  // + 4 statements per loaded node
  CHECK(h.ResidentIds() == V{1, 2, 3});
}

// A long random run on a building-like map (rooms of 12 keyframes chained by neighbour links,
// loop closures between rooms), random hypotheses, localized now and then. The digest covers
// every tick's retrieved and transferred ids and its graph-search statements: it pins basic's
// decisions and accounting, so a refactor that changes neither keeps it. (Pinned on main's basic,
// kept by moving the searches onto the database, re-pinned by the + 1 of the second local pass:
// retrieved 1,201 -> 1,157, search statements 4,500 -> 4,304 over the 600 ticks.)
struct RunDigest {
  std::uint64_t digest = 1469598103934665603ULL;  // FNV-1a
  std::uint64_t retrieved = 0, transferred = 0, search_statements = 0;
};

RunDigest RandomRun() {
  test::MapSpec s;
  std::mt19937 rng(11);
  for (int room = 0; room < 8; ++room) {
    for (int i = 0; i < 12; ++i) {
      s.positions.emplace_back(25.0 * room + 2.0 * (i % 4), 2.0 * (i / 4), 0.0);
      const auto id = static_cast<std::int64_t>(s.positions.size());
      if (id > 1) s.links.emplace_back(id - 1, id, LinkKind::kNeighbor);
    }
  }
  const auto n = static_cast<std::int64_t>(s.positions.size());
  for (int i = 0; i < 20; ++i) {
    const std::int64_t a = 1 + static_cast<std::int64_t>(rng() % static_cast<unsigned>(n));
    const std::int64_t b = 1 + static_cast<std::int64_t>(rng() % static_cast<unsigned>(n));
    if (a != b) s.links.emplace_back(a, b, i % 3 == 0 ? LinkKind::kLocalSpaceClosure : LinkKind::kGlobalClosure);
  }
  BasicOptions o;
  o.memory_thr = 20;
  for (int i = 1; i <= 20; ++i) o.initial_wm.push_back(KeyframeId{i});
  Harness h(s, static_cast<std::uint32_t>(n), 20, Basic(o));
  h.verify_slots = false;
  RunDigest d;
  auto mix = [&](std::uint64_t v) { d.digest = (d.digest ^ v) * 1099511628211ULL; };
  h.Start(Ctx(0, 0.0, 0.0));
  double x = 0.0;
  for (std::uint64_t t = 1; t <= 600; ++t) {
    x = std::clamp(x + static_cast<double>(static_cast<int>(rng() % 7) - 3), 0.0, 185.0);
    std::int64_t highest = 0;
    if (rng() % 4 != 0 && !h.ws.resident().empty()) {
      highest = h.ws.resident()[rng() % h.ws.resident().size()].id.value;
    }
    const std::int64_t localized = rng() % 3 == 0 ? highest : 0;
    TickContext c = Ctx(t, 0.5 * static_cast<double>(t), x, highest, localized);
    c.small_displacement = rng() % 5 == 0;
    const auto tel = h.Tick(c);
    const auto& r = Policy(h).last_tick();
    mix(t);
    for (auto id : Ids(h.index, r.retrieved)) mix(static_cast<std::uint64_t>(id));
    mix(0xFFFF);
    for (auto id : Ids(h.index, r.transferred)) mix(static_cast<std::uint64_t>(id));
    mix(0xFFFE);
    mix(tel.search_queries);
    d.retrieved += r.retrieved.size();
    d.transferred += r.transferred.size();
    d.search_statements += tel.search_queries;
  }
  return d;
}

TEST_CASE("basic: decisions and search statements of a long random run are pinned") {
  const RunDigest d = RandomRun();
  MESSAGE("retrieved " << d.retrieved << ", transferred " << d.transferred << ", search statements "
                       << d.search_statements);
  CHECK(d.retrieved > 300);  // the run exercises retrieval, transfer and the searches
  CHECK(d.transferred > 300);
  CHECK(d.search_statements > 1000);
  CHECK(d.digest == 3741518236155812713ULL);
}

}  // namespace
}  // namespace zm
