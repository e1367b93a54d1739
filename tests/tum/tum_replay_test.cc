// `zonemapd --tum DIR [--odom FILE]` (lib/tum/tum_replay.h) on TUM folders the test writes (no
// real recording can be downloaded here), against a map imported from the same folder
// (`zonemap import-tum`): the replay lists every colour frame in stamp order, gaps included, with
// the odometry of the nearest stamp as the body pose or the frame before's; zonemapd's session
// reads the files at its input edge and localizes from pixels, with and without odometry; gaps
// and bad images run on odometry, counted and named, never fatal; `image` lines over a pipe take
// the same path.
#include "tum/tum_replay.h"

#include <doctest/doctest.h>
#include <fcntl.h>
#include <unistd.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "geometry/trajectory.h"
#include "import/tum_import.h"
#include "localization/camera.h"
#include "mapdb/mapdb_test_util.h"
#include "runtime/daemon.h"
#include "support/step_allocations.h"
#include "support/test_util.h"
#include "support/tum_folder_writer.h"

namespace zm {
namespace {

using test::Contains;

using test::TempDir;
using test::TumFolderSpec;
using test::WriteTumFolder;

std::vector<std::string> Lines(const std::string& path) {
  std::ifstream f(path);
  std::vector<std::string> out;
  std::string l;
  while (std::getline(f, l)) out.push_back(l);
  return out;
}

// The writer's groundtruth moved by kOffset: its camera path runs along y = 0 and starts at
// x = 0, the edges of the import's 8 m zone cells, where whether a pose is inside its zone
// depends on the platform's rounding (it was not, under aarch64).
const Eigen::Vector3d kOffset(0.31, 0.43, 0.0);

void ShiftTrajectory(const std::string& path) {
  std::vector<std::string> out;
  for (const std::string& l : Lines(path)) {
    if (l.empty() || l[0] == '#') {
      out.push_back(l);
      continue;
    }
    std::istringstream in(l);
    double v[8];
    for (double& x : v) REQUIRE(static_cast<bool>(in >> x));
    char buf[256];
    std::snprintf(buf, sizeof buf, "%.6f %.9g %.9g %.9g %g %g %g %g", v[0], v[1] + kOffset.x(),
                  v[2] + kOffset.y(), v[3] + kOffset.z(), v[4], v[5], v[6], v[7]);
    out.emplace_back(buf);
  }
  std::ofstream f(path);
  for (const std::string& l : out) f << l << '\n';
}

// A folder of `spec` in dir/seq (groundtruth.txt beside its lists), and a map imported from an
// undamaged copy of it in dir/map_seq: keyframes every third frame, ORB features, a vocabulary.
struct Recording {
  TempDir dir;
  TumFolderSpec spec;
  std::string seq, groundtruth, map;
  CameraIntrinsics camera;
  Pose3 start = Pose3::Identity();

  explicit Recording(const TumFolderSpec& s) : spec(s) {
    TumFolderSpec clean = s;
    clean.depth_gaps.clear();
    clean.missing_colour.clear();
    clean.unreadable_colour.clear();
    clean.truncated_depth.clear();
    clean.wrong_size_colour.clear();
    const std::string map_poses = WriteTumFolder(dir.File("map_seq"), clean);
    ShiftTrajectory(map_poses);
    camera = test::TumTestCamera(s);
    TumImportOptions o;
    o.folder.camera = camera;
    o.keyframe_distance_m = 0.25;
    o.vocabulary.vocabulary.branching = 6;
    o.vocabulary.vocabulary.depth = 3;
    map = dir.File("map.db");
    auto r = ImportTum(dir.File("map_seq"), map_poses, map, o);
    REQUIRE_MESSAGE(r.ok(), r.status().ToString());
    REQUIRE(r->vocabulary_trained);
    auto db = MapDb::Open(map);
    REQUIRE(db.ok());
    auto kfs = (*db)->Keyframes();  // by id
    REQUIRE(kfs.ok());
    REQUIRE_FALSE(kfs->empty());
    start = kfs->front().pose;  // as zonemapd starts a replay without odometry
    seq = dir.File("seq");
    groundtruth = WriteTumFolder(seq, s);
    ShiftTrajectory(groundtruth);
  }

  [[nodiscard]] TumReplayOptions Options(bool odometry) const {
    TumReplayOptions o;
    o.folder.camera = camera;
    if (odometry) o.odom_path = groundtruth;
    o.start = start;
    return o;
  }
  // The body pose the groundtruth gives frame i (the writer's camera at x = step * i).
  [[nodiscard]] Pose3 TruthBody(int i) const {
    Pose3 cam = Pose3::Identity();
    cam.translation() = Eigen::Vector3d(spec.step_m * i, 0.0, 1.2) + kOffset;
    return BodyPoseFromCamera(cam);
  }
};

Profile TumProfile() {
  Profile p;
  p.source = "tum_replay_test";
  p.policy.kind = *ParsePolicyKind("semantic");
  p.map.memory_thr_keyframes = 16;
  p.loop.rate_hz = 30.0;
  p.input.max_route_waypoints = 16;
  return p;
}

// zonemapd over a camera-file source or a pipe of lines, its pose lines and stderr into files.
struct Run {
  std::unique_ptr<MapDb> db;
  std::unique_ptr<Daemon> daemon;
  std::string pose_path, diag_path;
  int pose_fd = -1, diag_fd = -1;
  int pipe_fd[2] = {-1, -1};

  Run(const Recording& rec, DaemonInput input, const std::vector<std::string>& lines = {}) {
    pose_path = rec.dir.File("pose.txt");
    diag_path = rec.dir.File("stderr.txt");
    pose_fd = ::open(pose_path.c_str(), O_CREAT | O_TRUNC | O_WRONLY, 0644);
    diag_fd = ::open(diag_path.c_str(), O_CREAT | O_TRUNC | O_WRONLY, 0644);
    REQUIRE(pose_fd >= 0);
    REQUIRE(diag_fd >= 0);
    if (input.kind == DaemonInput::Kind::kFd) {
      REQUIRE(::pipe(pipe_fd) == 0);
      std::string all;
      for (const std::string& l : lines) all += l + "\n";
      REQUIRE(all.size() < 60000);
      REQUIRE(::write(pipe_fd[1], all.data(), all.size()) == static_cast<ssize_t>(all.size()));
      ::close(pipe_fd[1]);
      pipe_fd[1] = -1;
      input.fd = pipe_fd[0];
    }
    auto d = MapDb::Open(rec.map);
    REQUIRE_MESSAGE(d.ok(), d.status().ToString());
    db = std::move(d).value();
    DaemonOptions o;
    o.pose_fd = pose_fd;
    o.diagnostics_fd = diag_fd;
    auto dm = Daemon::Create(TumProfile(), *db, input, o);
    REQUIRE_MESSAGE(dm.ok(), dm.status().ToString());
    daemon = std::move(dm).value();
  }
  ~Run() {
    daemon.reset();
    for (int fd : {pose_fd, diag_fd, pipe_fd[0]}) {
      if (fd >= 0) ::close(fd);
    }
  }
  void ToEnd() {
    daemon->Hello();
    test::StepToEnd([this] { return daemon->Step(); });
  }
  [[nodiscard]] std::vector<PoseLine> Poses() const {
    std::vector<PoseLine> out;
    for (const std::string& l : Lines(pose_path)) {
      if (l.rfind("pose ", 0) != 0) continue;
      PoseLine p;
      REQUIRE_MESSAGE(ParsePoseLine(l, &p), l);
      out.push_back(p);
    }
    return out;
  }
};

// zonemapd --tum over `rec` (odometry from its groundtruth or none), replayed to the end.
struct TumRun {
  std::unique_ptr<TumReplay> replay;
  std::unique_ptr<Run> run;

  TumRun(const Recording& rec, bool odometry) {
    auto r = TumReplay::Open(rec.seq, rec.Options(odometry), rec.camera);
    REQUIRE_MESSAGE(r.ok(), r.status().ToString());
    replay = std::move(r).value();
    DaemonInput in;
    in.kind = DaemonInput::Kind::kCameraFiles;
    in.camera_files = replay.get();
    run = std::make_unique<Run>(rec, in);
    run->ToEnd();
  }
};

TEST_CASE(
    "tum replay: every colour frame by stamp, gaps included, odometry of the nearest stamp as the "
    "body pose") {
  TumFolderSpec spec;
  spec.frames = 8;
  spec.depth_gaps = {2, 5};
  Recording rec(spec);
  auto r = TumReplay::Open(rec.seq, rec.Options(true), rec.camera);
  REQUIRE_MESSAGE(r.ok(), r.status().ToString());
  TumReplay& replay = *r.value();
  CHECK(replay.frame_count() == 8);
  CHECK(replay.folder().gaps == 2);
  CHECK(replay.width() == 320);
  CHECK(replay.height() == 240);
  CHECK(std::string(replay.kind()) == "tum");
  CHECK(replay.listing_problems().empty());  // the gaps are said when replayed
  CameraFrameFiles f;
  double last = -1.0;
  for (int i = 0; i < 8; ++i) {
    CAPTURE(i);
    REQUIRE(replay.Next(&f).value());
    CHECK(f.stamp_s > last);
    last = f.stamp_s;
    CHECK(Contains(std::string(f.colour_path), "/rgb/"));
    if (spec.depth_gaps.contains(i)) {
      CHECK(f.depth_path.empty());
      CHECK(Contains(std::string(f.note), "no depth within 0.02"));
    } else {
      CHECK(Contains(std::string(f.depth_path), "/depth/"));
    }
    CHECK(f.odom.isApprox(rec.TruthBody(i), 1e-9));
  }
  CHECK_FALSE(replay.Next(&f).value());
  CHECK(replay.frames_without_odometry() == 0);

  // Without an odometry file: the start pose throughout (the previous estimate is the
  // prediction), here the map's first keyframe, i.e. frame 0's body pose.
  CHECK(rec.start.isApprox(rec.TruthBody(0), 1e-9));
  auto none = TumReplay::Open(rec.seq, rec.Options(false), rec.camera);
  REQUIRE(none.ok());
  while (none.value()->Next(&f).value()) CHECK(f.odom.isApprox(rec.start));
  CHECK(none.value()->frames_without_odometry() == 8);

  // An odometry file that stops after frame 3: the later frames hold frame 3's.
  TumReplayOptions o = rec.Options(true);
  o.odom_path = rec.dir.File("short.txt");
  {
    std::ofstream out(o.odom_path);
    const auto lines = Lines(rec.groundtruth);
    for (std::size_t i = 0; i < lines.size() && i < 6; ++i) out << lines[i] << '\n';  // 2 comments
  }
  auto held = TumReplay::Open(rec.seq, o, rec.camera);
  REQUIRE(held.ok());
  for (int i = 0; held.value()->Next(&f).value(); ++i) {
    CHECK(f.odom.isApprox(rec.TruthBody(std::min(i, 3)), 1e-9));
  }
  CHECK(held.value()->frames_without_odometry() == 4);
}

TEST_CASE(
    "tum replay: a folder camera that is not the map's, and a bad folder, are refused at open") {
  TumFolderSpec spec;
  spec.frames = 4;
  Recording rec(spec);
  TumReplayOptions o = rec.Options(true);
  o.folder.camera = kTumFr1Camera;  // the default flags against a 320x240 map
  auto r = TumReplay::Open(rec.seq, o, rec.camera);
  REQUIRE_FALSE(r.ok());
  CHECK(Contains(r.status().message(),
                 "the TUM camera (fx 517.30 fy 516.50 cx 318.60 cy 255.30, 640x480) "
                 "is not the map's camera (fx 256.00"));
  CHECK(Contains(r.status().message(), "--fx --fy --cx --cy --width --height"));
  // Half the size with the intrinsics halved is the same camera: accepted.
  o.folder.camera = ScaledIntrinsics(rec.camera, 160, 120);
  CHECK(TumReplay::Open(rec.seq, o, rec.camera).ok());
  o = rec.Options(true);
  CHECK_FALSE(TumReplay::Open(rec.dir.File("nothing"), o, rec.camera).ok());
  o.odom_path = rec.dir.File("no_odometry.txt");
  auto no_odom = TumReplay::Open(rec.seq, o, rec.camera);
  REQUIRE_FALSE(no_odom.ok());
  CHECK(Contains(no_odom.status().message(), "no_odometry.txt"));
}

TEST_CASE(
    "zonemapd --tum: localizes from pixels, with the groundtruth as odometry and without "
    "odometry") {
  TumFolderSpec spec;
  spec.frames = 12;
  Recording rec(spec);
  for (const bool odometry : {true, false}) {
    CAPTURE(odometry);
    const TumRun tum(rec, odometry);
    Run& run = *tum.run;
    CHECK(Contains(Lines(run.pose_path).at(0), " input tum images 320x240"));
    const std::vector<PoseLine> poses = run.Poses();
    REQUIRE(poses.size() == 12);
    int localized = 0;
    for (int i = 0; i < 12; ++i) {
      CAPTURE(i);
      const PoseLine& p = poses[static_cast<std::size_t>(i)];
      if (!p.loop_closure) continue;
      ++localized;
      // A PnP fix from pixels on the map's keyframes: within 5 cm of the groundtruth (the
      // writer's frames are windows of one flat texture, 12 px apart, not renders at the
      // groundtruth's 0.1 m steps, so pixels and poses agree only to a few centimetres).
      CHECK((p.pose.translation() - rec.TruthBody(i).translation()).norm() < 0.05);
    }
    MESSAGE("localized ", localized, " of 12 frames, odometry ", odometry);
    CHECK(localized >= 9);
    const nlohmann::json sum = run.daemon->Summary(false);
    CHECK(sum["images"]["frames"] == 12);
    CHECK(sum["images"]["refused"] == 0);
    CHECK(sum["images"]["frames_without_odometry"] == (odometry ? 0 : 12));
    CHECK(sum["malformed_lines"] == 0);
    CHECK(run.daemon->loop().totals().images_refused == 0);
  }
}

TEST_CASE("zonemapd --tum: gaps and bad images run on odometry, counted and named, never fatal") {
  TumFolderSpec spec;
  spec.frames = 12;
  spec.depth_gaps = {1};
  spec.missing_colour = {3};
  spec.unreadable_colour = {5};
  spec.wrong_size_colour = {7};
  spec.truncated_depth = {9};  // depth is not read: the frame localizes
  Recording rec(spec);
  {  // a truncated colour image: the front-end finds it
    const std::string rgb =
        rec.seq + "/rgb/" + test::TumStamp(1305031100.0 + 10 * spec.frame_dt_s) + ".png";
    std::filesystem::resize_file(rgb, std::filesystem::file_size(rgb) / 2);
  }
  const TumRun tum(rec, true);
  Run& run = *tum.run;
  const std::vector<PoseLine> poses = run.Poses();
  REQUIRE(poses.size() == 12);  // every frame answered
  for (const int i : {1, 3, 5, 7, 10}) {
    CAPTURE(i);
    CHECK_FALSE(poses[static_cast<std::size_t>(i)].loop_closure);
    // On odometry: the groundtruth under the correction of the last fix.
    const PoseLine& p = poses[static_cast<std::size_t>(i)];
    CHECK((p.pose.translation() - rec.TruthBody(i).translation()).norm() < 0.03);
  }
  CHECK(poses[9].loop_closure);
  const ImageRefusalCounts& r = run.daemon->image_refusals();
  CHECK(r[ImageRefusal::kNoDepth] == 1);
  CHECK(r[ImageRefusal::kUnreadable] == 2);
  CHECK(r[ImageRefusal::kFrontEnd] == 2);
  CHECK(r.total == 5);
  const std::vector<std::string> diag = Lines(run.diag_path);
  REQUIRE(diag.size() == 5);
  CHECK(Contains(diag[0], "input line 2 (stamp "));
  CHECK(Contains(diag[0], "(no_depth): no depth image for the frame (no depth within 0.02"));
  CHECK(Contains(diag[0], "rgb.txt + depth.txt: a gap)"));
  CHECK(Contains(diag[1], "(unreadable): colour image " + rec.seq + "/rgb/"));
  CHECK(Contains(diag[1], "No such file or directory"));
  CHECK(Contains(diag[2], "is neither PNG nor JPEG"));
  CHECK(Contains(diag[3], "(front_end): " + rec.seq + "/rgb/"));
  CHECK(Contains(diag[3], "is 160x120, expected 320x240"));
  CHECK(Contains(diag[4], "(front_end): "));
  CHECK(Contains(diag[4], "ends before its image does"));  // the truncated PNG
}

TEST_CASE("image lines over a pipe localize on the map from the same recording") {
  TumFolderSpec spec;
  spec.frames = 12;
  Recording rec(spec);
  auto folder = ReadTumFolder(rec.seq, rec.Options(true).folder);
  REQUIRE(folder.ok());
  std::vector<std::string> lines;
  for (std::size_t i = 0; i < folder->frames.size(); ++i) {
    const TumFrameFiles& f = folder->frames[i];
    lines.push_back(FormatImageLine(f.stamp_s, rec.TruthBody(static_cast<int>(i)), f.rgb_path,
                                    i % 2 == 0 ? f.depth_path : "-"));
  }
  DaemonInput in;
  in.kind = DaemonInput::Kind::kFd;
  Run run(rec, in, lines);  // --images auto: the map has a vocabulary
  run.ToEnd();
  CHECK(Contains(Lines(run.pose_path).at(0), " input stream images 320x240"));
  const std::vector<PoseLine> poses = run.Poses();
  REQUIRE(poses.size() == 12);
  int localized = 0;
  for (std::size_t i = 0; i < poses.size(); ++i) {
    CHECK(poses[i].stamp_s == doctest::Approx(folder->frames[i].stamp_s).epsilon(1e-12));
    if (poses[i].loop_closure) ++localized;
  }
  CHECK(localized >= 9);
  CHECK(run.daemon->image_refusals().total == 0);
}

}  // namespace
}  // namespace zm
