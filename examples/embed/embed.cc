// A host robot program that keeps its OWN keyframes and lets zonemap decide which of them are
// resident (zonemap::ZoneManager, docs/api.md). Nothing of zonemap's map database or arena is
// used: the host has its own keyframe type, its own storage file and its own in-memory map.
//
//   zonemap_embed SCENARIO_DIR [--policy P|all] [--memory-thr N] [--ticks N] [--work DIR]
//
// SCENARIO_DIR is a `zonemap sim` folder; the host reads only plain files from it: the keyframe
// poses (mapping_gt.tum, keyframe id = line number), the zone polygons (zones.geojson, which
// zonemap assigns the keyframes to) and the robot's path (localization_gt.tum, one pose a tick).
// Its "database" is a file of fixed-size records it writes itself; loading a keyframe reads and
// verifies its record. The program checks zonemap's contract as it carries each answer out:
// every unloaded id was resident, every loaded id was not, and for the bounded policies the
// host never holds more than K_max keyframes at any instant. Exit status 1 on any violation.
#include <zonemap/zonemap.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <unordered_map>
#include <vector>

#include <unistd.h>

namespace {

// ---- The host's own keyframes and storage (what a SLAM system already has) ----

constexpr std::size_t kRecordBytes = 4096;  // one keyframe's record in the host's store file

struct HostKeyframe {
  std::int64_t id = 0;
  double pose[7] = {};               // x y z qx qy qz qw
  std::vector<std::uint8_t> blob;    // the "descriptors": what makes keyframes expensive
};

struct PoseLine {
  double stamp = 0.0;
  zonemap::Pose pose;
};

std::vector<PoseLine> ReadTum(const std::string& path) {
  std::vector<PoseLine> out;
  std::ifstream in(path);
  std::string line;
  while (std::getline(in, line)) {
    if (line.empty() || line[0] == '#') continue;
    std::istringstream s(line);
    PoseLine p;
    s >> p.stamp >> p.pose.x >> p.pose.y >> p.pose.z >> p.pose.qx >> p.pose.qy >> p.pose.qz >>
        p.pose.qw;
    if (s) out.push_back(p);
  }
  return out;
}

std::uint8_t PatternByte(std::int64_t id, std::size_t i) {
  return static_cast<std::uint8_t>((static_cast<std::uint64_t>(id) * 2654435761u + i) >> 3);
}

class HostStore {
 public:
  // Writes every keyframe's record: id, pose, then a pattern derived from the id.
  bool Write(const std::string& path, const std::vector<PoseLine>& keyframes) {
    path_ = path;
    std::ofstream out(path, std::ios::binary | std::ios::trunc);
    std::vector<char> rec(kRecordBytes);
    for (std::size_t i = 0; i < keyframes.size(); ++i) {
      const std::int64_t id = static_cast<std::int64_t>(i) + 1;
      const zonemap::Pose& p = keyframes[i].pose;
      const double pose[7] = {p.x, p.y, p.z, p.qx, p.qy, p.qz, p.qw};
      std::memcpy(rec.data(), &id, sizeof id);
      std::memcpy(rec.data() + 8, pose, sizeof pose);
      for (std::size_t b = 64; b < kRecordBytes; ++b) rec[b] = static_cast<char>(PatternByte(id, b));
      out.write(rec.data(), static_cast<std::streamsize>(rec.size()));
    }
    return static_cast<bool>(out);
  }
  // Reads and verifies keyframe `id`'s record.
  bool Load(std::int64_t id, HostKeyframe* kf) {
    if (!in_.is_open()) in_.open(path_, std::ios::binary);
    std::vector<char> rec(kRecordBytes);
    in_.seekg(static_cast<std::streamoff>((id - 1) * static_cast<std::int64_t>(kRecordBytes)));
    in_.read(rec.data(), static_cast<std::streamsize>(rec.size()));
    if (!in_) return false;
    std::memcpy(&kf->id, rec.data(), sizeof kf->id);
    std::memcpy(kf->pose, rec.data() + 8, sizeof kf->pose);
    kf->blob.assign(rec.begin() + 64, rec.end());
    for (std::size_t b = 64; b < kRecordBytes; ++b) {
      if (kf->blob[b - 64] != PatternByte(id, b)) return false;
    }
    return kf->id == id;
  }

 private:
  std::string path_;
  std::ifstream in_;
};

// ---- Driving zonemap ----

struct Options {
  std::string scenario;
  std::string policy = "semantic";
  std::uint64_t memory_thr = 0;  // 0 = a quarter of the map
  std::size_t ticks = 0;         // 0 = every pose of the path
  std::string work;
};

struct RunResult {
  bool ok = true;
  std::vector<zonemap::ZoneId> zones;  // the zone of every tick (the oracle's future)
};

double Quantile(std::vector<double> v, double q) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  const auto rank = static_cast<std::size_t>(std::ceil(q * static_cast<double>(v.size())));
  return v[std::min(v.size() - 1, rank == 0 ? 0 : rank - 1)];
}

RunResult Run(const Options& o, const std::string& policy, const std::vector<PoseLine>& keyframes,
              const std::vector<PoseLine>& path, HostStore& store,
              const std::vector<zonemap::ZoneId>& future) {
  RunResult result;
  auto fail = [&](const std::string& what) {
    std::fprintf(stderr, "embed [%s]: %s\n", policy.c_str(), what.c_str());
    result.ok = false;
    return result;
  };
  auto bad = [&](const std::string& what) {
    fail(what);
    return false;
  };

  zonemap::HostMap map;
  for (std::size_t i = 0; i < keyframes.size(); ++i) {
    const auto id = static_cast<std::int64_t>(i) + 1;
    map.keyframes.push_back({.id = {id}, .pose = keyframes[i].pose, .weight = 0,
                             .bytes = kRecordBytes});
    if (i > 0) map.links.push_back({.from = {id - 1}, .to = {id}, .kind = zonemap::LinkKind::kNeighbor});
  }
  map.zone_file = o.scenario + "/zones.geojson";
  zonemap::ManagerOptions mo;
  mo.policy = policy;
  mo.memory_thr_keyframes = o.memory_thr != 0 ? o.memory_thr : std::max<std::uint64_t>(1, keyframes.size() / 4);
  if (policy == "oracle") mo.oracle_future = future;
  auto created = zonemap::ZoneManager::Create(map, mo);
  if (!created.ok()) return fail("Create: " + created.status().ToString());
  zonemap::ZoneManager& manager = **created;
  if (policy == "predictive" && !future.empty()) {
    // The planned route: the zone sequence of the path (a navigation stack would know it).
    std::vector<zonemap::ZoneId> route;
    for (zonemap::ZoneId z : future) {
      if (z != zonemap::kNoZone && (route.empty() || route.back() != z)) route.push_back(z);
    }
    if (auto s = manager.SetRoute(route); !s.ok()) return fail("SetRoute: " + s.ToString());
  }

  std::unordered_map<std::int64_t, HostKeyframe> resident;  // the host's working memory
  std::uint32_t peak = 0;
  std::uint64_t loaded = 0, unloaded = 0;
  std::vector<double> call_us;
  const bool bounded = manager.bounded();
  const std::uint32_t k_max = manager.k_max();

  // Carries out one answer: every unload, then the loads in order, checking as it goes.
  auto carry = [&](const zonemap::Answer& a) -> bool {
    for (zonemap::KeyframeId id : a.unload) {
      if (resident.erase(id.value) != 1) return bad("unload of keyframe " + std::to_string(id.value) + ", which is not resident");
      ++unloaded;
    }
    for (zonemap::KeyframeId id : a.load) {
      if (resident.count(id.value) != 0) return bad("load of keyframe " + std::to_string(id.value) + ", already resident");
      HostKeyframe kf;
      if (!store.Load(id.value, &kf)) return bad("the host store cannot read keyframe " + std::to_string(id.value));
      resident.emplace(id.value, std::move(kf));
      ++loaded;
      peak = std::max(peak, static_cast<std::uint32_t>(resident.size()));
      if (bounded && resident.size() > k_max) {
        return bad("holding " + std::to_string(resident.size()) + " keyframes, above K_max " +
                   std::to_string(k_max));
      }
    }
    if (resident.size() != a.resident_after) return bad("resident count differs from the answer's");
    return true;
  };

  const std::size_t ticks = o.ticks != 0 ? std::min(o.ticks, path.size()) : path.size();
  for (std::size_t t = 0; t < ticks; ++t) {
    const auto t0 = std::chrono::steady_clock::now();
    auto a = manager.Update({.stamp_s = path[t].stamp, .pose = path[t].pose, .zone = zonemap::kNoZone});
    call_us.push_back(std::chrono::duration<double, std::micro>(std::chrono::steady_clock::now() - t0).count());
    if (!a.ok()) return fail("Update: " + a.status().ToString());
    result.zones.push_back(a->zone);
    if (!carry(*a)) return result;

    // The host's localization, a stand-in: the nearest resident keyframe within 1.5 m.
    zonemap::LocalizationInput loc;
    double best = 1.5 * 1.5;
    for (const auto& [id, kf] : resident) {
      const double dx = kf.pose[0] - path[t].pose.x, dy = kf.pose[1] - path[t].pose.y;
      const double d2 = dx * dx + dy * dy;
      if (d2 < best || (d2 == best && id > loc.localized_on.value)) {
        best = d2;
        loc.localized_on = {id};
      }
    }
    loc.highest_hypothesis = loc.localized_on;
    const auto t1 = std::chrono::steady_clock::now();
    auto b = manager.AfterLocalization(loc);
    call_us.push_back(std::chrono::duration<double, std::micro>(std::chrono::steady_clock::now() - t1).count());
    if (!b.ok()) return fail("AfterLocalization: " + b.status().ToString());
    if (!carry(*b)) return result;
  }
  for (std::size_t i = 0; i < keyframes.size(); ++i) {
    const auto id = static_cast<std::int64_t>(i) + 1;
    if (manager.IsResident({id}) != (resident.count(id) != 0)) {
      return fail("zonemap and the host disagree about keyframe " + std::to_string(id));
    }
  }
  const zonemap::ManagerStats st = manager.stats();
  std::printf("embed [%s]: K_max %u of %zu keyframes, %zu ticks: peak resident %u%s, %llu loaded, "
              "%llu unloaded, %llu zone loads; zonemap call median %.2f us, p99 %.2f us\n",
              policy.c_str(), k_max, keyframes.size(), ticks, peak,
              bounded ? (peak <= k_max ? " <= K_max" : " > K_max!") : " (not bounded)",
              static_cast<unsigned long long>(loaded), static_cast<unsigned long long>(unloaded),
              static_cast<unsigned long long>(st.zone_loads), Quantile(call_us, 0.5),
              Quantile(call_us, 0.99));
  if (st.keyframes_loaded != loaded || st.keyframes_unloaded != unloaded) {
    return fail("zonemap's counts differ from the host's");
  }
  return result;
}

}  // namespace

int main(int argc, char** argv) {
  Options o;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto next = [&]() -> std::string {
      if (i + 1 >= argc) {
        std::fprintf(stderr, "embed: %s needs a value\n", a.c_str());
        std::exit(2);
      }
      return argv[++i];
    };
    if (a == "--policy") o.policy = next();
    else if (a == "--memory-thr") o.memory_thr = std::stoull(next());
    else if (a == "--ticks") o.ticks = std::stoull(next());
    else if (a == "--work") o.work = next();
    else if (a == "--help" || a == "-h") {
      std::printf("usage: zonemap_embed SCENARIO_DIR [--policy P|all] [--memory-thr N] [--ticks N] [--work DIR]\n");
      return 0;
    } else if (o.scenario.empty()) o.scenario = a;
    else {
      std::fprintf(stderr, "embed: unexpected argument '%s'\n", a.c_str());
      return 2;
    }
  }
  if (o.scenario.empty()) {
    std::fprintf(stderr, "embed: give a scenario directory (zonemap sim hospital --out DIR)\n");
    return 2;
  }
  std::printf("embed: zonemap %s\n", zonemap::Version());
  const std::vector<PoseLine> keyframes = ReadTum(o.scenario + "/mapping_gt.tum");
  const std::vector<PoseLine> path = ReadTum(o.scenario + "/localization_gt.tum");
  if (keyframes.empty() || path.empty()) {
    std::fprintf(stderr, "embed: no keyframes or no path in %s\n", o.scenario.c_str());
    return 1;
  }
  const std::string work = o.work.empty() ? std::filesystem::temp_directory_path().string() : o.work;
  const std::string store_path = work + "/zonemap_embed_store_" + std::to_string(::getpid()) + ".bin";
  HostStore store;
  if (!store.Write(store_path, keyframes)) {
    std::fprintf(stderr, "embed: cannot write the host store %s\n", store_path.c_str());
    return 1;
  }
  std::vector<std::string> policies = {o.policy};
  if (o.policy == "oracle") policies = {"semantic", "oracle"};  // the oracle needs the future
  if (o.policy == "all") policies = {"semantic", "predictive", "oracle", "radius", "basic", "unbounded"};
  bool ok = true;
  std::vector<zonemap::ZoneId> future;  // the zones semantic saw, tick by tick
  for (const std::string& p : policies) {
    RunResult r = Run(o, p, keyframes, path, store, future);
    ok = ok && r.ok;
    if (p == "semantic" && r.ok) future = r.zones;
  }
  std::filesystem::remove(store_path);
  std::printf("embed: %s\n", ok ? "ok" : "FAILED");
  return ok ? 0 : 1;
}
