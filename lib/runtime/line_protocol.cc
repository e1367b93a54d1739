// Line protocol parser: std::from_chars over a string_view, writing into reserved vectors.
#include "runtime/line_protocol.h"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <limits>
#include <string>

namespace zm {
namespace {

class Cursor {
 public:
  explicit Cursor(std::string_view s) : s_(s) {}
  void SkipSpace() {
    while (pos_ < s_.size() && (s_[pos_] == ' ' || s_[pos_] == '\t' || s_[pos_] == '\r')) ++pos_;
  }
  [[nodiscard]] bool AtEnd() {
    SkipSpace();
    return pos_ >= s_.size();
  }
  std::string_view Token() {
    SkipSpace();
    const std::size_t start = pos_;
    while (pos_ < s_.size() && s_[pos_] != ' ' && s_[pos_] != '\t' && s_[pos_] != '\r') ++pos_;
    return s_.substr(start, pos_ - start);
  }
  // A finite number (from_chars refuses "inf", "nan" parses but is refused here; 1e309 is out of
  // range). Finite but absurd values (1e308 m) are the input gate's business.
  bool Double(double* out) {
    const std::string_view t = Token();
    if (t.empty()) return false;
    const auto r = std::from_chars(t.data(), t.data() + t.size(), *out);
    return r.ec == std::errc() && r.ptr == t.data() + t.size() && std::isfinite(*out);
  }
  bool Uint(std::uint64_t* out) {
    const std::string_view t = Token();
    if (t.empty()) return false;
    const auto r = std::from_chars(t.data(), t.data() + t.size(), *out);
    return r.ec == std::errc() && r.ptr == t.data() + t.size();
  }
  [[nodiscard]] std::size_t pos() const { return pos_; }

 private:
  std::string_view s_;
  std::size_t pos_ = 0;
};

int HexValue(char c) {
  if (c >= '0' && c <= '9') return c - '0';
  if (c >= 'a' && c <= 'f') return c - 'a' + 10;
  if (c >= 'A' && c <= 'F') return c - 'A' + 10;
  return -1;
}

LineKind Fail(LineError* e, const char* what, std::size_t column,
              RejectReason reason = RejectReason::kSyntax) {
  if (e != nullptr) *e = {what, column, reason};
  return LineKind::kMalformed;
}

// The stamp and odometry pose every frame and image line starts with. On success the frame holds
// them and nothing else: no features, no image (a Frame's buffers are passed around the session
// and the loop by swapping, so whatever an earlier frame left in them must go).
bool ParseStampPose(Cursor& c, InputLine* out, LineError* error, LineKind* failed) {
  double v[8];
  for (double& x : v) {
    if (!c.Double(&x)) {
      *failed = Fail(error, "bad number in stamp/pose", c.pos());
      return false;
    }
  }
  const Eigen::Quaterniond q(v[7], v[4], v[5], v[6]);  // w last on the wire, first in Eigen
  const double norm = q.norm();
  // Only a quaternion that cannot be normalised at all is refused here; how far from unit a
  // sane one may be is the input gate's tolerance ([input] quaternion_tolerance).
  if (!(norm > 1e-12) || !std::isfinite(norm)) {
    *failed =
        Fail(error, "quaternion has no length", c.pos(), RejectReason::kQuaternionNotUnit);
    return false;
  }
  Frame& frame = out->frame;
  frame.stamp_s = v[0];
  frame.odom = Pose3::Identity();
  Eigen::Quaterniond unit = q;
  unit.coeffs() /= norm;
  frame.odom.linear() = unit.toRotationMatrix();
  frame.odom.translation() = Eigen::Vector3d(v[1], v[2], v[3]);
  out->quaternion_norm = norm;
  frame.descriptors.clear();  // keeps capacity: no allocation
  frame.keypoints.clear();
  frame.colour_codec = ImageCodec::kNone;
  frame.colour.clear();
  frame.depth_codec = ImageCodec::kNone;
  frame.depth.clear();
  return true;
}

LineKind ParseFrame(Cursor& c, InputLine* out, LineError* error) {
  LineKind failed = LineKind::kMalformed;
  if (!ParseStampPose(c, out, error, &failed)) return failed;
  std::uint64_t n = 0;
  if (!c.Uint(&n)) return Fail(error, "bad feature count", c.pos());
  if (n > out->max_features()) {
    return Fail(error, "more features than the frame's capacity", c.pos(),
                RejectReason::kTooManyFeatures);
  }
  Frame& frame = out->frame;
  for (std::uint64_t i = 0; i < n; ++i) {
    double u = 0, w = 0;
    if (!c.Double(&u) || !c.Double(&w)) return Fail(error, "bad keypoint", c.pos());
    // Keypoints are stored as float: a larger value would be undefined to convert (found by
    // fuzz/line_protocol_fuzz.cc; fuzz/regressions/line_protocol/).
    constexpr double kFloatMax = 3.4028234663852886e38;  // FLT_MAX
    if (std::abs(u) > kFloatMax || std::abs(w) > kFloatMax) {
      return Fail(error, "keypoint out of float range", c.pos());
    }
    const std::string_view hex = c.Token();
    if (hex.size() != 2 * kDescriptorBytes) {
      return Fail(error, "descriptor is not 64 hex digits", c.pos());
    }
    Descriptor256 d;
    for (std::size_t b = 0; b < kDescriptorBytes; ++b) {
      const int hi = HexValue(hex[2 * b]);
      const int lo = HexValue(hex[2 * b + 1]);
      if (hi < 0 || lo < 0) return Fail(error, "bad hex digit in descriptor", c.pos());
      d[b] = static_cast<std::uint8_t>(hi * 16 + lo);
    }
    frame.descriptors.push_back(d);
    frame.keypoints.push_back(static_cast<float>(u));
    frame.keypoints.push_back(static_cast<float>(w));
  }
  if (!c.AtEnd()) return Fail(error, "trailing data after the last feature", c.pos());
  return LineKind::kFrame;
}

LineKind ParseImage(Cursor& c, InputLine* out, LineError* error) {
  LineKind failed = LineKind::kMalformed;
  if (!ParseStampPose(c, out, error, &failed)) return failed;
  const std::string_view colour = c.Token();
  if (colour.empty()) return Fail(error, "missing colour image path", c.pos());
  if (colour.size() > kMaxImagePathBytes) {
    return Fail(error, "colour image path longer than 4095 bytes", c.pos());
  }
  const std::string_view depth = c.Token();
  if (depth.empty()) return Fail(error, "missing depth image path ('-' for none)", c.pos());
  if (depth.size() > kMaxImagePathBytes) {
    return Fail(error, "depth image path longer than 4095 bytes", c.pos());
  }
  if (!c.AtEnd()) return Fail(error, "trailing data after the depth image path", c.pos());
  out->colour_path = colour;
  out->depth_path = depth;
  return LineKind::kImage;
}

LineKind ParseRoute(Cursor& c, InputLine* out, LineError* error) {
  std::uint64_t n = 0;
  if (!c.Uint(&n)) return Fail(error, "bad waypoint count", c.pos());
  if (n > out->max_waypoints()) {
    return Fail(error, "more waypoints than reserved ([input] max_route_waypoints)", c.pos(),
                RejectReason::kRouteTooLong);
  }
  out->waypoints.clear();  // keeps capacity
  for (std::uint64_t i = 0; i < n; ++i) {
    double x = 0, y = 0, z = 0;
    if (!c.Double(&x) || !c.Double(&y) || !c.Double(&z)) {
      return Fail(error, "bad waypoint coordinate", c.pos());
    }
    out->waypoints.emplace_back(x, y, z);
  }
  if (!c.AtEnd()) return Fail(error, "trailing data after the last waypoint", c.pos());
  return LineKind::kRoute;
}

LineKind ParseBudget(Cursor& c, InputLine* out, LineError* error) {
  std::uint64_t k = 0;
  if (!c.Uint(&k)) return Fail(error, "bad keyframe count", c.pos());
  if (!c.AtEnd()) return Fail(error, "trailing data after the keyframe count", c.pos());
  if (k == 0 || k > std::numeric_limits<std::uint32_t>::max()) {
    return Fail(error, "budget must be 1 .. 4294967295 keyframes", c.pos(),
                RejectReason::kBudgetInvalid);
  }
  out->budget_keyframes = k;
  return LineKind::kBudget;
}

}  // namespace

const char* RejectReasonName(RejectReason reason) {
  switch (reason) {
    case RejectReason::kSyntax: return "syntax";
    case RejectReason::kLineTooLong: return "line_too_long";
    case RejectReason::kTooManyFeatures: return "too_many_features";
    case RejectReason::kStampNotIncreasing: return "stamp_not_increasing";
    case RejectReason::kStampOutOfRange: return "stamp_out_of_range";
    case RejectReason::kPositionOutsideMap: return "position_outside_map";
    case RejectReason::kQuaternionNotUnit: return "quaternion_not_unit";
    case RejectReason::kRouteTooLong: return "route_too_long";
    case RejectReason::kRouteOutsideMap: return "route_outside_map";
    case RejectReason::kBudgetInvalid: return "budget_invalid";
    case RejectReason::kNoFrontEnd: return "no_front_end";
    case RejectReason::kCount: break;
  }
  return "unknown";
}

void InputLine::Reserve(std::uint32_t max_features, std::uint32_t max_waypoints) {
  frame.Reserve(max_features);
  waypoints.reserve(max_waypoints);
  max_features_ = max_features;
  max_waypoints_ = max_waypoints;
}

std::size_t MaxInputLineBytes(std::uint32_t max_features, std::uint32_t max_waypoints) {
  // Numbers up to 24 characters (%.17g of any double), one separator each.
  const std::size_t frame = 512 + std::size_t{max_features} * (2 * 25 + 2 * kDescriptorBytes + 1);
  const std::size_t route = 64 + std::size_t{max_waypoints} * 3 * 25;
  const std::size_t image = 512 + 2 * (kMaxImagePathBytes + 1);
  return std::max({frame, route, image});
}

LineKind ParseInputLine(std::string_view line, InputLine* out, LineError* error) {
  Cursor c(line);
  if (c.AtEnd()) return LineKind::kIgnored;
  const std::string_view head = c.Token();
  if (!head.empty() && head.front() == '#') return LineKind::kIgnored;
  if (head == "frame") return ParseFrame(c, out, error);
  if (head == "image") return ParseImage(c, out, error);
  if (head == "route") return ParseRoute(c, out, error);
  if (head == "budget") return ParseBudget(c, out, error);
  return Fail(error, "line does not start with 'frame', 'image', 'route' or 'budget'", 0);
}

std::string FormatFrameLine(const Frame& frame) {
  const Eigen::Quaterniond q(frame.odom.linear());
  const Eigen::Vector3d t = frame.odom.translation();
  char buf[256];
  std::snprintf(buf, sizeof buf, "frame %.9g %.9g %.9g %.9g %.9g %.9g %.9g %.9g %u", frame.stamp_s,
                t.x(), t.y(), t.z(), q.x(), q.y(), q.z(), q.w(), frame.feature_count());
  std::string out = buf;
  static const char* kHex = "0123456789abcdef";
  for (std::uint32_t i = 0; i < frame.feature_count(); ++i) {
    std::snprintf(buf, sizeof buf, " %.9g %.9g ", static_cast<double>(frame.keypoints[2 * i]),
                  static_cast<double>(frame.keypoints[2 * i + 1]));
    out += buf;
    for (std::uint8_t b : frame.descriptors[i]) {
      out += kHex[b >> 4];
      out += kHex[b & 15];
    }
  }
  return out;
}

std::string FormatImageLine(double stamp_s, const Pose3& odom, std::string_view colour_path,
                            std::string_view depth_path) {
  const Eigen::Quaterniond q(odom.linear());
  const Eigen::Vector3d t = odom.translation();
  char buf[256];
  // Stamps with microseconds, as TUM's files and a camera driver's clock give them. A stamp no
  // clock gives (the fuzzer's 1e302) would print 300 digits and be cut at the buffer, so the
  // line would not parse back: beyond 1e15 s it is written in %.17g, short and exact.
  const int n = std::abs(stamp_s) < 1e15
                    ? std::snprintf(buf, sizeof buf, "image %.6f ", stamp_s)
                    : std::snprintf(buf, sizeof buf, "image %.17g ", stamp_s);
  std::snprintf(buf + n, sizeof buf - static_cast<std::size_t>(n),
                "%.9g %.9g %.9g %.9g %.9g %.9g %.9g ", t.x(), t.y(), t.z(), q.x(), q.y(), q.z(),
                q.w());
  std::string out = buf;
  out += colour_path;
  out += ' ';
  out += depth_path;
  return out;
}

std::string FormatRouteLine(std::span<const Eigen::Vector3d> waypoints) {
  std::string out = "route " + std::to_string(waypoints.size());
  char buf[96];
  for (const Eigen::Vector3d& p : waypoints) {
    std::snprintf(buf, sizeof buf, " %.9g %.9g %.9g", p.x(), p.y(), p.z());
    out += buf;
  }
  return out;
}

}  // namespace zm
