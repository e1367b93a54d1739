// What a ZoneManager tick costs a host, through the public API only (zonemap/zonemap.h): one
// Update (zone of the pose, the policy's plan, the net answer) and one AfterLocalization per
// iteration, as a host calls them, with the answer's ids read as a host reads them. Set beside
// zm_policy_bench (the same building, walk and K_max, the policy alone) it gives the facade's own
// cost: zone lookup, pose conversion, reference counts, the answer.
//
// Synthetic building (zm_policy_bench's): rooms of 50 keyframes on a 2 m grid, rooms 20 m apart
// on a square grid in snake order, each room a zone; neighbour links, a closure every 10th
// keyframe. The host walks the mapping trajectory:
//   stride 1  = one keyframe per tick, a zone change every 50 ticks (steady state);
//   stride 50 = a zone change on every tick (the zone policies' worst case).
// K_max = 400 keyframes (8 rooms). Zones reach the manager three ways (`zones`):
//   0 host     the host passes its zone in TickInput::zone (no lookup);
//   1 nearest  memberships only; the zone of the nearest keyframe within 5 m (a grid search);
//   2 polygons a GeoJSON zone file, annotated at Create, polygon lookup with hysteresis (as
//              zonemapd and examples/embed).
// BM_Create: ZoneManager::Create over the same maps (polygon zones: annotation included).
//
//   build/host-release/bench/zm_api_bench --benchmark_min_time=0.2 --benchmark_repetitions=5
//       --benchmark_report_aggregates_only=true        (one command line)
#include <benchmark/benchmark.h>

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <memory>
#include <string>
#include <vector>

#include "zonemap/zonemap.h"

namespace {

constexpr int kZoneSize = 50;
constexpr std::uint64_t kKMax = 400;
constexpr double kRoomPitchM = 20.0;

struct World {
  zonemap::HostMap map;
  std::vector<zonemap::ZoneId> zone_of;  // per keyframe (index = id - 1)
  std::string zone_file;
  ~World() {
    if (!zone_file.empty()) std::filesystem::remove(zone_file);
  }
};

zonemap::Pose At(double x, double y) { return {x, y, 0.0, 0.0, 0.0, 0.0, 1.0}; }

// zones: 0/1 = memberships, 2 = a GeoJSON file of the rooms' squares.
std::unique_ptr<World> MakeWorld(int n, int zones_way) {
  auto w = std::make_unique<World>();
  const int zones = (n + kZoneSize - 1) / kZoneSize;
  const int cols = std::max(1, static_cast<int>(std::ceil(std::sqrt(zones))));
  auto room_xy = [&](int z, double* x0, double* y0) {
    const int row = z / cols;
    const int col = row % 2 == 0 ? z % cols : cols - 1 - z % cols;  // snake: consecutive adjacent
    *x0 = kRoomPitchM * col;
    *y0 = kRoomPitchM * row;
  };
  for (int i = 0; i < n; ++i) {
    const int z = i / kZoneSize, j = i % kZoneSize;
    double x0 = 0, y0 = 0;
    room_xy(z, &x0, &y0);
    const zonemap::KeyframeId id{i + 1};
    w->map.keyframes.push_back(
        {.id = id, .pose = At(x0 + 2.0 * (j % 7), y0 + 2.0 * (j / 7)), .weight = 0, .bytes = 16384});
    w->zone_of.push_back(zonemap::ZoneId{z});
    if (i > 0) w->map.links.push_back({zonemap::KeyframeId{i}, id, zonemap::LinkKind::kNeighbor});
    if (i >= 7 && i % 10 == 0) {
      w->map.links.push_back({zonemap::KeyframeId{i - 6}, id, zonemap::LinkKind::kGlobalClosure});
    }
  }
  if (zones_way < 2) {
    for (int z = 0; z < zones; ++z) w->map.zone_names.push_back("room" + std::to_string(z));
    for (int i = 0; i < n; ++i) {
      w->map.memberships.push_back({zonemap::ZoneId{i / kZoneSize}, zonemap::KeyframeId{i + 1}});
    }
    return w;
  }
  // Rooms are the squares [x0 - 2, x0 + 16] x [y0 - 2, y0 + 16] around their keyframes' 7 x 8
  // grid (2 m gaps between rooms; a pose there keeps the current zone).
  w->zone_file = (std::filesystem::temp_directory_path() /
                  ("zm_api_bench_" + std::to_string(::getpid()) + "_" + std::to_string(n) + ".geojson"))
                     .string();
  std::ofstream geo(w->zone_file);
  geo << "{\"type\": \"FeatureCollection\", \"features\": [\n";
  for (int z = 0; z < zones; ++z) {
    double x0 = 0, y0 = 0;
    room_xy(z, &x0, &y0);
    const double a = x0 - 2, b = y0 - 2, c = x0 + 16, d = y0 + 16;
    geo << (z ? ",\n" : "") << "{\"type\": \"Feature\", \"properties\": {\"name\": \"room" << z
        << "\", \"kind\": \"room\"}, \"geometry\": {\"type\": \"Polygon\", \"coordinates\": [[["
        << a << ", " << b << "], [" << c << ", " << b << "], [" << c << ", " << d << "], [" << a
        << ", " << d << "], [" << a << ", " << b << "]]]}}";
  }
  geo << "\n]}\n";
  w->map.zone_file = w->zone_file;
  w->map.doorway_band_m = 0.0;
  return w;
}

void BM_Tick(benchmark::State& state, const char* policy) {
  const int n = static_cast<int>(state.range(0));
  const auto stride = static_cast<std::uint64_t>(state.range(1));
  const int zones_way = static_cast<int>(state.range(2));
  const auto w = MakeWorld(n, zones_way);
  const auto count = static_cast<std::uint64_t>(n);
  auto kf_at = [&](std::uint64_t tick) { return (tick * stride + tick / count) % count; };

  zonemap::ManagerOptions opt;
  opt.policy = policy;
  opt.memory_thr_keyframes = kKMax;
  if (std::string(policy) == "oracle") {
    // The zone of every tick the benchmark can reach (its own iteration cap).
    for (std::uint64_t t = 0; t < 400000; ++t) opt.oracle_future.push_back(w->zone_of[kf_at(t)]);
  }
  auto made = zonemap::ZoneManager::Create(w->map, opt);
  if (!made.ok()) {
    state.SkipWithError(made.status().ToString().c_str());
    return;
  }
  zonemap::ZoneManager& mgr = **made;
  std::uint64_t tick = 0;
  std::uint64_t moved = 0;
  std::uint64_t checksum = 0;
  auto carry = [&](const zonemap::Answer& a) {  // what a host reads of an answer
    moved += a.unload.size() + a.load.size();
    for (zonemap::KeyframeId id : a.unload) checksum += static_cast<std::uint64_t>(id.value);
    for (zonemap::KeyframeId id : a.load) checksum -= static_cast<std::uint64_t>(id.value);
  };
  auto one_tick = [&]() -> bool {
    const std::uint64_t k = kf_at(tick);
    const zonemap::KeyframeInfo& kf = w->map.keyframes[k];
    zonemap::TickInput in{.stamp_s = static_cast<double>(tick), .pose = kf.pose};
    if (zones_way == 0) in.zone = w->zone_of[k];
    auto a = mgr.Update(in);
    if (!a.ok()) {
      state.SkipWithError(a.status().ToString().c_str());
      return false;
    }
    carry(*a);
    auto b = mgr.AfterLocalization({.highest_hypothesis = kf.id, .localized_on = kf.id});
    if (!b.ok()) {
      state.SkipWithError(b.status().ToString().c_str());
      return false;
    }
    carry(*b);
    ++tick;
    return true;
  };
  if (!one_tick()) return;  // the start-up load, outside the measurement
  moved = 0;
  const std::uint64_t first = tick;
  for (auto _ : state) {
    if (!one_tick()) return;
  }
  benchmark::DoNotOptimize(checksum);
  const auto ticks = static_cast<double>(tick - first);
  state.counters["moved_per_tick"] = static_cast<double>(moved) / std::max(1.0, ticks);
  state.counters["k_max"] = mgr.k_max();
  state.counters["peak"] = mgr.stats().peak_resident;
}

void BM_Create(benchmark::State& state) {
  const int n = static_cast<int>(state.range(0));
  const auto w = MakeWorld(n, 2);
  zonemap::ManagerOptions opt;
  opt.policy = "semantic";
  opt.memory_thr_keyframes = kKMax;
  for (auto _ : state) {
    auto made = zonemap::ZoneManager::Create(w->map, opt);
    if (!made.ok()) {
      state.SkipWithError(made.status().ToString().c_str());
      return;
    }
    benchmark::DoNotOptimize(made);
  }
}

void Ticks(benchmark::internal::Benchmark* b) {
  for (int zones : {0, 1, 2}) {
    for (int stride : {1, 50}) {
      for (int n : {1000, 10000, 100000}) b->Args({n, stride, zones});
    }
  }
  b->ArgNames({"keyframes", "stride", "zones"})->Unit(benchmark::kMicrosecond);
}

BENCHMARK_CAPTURE(BM_Tick, semantic, "semantic")->Apply(Ticks);
BENCHMARK_CAPTURE(BM_Tick, predictive, "predictive")->Apply(Ticks);
BENCHMARK_CAPTURE(BM_Tick, oracle, "oracle")->Apply(Ticks);
BENCHMARK_CAPTURE(BM_Tick, radius, "radius")->Apply(Ticks);
BENCHMARK_CAPTURE(BM_Tick, basic, "basic")->Apply(Ticks);
BENCHMARK_CAPTURE(BM_Tick, unbounded, "unbounded")->Apply(Ticks);
BENCHMARK(BM_Create)->Arg(1000)->Arg(10000)->Arg(100000)->ArgName("keyframes")->Unit(
    benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
