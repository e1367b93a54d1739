// Decision time per tick of every memory policy against map size (100 to 100,000 keyframes),
// excluding I/O: only the policy's PlanBeforeLocalize/PlanAfterLocalize run (policies keep their
// own residency state, so no WorkingSet, arena or database is involved).
//
// Synthetic building: rooms of 50 keyframes (2 m grid) on a square grid of rooms 20 m apart,
// each room a zone, rooms adjacent on the grid; keyframes chained by neighbour links, with a
// loop closure every 10th keyframe. The robot follows the mapping trajectory (keyframe order):
//   stride 1  = one keyframe per tick, a zone change every 50 ticks (steady state);
//   stride 50 = a zone change on every tick (the worst case for the zone policies).
// K_max = 400 keyframes (8 zones) for every bounded policy and MemoryThr for basic.
//
//   build/host-release/bench/zm_policy_bench --benchmark_min_time=0.2
//   (Debian 12's Google Benchmark 1.7.1 takes seconds as a plain number; "0.2s" is 1.8's form.)
#include <benchmark/benchmark.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <vector>

#include "memory/basic_policy.h"
#include "memory/map_index.h"
#include "memory/plan.h"
#include "memory/policy.h"

namespace {

constexpr int kZoneSize = 50;
constexpr std::uint32_t kKMax = 400;
constexpr std::size_t kFutureTicks = 400000;

struct World {
  zm::MapIndex index;
  std::vector<zm::ZoneId> zone_of;  // per keyframe index
};

World MakeWorld(int n) {
  const int zones = (n + kZoneSize - 1) / kZoneSize;
  const int cols = std::max(1, static_cast<int>(std::ceil(std::sqrt(zones))));
  std::vector<zm::KeyframeMeta> kfs(static_cast<std::size_t>(n));
  std::vector<zm::ZoneMember> members;
  std::vector<zm::LinkRecord> links;
  for (int i = 0; i < n; ++i) {
    const int z = i / kZoneSize, j = i % kZoneSize;
    const int row = z / cols;
    const int col = row % 2 == 0 ? z % cols : cols - 1 - z % cols;  // snake: consecutive rooms adjacent
    auto& k = kfs[static_cast<std::size_t>(i)];
    k.id = zm::KeyframeId{i + 1};
    k.pose = zm::PoseFromXYYaw(20.0 * col + 2.0 * (j % 7), 20.0 * row + 2.0 * (j / 7), 0.0);
    k.payload_bytes = 16384;
    members.push_back({zm::ZoneId{z}, k.id});
    if (i > 0) links.push_back({zm::KeyframeId{i}, k.id, zm::LinkKind::kNeighbor, {}, {}});
    if (i >= 7 && i % 10 == 0) {
      links.push_back({zm::KeyframeId{i - 6}, k.id, zm::LinkKind::kGlobalClosure, {}, {}});
    }
  }
  std::vector<std::vector<zm::ZoneId>> adj(static_cast<std::size_t>(zones));
  for (int z = 0; z + 1 < zones; ++z) adj[static_cast<std::size_t>(z)].push_back(zm::ZoneId{z + 1});
  for (int z = 0; z + 2 * cols - 1 < zones; z += 2 * cols) {  // a few cross links between rows
    adj[static_cast<std::size_t>(z)].push_back(zm::ZoneId{z + 2 * cols - 1});
  }
  zm::MapIndexInput in;
  in.keyframes = kfs;
  in.links = links;
  in.members = members;
  in.zone_count = zones;
  in.zone_adjacency = adj;
  auto built = zm::MapIndex::Build(in);
  if (!built.ok()) {
    std::fprintf(stderr, "%s\n", built.status().ToString().c_str());
    std::abort();
  }
  World w{std::move(built).value(), {}};
  for (int i = 0; i < n; ++i) w.zone_of.push_back(zm::ZoneId{i / kZoneSize});
  return w;
}

void BM_Policy(benchmark::State& state, const char* policy) {
  const int n = static_cast<int>(state.range(0));
  const auto stride = static_cast<std::uint32_t>(state.range(1));
  const World w = MakeWorld(n);
  const std::uint32_t count = w.index.keyframe_count();
  auto kf_at = [&](std::uint64_t tick) {
    return static_cast<zm::KfIndex>((tick * stride + tick / count) % count);
  };
  zm::PolicyOptions o;
  o.kind = *zm::ParsePolicyKind(policy);
  o.k_max = kKMax;
  for (std::uint64_t t = 0; t < kFutureTicks; ++t) o.oracle.future.push_back(w.zone_of[kf_at(t)]);
  for (zm::KfIndex k = 0; k < std::min<std::uint32_t>(kKMax, count); ++k) {
    o.basic.initial_wm.push_back(w.index.id(k));
  }
  auto made = zm::MakePolicy(w.index, o);
  if (!made.ok()) {
    state.SkipWithError(made.status().ToString().c_str());
    return;
  }
  auto& p = **made;
  zm::Plan plan(w.index);
  zm::TickContext ctx;
  ctx.pose = zm::Pose3::Identity();
  ctx.pose.translation() = w.index.position(0);
  ctx.zone = w.zone_of[0];
  p.Start(ctx, &plan);
  std::uint64_t tick = 1;
  std::uint64_t moved = 0;
  // basic only: WM size after retrieval (before its transfer) against MemoryThr.
  const auto* basic = dynamic_cast<const zm::BasicPolicy*>(&p);
  std::uint64_t over_ticks = 0, over_sum = 0, ticks = 0;
  std::uint32_t peak_wm = 0;
  for (auto _ : state) {
    const zm::KfIndex k = kf_at(tick);
    ctx.tick = tick;
    ctx.now_s = static_cast<double>(tick);
    ctx.pose.translation() = w.index.position(k);
    ctx.zone = w.zone_of[k];
    ctx.highest_hypothesis = w.index.id(k);
    ctx.localized_on = w.index.id(k);
    plan.Clear();
    p.PlanBeforeLocalize(ctx, &plan);
    moved += plan.acquires().size() + plan.releases().size();
    plan.Clear();
    p.PlanAfterLocalize(ctx, &plan);
    moved += plan.acquires().size() + plan.releases().size();
    benchmark::DoNotOptimize(plan);
    if (basic != nullptr) {
      const auto wm = basic->wm_size() + static_cast<std::uint32_t>(basic->last_tick().transferred.size());
      peak_wm = std::max(peak_wm, wm);
      if (wm > kKMax) {
        ++over_ticks;
        over_sum += wm - kKMax;
      }
    }
    ++ticks;
    ++tick;
  }
  if (basic != nullptr) {
    state.counters["wm_peak"] = peak_wm;
    state.counters["over_thr_frac"] = static_cast<double>(over_ticks) / static_cast<double>(ticks);
    state.counters["over_thr_mean"] =
        over_ticks == 0 ? 0.0 : static_cast<double>(over_sum) / static_cast<double>(over_ticks);
  }
  state.counters["refs_per_tick"] =
      benchmark::Counter(static_cast<double>(moved), benchmark::Counter::kAvgIterations);
}

void Sizes(benchmark::internal::Benchmark* b) {
  for (int stride : {1, 50}) {
    for (int n : {100, 1000, 10000, 100000}) b->Args({n, stride});
  }
  b->ArgNames({"keyframes", "stride"})->Unit(benchmark::kMicrosecond);
}

BENCHMARK_CAPTURE(BM_Policy, semantic, "semantic")->Apply(Sizes);
BENCHMARK_CAPTURE(BM_Policy, predictive, "predictive")->Apply(Sizes);
BENCHMARK_CAPTURE(BM_Policy, oracle, "oracle")->Apply(Sizes);
BENCHMARK_CAPTURE(BM_Policy, radius, "radius")->Apply(Sizes);
BENCHMARK_CAPTURE(BM_Policy, basic, "basic")->Apply(Sizes);
BENCHMARK_CAPTURE(BM_Policy, unbounded, "unbounded")->Apply(Sizes);

}  // namespace

BENCHMARK_MAIN();
