#include "import/tum_import.h"

#include <chrono>
#include <cmath>
#include <filesystem>
#include <memory>
#include <numbers>
#include <sstream>

#include "common/elapsed.h"
#include "geometry/trajectory.h"
#include "localization/camera.h"
#include "segment/split.h"
#include "tum/tum_frame.h"
#include "zones/annotate.h"

namespace zm {
namespace {

namespace fs = std::filesystem;

std::string Stamp(double s) {
  std::ostringstream o;
  o.precision(6);
  o << std::fixed << s;
  return o.str();
}

// The pose of the nearest stamp within `tolerance`, or nullptr. `traj` is sorted by stamp.
const Pose3* NearestPose(const Trajectory& traj, double stamp, double tolerance) {
  const auto& s = traj.stamps_s;
  const auto it = std::lower_bound(s.begin(), s.end(), stamp);
  std::size_t best = s.size();
  if (it != s.end()) best = static_cast<std::size_t>(it - s.begin());
  if (it != s.begin()) {
    const std::size_t before = static_cast<std::size_t>(it - s.begin()) - 1;
    if (best == s.size() || stamp - s[before] <= s[best] - stamp) best = before;
  }
  if (best == s.size() || std::abs(s[best] - stamp) > tolerance) return nullptr;
  return &traj.poses[best];
}

double AngleDeg(const Pose3& a, const Pose3& b) {
  const Eigen::AngleAxisd d(a.linear().transpose() * b.linear());
  return std::abs(d.angle()) * 180.0 / std::numbers::pi;
}

}  // namespace

Status ValidateTumImportOptions(const TumImportOptions& o) {
  ZM_RETURN_IF_ERROR(ValidateTumFolderOptions(o.folder));
  ZM_RETURN_IF_ERROR(ValidateOrbOptions(o.orb));
  ZM_RETURN_IF_ERROR(ValidateMapVocabularyOptions(o.vocabulary));
  if (!(o.max_pose_difference_s > 0.0) || !std::isfinite(o.max_pose_difference_s)) {
    return InvalidArgument("pose association tolerance " + std::to_string(o.max_pose_difference_s) +
                           " s: must be finite and > 0");
  }
  if (!(o.keyframe_distance_m >= 0.0) || !(o.keyframe_angle_deg >= 0.0) ||
      !std::isfinite(o.keyframe_distance_m) || !std::isfinite(o.keyframe_angle_deg)) {
    return InvalidArgument("keyframe distance " + std::to_string(o.keyframe_distance_m) +
                           " m and angle " + std::to_string(o.keyframe_angle_deg) +
                           " deg: must be finite and >= 0");
  }
  if (o.dense.jpeg_quality < 1 || o.dense.jpeg_quality > 100) {
    return InvalidArgument("JPEG quality " + std::to_string(o.dense.jpeg_quality) +
                           ": must be in [1, 100]");
  }
  if (o.dense.cloud_step > kMaxCloudStep) {
    return InvalidArgument("cloud step " + std::to_string(o.dense.cloud_step) + ": at most " +
                           std::to_string(kMaxCloudStep));
  }
  return Status::Ok();
}

Result<TumImportReport> ImportTum(const std::string& dir, const std::string& poses_path,
                                  const std::string& out_path, const TumImportOptions& options) {
  const auto t0 = std::chrono::steady_clock::now();
  ZM_RETURN_IF_ERROR(ValidateTumImportOptions(options));
  std::error_code ec;
  if (fs::exists(out_path, ec) && !options.overwrite) {
    return FailedPrecondition(out_path + " already exists (pass --overwrite to replace it)");
  }
  TumImportReport report;
  report.camera = options.folder.camera;
  ZM_ASSIGN_OR_RETURN(const TumFolder folder, ReadTumFolder(dir, options.folder));
  report.listing = folder.listing;
  report.colour_entries = folder.colour_entries;
  report.frames = static_cast<std::uint32_t>(folder.frames.size());
  report.gaps = folder.gaps;
  report.malformed_lines = folder.malformed_lines;
  report.problems = folder.problems;

  ZM_ASSIGN_OR_RETURN(Trajectory traj, ReadTrajectory(poses_path, TrajectoryFormat::kTum));
  report.poses = static_cast<std::uint32_t>(traj.size());
  {  // sorted by stamp for the nearest-stamp search (a TUM file is, but nothing says it must be)
    std::vector<std::size_t> order(traj.size());
    for (std::size_t i = 0; i < order.size(); ++i) order[i] = i;
    std::sort(order.begin(), order.end(),
              [&](std::size_t a, std::size_t b) { return traj.stamps_s[a] < traj.stamps_s[b]; });
    Trajectory sorted;
    for (const std::size_t i : order) sorted.Add(traj.stamps_s[i], traj.poses[i]);
    traj = std::move(sorted);
  }

  ZM_ASSIGN_OR_RETURN(OrbExtractor extractor, OrbExtractor::Create(options.orb, options.folder.camera));
  OrbFeatures features(options.orb.max_features);

  const std::string tmp = out_path + ".tmp";
  struct TmpGuard {  // removes OUT.tmp unless the import completed
    std::string path;
    bool keep = false;
    ~TmpGuard() {
      if (keep) return;
      std::error_code e;
      for (const char* suffix : {"", "-wal", "-shm", "-journal"}) fs::remove(path + suffix, e);
    }
  } guard{tmp};
  std::vector<KeyframeMeta> metas;
  {
    ZM_ASSIGN_OR_RETURN(std::unique_ptr<MapDbWriter> writer,
                        MapDbWriter::Create(tmp, /*overwrite=*/true));
    ZM_RETURN_IF_ERROR(writer->SetCamera(options.folder.camera));
    ZM_RETURN_IF_ERROR(writer->SetSource("tum:" + dir + " poses:" + poses_path));

    TumFrameImages images;
    const Pose3* last_keyframe_cam = nullptr;
    Pose3 last_cam = Pose3::Identity();
    std::uint64_t done = 0;
    for (const TumFrameFiles& frame : folder.frames) {
      ++done;
      if (options.progress && (done % 64 == 0 || done == folder.frames.size())) {
        options.progress("frames", done, folder.frames.size());
      }
      const Pose3* t_map_cam = NearestPose(traj, frame.stamp_s, options.max_pose_difference_s);
      if (t_map_cam == nullptr) {
        ++report.frames_without_pose;
        continue;
      }
      if (last_keyframe_cam != nullptr &&
          (last_cam.translation() - t_map_cam->translation()).norm() < options.keyframe_distance_m &&
          AngleDeg(last_cam, *t_map_cam) < options.keyframe_angle_deg) {
        continue;  // too close to the last keyframe
      }
      Status st = ReadTumFrame(frame, options.folder, &images);
      const KeyframeId id{static_cast<std::int64_t>(metas.size()) + 1};
      Result<OrbKeyframe> kf =
          st.ok() ? BuildOrbKeyframe(extractor, features, images.colour,
                                     DepthImage{images.depth16, options.folder.depth_units_per_m},
                                     id, options.dense)
                  : Result<OrbKeyframe>(st);
      if (!kf.ok()) {
        ++report.refused;
        report.problems.push_back("frame " + Stamp(frame.stamp_s) + " refused: " +
                                  kf.status().message());
        continue;
      }
      KeyframeMeta meta;
      meta.id = id;
      meta.stamp_s = frame.stamp_s;
      meta.pose = BodyPoseFromCamera(*t_map_cam);
      meta.weight = 0;
      meta.payload_bytes = kf->resident_bytes;
      const KeyframeRecord rec{meta, kf->payload};
      ZM_RETURN_IF_ERROR(writer->InsertKeyframes(std::span<const KeyframeRecord>(&rec, 1)));
      report.features += kf->features;
      report.features_with_point += kf->with_point;
      report.total_payload_bytes += kf->payload.size();
      report.largest_resident_bytes = std::max(report.largest_resident_bytes, kf->resident_bytes);
      report.extract_ms += kf->extract_ms;
      metas.push_back(meta);
      last_cam = *t_map_cam;
      last_keyframe_cam = &last_cam;
    }
    report.keyframes = static_cast<std::uint32_t>(metas.size());
    if (metas.empty()) {
      return FailedPrecondition("TUM folder " + dir + ": no keyframe (" +
                                std::to_string(report.frames) + " frames, " +
                                std::to_string(report.frames_without_pose) + " without a pose in " +
                                poses_path + ", " + std::to_string(report.refused) + " refused)");
    }
    // Odometry between consecutive keyframes, with the simulator's odometry information
    // (sigma 2 cm, 0.01 rad).
    std::vector<LinkRecord> links;
    for (std::size_t i = 1; i < metas.size(); ++i) {
      LinkRecord l;
      l.from = metas[i - 1].id;
      l.to = metas[i].id;
      l.type = LinkType::kNeighbor;
      l.transform = metas[i - 1].pose.inverse() * metas[i].pose;
      for (int d = 0; d < 6; ++d) l.information[static_cast<std::size_t>(d * 7)] = d < 3 ? 2500.0 : 10000.0;
      links.push_back(l);
    }
    ZM_RETURN_IF_ERROR(writer->InsertLinks(links));
    report.links = static_cast<std::uint32_t>(links.size());
    ZM_RETURN_IF_ERROR(writer->Finish());
  }

  // Zones from the keyframe positions, assigned by the annotation rules.
  {
    std::vector<Eigen::Vector2d> positions;
    positions.reserve(metas.size());
    for (const KeyframeMeta& m : metas) positions.emplace_back(m.pose.translation().head<2>());
    KeyframeZoneOptions kz;
    kz.cell_size_m = options.zone_cell_m;
    kz.max_keyframes = options.zone_max_keyframes;
    ZM_ASSIGN_OR_RETURN(std::vector<Zone> made, ZonesFromKeyframes(positions, kz));
    ZoneSet zones;
    for (Zone& z : made) ZM_RETURN_IF_ERROR(zones.Add(std::move(z), {}, "keyframe zones"));
    ZM_ASSIGN_OR_RETURN(const AnnotationReport annotated, AnnotateDatabase(tmp, zones, AnnotateOptions{}));
    report.zones = static_cast<std::uint32_t>(annotated.zones.size());
  }
  if (options.train_vocabulary) {
    ZM_ASSIGN_OR_RETURN(report.vocabulary, TrainAndStoreMapVocabulary(tmp, options.vocabulary));
    report.vocabulary_trained = true;
  }
  fs::rename(tmp, out_path, ec);
  if (ec) return IoError("cannot rename " + tmp + " to " + out_path + ": " + ec.message());
  guard.keep = true;
  report.ms = MsSince(t0);
  return report;
}

}  // namespace zm
