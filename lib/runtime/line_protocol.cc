// Line protocol parser: std::from_chars over a string_view, writing into reserved vectors.
#include "runtime/line_protocol.h"

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

LineKind Fail(LineError* e, const char* what, std::size_t column) {
  if (e != nullptr) *e = {what, column};
  return LineKind::kMalformed;
}

}  // namespace

LineKind ParseFrameLine(std::string_view line, std::size_t max_features, Frame* frame,
                        LineError* error) {
  Cursor c(line);
  if (c.AtEnd()) return LineKind::kIgnored;
  const std::string_view head = c.Token();
  if (!head.empty() && head.front() == '#') return LineKind::kIgnored;
  if (head != "frame") return Fail(error, "line does not start with 'frame'", 0);

  double v[8];
  for (double& x : v) {
    if (!c.Double(&x)) return Fail(error, "bad number in stamp/pose", c.pos());
  }
  const Eigen::Quaterniond q(v[7], v[4], v[5], v[6]);  // w last on the wire, first in Eigen
  const double norm = q.norm();
  if (norm < 0.5 || norm > 1.5) return Fail(error, "quaternion is not unit length", c.pos());
  std::uint64_t n = 0;
  if (!c.Uint(&n)) return Fail(error, "bad feature count", c.pos());
  if (n > max_features) return Fail(error, "more features than the frame's capacity", c.pos());

  frame->stamp_s = v[0];
  frame->odom = Pose3::Identity();
  frame->odom.linear() = q.normalized().toRotationMatrix();
  frame->odom.translation() = Eigen::Vector3d(v[1], v[2], v[3]);
  frame->descriptors.clear();  // keeps capacity: no allocation
  frame->keypoints.clear();
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
    frame->descriptors.push_back(d);
    frame->keypoints.push_back(static_cast<float>(u));
    frame->keypoints.push_back(static_cast<float>(w));
  }
  if (!c.AtEnd()) return Fail(error, "trailing data after the last feature", c.pos());
  return LineKind::kFrame;
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

}  // namespace zm
