// `zonemap soak`: a long run of the semantic policy (Algorithm 1) on a tiny synthetic map built
// in-process with MapDbWriter, to show that memory stays flat and bounded over many ticks
// (issue 11). Each tick: the zone of a repeating walk (every zone in turn, then back and
// forth, so LRU evicts and reloads), PlanBeforeLocalize + WorkingSet::Apply through the real
// MapDb into a K_max-slot arena, a cheap localizer pass over the resident keyframes (decode
// each slot in place, one Hamming distance), PlanAfterLocalize + Apply.
//
// Checked at every tick: resident <= K_max, and the peak inside the tick <= K_max (the run fails
// otherwise). Sampled: RSS from /proc/self/statm; after a warm-up (first 10 % of the ticks) the
// least-squares slope of RSS against ticks is reported in bytes per 1000 ticks. A figures
// program, not a timed test: run it under the ASan build (smaller --ticks) for LeakSanitizer.
#include <unistd.h>

#include <algorithm>
#include <bit>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <memory>
#include <nlohmann/json.hpp>
#include <random>
#include <string>
#include <vector>

#include "arena/arena.h"
#include "commands.h"
#include "mapdb/keyframe_payload.h"
#include "mapdb/map_db.h"
#include "memory/map_index.h"
#include "memory/plan.h"
#include "memory/policy.h"
#include "memory/working_set.h"

namespace zm::app {
namespace {

struct SoakOpts {
  std::uint64_t ticks = 1'000'000;
  std::uint32_t zones = 8;
  std::uint32_t keyframes_per_zone = 25;
  std::uint32_t k_max = 60;
  std::uint32_t ticks_per_zone = 20;
  std::uint32_t features = 64;
  std::uint32_t samples = 200;
  std::string dir;  // where the temporary map lives; default /dev/shm or the temp dir
  bool json = false;
};

std::uint64_t RssBytes() {
  std::ifstream statm("/proc/self/statm");
  std::uint64_t size = 0, resident = 0;
  statm >> size >> resident;
  return resident * static_cast<std::uint64_t>(sysconf(_SC_PAGESIZE));
}

// Zone z holds keyframes z*n+1 .. (z+1)*n, plus the first keyframe of zone z+1 (a doorway
// keyframe shared by neighbours, so the union counting of overlapping zones is exercised).
Status BuildMap(const std::string& path, const SoakOpts& o) {
  ZM_ASSIGN_OR_RETURN(auto writer, MapDbWriter::Create(path, /*overwrite=*/true));
  std::mt19937 rng(42);
  const std::uint32_t total = o.zones * o.keyframes_per_zone;
  std::vector<std::vector<std::byte>> payloads;
  std::vector<KeyframeRecord> records;
  payloads.reserve(total);
  for (std::uint32_t i = 1; i <= total; ++i) {
    std::vector<Descriptor256> desc(o.features);
    for (auto& d : desc)
      for (auto& b : d) b = static_cast<std::uint8_t>(rng());
    std::vector<float> pts(3 * o.features, 1.0f), kps(2 * o.features, 100.0f);
    std::vector<std::byte> dense(512, std::byte{0x11});
    ZM_ASSIGN_OR_RETURN(auto blob, EncodePayload(PayloadParts{KeyframeId{i}, desc, pts, kps,
                                                              DenseFormat::kOpaque, dense, 0}));
    payloads.push_back(std::move(blob));
    KeyframeRecord r;
    r.meta.id = KeyframeId{i};
    r.meta.stamp_s = 0.1 * i;
    r.meta.pose = PoseFromXYYaw(0.5 * i, 0.0, 0.0);
    r.meta.payload_bytes = static_cast<std::uint32_t>(payloads.back().size());
    r.payload = payloads.back();
    records.push_back(r);
  }
  ZM_RETURN_IF_ERROR(writer->InsertKeyframes(records));
  std::vector<ZoneRecord> zones;
  std::vector<ZoneMember> members;
  for (std::uint32_t z = 0; z < o.zones; ++z) {
    ZoneRecord zr;
    zr.id = ZoneId{static_cast<std::int32_t>(z)};
    zr.name = "Z" + std::to_string(z);
    zr.kind = "room";
    const double x0 = 0.5 * z * o.keyframes_per_zone, x1 = x0 + 0.5 * o.keyframes_per_zone;
    zr.polygon = {{x0, -1.0}, {x1, -1.0}, {x1, 1.0}, {x0, 1.0}};
    zones.push_back(zr);
    for (std::uint32_t k = 0; k < o.keyframes_per_zone; ++k) {
      members.push_back({zr.id, KeyframeId{z * o.keyframes_per_zone + k + 1}});
    }
    if (z + 1 < o.zones) members.push_back({zr.id, KeyframeId{(z + 1) * o.keyframes_per_zone + 1}});
  }
  ZM_RETURN_IF_ERROR(writer->ReplaceZones(zones, members));
  return writer->Finish();
}

// The walk: 0, 1, ..., Z-1, then Z-2 back to 1, repeated; every step evicts once the active
// set is full (K_max holds about two zones).
std::vector<ZoneId> MakeWalk(std::uint32_t zones) {
  std::vector<ZoneId> walk;
  for (std::uint32_t z = 0; z < zones; ++z) walk.push_back(ZoneId{static_cast<std::int32_t>(z)});
  for (std::uint32_t z = zones >= 2 ? zones - 2 : 0; z >= 1 && z < zones; --z) {
    walk.push_back(ZoneId{static_cast<std::int32_t>(z)});
  }
  return walk;
}

struct SoakReport {
  std::uint64_t ticks = 0;
  std::uint32_t k_max = 0;
  std::uint32_t max_resident = 0;
  std::uint64_t over_budget_ticks = 0;
  std::uint64_t keyframes_loaded = 0;
  std::uint64_t zone_loads = 0;
  std::uint64_t db_transactions = 0;
  std::uint64_t localizer_views = 0;
  std::uint64_t localizer_checksum = 0;  // sum of best distances (keeps the work observable)
  std::uint64_t rss_warm_bytes = 0;
  std::uint64_t rss_end_bytes = 0;
  std::uint64_t rss_max_bytes = 0;
  double rss_slope_bytes_per_1000_ticks = 0.0;
  double seconds = 0.0;
};

Result<SoakReport> Soak(const SoakOpts& o) {
  if (o.zones < 2 || o.keyframes_per_zone == 0 || o.ticks_per_zone == 0 || o.samples < 2) {
    return InvalidArgument("need --zones >= 2, --keyframes-per-zone, --ticks-per-zone >= 1, --samples >= 2");
  }
  if (o.k_max < o.keyframes_per_zone + 1) {
    return InvalidArgument("--k-max " + std::to_string(o.k_max) + " is below one zone (" +
                           std::to_string(o.keyframes_per_zone + 1) + " keyframes)");
  }
  std::error_code ec;
  const std::filesystem::path base =
      !o.dir.empty() ? std::filesystem::path(o.dir)
      : std::filesystem::is_directory("/dev/shm", ec) ? std::filesystem::path("/dev/shm")
                                                       : std::filesystem::temp_directory_path();
  const std::string path = (base / ("zonemap_soak_" + std::to_string(getpid()) + ".db")).string();
  struct Cleanup {
    std::string p;
    ~Cleanup() {
      std::error_code e;
      std::filesystem::remove(p, e);
    }
  } cleanup{path};
  ZM_RETURN_IF_ERROR(BuildMap(path, o));

  ZM_ASSIGN_OR_RETURN(auto db, MapDb::Open(path));
  ZM_ASSIGN_OR_RETURN(auto kfs, db->Keyframes());
  ZM_ASSIGN_OR_RETURN(auto links, db->Links());
  ZM_ASSIGN_OR_RETURN(auto members, db->ZoneMembers());
  MapIndexInput in;
  in.keyframes = kfs;
  in.links = links;
  in.members = members;
  in.zone_count = static_cast<std::int32_t>(db->metadata().zone_count);
  ZM_ASSIGN_OR_RETURN(MapIndex index, MapIndex::Build(in));
  PolicyOptions po;
  po.policy = "semantic";
  po.k_max = o.k_max;
  ZM_ASSIGN_OR_RETURN(auto policy, MakePolicy(index, po));
  auto created = Arena::Create({.memory_thr_keyframes = o.k_max, .budget_bytes = 0,
                                .slot_bytes = db->metadata().largest_payload_bytes, .lock = false,
                                .prefault = false});
  if (!std::holds_alternative<Arena>(created)) return Internal("cannot create the arena");
  Arena arena = std::move(std::get<Arena>(created));
  WorkingSet ws(index, arena, *db, o.k_max);
  Plan plan(index);
  const std::vector<ZoneId> walk = MakeWalk(o.zones);
  std::vector<std::uint8_t> query(kDescriptorBytes, 0x5A);

  SoakReport rep;
  rep.k_max = o.k_max;
  const std::uint64_t warmup = o.ticks / 10;
  const std::uint64_t every = std::max<std::uint64_t>(1, (o.ticks - warmup) / o.samples);
  std::vector<double> xs, ys;
  xs.reserve(o.samples + 2);
  ys.reserve(o.samples + 2);

  TickTelemetry tel;
  TickContext ctx;
  ctx.zone = walk[0];
  ctx.pose = PoseFromXYYaw(0.25 * o.keyframes_per_zone, 0.0, 0.0);
  plan.Clear();
  policy->Start(ctx, &plan);
  ZM_RETURN_IF_ERROR(ws.Apply(plan, &tel));
  const auto t0 = std::chrono::steady_clock::now();
  std::uint64_t checksum = 0;
  for (std::uint64_t t = 0; t < o.ticks; ++t) {
    tel = {};
    ctx.tick = t;
    ctx.now_s = 0.1 * static_cast<double>(t);
    ctx.zone = walk[(t / o.ticks_per_zone) % walk.size()];
    ctx.pose = PoseFromXYYaw(0.5 * o.keyframes_per_zone * (ctx.zone.value + 0.5), 0.0, 0.0);
    ctx.highest_hypothesis = KeyframeId{0};
    ctx.localized_on = KeyframeId{0};
    plan.Clear();
    policy->PlanBeforeLocalize(ctx, &plan);
    if (Status st = ws.Apply(plan, &tel); !st.ok()) return st.Annotate("tick " + std::to_string(t));
    // The cheap localizer: decode every resident slot in place, one Hamming distance each.
    std::uint32_t best = 257;
    KeyframeId best_id{0};
    for (const WorkingSet::Resident& r : ws.resident()) {
      auto view = DecodePayload(arena.Slot(r.slot), DecodeOptions{.verify_crc = false}, true);
      if (!view.ok() || view->id != r.id) {
        return Corrupt("tick " + std::to_string(t) + ": slot of keyframe " + std::to_string(r.id.value) +
                       " does not hold it");
      }
      ++rep.localizer_views;
      if (view->feature_count == 0) continue;
      std::uint32_t d = 0;
      const std::uint8_t* desc = view->descriptor(0);
      for (std::size_t i = 0; i < kDescriptorBytes; ++i) {
        d += static_cast<std::uint32_t>(std::popcount(static_cast<unsigned>(desc[i] ^ query[i])));
      }
      if (d < best) {
        best = d;
        best_id = r.id;
      }
    }
    checksum += best;
    ctx.highest_hypothesis = best_id;
    ctx.localized_on = best_id;
    plan.Clear();
    policy->PlanAfterLocalize(ctx, &plan);
    if (Status st = ws.Apply(plan, &tel); !st.ok()) return st.Annotate("tick " + std::to_string(t));

    const std::uint32_t resident = ws.resident_count();
    rep.max_resident = std::max({rep.max_resident, resident, tel.peak_resident_keyframes});
    if (resident > o.k_max || tel.peak_resident_keyframes > o.k_max || tel.over_budget) {
      ++rep.over_budget_ticks;
    }
    rep.keyframes_loaded += tel.keyframes_loaded;
    rep.zone_loads += tel.zones_loaded;
    rep.db_transactions += tel.db_transactions;
    if (t == warmup) rep.rss_warm_bytes = RssBytes();
    if (t >= warmup && ((t - warmup) % every == 0 || t + 1 == o.ticks)) {
      const std::uint64_t rss = RssBytes();
      xs.push_back(static_cast<double>(t));
      ys.push_back(static_cast<double>(rss));
      rep.rss_max_bytes = std::max(rep.rss_max_bytes, rss);
      rep.rss_end_bytes = rss;
    }
  }
  rep.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  rep.ticks = o.ticks;
  // Least-squares slope of RSS over ticks after warm-up.
  if (xs.size() >= 2) {
    double mx = 0, my = 0;
    for (std::size_t i = 0; i < xs.size(); ++i) {
      mx += xs[i];
      my += ys[i];
    }
    mx /= static_cast<double>(xs.size());
    my /= static_cast<double>(xs.size());
    double sxy = 0, sxx = 0;
    for (std::size_t i = 0; i < xs.size(); ++i) {
      sxy += (xs[i] - mx) * (ys[i] - my);
      sxx += (xs[i] - mx) * (xs[i] - mx);
    }
    rep.rss_slope_bytes_per_1000_ticks = sxx > 0 ? 1000.0 * sxy / sxx : 0.0;
  }
  rep.localizer_checksum = checksum;
  return rep;
}

}  // namespace

void AddSoakCommand(CLI::App& app, CommandContext& ctx) {
  auto o = std::make_shared<SoakOpts>();
  CLI::App* cmd = app.add_subcommand(
      "soak", "run the semantic policy for many ticks on a tiny synthetic map; check resident <= "
              "K_max every tick and report the RSS slope after warm-up");
  cmd->add_option("--ticks", o->ticks, "ticks to run")->capture_default_str();
  cmd->add_option("--zones", o->zones, "zones in the synthetic map")->capture_default_str();
  cmd->add_option("--keyframes-per-zone", o->keyframes_per_zone, "keyframes per zone (+1 doorway)")
      ->capture_default_str();
  cmd->add_option("--k-max", o->k_max, "keyframe budget (MemoryThr) = arena slots")->capture_default_str();
  cmd->add_option("--ticks-per-zone", o->ticks_per_zone, "ticks spent in each zone of the walk")
      ->capture_default_str();
  cmd->add_option("--samples", o->samples, "RSS samples after warm-up")->capture_default_str();
  cmd->add_option("--dir", o->dir, "folder for the temporary map (default /dev/shm)");
  cmd->add_flag("--json", o->json, "print the figures as JSON");
  cmd->callback([o, &ctx] {
    auto r = Soak(*o);
    if (!r.ok()) {
      ctx.Fail("soak", r.status());
      return;
    }
    const SoakReport& s = *r;
    if (o->json) {
      nlohmann::json j = {{"ticks", s.ticks},
                          {"k_max", s.k_max},
                          {"max_resident", s.max_resident},
                          {"over_budget_ticks", s.over_budget_ticks},
                          {"keyframes_loaded", s.keyframes_loaded},
                          {"zone_loads", s.zone_loads},
                          {"db_transactions", s.db_transactions},
                          {"rss_warm_bytes", s.rss_warm_bytes},
                          {"rss_end_bytes", s.rss_end_bytes},
                          {"rss_max_bytes", s.rss_max_bytes},
                          {"rss_slope_bytes_per_1000_ticks", s.rss_slope_bytes_per_1000_ticks},
                          {"localizer_views", s.localizer_views},
                          {"localizer_checksum", s.localizer_checksum},
                          {"seconds", s.seconds}};
      std::printf("%s\n", j.dump(2).c_str());
    } else {
      std::printf("ticks %llu  k_max %u  max resident %u  over-budget ticks %llu\n",
                  static_cast<unsigned long long>(s.ticks), s.k_max, s.max_resident,
                  static_cast<unsigned long long>(s.over_budget_ticks));
      std::printf("zone loads %llu  keyframes loaded %llu  transactions %llu  (%.1f s, %.2f us/tick)\n",
                  static_cast<unsigned long long>(s.zone_loads),
                  static_cast<unsigned long long>(s.keyframes_loaded),
                  static_cast<unsigned long long>(s.db_transactions), s.seconds,
                  1e6 * s.seconds / static_cast<double>(std::max<std::uint64_t>(1, s.ticks)));
      std::printf("RSS after warm-up %.2f MiB, at end %.2f MiB, max %.2f MiB, slope %.1f bytes / 1000 ticks\n",
                  static_cast<double>(s.rss_warm_bytes) / 1048576.0,
                  static_cast<double>(s.rss_end_bytes) / 1048576.0,
                  static_cast<double>(s.rss_max_bytes) / 1048576.0, s.rss_slope_bytes_per_1000_ticks);
    }
    if (s.over_budget_ticks > 0) {
      ctx.Fail("soak", "resident keyframes exceeded K_max " + std::to_string(s.k_max) + " on " +
                           std::to_string(s.over_budget_ticks) + " ticks");
    }
  });
}

}  // namespace zm::app
