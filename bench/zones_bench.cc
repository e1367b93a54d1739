// GetZone cost against the number of zones (10 .. 10,000): the grid index should stay flat
// while a brute-force scan grows linearly. Rooms tile a building floor row by row: random room
// widths and row depths, and every other room pair cut by a slanted wall into two
// quadrilaterals, so the set mixes rectangles and general polygons. Poses follow a random walk
// (as a robot would), one lookup per benchmark iteration, so "Time" is ns per lookup.
#include <benchmark/benchmark.h>

#include <cmath>
#include <random>
#include <string>
#include <vector>

#include "zones/polygon.h"
#include "zones/zone_index.h"
#include "zones/zone_set.h"

namespace {

// Built by append: GCC 12's -Wrestrict misfires on `"r" + std::to_string(i)` at -O3.
std::string RoomName(int i) {
  std::string name = "r";
  name += std::to_string(i);
  return name;
}

zm::ZoneSet TiledFloor(int zone_count, std::uint32_t seed, Eigen::Vector2d& extent) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> width(3.0, 9.0), depth(4.0, 8.0), slant(-1.0, 1.0);
  const int per_row = std::max(2, static_cast<int>(std::lround(std::sqrt(zone_count))));
  zm::ZoneSet set;
  double y = 0.0, max_x = 0.0;
  int made = 0;
  while (made < zone_count) {
    const double h = depth(rng);
    double x = 0.0;
    for (int i = 0; i < per_row && made < zone_count; ++i) {
      const double w = width(rng);
      zm::Zone z;
      z.kind = "room";
      if (made + 1 < zone_count && i % 2 == 0) {
        // Two quadrilaterals sharing a slanted wall.
        const double xa = x + w / 2 + slant(rng), xb = x + w / 2 + slant(rng);
        z.name = RoomName(made++);
        z.polygon = {{x, y}, {xa, y}, {xb, y + h}, {x, y + h}};
        (void)set.Add(z);
        z.name = RoomName(made++);
        z.polygon = {{xa, y}, {x + w, y}, {x + w, y + h}, {xb, y + h}};
        (void)set.Add(z);
      } else {
        z.name = RoomName(made++);
        z.polygon = {{x, y}, {x + w, y}, {x + w, y + h}, {x, y + h}};
        (void)set.Add(z);
      }
      x += w;
    }
    max_x = std::max(max_x, x);
    y += h;
  }
  extent = {max_x, y};
  return set;
}

std::vector<zm::Pose3> RandomWalk(const Eigen::Vector2d& extent, std::size_t n) {
  std::mt19937 rng(11);
  std::normal_distribution<double> step(0.0, 0.3);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::vector<zm::Pose3> poses;
  poses.reserve(n);
  Eigen::Vector2d p(extent.x() * u(rng), extent.y() * u(rng));
  for (std::size_t i = 0; i < n; ++i) {
    p += Eigen::Vector2d(step(rng), step(rng));
    p = p.cwiseMax(Eigen::Vector2d::Zero()).cwiseMin(extent);
    if (i % 512 == 0) p = {extent.x() * u(rng), extent.y() * u(rng)};  // teleport: cold cells
    poses.push_back(zm::PoseFromXYYaw(p.x(), p.y(), 0.0));
  }
  return poses;
}

void BM_GetZone(benchmark::State& state) {
  Eigen::Vector2d extent;
  const zm::ZoneSet set = TiledFloor(static_cast<int>(state.range(0)), 1, extent);
  const zm::ZoneIndex index(set);
  const auto poses = RandomWalk(extent, 1 << 14);
  zm::ZoneId cur = zm::kNoZone;
  std::size_t i = 0, switches = 0;
  for (auto _ : state) {
    const zm::ZoneId next = index.GetZone(poses[i++ & (poses.size() - 1)], cur);
    switches += next != cur;
    cur = next;
    benchmark::DoNotOptimize(cur);
  }
  state.counters["zones"] = static_cast<double>(set.size());
  state.counters["cells"] = static_cast<double>(index.cell_count());
  state.counters["cand_per_cell"] =
      static_cast<double>(index.candidate_entries()) / static_cast<double>(index.cell_count());
  state.counters["switch_frac"] = static_cast<double>(switches) / static_cast<double>(i);
}

void BM_Lookup(benchmark::State& state) {
  Eigen::Vector2d extent;
  const zm::ZoneSet set = TiledFloor(static_cast<int>(state.range(0)), 1, extent);
  const zm::ZoneIndex index(set);
  const auto poses = RandomWalk(extent, 1 << 14);
  std::size_t i = 0;
  for (auto _ : state) {
    benchmark::DoNotOptimize(index.Lookup(poses[i++ & (poses.size() - 1)].translation()));
  }
}

// The baseline the grid replaces: point-in-polygon against every zone.
void BM_BruteForce(benchmark::State& state) {
  Eigen::Vector2d extent;
  const zm::ZoneSet set = TiledFloor(static_cast<int>(state.range(0)), 1, extent);
  const auto poses = RandomWalk(extent, 1 << 14);
  std::size_t i = 0;
  for (auto _ : state) {
    const Eigen::Vector2d p = poses[i++ & (poses.size() - 1)].translation().head<2>();
    zm::ZoneId found = zm::kNoZone;
    for (const zm::Zone& z : set.zones()) {
      if (zm::PointInPolygon(z.polygon, p)) {
        found = z.id;
        break;
      }
    }
    benchmark::DoNotOptimize(found);
  }
}

void BM_BuildIndex(benchmark::State& state) {
  Eigen::Vector2d extent;
  const zm::ZoneSet set = TiledFloor(static_cast<int>(state.range(0)), 1, extent);
  for (auto _ : state) {
    const zm::ZoneIndex index(set);
    benchmark::DoNotOptimize(index.cell_count());
  }
}

BENCHMARK(BM_GetZone)->Arg(10)->Arg(100)->Arg(1000)->Arg(10000);
BENCHMARK(BM_Lookup)->Arg(10)->Arg(100)->Arg(1000)->Arg(10000);
BENCHMARK(BM_BruteForce)->Arg(10)->Arg(100)->Arg(1000)->Arg(10000);
BENCHMARK(BM_BuildIndex)->Arg(10)->Arg(100)->Arg(1000)->Arg(10000)->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
