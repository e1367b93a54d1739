// Scenario generation: mapping run -> map.db, patrol -> frames.bin, plus ground truth, zones and
// metadata (see scenario.h). Work is done in chunks; inside a chunk items are independent (each
// keyframe/frame has its own Rng stream), so worker threads never change the output.
#include "sim/scenario.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <functional>
#include <fstream>
#include <nlohmann/json.hpp>
#include <numbers>
#include <optional>
#include <thread>

#include "geometry/trajectory.h"
#include "localization/camera.h"
#include "localization/map_vocabulary.h"
#include "mapdb/dense_codec.h"
#include "mapdb/map_db.h"
#include "runtime/frames_file.h"
#include "sim/progress.h"
#include "zones/annotate.h"
#include "zones/zone_set.h"

namespace zm::sim {
namespace {

constexpr std::uint64_t kStreamMappingRoute = 11;
constexpr std::uint64_t kStreamPatrol = 12;
constexpr std::uint64_t kStreamOdometry = 13;
constexpr std::uint64_t kStreamKeyframe = 1'000'000;
constexpr std::uint64_t kStreamFrame = 50'000'000;

constexpr double kDeg = std::numbers::pi / 180.0;

// Runs fn(i) for i in [0, n) on up to `threads` threads.
template <class Fn>
void ParallelFor(std::size_t n, int threads, Fn&& fn) {
  const std::size_t workers = std::min<std::size_t>(n, static_cast<std::size_t>(std::max(1, threads)));
  if (workers <= 1) {
    for (std::size_t i = 0; i < n; ++i) fn(i);
    return;
  }
  std::atomic<std::size_t> next{0};
  std::vector<std::thread> pool;
  pool.reserve(workers);
  for (std::size_t w = 0; w < workers; ++w) {
    pool.emplace_back([&] {
      for (std::size_t i = next.fetch_add(1); i < n; i = next.fetch_add(1)) fn(i);
    });
  }
  for (auto& t : pool) t.join();
}

struct Planners {
  std::vector<Planner> per_floor;
  Planners(const Building& b, double radius) {
    per_floor.reserve(b.floors.size());
    for (const FloorMap& f : b.floors) per_floor.emplace_back(f.grid, radius);
  }
};

// Drives from the current position to zone `goal`, through the elevator when it is on another
// floor. Returns false (and moves nowhere) if the goal cannot be reached.
bool GoTo(const Building& b, Planners& planners, TrajectoryBuilder& tb, int goal) {
  const ZoneDef& z = b.zones[static_cast<std::size_t>(goal)];
  int floor = tb.floor();
  if (z.floor != floor) {
    if (b.elevator_zone.empty()) return false;
    const ZoneDef& here = b.zones[static_cast<std::size_t>(b.elevator_zone[static_cast<std::size_t>(floor)])];
    const ZoneDef& there = b.zones[static_cast<std::size_t>(b.elevator_zone[static_cast<std::size_t>(z.floor)])];
    auto& p0 = planners.per_floor[static_cast<std::size_t>(floor)];
    auto& p1 = planners.per_floor[static_cast<std::size_t>(z.floor)];
    if (!p0.Connected(tb.position(), here.viewpoint) || !p1.Connected(there.viewpoint, z.viewpoint)) {
      return false;
    }
    tb.Drive(p0.Plan(tb.position(), here.viewpoint));
    tb.ChangeFloor(z.floor);
    floor = z.floor;
  }
  auto& planner = planners.per_floor[static_cast<std::size_t>(floor)];
  const auto path = planner.Plan(tb.position(), z.viewpoint);
  if (path.empty()) return false;
  tb.Drive(path);
  return true;
}

double PathLength(const std::vector<PoseSample>& s) {
  double len = 0.0;
  for (std::size_t i = 1; i < s.size(); ++i) len += std::hypot(s[i].x - s[i - 1].x, s[i].y - s[i - 1].y);
  return len;
}

// Odometry poses for the frames (see DriftOptions).
std::vector<Pose3> Odometry(const std::vector<PoseSample>& truth, const DriftOptions& o, std::uint64_t seed) {
  Rng rng(seed, kStreamOdometry);
  std::vector<Pose3> odom;
  odom.reserve(truth.size());
  if (truth.empty()) return odom;
  double x = truth[0].x, y = truth[0].y, yaw = truth[0].yaw;
  odom.push_back(PoseFromXYYaw(x, y, yaw, truth[0].z));
  for (std::size_t i = 1; i < truth.size(); ++i) {
    const PoseSample& a = truth[i - 1];
    const PoseSample& b = truth[i];
    // True step in a's body frame.
    const double c = std::cos(a.yaw), s = std::sin(a.yaw);
    const double dxw = b.x - a.x, dyw = b.y - a.y;
    double fwd = c * dxw + s * dyw, lat = -s * dxw + c * dyw;
    double dyaw = std::remainder(b.yaw - a.yaw, 2.0 * std::numbers::pi);
    const double d = std::hypot(fwd, lat);
    fwd += o.trans_bias * d + rng.Normal(0.0, o.trans_noise_per_m * d);
    lat += rng.Normal(0.0, 0.5 * o.trans_noise_per_m * d);
    dyaw += (o.heading_bias_deg_per_m * d + rng.Normal(0.0, o.heading_noise_deg_per_m * d)) * kDeg +
            o.rot_bias * dyaw + rng.Normal(0.0, o.rot_noise * std::abs(dyaw));
    x += std::cos(yaw) * fwd - std::sin(yaw) * lat;
    y += std::sin(yaw) * fwd + std::cos(yaw) * lat;
    yaw = std::remainder(yaw + dyaw, 2.0 * std::numbers::pi);
    odom.push_back(PoseFromXYYaw(x, y, yaw, b.z));
  }
  return odom;
}

Status WriteText(const std::string& path, const std::string& text) {
  std::ofstream out(path, std::ios::binary);
  if (!out) return IoError("cannot create " + path);
  out << text;
  if (!out) return IoError("cannot write " + path);
  return Status::Ok();
}

Result<ZoneSet> ToZoneSet(const Building& b) {
  ZoneSet set;
  for (const ZoneDef& z : b.zones) {
    Zone zone;
    zone.name = z.name;
    zone.kind = z.kind;
    zone.floor = z.floor;
    zone.z_min_m = z.floor * b.floor_height_m - 1.0;
    zone.z_max_m = (z.floor + 1) * b.floor_height_m - 1.0;
    zone.polygon = z.polygon;
    ZM_RETURN_IF_ERROR(set.Add(std::move(zone), {}, "zone " + z.name));
  }
  return set;
}

// One rendered keyframe.
struct KeyframeOut {
  std::vector<std::byte> payload;
  std::uint32_t features = 0;
  std::uint32_t resident_bytes = 0;
  Status status;
};

constexpr std::uint64_t kStreamProbe = 90'000'000;
constexpr std::uint64_t kStreamLighting = 14;

// Renders one keyframe at width x height (oracle features or ORB from its pixels).
using KeyframeRenderer = std::function<Status(const PoseSample&, std::uint32_t, std::uint32_t,
                                              KeyframeId, Rng&, RenderedKeyframe*)>;

// The calling thread's extractor for images of width x height (ORB keyframes and frames render
// on worker threads; an extractor is not thread-safe).
Result<OrbExtractor*> ThreadExtractor(const ScenarioOptions& o, std::uint32_t width,
                                      std::uint32_t height) {
  thread_local std::unique_ptr<OrbExtractor> extractor;
  thread_local std::uint32_t made_w = 0, made_h = 0;
  if (!extractor || made_w != width || made_h != height) {
    ZM_ASSIGN_OR_RETURN(OrbExtractor e,
                        OrbExtractor::Create(o.orb, ScaledIntrinsics(o.camera.intrinsics, width, height)));
    extractor = std::make_unique<OrbExtractor>(std::move(e));
    made_w = width;
    made_h = height;
  }
  return extractor.get();
}

// The dense resolution whose resident footprint is footprint_scale x the full one. The resident
// bytes of a keyframe are a per-feature part (descriptors, keypoints, decoded points: fixed by the
// features) plus a per-pixel part (colour, depth, cloud, and the compressed images); probing up
// to 8 keyframes spread over the run at full resolution measures both, and the pixel count is
// solved for  F + P * per_pixel = scale * (F + P_full * per_pixel).  Width is a multiple of 8
// (JPEG blocks), height keeps the aspect.
Status ChooseDenseResolution(const std::vector<PoseSample>& kf, const ScenarioOptions& o,
                             const KeyframeRenderer& render_keyframe, std::uint32_t* width,
                             std::uint32_t* height) {
  const std::size_t probes = std::min<std::size_t>(8, kf.size());
  std::vector<double> resident(probes, 0.0), fixed(probes, 0.0);
  std::vector<Status> status(probes);
  ParallelFor(probes, o.threads, [&](std::size_t p) {
    const std::size_t i = p * kf.size() / probes;
    Rng rng(o.seed, kStreamProbe + p);
    RenderedKeyframe r;
    status[p] = render_keyframe(kf[i], o.dense.width, o.dense.height, KeyframeId{1}, rng, &r);
    const auto n = static_cast<std::uint32_t>(r.features.descriptors.size());
    resident[p] = r.resident_bytes;
    fixed[p] = static_cast<double>(PayloadSize(n, 0, /*points_on_disk=*/false)) + 12.0 * n;
  });
  for (const Status& s : status) ZM_RETURN_IF_ERROR(s);
  double r1 = 0.0, f = 0.0;
  for (std::size_t p = 0; p < probes; ++p) {
    r1 += resident[p] / static_cast<double>(probes);
    f += fixed[p] / static_cast<double>(probes);
  }
  const double full_px = static_cast<double>(o.dense.width) * o.dense.height;
  const double per_px = (r1 - f) / full_px;
  const double px = (o.dense.footprint_scale * r1 - f) / per_px;
  if (!(px >= 64.0 * 48.0)) {
    return InvalidArgument("--footprint-scale " + std::to_string(o.dense.footprint_scale) +
                           " leaves " + std::to_string(static_cast<long long>(px)) +
                           " pixels per keyframe (features alone are " + std::to_string(std::lround(f)) +
                           " of " + std::to_string(std::lround(r1)) + " resident bytes); the minimum is 64x48");
  }
  const double k = std::sqrt(px / full_px);
  const double aspect = static_cast<double>(o.dense.height) / o.dense.width;
  *width = std::min(o.dense.width, static_cast<std::uint32_t>(std::max(1L, std::lround(o.dense.width * k / 8.0))) * 8);
  *height = std::min(o.dense.height, static_cast<std::uint32_t>(std::lround(*width * aspect)));
  if (*width < 8 || *height < 8) {
    return InvalidArgument("--footprint-scale " + std::to_string(o.dense.footprint_scale) +
                           " gives a dense image of " + std::to_string(*width) + "x" +
                           std::to_string(*height) + ", below 8x8");
  }
  return Status::Ok();
}

}  // namespace

Result<ScenarioReport> WriteScenario(const Building& b, const ScenarioOptions& o, const std::string& dir) {
  if (b.zones.empty() || b.floors.empty()) return InvalidArgument("the building has no zones");
  if (!(o.rate_hz > 0.0 && o.rate_hz <= 100.0)) {
    return InvalidArgument("frame rate " + std::to_string(o.rate_hz) + " Hz is outside (0, 100]");
  }
  if (o.tasks < 1 || o.tasks > 100000) return InvalidArgument("tasks must be in [1, 100000]");
  ZM_RETURN_IF_ERROR(ValidateDenseOptions(o.dense));
  if (o.noise.max_features < 1 || o.noise.max_features > kMaxFeaturesPerKeyframe) {
    return InvalidArgument("max features must be in [1, " + std::to_string(kMaxFeaturesPerKeyframe) + "]");
  }
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec) return IoError("cannot create output folder " + dir + ": " + ec.message());

  const bool pixels = o.features == FeatureSource::kOrb;
  if (pixels) ZM_RETURN_IF_ERROR(ValidateOrbOptions(o.orb));
  // ORB from pixels draws the textured look (nothing of a landmark); the oracle keeps the flat
  // look with its landmark spots, byte for byte what it was.
  DenseOptions dense = o.dense;
  dense.style = pixels ? SurfaceStyle::kTextured : SurfaceStyle::kFlat;

  ScenarioReport report;
  report.zones = b.zones.size();
  const LandmarkMap landmarks = LandmarkMap::Generate(b, o.landmarks, o.seed);
  report.landmarks = landmarks.landmarks().size();
  Planners planners(b, o.robot_radius_m);

  // --- Mapping run: visit every reachable zone, nearest first, floor by floor; spin in rooms.
  const ZoneDef& start = b.zones[static_cast<std::size_t>(b.start_zone)];
  if (!planners.per_floor[static_cast<std::size_t>(start.floor)].Clear(start.viewpoint)) {
    return FailedPrecondition("the start zone " + start.name + " has no room for a robot of radius " +
                              std::to_string(o.robot_radius_m) + " m");
  }
  std::vector<bool> reachable(b.zones.size(), false);
  for (std::size_t i = 0; i < b.zones.size(); ++i) {
    const ZoneDef& z = b.zones[i];
    if (z.floor == start.floor) {
      reachable[i] = planners.per_floor[static_cast<std::size_t>(z.floor)].Connected(start.viewpoint, z.viewpoint);
    } else if (!b.elevator_zone.empty()) {
      const ZoneDef& e0 = b.zones[static_cast<std::size_t>(b.elevator_zone[static_cast<std::size_t>(start.floor)])];
      const ZoneDef& e1 = b.zones[static_cast<std::size_t>(b.elevator_zone[static_cast<std::size_t>(z.floor)])];
      reachable[i] = planners.per_floor[static_cast<std::size_t>(start.floor)].Connected(start.viewpoint, e0.viewpoint) &&
                     planners.per_floor[static_cast<std::size_t>(z.floor)].Connected(e1.viewpoint, z.viewpoint);
    }
    if (!reachable[i]) ++report.unreachable_zones;
  }
  TrajectoryBuilder mapping(o.motion, 0.1, o.camera.height_m, b.floor_height_m);
  {
    Rng rng(o.seed, kStreamMappingRoute);
    mapping.Start(start.floor, start.viewpoint, rng.Uniform(-std::numbers::pi, std::numbers::pi));
    mapping.Spin(2.0 * std::numbers::pi);
    std::vector<bool> done(b.zones.size(), false);
    done[static_cast<std::size_t>(b.start_zone)] = true;
    for (std::size_t f = 0; f < b.floors.size(); ++f) {
      const int floor = static_cast<int>((static_cast<std::size_t>(start.floor) + f) % b.floors.size());
      while (true) {
        int best = -1;
        double best_d = 1e18;
        for (std::size_t i = 0; i < b.zones.size(); ++i) {
          if (done[i] || !reachable[i] || b.zones[i].floor != floor) continue;
          const double d = (b.zones[i].viewpoint - mapping.position()).squaredNorm() +
                           (mapping.floor() == floor ? 0.0 : 1e12);
          if (d < best_d) {
            best_d = d;
            best = static_cast<int>(i);
          }
        }
        if (best < 0) break;
        done[static_cast<std::size_t>(best)] = true;
        if (!GoTo(b, planners, mapping, best)) continue;
        if (b.zones[static_cast<std::size_t>(best)].kind != "corridor") mapping.Spin(2.0 * std::numbers::pi);
      }
    }
  }
  // Keyframes every keyframe_distance_m or keyframe_angle_deg (or a floor change).
  std::vector<PoseSample> kf_samples;
  for (const PoseSample& s : mapping.samples()) {
    if (!kf_samples.empty()) {
      const PoseSample& last = kf_samples.back();
      const double moved = std::hypot(s.x - last.x, s.y - last.y);
      const double turned = std::abs(std::remainder(s.yaw - last.yaw, 2.0 * std::numbers::pi));
      if (moved < o.keyframe_distance_m && turned < o.keyframe_angle_deg * kDeg &&
          std::abs(s.z - last.z) < 0.5) {
        continue;
      }
    }
    kf_samples.push_back(s);
  }
  report.keyframes = kf_samples.size();
  report.mapping_length_m = PathLength(mapping.samples());

  // --- Render keyframes and write the database.
  // Written (keyframes, links, then zones) as map.db.tmp and renamed over map.db only when
  // complete, so a crash leaves the previous map.db or none, never a half-written one
  // (tests/reliability/crash_safety_test.cc).
  const std::string final_db_path = dir + "/map.db";
  const std::string db_path = final_db_path + ".tmp";
  ZM_ASSIGN_OR_RETURN(auto writer, MapDbWriter::Create(db_path, /*overwrite=*/true));
  ZM_RETURN_IF_ERROR(writer->SetCamera(o.camera.intrinsics));
  ZM_RETURN_IF_ERROR(writer->SetSource(o.source.empty() ? "sim " + b.kind + " seed=" + std::to_string(o.seed) : o.source));

  // The dense resolution: the configured one, or the one whose resident footprint is
  // footprint_scale times it (ChooseDenseResolution).
  const KeyframeRenderer render_keyframe = [&](const PoseSample& s, std::uint32_t w,
                                                std::uint32_t h, KeyframeId id, Rng& rng,
                                                RenderedKeyframe* out) -> Status {
    if (!pixels) {
      return RenderKeyframe(b, landmarks, s.floor, s.pose(), o.camera, o.noise, dense, w, h, id,
                            rng, out);
    }
    ZM_ASSIGN_OR_RETURN(OrbExtractor * extractor, ThreadExtractor(o, w, h));
    return RenderKeyframeFromPixels(b, s.floor, s.pose(), o.camera, dense, w, h, id, rng.Next(),
                                    *extractor, out);
  };
  std::uint32_t dense_w = o.dense.width, dense_h = o.dense.height;
  if (o.dense.footprint_scale < 1.0 && !kf_samples.empty()) {
    ZM_RETURN_IF_ERROR(ChooseDenseResolution(kf_samples, o, render_keyframe, &dense_w, &dense_h));
  }
  report.dense_width = dense_w;
  report.dense_height = dense_h;
  const auto render = [&](std::size_t i, KeyframeOut* out) {
    const PoseSample& s = kf_samples[i];
    Rng rng(o.seed, kStreamKeyframe + i);
    RenderedKeyframe kf;
    out->status = render_keyframe(s, dense_w, dense_h, KeyframeId{static_cast<std::int64_t>(i + 1)}, rng, &kf);
    out->payload = std::move(kf.payload);
    out->features = static_cast<std::uint32_t>(kf.features.descriptors.size());
    out->resident_bytes = kf.resident_bytes;
  };
  std::vector<std::uint32_t> sizes, resident;
  sizes.reserve(kf_samples.size());
  resident.reserve(kf_samples.size());
  std::uint64_t feature_sum = 0;
  const auto t_keyframes = std::chrono::steady_clock::now();
  {
    Progress progress(o.progress, "keyframes", kf_samples.size());
    // Chunks render on the worker threads while the previous chunk is written to SQLite on this
    // one, so the database writes hide behind the rendering.
    constexpr std::size_t kChunk = 64;
    std::vector<KeyframeOut> ready, next;
    const auto render_chunk = [&](std::size_t c0, std::vector<KeyframeOut>* chunk) {
      const std::size_t n = std::min(kChunk, kf_samples.size() - c0);
      chunk->assign(n, KeyframeOut{});
      ParallelFor(n, o.threads, [&](std::size_t k) { render(c0 + k, &(*chunk)[k]); });
    };
    const auto write_chunk = [&](std::size_t c0, std::vector<KeyframeOut>& chunk) -> Status {
      std::vector<KeyframeRecord> records(chunk.size());
      for (std::size_t k = 0; k < chunk.size(); ++k) {
        ZM_RETURN_IF_ERROR(chunk[k].status);
        const PoseSample& s = kf_samples[c0 + k];
        records[k].meta.id = KeyframeId{static_cast<std::int64_t>(c0 + k + 1)};
        records[k].meta.stamp_s = s.t_s;
        records[k].meta.pose = s.pose();
        records[k].meta.weight = 0;
        records[k].payload = chunk[k].payload;
        sizes.push_back(static_cast<std::uint32_t>(chunk[k].payload.size()));
        resident.push_back(chunk[k].resident_bytes);
        feature_sum += chunk[k].features;
      }
      ZM_RETURN_IF_ERROR(writer->InsertKeyframes(records));
      progress.Update(c0 + chunk.size());
      return Status::Ok();
    };
    if (!kf_samples.empty()) render_chunk(0, &ready);
    for (std::size_t c0 = 0; c0 < kf_samples.size(); c0 += kChunk) {
      const std::size_t c1 = c0 + kChunk;
      Status written;
      if (c1 < kf_samples.size()) {
        std::thread writer_thread([&] { written = write_chunk(c0, ready); });
        render_chunk(c1, &next);
        writer_thread.join();
      } else {
        written = write_chunk(c0, ready);
      }
      ZM_RETURN_IF_ERROR(written);
      std::swap(ready, next);
    }
  }
  {
    std::vector<LinkRecord> links;
    for (std::size_t i = 1; i < kf_samples.size(); ++i) {
      LinkRecord l;
      l.from = KeyframeId{static_cast<std::int64_t>(i)};
      l.to = KeyframeId{static_cast<std::int64_t>(i + 1)};
      l.type = LinkKind::kNeighbor;
      l.transform = kf_samples[i - 1].pose().inverse() * kf_samples[i].pose();
      // Odometry-like uncertainty: 2 cm, 0.01 rad.
      for (int d = 0; d < 6; ++d) l.information[static_cast<std::size_t>(d * 7)] = d < 3 ? 2500.0 : 10000.0;
      links.push_back(l);
    }
    report.links = links.size();
    ZM_RETURN_IF_ERROR(writer->InsertLinks(links));
  }
  ZM_RETURN_IF_ERROR(writer->Finish());
  writer.reset();
  report.keyframes_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t_keyframes).count();
  if (!sizes.empty()) {
    const auto stats = [](std::vector<std::uint32_t> v, std::uint32_t* lo, std::uint32_t* median,
                          std::uint32_t* hi, double* mean) {
      std::sort(v.begin(), v.end());
      *lo = v.front();
      *hi = v.back();
      *median = v[v.size() / 2];
      double sum = 0.0;
      for (const std::uint32_t x : v) sum += x;
      *mean = sum / static_cast<double>(v.size());
    };
    stats(sizes, &report.keyframe_bytes_min, &report.keyframe_bytes_median, &report.keyframe_bytes_max,
          &report.keyframe_bytes_mean);
    stats(resident, &report.resident_bytes_min, &report.resident_bytes_median,
          &report.resident_bytes_max, &report.resident_bytes_mean);
    report.mean_features_per_keyframe = feature_sum / sizes.size();
  }

  // Zones into the database (membership with the doorway band) and zones.geojson.
  ZM_ASSIGN_OR_RETURN(ZoneSet zone_set, ToZoneSet(b));
  {
    AnnotateOptions ao;
    ao.band_m = o.annotate_band_m;
    ZM_ASSIGN_OR_RETURN(auto annotation, AnnotateDatabase(db_path, zone_set, ao));
    (void)annotation;
  }
  // A journal left by an earlier crashed writer of map.db must not be applied to the new file.
  for (const char* suffix : {"-wal", "-shm", "-journal"}) std::filesystem::remove(final_db_path + suffix, ec);
  std::filesystem::rename(db_path, final_db_path, ec);
  if (ec) return IoError("renaming " + db_path + " to " + final_db_path + ": " + ec.message());
  ZM_RETURN_IF_ERROR(WriteGeoJson(zone_set, dir + "/zones.geojson"));
  if (pixels) {
    // The map's vocabulary, from its own keyframes (zonemap vocab does the same on any map).
    const auto t_vocab = std::chrono::steady_clock::now();
    MapVocabularyOptions vo;
    vo.word_features = o.orb.word_features;
    vo.max_keyframes = o.vocabulary_max_keyframes;
    ZM_ASSIGN_OR_RETURN(MapVocabularyReport vr, TrainAndStoreMapVocabulary(final_db_path, vo));
    report.vocabulary_words = vr.words;
    report.vocabulary_bytes = vr.memory_bytes;
    report.vocabulary_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t_vocab).count();
  }

  // --- Localization run: a patrol of tasks with revisits.
  const double period = 1.0 / o.rate_hz;
  TrajectoryBuilder patrol(o.motion, period, o.camera.height_m, b.floor_height_m);
  std::vector<int> goals;
  std::vector<std::pair<std::uint64_t, std::uint64_t>> task_frames;
  {
    Rng rng(o.seed, kStreamPatrol);
    std::vector<int> candidates;
    for (std::size_t i = 0; i < b.zones.size(); ++i) {
      if (reachable[i] && b.zones[i].kind != "corridor" && b.zones[i].kind != "elevator") {
        candidates.push_back(static_cast<int>(i));
      }
    }
    if (candidates.empty()) {
      for (std::size_t i = 0; i < b.zones.size(); ++i) {
        if (reachable[i]) candidates.push_back(static_cast<int>(i));
      }
    }
    patrol.Start(start.floor, start.viewpoint, rng.Uniform(-std::numbers::pi, std::numbers::pi));
    int current = b.start_zone;
    std::vector<int> visited;
    for (int t = 0; t < o.tasks; ++t) {
      int goal = -1;
      for (int tries = 0; tries < 16 && (goal < 0 || goal == current); ++tries) {
        if (!visited.empty() && rng.Bernoulli(o.revisit_probability)) {
          goal = visited[rng.Below(visited.size())];
        } else {
          goal = candidates[rng.Below(candidates.size())];
        }
      }
      if (goal == current && candidates.size() > 1) continue;
      const std::uint64_t first = patrol.samples().size() - 1;
      if (!GoTo(b, planners, patrol, goal)) continue;
      task_frames.emplace_back(first, patrol.samples().size() - 1);
      goals.push_back(goal);
      if (std::find(visited.begin(), visited.end(), goal) == visited.end()) visited.push_back(goal);
      current = goal;
    }
  }
  const std::vector<PoseSample>& truth = patrol.samples();
  report.frames = truth.size();
  report.tasks = goals.size();
  report.localization_length_m = PathLength(truth);
  report.localization_duration_s = truth.empty() ? 0.0 : truth.back().t_s;
  const std::vector<Pose3> odom = Odometry(truth, o.drift, o.seed);
  {
    ZM_ASSIGN_OR_RETURN(FrameWriter fw, FrameWriter::Create(dir + "/frames.bin", o.camera.intrinsics, o.rate_hz));
    if (pixels) fw.SetImageSize(dense_w, dense_h);
    // This run's exposure against the mapping run's (gain 1, offset 0).
    double run_gain = 1.0, run_offset = 0.0;
    if (pixels) {
      Rng light_rng(o.seed, kStreamLighting);
      run_gain = 1.0 + light_rng.Uniform(-o.lighting.gain_spread, o.lighting.gain_spread);
      run_offset = light_rng.Uniform(-o.lighting.offset_spread, o.lighting.offset_spread);
    }
    report.lighting_gain = run_gain;
    report.lighting_offset = run_offset;
    std::uint64_t jpeg_total = 0;
    const auto t_frames = std::chrono::steady_clock::now();
    Progress progress(o.progress, "frames", truth.size());
    constexpr std::size_t kChunk = 512;
    std::vector<Frame> chunk;
    std::uint64_t feature_total = 0;
    for (std::size_t c0 = 0; c0 < truth.size(); c0 += kChunk) {
      const std::size_t n = std::min(kChunk, truth.size() - c0);
      chunk.assign(n, Frame{});
      std::vector<Status> frame_status(n);
      ParallelFor(n, o.threads, [&](std::size_t k) {
        const std::size_t i = c0 + k;
        const Pose3 pose = truth[i].pose();
        Rng rng(o.seed, kStreamFrame + i);
        Frame& f = chunk[k];
        f.index = i;
        f.stamp_s = truth[i].t_s;
        f.odom = odom[i];
        if (pixels) {
          // The camera's frame: rendered, lit as this run is, smeared by the turn, JPEG.
          FrameLight light;
          const double t = truth[i].t_s;
          light.gain = static_cast<float>(run_gain * (1.0 + o.lighting.flicker * std::sin(2.0 * std::numbers::pi * t / 20.0)));
          light.offset = static_cast<float>(run_offset);
          if (i > 0 && o.lighting.exposure_s > 0.0) {
            const double dt = std::max(1e-6, truth[i].t_s - truth[i - 1].t_s);
            const double yaw_rate = std::abs(std::remainder(truth[i].yaw - truth[i - 1].yaw, 2.0 * std::numbers::pi)) / dt;
            light.blur_px = static_cast<float>(yaw_rate * o.lighting.exposure_s * o.camera.intrinsics.fx *
                                               dense_w / o.camera.intrinsics.width);
          }
          static const LandmarkMap kNoLandmarks;
          thread_local RgbdImage img;
          RenderRgbd(b, truth[i].floor, pose, o.camera, kNoLandmarks, {}, dense_w, dense_h, dense,
                     rng.Next(), &img, light);
          auto jpeg = EncodeJpegRgb(img.rgb, dense_w, dense_h, dense.jpeg_quality);
          if (!jpeg.ok()) {
            frame_status[k] = jpeg.status();
            return;
          }
          f.colour_codec = ImageCodec::kJpeg;
          f.colour = std::move(jpeg).value();
          return;
        }
        std::vector<VisibleLandmark> visible;
        landmarks.Visible(b, truth[i].floor, pose, o.camera, &visible);
        FeatureSet fs;
        MakeFeatures(landmarks, visible, pose, o.camera, o.noise, /*with_points=*/false, rng, &fs);
        f.descriptors = std::move(fs.descriptors);
        f.keypoints = std::move(fs.keypoints);
      });
      for (const Status& st : frame_status) ZM_RETURN_IF_ERROR(st);
      for (const Frame& f : chunk) {
        ZM_RETURN_IF_ERROR(fw.Append(f));
        feature_total += f.feature_count();
        jpeg_total += f.colour.size();
      }
      progress.Update(c0 + n);
    }
    ZM_RETURN_IF_ERROR(fw.Finish());
    if (!truth.empty()) {
      report.mean_features_per_frame = feature_total / truth.size();
      report.frame_jpeg_bytes_mean = static_cast<std::uint32_t>(jpeg_total / truth.size());
    }
    report.frames_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t_frames).count();
  }

  // --- Ground truth, grids, route, metadata.
  {
    Trajectory t;
    for (const PoseSample& s : kf_samples) t.Add(s.t_s, s.pose());
    ZM_RETURN_IF_ERROR(WriteTrajectory(dir + "/mapping_gt.tum", t, TrajectoryFormat::kTum));
    Trajectory l;
    for (const PoseSample& s : truth) l.Add(s.t_s, s.pose());
    ZM_RETURN_IF_ERROR(WriteTrajectory(dir + "/localization_gt.tum", l, TrajectoryFormat::kTum));
  }
  for (std::size_t f = 0; f < b.floors.size(); ++f) {
    ZM_RETURN_IF_ERROR(WriteRosMap(b.floors[f].grid, dir, f == 0 ? "map" : "map_f" + std::to_string(f)));
  }
  {
    nlohmann::ordered_json route;
    route["format"] = "zonemap route";
    route["version"] = 1;
    nlohmann::ordered_json tasks = nlohmann::ordered_json::array();
    for (std::size_t i = 0; i < goals.size(); ++i) {
      tasks.push_back({{"goal_zone", b.zones[static_cast<std::size_t>(goals[i])].name},
                       {"start_frame", task_frames[i].first},
                       {"end_frame", task_frames[i].second}});
    }
    route["tasks"] = tasks;
    // The zones the patrol passes through, in order (a frame outside every zone keeps the last).
    nlohmann::ordered_json visits = nlohmann::ordered_json::array();
    int last = -1;
    std::uint64_t first_frame = 0;
    for (std::size_t i = 0; i <= truth.size(); ++i) {
      int z = -1;
      if (i < truth.size()) {
        z = ZoneAt(b, truth[i].floor, Eigen::Vector2d(truth[i].x, truth[i].y));
        if (z < 0) z = last;
      }
      if (i == truth.size() || z != last) {
        if (last >= 0) {
          visits.push_back({{"zone", b.zones[static_cast<std::size_t>(last)].name},
                            {"first_frame", first_frame},
                            {"last_frame", i - 1}});
        }
        last = z;
        first_frame = i;
      }
    }
    route["zones"] = visits;
    ZM_RETURN_IF_ERROR(WriteText(dir + "/route.json", route.dump(1) + "\n"));
  }
  {
    const CameraIntrinsics& k = o.camera.intrinsics;
    nlohmann::ordered_json j;
    j["format"] = "zonemap scenario";
    j["version"] = 1;
    j["kind"] = b.kind;
    j["seed"] = o.seed;
    j["source"] = o.source.empty() ? "sim " + b.kind + " seed=" + std::to_string(o.seed) : o.source;
    j["area_m2"] = b.area_m2;
    j["floors"] = b.floors.size();
    j["floor_height_m"] = b.floor_height_m;
    j["resolution_m"] = b.floors[0].grid.resolution_m;
    j["counts"] = {{"zones", report.zones},         {"unreachable_zones", report.unreachable_zones},
                   {"landmarks", report.landmarks}, {"keyframes", report.keyframes},
                   {"links", report.links},         {"frames", report.frames},
                   {"tasks", report.tasks}};
    j["camera"] = {{"fx", k.fx}, {"fy", k.fy}, {"cx", k.cx}, {"cy", k.cy}, {"width", k.width},
                   {"height", k.height}, {"hfov_deg", o.hfov_deg}, {"range_m", o.camera.range_m},
                   {"height_m", o.camera.height_m}};
    j["dense"] = {{"format", "jpeg_rgb+rvl_depth16_mm"},
                  {"width", report.dense_width},
                  {"height", report.dense_height},
                  {"full_width", o.dense.width},
                  {"full_height", o.dense.height},
                  {"footprint_scale", o.dense.footprint_scale},
                  {"range_m", o.dense.range_m},
                  {"jpeg_quality", o.dense.jpeg_quality},
                  {"cloud_step", o.dense.cloud_step}};
    // On disk (the compressed payload) and resident (what a keyframe occupies in its slot).
    j["keyframe_bytes"] = {{"min", report.keyframe_bytes_min}, {"median", report.keyframe_bytes_median},
                           {"max", report.keyframe_bytes_max}, {"mean", report.keyframe_bytes_mean}};
    j["resident_bytes"] = {{"min", report.resident_bytes_min}, {"median", report.resident_bytes_median},
                           {"max", report.resident_bytes_max}, {"mean", report.resident_bytes_mean}};
    j["features"] = {{"source", pixels ? "orb" : "oracle"},
                     {"max_per_view", pixels ? o.orb.max_features : o.noise.max_features},
                     {"mean_per_keyframe", report.mean_features_per_keyframe},
                     {"mean_per_frame", report.mean_features_per_frame},
                     {"bit_flip_probability", o.noise.bit_flip_probability},
                     {"pixel_sigma", o.noise.pixel_sigma},
                     {"outlier_ratio", o.noise.outlier_ratio}};
    if (pixels) {
      j["orb"] = {{"max_features", o.orb.max_features},   {"word_features", o.orb.word_features},
                  {"scale_factor", o.orb.scale_factor},   {"levels", o.orb.levels},
                  {"fast_threshold", o.orb.fast_threshold}};
      j["frames_images"] = {{"format", "jpeg_rgb"},
                            {"width", report.dense_width},
                            {"height", report.dense_height},
                            {"jpeg_bytes_mean", report.frame_jpeg_bytes_mean}};
      j["lighting"] = {{"gain", report.lighting_gain},
                       {"offset", report.lighting_offset},
                       {"gain_spread", o.lighting.gain_spread},
                       {"offset_spread", o.lighting.offset_spread},
                       {"flicker", o.lighting.flicker},
                       {"exposure_s", o.lighting.exposure_s}};
      j["decor"] = {{"seed", o.dense.decor_seed}, {"repeated", o.dense.repeated_decor}};
      j["vocabulary"] = {{"words", report.vocabulary_words}, {"memory_bytes", report.vocabulary_bytes}};
    }
    j["mapping"] = {{"keyframe_distance_m", o.keyframe_distance_m},
                    {"keyframe_angle_deg", o.keyframe_angle_deg},
                    {"length_m", report.mapping_length_m}};
    j["localization"] = {{"rate_hz", o.rate_hz},
                         {"tasks", report.tasks},
                         {"revisit_probability", o.revisit_probability},
                         {"length_m", report.localization_length_m},
                         {"duration_s", report.localization_duration_s}};
    j["motion"] = {{"speed_mps", o.motion.speed_mps}, {"turn_rate_dps", o.motion.turn_rate_dps},
                   {"robot_radius_m", o.robot_radius_m}};
    j["drift"] = {{"trans_noise_per_m", o.drift.trans_noise_per_m},
                  {"trans_bias", o.drift.trans_bias},
                  {"heading_noise_deg_per_m", o.drift.heading_noise_deg_per_m},
                  {"heading_bias_deg_per_m", o.drift.heading_bias_deg_per_m},
                  {"rot_noise", o.drift.rot_noise},
                  {"rot_bias", o.drift.rot_bias}};
    j["files"] = {{"map_db", "map.db"},
                  {"zones", "zones.geojson"},
                  {"map_yaml", "map.yaml"},
                  {"mapping_gt", "mapping_gt.tum"},
                  {"localization_gt", "localization_gt.tum"},
                  {"frames", "frames.bin"},
                  {"route", "route.json"}};
    ZM_RETURN_IF_ERROR(WriteText(dir + "/scenario.json", j.dump(2) + "\n"));
  }
  return report;
}

}  // namespace zm::sim
