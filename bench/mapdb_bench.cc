// Zone-load throughput of the map database against the raw read of the same bytes, printed as
// figures (not a timed test; docs/mapdb.md has the measured runs):
//
//   CRC-32C   the payload checksum kernels (scalar reference, hardware) and zlib's crc32, GB/s
//   zone      MapDb::LoadZone over every zone: one transaction, blob reads into arena slots
//   stepped   the same loads time-sliced: BeginZoneLoad, then StepZoneLoad with --step-kf
//             keyframes per step (1 = one keyframe a step)
//   per-kf    MapDb::LoadKeyframes over the same keyframes (RTAB-Map's way: 4 statements each)
//   read()    a sequential read() of a file holding the same payload bytes in the order the
//             zone pass reads them, 1 MiB at a time into one buffer (like dd bs=1M): the physical
//             limit of getting those bytes into memory
//   read->slot  the same file, each keyframe's bytes read() straight into its arena slot
//
// Warm: every method runs once to warm the page cache, then --reps times interleaved (so drift
// hits all alike). Cold (unless --no-cold, and only on a file system with a page cache): before
// each timed pass the files' pages are dropped with posix_fadvise(POSIX_FADV_DONTNEED) and the
// database reopened (so SQLite's own cache is cold too). Medians, with the min-max spread.
//
//   zm_mapdb_bench [--db MAP.db] [--keyframes 2000 --zones 40 --payload-kb 40 --page-kb 0]
//                  [--reps 5] [--dir DIR] [--step-kf 1] [--no-crc] [--mmap-mb N (0 = off)] [--no-cold]
//                  [--crc-mb 64]
//
// Without --db a synthetic map is built in DIR (default: the temp directory); with --db the
// raw copy of the payloads is written beside the map (same file system) and removed at the end.
#include <fcntl.h>
#include <unistd.h>
#include <zlib.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <functional>
#include <random>
#include <string>
#include <variant>
#include <vector>

#include "arena/arena.h"
#include "mapdb/keyframe_payload.h"
#include "mapdb/map_db.h"
#include "simd/crc32c.h"

namespace {

using Clock = std::chrono::steady_clock;

struct Args {
  std::string db;  // existing map; empty = build a synthetic one
  int keyframes = 2000;
  int zones = 40;
  int payload_kb = 40;
  std::uint32_t page_kb = 0;  // 0 = MapDbWriter's choice
  int reps = 5;
  std::uint32_t step_kf = 1;
  bool crc = true;
  bool cold = true;
  std::int64_t mmap_mb = -1;  // -1: MapDbOptions' default (the whole file)
  std::size_t crc_mb = 64;
  std::string dir;
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

struct Spread {
  double median = 0, min = 0, max = 0;
};
Spread Summarise(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return {v[v.size() / 2], v.front(), v.back()};
}

void DropCache(const std::string& path) {
  const int fd = ::open(path.c_str(), O_RDONLY);
  if (fd < 0) Die("cannot open " + path);
  if (::posix_fadvise(fd, 0, 0, POSIX_FADV_DONTNEED) != 0) Die("posix_fadvise failed on " + path);
  ::close(fd);
}

// Whether dropping `path` from the page cache makes reading it slower (false on tmpfs, where
// the pages are the file): reads it warm, drops, reads it cold.
bool CacheDrops(const std::string& path, std::vector<std::byte>& buf) {
  const auto read_all = [&] {
    const auto t0 = Clock::now();
    const int fd = ::open(path.c_str(), O_RDONLY);
    while (::read(fd, buf.data(), buf.size()) > 0) {
    }
    ::close(fd);
    return std::chrono::duration<double>(Clock::now() - t0).count();
  };
  read_all();
  const double warm = read_all();
  DropCache(path);
  const double cold = read_all();
  return cold > 1.5 * warm;
}

void BuildSynthetic(const Args& a, const std::string& db_path) {
  std::mt19937 rng(1);
  const std::uint32_t features = 300;
  const std::size_t feature_bytes = zm::PayloadSize(features, 0);
  const std::size_t want_bytes = static_cast<std::size_t>(a.payload_kb) * 1024;
  const auto dense_bytes =
      static_cast<std::uint32_t>(want_bytes > feature_bytes ? want_bytes - feature_bytes : 0);
  std::vector<zm::Descriptor256> desc(features);
  std::vector<float> pts(3 * features), kps(2 * features);
  std::vector<std::byte> dense(dense_bytes);
  auto w = zm::MapDbWriter::Create(db_path, /*overwrite=*/true,
                                   zm::MapDbWriterOptions{.page_bytes = a.page_kb * 1024});
  if (!w.ok()) Die(w.status().ToString());
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

// GB/s of `fn` over `buf`, median of 7.
Spread CrcRate(const std::function<std::uint32_t(const void*, std::size_t)>& fn,
               const std::vector<std::byte>& buf, std::size_t bytes) {
  std::vector<double> rates;
  volatile std::uint32_t sink = 0;
  const std::size_t rounds = std::max<std::size_t>(1, (256u << 20) / bytes);  // ~256 MiB a sample
  for (int r = 0; r < 7; ++r) {
    const auto t0 = Clock::now();
    for (std::size_t i = 0; i < rounds; ++i) sink = sink + fn(buf.data(), bytes);
    const double s = std::chrono::duration<double>(Clock::now() - t0).count();
    rates.push_back(static_cast<double>(bytes * rounds) / s / 1e9);
  }
  return Summarise(rates);
}

void CrcSection(const Args& a) {
  std::vector<std::byte> buf(a.crc_mb << 20);
  std::mt19937_64 rng(9);
  for (std::size_t i = 0; i + 8 <= buf.size(); i += 8) {
    const std::uint64_t v = rng();
    std::memcpy(buf.data() + i, &v, 8);
  }
  struct K {
    const char* name;
    std::function<std::uint32_t(const void*, std::size_t)> fn;
  };
  std::vector<K> kernels = {
      {"zlib crc32", [](const void* p, std::size_t n) {
         uLong c = crc32(0L, Z_NULL, 0);
         const auto* b = static_cast<const Bytef*>(p);
         for (std::size_t off = 0; off < n; off += 1u << 30) {
           c = crc32(c, b + off, static_cast<uInt>(std::min<std::size_t>(n - off, 1u << 30)));
         }
         return static_cast<std::uint32_t>(c);
       }},
      {"crc32c scalar", [](const void* p, std::size_t n) { return zm::simd::scalar::Crc32c(p, n); }}};
  if (zm::simd::Crc32cHardwareAvailable()) {
    kernels.push_back({zm::simd::ActiveCrc32cKernel(),
                       [](const void* p, std::size_t n) { return zm::simd::Crc32c(p, n); }});
  }
  std::printf("\nCRC kernels (active CRC-32C kernel: %s), GB/s (10^9 B/s), median of 7 [min-max]\n",
              zm::simd::ActiveCrc32cKernel());
  const std::size_t small = std::min<std::size_t>(buf.size(), 1600 * 1000);
  std::printf("%-16s %26s %26s\n", "kernel", "1.6 MB (a dense keyframe)",
              (std::to_string(a.crc_mb) + " MiB").c_str());
  for (const K& k : kernels) {
    const Spread s1 = CrcRate(k.fn, buf, small);
    const Spread s2 = CrcRate(k.fn, buf, buf.size());
    std::printf("%-16s %12.2f [%5.2f-%5.2f] %12.2f [%5.2f-%5.2f]\n", k.name, s1.median, s1.min,
                s1.max, s2.median, s2.min, s2.max);
  }
}

}  // namespace

int main(int argc, char** argv) {
  Args a;
  for (int i = 1; i < argc; ++i) {
    const std::string k = argv[i];
    if (k == "--no-crc") {
      a.crc = false;
      continue;
    }
    if (k == "--no-cold") {
      a.cold = false;
      continue;
    }
    if (i + 1 >= argc) Die("missing value for " + k + " (or unknown flag)");
    const char* v = argv[++i];
    if (k == "--db") a.db = v;
    else if (k == "--keyframes") a.keyframes = std::atoi(v);
    else if (k == "--zones") a.zones = std::atoi(v);
    else if (k == "--payload-kb") a.payload_kb = std::atoi(v);
    else if (k == "--page-kb") a.page_kb = static_cast<std::uint32_t>(std::atoi(v));
    else if (k == "--reps") a.reps = std::atoi(v);
    else if (k == "--step-kf") a.step_kf = static_cast<std::uint32_t>(std::atoi(v));
    else if (k == "--dir") a.dir = v;
    else if (k == "--mmap-mb") a.mmap_mb = std::atoll(v);
    else if (k == "--crc-mb") a.crc_mb = static_cast<std::size_t>(std::atoll(v));
    else Die("unknown option " + k);
  }
  if (a.reps <= 0 || a.step_kf == 0 || a.crc_mb == 0) Die("--reps, --step-kf and --crc-mb must be positive");
  if (a.dir.empty()) {
    a.dir = a.db.empty() ? std::filesystem::temp_directory_path().string()
                         : std::filesystem::absolute(a.db).parent_path().string();
  }
  std::string db_path = a.db;
  const std::string raw_path = a.dir + "/zm_mapdb_bench.bin";
  double build_s = 0;
  if (db_path.empty()) {
    if (a.keyframes <= 0 || a.zones <= 0 || a.keyframes % a.zones != 0) {
      Die("--keyframes must be a positive multiple of --zones");
    }
    db_path = a.dir + "/zm_mapdb_bench.db";
    const auto t0 = Clock::now();
    BuildSynthetic(a, db_path);
    build_s = std::chrono::duration<double>(Clock::now() - t0).count();
  }
  zm::MapDbOptions options{.verify_checksums = a.crc, .sqlite_heap_limit_bytes = 0};
  if (a.mmap_mb >= 0) options.mmap_bytes = a.mmap_mb << 20;
  auto opened = zm::MapDb::Open(db_path, options);
  if (!opened.ok()) Die(opened.status().ToString());
  std::unique_ptr<zm::MapDb> db = std::move(opened).value();
  const zm::MapMetadata meta = db->metadata();
  auto members_r = db->ZoneMembers();
  if (!members_r.ok()) Die(members_r.status().ToString());
  std::vector<std::vector<zm::KeyframeId>> zone_ids(meta.zone_count);
  for (const auto& m : *members_r) zone_ids[static_cast<std::size_t>(m.zone.value)].push_back(m.keyframe);
  std::size_t largest_zone = 1;
  for (const auto& z : zone_ids) largest_zone = std::max(largest_zone, z.size());

  auto created = zm::Arena::Create({.memory_thr_keyframes = largest_zone, .budget_bytes = 0,
                                    .slot_bytes = meta.largest_payload_bytes, .lock = false,
                                    .prefault = true});
  if (auto* e = std::get_if<zm::ArenaError>(&created)) Die(e->message);
  zm::Arena& arena = std::get<zm::Arena>(created);
  Sink sink(largest_zone);

  // The raw copy: every zone's payloads in the order a zone pass reads them, and where each
  // keyframe starts (read->slot reads them one by one).
  std::vector<std::vector<std::uint32_t>> raw_sizes(zone_ids.size());
  std::uint64_t pass_bytes = 0, pass_keyframes = 0;
  {
    const int fd = ::open(raw_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    if (fd < 0) Die("cannot create " + raw_path);
    for (std::size_t z = 0; z < zone_ids.size(); ++z) {
      for (const zm::KeyframeId id : zone_ids[z]) {
        const zm::KeyframeId one[] = {id};
        struct Capture final : zm::LoadSink {
          zm::SlotIndex slot{0};
          std::uint32_t bytes = 0;
          bool Wants(zm::KeyframeId) override { return true; }
          void Loaded(zm::KeyframeId, zm::SlotIndex s, std::uint32_t b) override {
            slot = s;
            bytes = b;
          }
        } cap;
        auto r = db->LoadKeyframes(one, arena, cap);
        if (!r.ok()) Die(r.status().ToString());
        const auto bytes = arena.Slot(cap.slot).first(cap.bytes);
        if (::write(fd, bytes.data(), bytes.size()) != static_cast<ssize_t>(bytes.size())) Die("write failed");
        arena.Release(cap.slot);
        raw_sizes[z].push_back(cap.bytes);
        pass_bytes += cap.bytes;
        ++pass_keyframes;
      }
    }
    ::fsync(fd);
    ::close(fd);
  }

  std::uint64_t zone_queries = 0, kf_queries = 0, steps_per_pass = 0;
  const auto zone_pass = [&] {
    const auto t0 = Clock::now();
    for (std::size_t z = 0; z < zone_ids.size(); ++z) {
      auto st = db->LoadZone(zm::ZoneId{static_cast<std::int32_t>(z)}, arena, sink);
      if (!st.ok()) Die(st.status().ToString());
      zone_queries += st->queries;
      sink.ReleaseAll(arena);
    }
    return std::chrono::duration<double>(Clock::now() - t0).count();
  };
  const auto stepped_pass = [&] {
    const auto t0 = Clock::now();
    std::uint64_t steps = 0;
    for (std::size_t z = 0; z < zone_ids.size(); ++z) {
      if (auto b = db->BeginZoneLoad(zm::ZoneId{static_cast<std::int32_t>(z)}, arena, sink); !b.ok()) {
        Die(b.status().ToString());
      }
      for (bool done = false; !done; ++steps) {
        auto st = db->StepZoneLoad(zm::LoadBudget{.max_keyframes = a.step_kf});
        if (!st.ok()) Die(st.status().ToString());
        done = st->done;
      }
      sink.ReleaseAll(arena);
    }
    steps_per_pass = steps;
    return std::chrono::duration<double>(Clock::now() - t0).count();
  };
  const auto kf_pass = [&] {
    const auto t0 = Clock::now();
    for (const auto& ids : zone_ids) {
      auto st = db->LoadKeyframes(ids, arena, sink);
      if (!st.ok()) Die(st.status().ToString());
      kf_queries += st->queries;
      sink.ReleaseAll(arena);
    }
    return std::chrono::duration<double>(Clock::now() - t0).count();
  };
  std::vector<std::byte> buf(1 << 20);
  const auto read_pass = [&] {
    const auto t0 = Clock::now();
    const int fd = ::open(raw_path.c_str(), O_RDONLY);
    if (fd < 0) Die("cannot open " + raw_path);
    std::uint64_t got = 0;
    ssize_t n;
    while ((n = ::read(fd, buf.data(), buf.size())) > 0) got += static_cast<std::uint64_t>(n);
    ::close(fd);
    if (got != pass_bytes) Die("short read of " + raw_path);
    return std::chrono::duration<double>(Clock::now() - t0).count();
  };
  const auto read_slot_pass = [&] {
    const auto t0 = Clock::now();
    const int fd = ::open(raw_path.c_str(), O_RDONLY);
    if (fd < 0) Die("cannot open " + raw_path);
    for (const auto& sizes : raw_sizes) {
      std::uint32_t i = 0;
      for (const std::uint32_t bytes : sizes) {
        auto dst = arena.Slot(zm::SlotIndex{i++}).first(bytes);
        if (::read(fd, dst.data(), dst.size()) != static_cast<ssize_t>(dst.size())) Die("short read");
      }
    }
    ::close(fd);
    return std::chrono::duration<double>(Clock::now() - t0).count();
  };

  std::printf("mapdb_bench: %s: %llu keyframes of %.1f KiB mean (%.1f MB a pass) in %zu zones "
              "(largest %zu); SQLite page %u bytes%s\n",
              db_path.c_str(), static_cast<unsigned long long>(pass_keyframes),
              static_cast<double>(pass_bytes) / static_cast<double>(pass_keyframes) / 1024.0,
              static_cast<double>(pass_bytes) / 1e6, zone_ids.size(), largest_zone, meta.page_bytes,
              build_s > 0 ? (", built in " + std::to_string(build_s) + " s").c_str() : "");
  std::printf("payload checksums %s (CRC-32C kernel %s), SQLite mmap_size %s, step = %u keyframe(s)\n",
              a.crc ? "on" : "off", zm::simd::ActiveCrc32cKernel(),
              options.mmap_bytes == zm::kMapDbMmapWholeFile
                  ? "whole file (default)"
                  : (std::to_string(options.mmap_bytes >> 20) + " MiB").c_str(),
              a.step_kf);

  const double mb = static_cast<double>(pass_bytes) / 1e6;
  const auto row = [&](const char* name, const Spread& t, const Spread& rd, const std::string& extra) {
    std::printf("%-12s %9.1f %8.0f [%5.0f-%5.0f] %10.2f   %s\n", name, t.median * 1e3, mb / t.median,
                mb / t.max, mb / t.min, rd.median / t.median, extra.c_str());
  };
  const auto header = [] {
    std::printf("%-12s %9s %8s %13s %10s   %s\n", "method", "ms", "MB/s", "[min-max]", "x read()",
                "work per pass");
  };

  // ---- Warm page cache. -----------------------------------------------------------------------
  zone_pass();
  stepped_pass();
  kf_pass();
  read_pass();
  read_slot_pass();
  zone_queries = kf_queries = 0;
  std::vector<double> tz, ts, tk, tr, trs;
  for (int r = 0; r < a.reps; ++r) {
    tz.push_back(zone_pass());
    ts.push_back(stepped_pass());
    tk.push_back(kf_pass());
    tr.push_back(read_pass());
    trs.push_back(read_slot_pass());
  }
  const Spread z = Summarise(tz), s = Summarise(ts), k = Summarise(tk), rd = Summarise(tr),
               rs = Summarise(trs);
  std::printf("\nwarm page cache: medians of %d passes [slowest-fastest MB/s]\n", a.reps);
  header();
  const auto reps = static_cast<std::uint64_t>(a.reps);
  row("zone", z, rd, std::to_string(zone_queries / reps) + " statements, " + std::to_string(zone_ids.size()) + " transactions");
  row("stepped", s, rd, std::to_string(steps_per_pass) + " steps");
  row("per-kf", k, rd, std::to_string(kf_queries / reps) + " statements and transactions");
  row("read()", rd, rd, "1 MiB read() calls");
  row("read->slot", rs, rd, std::to_string(pass_keyframes) + " read() calls into slots");
  std::printf("zone load = %.0f %% of the sequential read() of the same bytes; stepped/one-shot time %.2f\n",
              100.0 * rd.median / z.median, s.median / z.median);

  // ---- Warm page cache, database reopened before each pass (SQLite's cache and memory map cold:
  // the first load of a zone after start-up). --------------------------------------------------
  {
    std::vector<double> tz2;
    for (int r = 0; r < a.reps; ++r) {
      db.reset();
      auto re = zm::MapDb::Open(db_path, options);
      if (!re.ok()) Die(re.status().ToString());
      db = std::move(re).value();
      tz2.push_back(zone_pass());
    }
    const Spread z2 = Summarise(tz2);
    std::printf("\nwarm page cache, database reopened before each pass (first loads after start-up)\n");
    header();
    row("zone", z2, rd, "");
  }

  // ---- Cold page cache. -----------------------------------------------------------------------
  if (a.cold) {
    if (!CacheDrops(raw_path, buf)) {
      std::printf("\ncold page cache: skipped (dropping %s from the page cache changes nothing: tmpfs?)\n",
                  raw_path.c_str());
    } else {
      std::vector<double> cz, cr, crs;
      for (int r = 0; r < a.reps; ++r) {
        db.reset();
        auto re = zm::MapDb::Open(db_path, options);
        if (!re.ok()) Die(re.status().ToString());
        db = std::move(re).value();
        DropCache(db_path);
        cz.push_back(zone_pass());
        DropCache(raw_path);
        cr.push_back(read_pass());
        DropCache(raw_path);
        crs.push_back(read_slot_pass());
      }
      const Spread c = Summarise(cz), cd = Summarise(cr), cs = Summarise(crs);
      std::printf("\ncold page cache (posix_fadvise DONTNEED before each pass, database reopened): "
                  "medians of %d\n", a.reps);
      header();
      row("zone", c, cd, "");
      row("read()", cd, cd, "");
      row("read->slot", cs, cd, "");
      std::printf("cold zone load = %.0f %% of the cold sequential read()\n", 100.0 * cd.median / c.median);
    }
  }

  CrcSection(a);

  std::error_code ec;
  std::filesystem::remove(raw_path, ec);
  if (a.db.empty()) std::filesystem::remove(db_path, ec);
  return 0;
}
