// zonemapd's session with camera frames given as files (issue 26 §4): an `image` line over a
// pipe is read at the input edge, ticked, and answered with a pose line; every kind of bad image
// (missing, unreadable, empty, not an image, too large, truncated, wrong size, missing depth)
// runs the frame on odometry, is counted under its reason and said once on stderr naming the
// file and the limit, and never stops the loop; a session started without a front-end refuses
// image lines; warm image steps allocate nothing.
#include <doctest/doctest.h>
#include <fcntl.h>
#include <unistd.h>

#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <random>
#include <sstream>

#include "arena/sanitizers.h"
#include "rooms_map.h"
#include "runtime/daemon.h"
#include "runtime/sqlite_heap.h"
#include "support/counting_allocator.h"
#include "support/step_allocations.h"
#include "support/test_util.h"

namespace zm {
namespace {

using test::Contains;
using test::Lines;

using test::RoomsMap;

Profile ImageProfile() {
  Profile p;
  p.source = "daemon_image_test";
  p.policy.kind = *ParsePolicyKind("semantic");
  p.map.memory_thr_keyframes = 20;
  p.localizer.reserve_features = 64;
  p.loop.rate_hz = 2.0;
  p.input.max_distance_from_map_m = 20.0;
  p.input.max_route_waypoints = 16;
  return p;
}

std::string ReadAll(const std::filesystem::path& p) {
  std::ifstream f(p);
  std::stringstream s;
  s << f.rdbuf();
  return s.str();
}

// A textured BGR image (blocks of random colour, blurred): ORB finds corners in it.
cv::Mat Texture(int w, int h, unsigned seed) {
  std::mt19937 rng(seed);
  cv::Mat img(h, w, CV_8UC3);
  for (int y = 0; y < h; y += 6) {
    for (int x = 0; x < w; x += 6) {
      img(cv::Rect(x, y, std::min(6, w - x), std::min(6, h - y))) =
          cv::Scalar(static_cast<double>(rng() % 256), static_cast<double>(rng() % 256),
                     static_cast<double>(rng() % 256));
    }
  }
  cv::GaussianBlur(img, img, cv::Size(3, 3), 0.8);
  return img;
}

// A daemon reading lines the test wrote into a pipe beforehand (they fit its buffer), its pose
// lines and diagnostics going to files.
class ImageSession {
 public:
  ImageSession(const RoomsMap& map, DaemonOptions options, const std::vector<std::string>& lines,
               const Profile& profile = ImageProfile())
      : dir_(map.dir()) {
    REQUIRE(::pipe(in_) == 0);
    std::string all;
    for (const std::string& l : lines) all += l + "\n";
    REQUIRE(all.size() < 60000);  // within the pipe's buffer: no feeder thread needed
    REQUIRE(::write(in_[1], all.data(), all.size()) == static_cast<ssize_t>(all.size()));
    ::close(in_[1]);
    pose_fd_ = ::open((dir_ / "pose.txt").c_str(), O_CREAT | O_TRUNC | O_WRONLY, 0644);
    diag_fd_ = ::open((dir_ / "stderr.txt").c_str(), O_CREAT | O_TRUNC | O_WRONLY, 0644);
    REQUIRE(pose_fd_ >= 0);
    REQUIRE(diag_fd_ >= 0);
    auto db = MapDb::Open(map.db());
    REQUIRE_MESSAGE(db.ok(), db.status().ToString());
    db_ = std::move(db).value();
    options.pose_fd = pose_fd_;
    options.diagnostics_fd = diag_fd_;
    DaemonInput input;
    input.kind = DaemonInput::Kind::kFd;
    input.fd = in_[0];
    auto d = Daemon::Create(profile, *db_, input, options);
    REQUIRE_MESSAGE(d.ok(), d.status().ToString());
    daemon = std::move(d).value();
  }
  ~ImageSession() {
    daemon.reset();
    ::close(in_[0]);
    ::close(pose_fd_);
    ::close(diag_fd_);
  }
  int StepToEnd() {
    return test::StepToEnd([this] { return daemon->Step(); });
  }
  [[nodiscard]] std::vector<PoseLine> Poses() const {
    std::vector<PoseLine> out;
    for (const std::string& l : Lines(ReadAll(dir_ / "pose.txt"))) {
      if (l.rfind("pose ", 0) != 0) continue;
      PoseLine p;
      REQUIRE_MESSAGE(ParsePoseLine(l, &p), l);
      out.push_back(p);
    }
    return out;
  }
  [[nodiscard]] std::string Hello() const { return Lines(ReadAll(dir_ / "pose.txt")).at(0); }
  [[nodiscard]] std::vector<std::string> Diagnostics() const {
    return Lines(ReadAll(dir_ / "stderr.txt"));
  }
  std::unique_ptr<Daemon> daemon;

 private:
  std::filesystem::path dir_;
  std::unique_ptr<MapDb> db_;
  int in_[2] = {-1, -1};
  int pose_fd_ = -1, diag_fd_ = -1;
};

std::string Write(const std::filesystem::path& p, const cv::Mat& img) {
  REQUIRE(cv::imwrite(p.string(), img));
  return p.string();
}

std::string WriteBytes(const std::filesystem::path& p, const std::string& bytes) {
  std::ofstream(p, std::ios::binary) << bytes;
  return p.string();
}

DaemonOptions Images320() {
  DaemonOptions o;
  o.images = DaemonImages::kOn;
  o.image_width = 320;  // half the map camera's 640x480: a plain scale
  o.image_height = 240;
  return o;
}

TEST_CASE("image lines over a pipe: a pose line each, bad images on odometry, counted and named") {
  RoomsMap map(4, 10, "image_lines");
  const auto d = map.dir();
  const std::string jpg = Write(d / "a.jpg", Texture(320, 240, 1));
  const std::string png = Write(d / "b.png", Texture(320, 240, 2));
  const std::string depth = Write(d / "d.png", cv::Mat(240, 320, CV_16UC1, cv::Scalar(5000)));
  const std::string small = Write(d / "small.png", Texture(160, 120, 3));
  std::string png_bytes = ReadAll(png);
  const std::string cut = WriteBytes(d / "cut.png", png_bytes.substr(0, png_bytes.size() / 2));
  const std::string text = WriteBytes(d / "text.png", "this is not a PNG");
  const std::string empty = WriteBytes(d / "empty.png", "");
  const std::string huge =
      WriteBytes(d / "huge.png", std::string(400000, 'x').replace(0, 8, "\x89PNG\r\n\x1a\n"));
  const std::string missing = (d / "missing.png").string();

  const auto line = [&](double t, const std::string& colour, const std::string& dep) {
    return FormatImageLine(t, PoseFromXYYaw(1.0 + t, 5.0, 0.0), colour, dep);
  };
  const std::vector<std::string> in = {
      line(1, jpg, depth),              // processed, features extracted
      line(2, png, depth),              // processed
      line(3, jpg, "-"),                // a camera without depth: processed
      line(4, missing, depth),          // unreadable
      line(5, text, depth),             // unreadable: neither PNG nor JPEG
      line(6, empty, depth),            // unreadable: empty
      line(7, huge, depth),             // too large for the reserve
      line(8, jpg, missing),            // no depth
      line(9, cut, depth),              // front-end: truncated
      line(10, small, depth),           // front-end: wrong size
      line(2, jpg, depth),              // stamp going back: a refused line, no tick, no pose line
      "image 11 1 5 0 0 0 0 1 " + jpg,  // syntax: no depth path
      line(12, png, depth),             // processed after all that
  };
  ImageSession s(map, Images320(), in);
  s.daemon->Hello();
  CHECK(s.StepToEnd() == static_cast<int>(in.size()));
  CHECK(Contains(s.Hello(), " images 320x240"));

  const std::vector<PoseLine> poses = s.Poses();
  REQUIRE(poses.size() == 11);  // every image frame the gate let through, refused images too
  for (std::size_t i = 0; i < poses.size(); ++i) {
    CAPTURE(i);
    const double t = i < 10 ? static_cast<double>(i + 1) : 12.0;
    CHECK(poses[i].stamp_s == t);
    // Nothing in this map matches a texture: every pose is odometry under the correction.
    CHECK_FALSE(poses[i].loop_closure);
    CHECK(poses[i].pose.translation().x() == doctest::Approx(1.0 + t));
  }
  const TickLoop& loop = s.daemon->loop();
  CHECK(loop.totals().ticks == 11);
  CHECK(loop.totals().images_refused == 2);  // the front-end's two

  const ImageRefusalCounts& r = s.daemon->image_refusals();
  CHECK(r[ImageRefusal::kUnreadable] == 3);
  CHECK(r[ImageRefusal::kTooLarge] == 1);
  CHECK(r[ImageRefusal::kNoDepth] == 1);
  CHECK(r[ImageRefusal::kFrontEnd] == 2);
  CHECK(r.total == 7);
  CHECK(s.daemon->rejects()[RejectReason::kStampNotIncreasing] == 1);
  CHECK(s.daemon->rejects()[RejectReason::kSyntax] == 1);

  const nlohmann::json sum = s.daemon->Summary(false);
  CHECK(sum["images"]["enabled"] == true);
  CHECK(sum["images"]["width"] == 320);
  CHECK(sum["images"]["frames"] == 11);
  CHECK(sum["images"]["refused"] == 7);
  CHECK(sum["images"]["refused_by_reason"]["front_end"] == 2);
  CHECK(sum["images"]["reserve_bytes"] == MaxEncodedImageBytes(320, 240));
  CHECK(sum["malformed_lines"] == 2);

  // One line each, naming the file and, where there is one, the limit.
  const std::vector<std::string> diag = s.Diagnostics();
  const auto said = [&](const std::string& a, const std::string& b) {
    return std::count_if(diag.begin(), diag.end(), [&](const std::string& l) {
      return Contains(l, "ran on odometry") && Contains(l, a) && Contains(l, b);
    });
  };
  CHECK(said("(unreadable): colour image " + missing, "No such file or directory") == 1);
  CHECK(said("(unreadable): colour image " + text, "is neither PNG nor JPEG") == 1);
  CHECK(said("(unreadable): colour image " + empty, "is empty (0 bytes)") == 1);
  CHECK(said("(too_large): colour image " + huge,
             "is 400000 bytes, above the reserve of " +
                 std::to_string(MaxEncodedImageBytes(320, 240)) + " bytes for 320x240 images") ==
        1);
  CHECK(said("(no_depth): depth image " + missing, "No such file or directory") == 1);
  CHECK(said("(front_end): " + cut, "PNG") == 1);
  CHECK(said("(front_end): " + small, "is 160x120, expected 320x240") == 1);
  CHECK(said("input line 4 (stamp 4.000000)", "") == 1);
}

TEST_CASE(
    "image lines need a front-end: off, or auto on a map without a vocabulary, refuses them") {
  RoomsMap map(2, 10, "image_off");
  const std::string jpg = Write(map.dir() / "a.jpg", Texture(640, 480, 4));
  const std::vector<std::string> in = {
      FormatImageLine(1, PoseFromXYYaw(2, 5, 0), jpg, "-"),
      map.FrameLine(2, 3.0, true),
  };
  for (const DaemonImages mode : {DaemonImages::kOff, DaemonImages::kAuto}) {
    DaemonOptions o;
    o.images = mode;
    ImageSession s(map, o, in);
    s.daemon->Hello();
    CHECK(s.StepToEnd() == 2);
    CHECK(Contains(s.Hello(), " images off"));
    CHECK(s.Poses().size() == 1);  // the frame line only
    CHECK(s.daemon->rejects()[RejectReason::kNoFrontEnd] == 1);
    const std::vector<std::string> diag = s.Diagnostics();
    REQUIRE(diag.size() == 1);
    CHECK(Contains(diag[0],
                   "refused (no_front_end): an image line, but this zonemapd reads no images"));
    CHECK(s.daemon->Summary(false)["malformed_by_reason"]["no_front_end"] == 1);
  }
  // On: the map camera's size by default.
  ImageSession on(
      map,
      [] {
        DaemonOptions o;
        o.images = DaemonImages::kOn;
        return o;
      }(),
      in);
  CHECK(on.StepToEnd() == 2);
  CHECK(on.Poses().size() == 2);
  CHECK(on.daemon->images().width == 640);
  CHECK(on.daemon->image_refusals().total == 0);
  CHECK(on.daemon->loop().totals().images_refused == 0);
}

TEST_CASE("an image size that is not a plain scale of the map camera is refused at start") {
  RoomsMap map(2, 10, "image_size");
  auto db = MapDb::Open(map.db());
  REQUIRE(db.ok());
  DaemonInput input;
  input.kind = DaemonInput::Kind::kFd;
  int p[2];
  REQUIRE(::pipe(p) == 0);
  input.fd = p[0];
  DaemonOptions o = Images320();
  o.image_width = 320;
  o.image_height = 200;  // 640x480 is 4:3
  auto d = Daemon::Create(ImageProfile(), *db.value(), input, o);
  REQUIRE_FALSE(d.ok());
  CHECK(Contains(d.status().message(),
                 "images of 320x200 are not a plain scale of the map camera's 640x480"));
  o.images = DaemonImages::kAuto;  // no vocabulary: a size says images were meant
  o.image_height = 240;
  d = Daemon::Create(ImageProfile(), *db.value(), input, o);
  REQUIRE_FALSE(d.ok());
  CHECK(Contains(d.status().message(), "--images on"));
  ::close(p[0]);
  ::close(p[1]);
}

TEST_CASE("warm image steps allocate nothing: JPEG and PNG frames, and refused images") {
  auto heap = SqliteHeap::Install(64 << 20);
  REQUIRE_MESSAGE(heap.ok(), heap.status().ToString());
  RoomsMap map(4, 10, "image_alloc");
  const auto d = map.dir();
  const std::string jpg[2] = {Write(d / "a.jpg", Texture(320, 240, 5)),
                              Write(d / "b.jpg", Texture(320, 240, 6))};
  const std::string png = Write(d / "c.png", Texture(320, 240, 7));
  const std::string missing = (d / "missing.png").string();
  std::vector<std::string> in;
  double t = 0;
  for (int i = 0; i < 80; ++i) {
    const double x = 1.0 + std::fmod(i * 0.7, 38.0);
    const Pose3 odom = PoseFromXYYaw(x, 5.0, 0.0);
    t += 0.5;
    if (i % 7 == 3) {
      in.push_back(FormatImageLine(t, odom, missing, "-"));  // refused at the edge
    } else if (i % 7 == 5) {
      in.push_back(FormatImageLine(t, odom, jpg[0], missing));  // no depth
    } else if (i % 5 == 1) {
      in.push_back(FormatImageLine(t, odom, png, "-"));
    } else {
      in.push_back(FormatImageLine(t, odom, jpg[i % 2], "-"));
    }
    if (i % 11 == 4) in.push_back(map.FrameLine(t += 0.1, x, true));  // a host's features too
  }
  ImageSession s(map, Images320(), in);
  const int warm = 30;
  for (int i = 0; i < warm; ++i) REQUIRE(s.daemon->Step().value());
  const test::StepAllocations warm_steps =
      test::CountStepAllocations([&] { return s.daemon->Step(); });
  CHECK(warm_steps.steps == in.size() - warm);
  CHECK(warm_steps.news == 0);
#if ZM_ASAN
  // ASan owns malloc, so the C libraries' malloc calls inside the scratch scope reach it:
  // FAST's BufferArea (one per pyramid level, orb_extractor_test) and libpng's (its structs,
  // zlib's inflate state) per PNG frame. Their bytes are freed in the frame.
  MESSAGE("mallocs in the warm window under ASan: ", warm_steps.mallocs);
#else
  CHECK(warm_steps.mallocs == 0);
#endif
  CHECK(s.daemon->image_refusals()[ImageRefusal::kUnreadable] > 5);
  CHECK(s.daemon->image_refusals()[ImageRefusal::kNoDepth] > 5);
  CHECK(s.daemon->loop().totals().images_refused == 0);
}

}  // namespace
}  // namespace zm
