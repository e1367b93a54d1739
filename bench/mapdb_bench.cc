// Zone-batch load throughput of the map database against its two references, printed as
// figures (not a timed test):
//   zone      MapDb::LoadZone, one transaction + one statement per zone, blob reads into slots
//   per-kf    MapDb::LoadKeyframes over the same keyframes, one point query each (RTAB-Map's way)
//   read()    a plain sequential read() of a file holding the same payload bytes, from the page
//             cache: the physical limit of getting those bytes into memory
// Every method runs once to warm the caches, then `--reps` times; medians are printed, with
// MB/s (10^6 bytes), keyframes/s and the ratios.
//
//   zm_mapdb_bench [--keyframes 2000] [--zones 40] [--payload-kb 40] [--reps 5] [--dir /tmp]
//                  [--no-crc] [--mmap-mb N]
#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <random>
#include <string>
#include <variant>
#include <vector>

#include "arena/arena.h"
#include "mapdb/keyframe_payload.h"
#include "mapdb/map_db.h"

namespace {

using Clock = std::chrono::steady_clock;

struct Args {
  int keyframes = 2000;
  int zones = 40;
  int payload_kb = 40;
  int reps = 5;
  bool crc = true;
  std::int64_t mmap_mb = 0;
  std::string dir = std::filesystem::temp_directory_path().string();
};

[[noreturn]] void Die(const std::string& what) {
  std::fprintf(stderr, "mapdb_bench: %s\n", what.c_str());
  std::exit(1);
}

void Check(const zm::Status& s) {
  if (!s.ok()) Die(s.ToString());
}

class Sink final : public zm::LoadSink {
 public:
  explicit Sink(std::size_t capacity) { slots_.reserve(capacity); }
  bool Wants(zm::KeyframeId) override { return true; }
  void Loaded(zm::KeyframeId, zm::SlotIndex slot, std::uint32_t) override { slots_.push_back(slot); }
  void ReleaseAll(zm::Arena& arena) {
    for (auto s : slots_) arena.Release(s);
    slots_.clear();
  }

 private:
  std::vector<zm::SlotIndex> slots_;
};

double Median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

}  // namespace

int main(int argc, char** argv) {
  Args a;
  for (int i = 1; i < argc; i += 2) {
    const std::string k = argv[i];
    if (k == "--no-crc") {
      a.crc = false;
      --i;
      continue;
    }
    if (i + 1 >= argc) Die("missing value for " + k);
    const char* v = argv[i + 1];
    if (k == "--keyframes") a.keyframes = std::atoi(v);
    else if (k == "--zones") a.zones = std::atoi(v);
    else if (k == "--payload-kb") a.payload_kb = std::atoi(v);
    else if (k == "--reps") a.reps = std::atoi(v);
    else if (k == "--dir") a.dir = v;
    else if (k == "--mmap-mb") a.mmap_mb = std::atoll(v);
    else Die("unknown option " + k);
  }
  if (a.keyframes <= 0 || a.zones <= 0 || a.keyframes % a.zones != 0 || a.reps <= 0) {
    Die("--keyframes must be a positive multiple of --zones");
  }
  const std::string db_path = a.dir + "/zm_mapdb_bench.db";
  const std::string raw_path = a.dir + "/zm_mapdb_bench.bin";

  // ---- Build the map: ~payload_kb per keyframe, 300 features + dense filler. -----------------
  const auto build0 = Clock::now();
  std::mt19937 rng(1);
  const std::uint32_t features = 300;
  const std::size_t feature_bytes = zm::PayloadSize(features, 0);
  const std::size_t want_bytes = static_cast<std::size_t>(a.payload_kb) * 1024;
  const auto dense_bytes =
      static_cast<std::uint32_t>(want_bytes > feature_bytes ? want_bytes - feature_bytes : 0);
  std::vector<zm::Descriptor256> desc(features);
  std::vector<float> pts(3 * features), kps(2 * features);
  std::vector<std::byte> dense(dense_bytes);
  std::uint64_t payload_total = 0;
  {
    auto w = zm::MapDbWriter::Create(db_path, /*overwrite=*/true);
    if (!w.ok()) Die(w.status().ToString());
    int fd = ::open(raw_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    if (fd < 0) Die("cannot create " + raw_path);
    const int per_zone = a.keyframes / a.zones;
    for (int z = 0; z < a.zones; ++z) {
      std::vector<std::vector<std::byte>> payloads;
      std::vector<zm::KeyframeRecord> recs;
      for (int j = 0; j < per_zone; ++j) {
        const std::int64_t id = z * per_zone + j + 1;
        for (auto& d : desc)
          for (auto& b : d) b = static_cast<std::uint8_t>(rng());
        for (auto& f : pts) f = static_cast<float>(rng() % 10000) * 0.01f;
        for (auto& f : kps) f = static_cast<float>(rng() % 640);
        for (auto& b : dense) b = static_cast<std::byte>(rng());
        auto p = zm::EncodePayload(zm::PayloadParts{zm::KeyframeId{id}, desc, pts, kps,
                                                    zm::DenseFormat::kOpaque, dense, 0});
        if (!p.ok()) Die(p.status().ToString());
        if (::write(fd, p->data(), p->size()) != static_cast<ssize_t>(p->size())) Die("write failed");
        payload_total += p->size();
        payloads.push_back(std::move(p).value());
      }
      for (int j = 0; j < per_zone; ++j) {
        zm::KeyframeMeta m;
        m.id = zm::KeyframeId{z * per_zone + j + 1};
        m.pose = zm::PoseFromXYYaw(z, j, 0.0);
        recs.push_back({m, payloads[static_cast<std::size_t>(j)]});
      }
      Check((*w)->InsertKeyframes(recs));
    }
    ::close(fd);
    std::vector<zm::ZoneRecord> zones(static_cast<std::size_t>(a.zones));
    std::vector<zm::ZoneMember> members;
    for (int z = 0; z < a.zones; ++z) {
      zones[static_cast<std::size_t>(z)].id = zm::ZoneId{z};
      zones[static_cast<std::size_t>(z)].name = "zone" + std::to_string(z);
      zones[static_cast<std::size_t>(z)].kind = "room";
      for (int j = 0; j < per_zone; ++j) members.push_back({zm::ZoneId{z}, zm::KeyframeId{z * per_zone + j + 1}});
    }
    Check((*w)->ReplaceZones(zones, members));
    Check((*w)->Finish());
  }
  const double build_s = std::chrono::duration<double>(Clock::now() - build0).count();

  auto db = zm::MapDb::Open(db_path, zm::MapDbOptions{.verify_checksums = a.crc,
                                                      .sqlite_heap_limit_bytes = 0,
                                                      .mmap_bytes = a.mmap_mb << 20});
  if (!db.ok()) Die(db.status().ToString());
  const auto& meta = (*db)->metadata();
  const auto per_zone = static_cast<std::uint64_t>(a.keyframes / a.zones);
  auto created = zm::Arena::Create({.memory_thr_keyframes = per_zone, .budget_bytes = 0,
                                    .slot_bytes = meta.largest_payload_bytes, .lock = false,
                                    .prefault = true});
  if (auto* e = std::get_if<zm::ArenaError>(&created)) Die(e->message);
  zm::Arena& arena = std::get<zm::Arena>(created);
  Sink sink(per_zone);
  auto members_r = (*db)->ZoneMembers();
  if (!members_r.ok()) Die(members_r.status().ToString());
  std::vector<std::vector<zm::KeyframeId>> zone_ids(static_cast<std::size_t>(a.zones));
  for (const auto& m : *members_r) zone_ids[static_cast<std::size_t>(m.zone.value)].push_back(m.keyframe);

  std::uint64_t queries_zone = 0, queries_kf = 0;
  const auto zone_pass = [&] {
    const auto t0 = Clock::now();
    for (int z = 0; z < a.zones; ++z) {
      auto st = (*db)->LoadZone(zm::ZoneId{z}, arena, sink);
      if (!st.ok()) Die(st.status().ToString());
      queries_zone += st->queries;
      sink.ReleaseAll(arena);
    }
    return std::chrono::duration<double>(Clock::now() - t0).count();
  };
  const auto kf_pass = [&] {
    const auto t0 = Clock::now();
    for (const auto& ids : zone_ids) {
      auto st = (*db)->LoadKeyframes(ids, arena, sink);
      if (!st.ok()) Die(st.status().ToString());
      queries_kf += st->queries;
      sink.ReleaseAll(arena);
    }
    return std::chrono::duration<double>(Clock::now() - t0).count();
  };
  std::vector<std::byte> buf(1 << 20);
  const auto read_pass = [&] {
    const auto t0 = Clock::now();
    int fd = ::open(raw_path.c_str(), O_RDONLY);
    if (fd < 0) Die("cannot open " + raw_path);
    std::uint64_t got = 0;
    ssize_t n;
    while ((n = ::read(fd, buf.data(), buf.size())) > 0) got += static_cast<std::uint64_t>(n);
    ::close(fd);
    if (got != payload_total) Die("short read of " + raw_path);
    return std::chrono::duration<double>(Clock::now() - t0).count();
  };

  zone_pass();  // warm the page cache and SQLite
  kf_pass();
  read_pass();
  queries_zone = queries_kf = 0;
  std::vector<double> tz, tk, tr;
  for (int r = 0; r < a.reps; ++r) {  // interleaved so drift hits all three alike
    tz.push_back(zone_pass());
    tk.push_back(kf_pass());
    tr.push_back(read_pass());
  }
  const double z = Median(tz), k = Median(tk), rd = Median(tr);
  const double mb = static_cast<double>(payload_total) / 1e6;
  const double n = a.keyframes;
  std::printf("mapdb_bench: %d keyframes of %.1f KiB (%.1f MB) in %d zones of %llu; built in %.1f s\n",
              a.keyframes, static_cast<double>(payload_total) / n / 1024.0, mb, a.zones,
              static_cast<unsigned long long>(per_zone), build_s);
  std::printf("medians of %d repetitions, warm page cache, %s, CRC check %s, mmap %lld MiB\n", a.reps,
              a.dir.c_str(), a.crc ? "on" : "off", static_cast<long long>(a.mmap_mb));
  std::printf("%-10s %10s %10s %12s %14s\n", "method", "ms", "MB/s", "keyframes/s", "queries/pass");
  std::printf("%-10s %10.2f %10.0f %12.0f %14llu\n", "zone", z * 1e3, mb / z, n / z,
              static_cast<unsigned long long>(queries_zone / static_cast<std::uint64_t>(a.reps)));
  std::printf("%-10s %10.2f %10.0f %12.0f %14llu\n", "per-kf", k * 1e3, mb / k, n / k,
              static_cast<unsigned long long>(queries_kf / static_cast<std::uint64_t>(a.reps)));
  std::printf("%-10s %10.2f %10.0f %12.0f %14s\n", "read()", rd * 1e3, mb / rd, n / rd, "-");
  std::printf("ratios: zone/per-kf throughput = %.2fx, zone/read() = %.2f (%.0f%% of the sequential-read limit)\n",
              k / z, rd / z, 100.0 * rd / z);
  std::error_code ec;
  std::filesystem::remove(db_path, ec);
  std::filesystem::remove(raw_path, ec);
  return 0;
}
