// The pose line: status and covariance tracking, formatting and parsing (see pose_output.h).
#include "runtime/pose_output.h"

#include <algorithm>
#include <charconv>
#include <cmath>

#include "runtime/text_line.h"

namespace zm {
namespace {

constexpr double kDegToRad = M_PI / 180.0;

Eigen::Matrix3d Hat(const Eigen::Vector3d& w) {
  Eigen::Matrix3d m;
  m << 0.0, -w.z(), w.y(), w.z(), 0.0, -w.x(), -w.y(), w.x(), 0.0;
  return m;
}

// Largest eigenvalue of a symmetric 2x2 block, closed form.
double LargestEigen2(double a, double b, double d) {
  const double mean = 0.5 * (a + d);
  const double diff = 0.5 * (a - d);
  return mean + std::sqrt(diff * diff + b * b);
}

TextLine& AppendPose(TextLine& t, const Pose3& p) {
  const Eigen::Quaterniond q(p.linear());
  const Eigen::Vector3d& x = p.translation();
  t.Sp().Fixed(x.x(), 6).Sp().Fixed(x.y(), 6).Sp().Fixed(x.z(), 6);
  t.Sp().Fixed(q.x(), 9).Sp().Fixed(q.y(), 9).Sp().Fixed(q.z(), 9).Sp().Fixed(q.w(), 9);
  return t;
}

// Token-by-token reader for ParsePoseLine.
class Tokens {
 public:
  explicit Tokens(std::string_view s) : s_(s) {}
  std::string_view Next() {
    while (pos_ < s_.size() && (s_[pos_] == ' ' || s_[pos_] == '\n' || s_[pos_] == '\r')) ++pos_;
    const std::size_t start = pos_;
    while (pos_ < s_.size() && s_[pos_] != ' ' && s_[pos_] != '\n' && s_[pos_] != '\r') ++pos_;
    return s_.substr(start, pos_ - start);
  }
  template <class T>
  bool Number(T* out) {
    const std::string_view t = Next();
    if (t.empty()) return false;
    const auto r = std::from_chars(t.data(), t.data() + t.size(), *out);
    return r.ec == std::errc() && r.ptr == t.data() + t.size();
  }
  bool Pose(Pose3* p) {
    double v[7];
    for (double& x : v) {
      if (!Number(&x)) return false;
    }
    Eigen::Quaterniond q(v[6], v[3], v[4], v[5]);
    if (!(q.norm() > 0.5)) return false;
    *p = Pose3::Identity();
    p->linear() = q.normalized().toRotationMatrix();
    p->translation() = Eigen::Vector3d(v[0], v[1], v[2]);
    return true;
  }
  [[nodiscard]] bool AtEnd() {
    while (pos_ < s_.size() && (s_[pos_] == ' ' || s_[pos_] == '\n' || s_[pos_] == '\r')) ++pos_;
    return pos_ >= s_.size();
  }

 private:
  std::string_view s_;
  std::size_t pos_ = 0;
};

}  // namespace

const char* LocalizationStatusName(LocalizationStatus s) {
  switch (s) {
    case LocalizationStatus::kLocalized: return "localized";
    case LocalizationStatus::kDeadReckoning: return "dead_reckoning";
    case LocalizationStatus::kLost: return "lost";
  }
  return "lost";
}

PoseTracker::PoseTracker(const PoseOutputOptions& options) : options_(options) {
  const double s2 = options.initial_sigma_m * options.initial_sigma_m;
  const double r = options.initial_sigma_deg * kDegToRad;
  cov_ = Covariance6::Zero();
  cov_.diagonal() << s2, s2, s2, r * r, r * r, r * r;
  const double m2 = options.map_sigma_m * options.map_sigma_m;
  const double mr = options.map_sigma_deg * kDegToRad;
  map_floor_ = Covariance6::Zero();
  map_floor_.diagonal() << m2, m2, m2, mr * mr, mr * mr, mr * mr;
}

void PoseTracker::Update(const TickRecord& record) {
  const Eigen::Vector3d position = record.pose.translation();
  if (record.loop_closure && record.closure_covariance.allFinite()) {
    cov_ = record.closure_covariance + map_floor_;
  } else if (has_last_) {
    // EKF prediction with the frame's displacement (see the header). A closure whose PnP
    // covariance could not be computed (singular normal equations) keeps the propagated one.
    const Eigen::Vector3d dp = position - last_position_;
    Covariance6 f = Covariance6::Identity();
    f.topRightCorner<3, 3>() = -Hat(dp);
    cov_ = (f * cov_ * f.transpose()).eval();
    const double travelled = dp.head<2>().norm();
    const double a = options_.odom_sigma_m_per_sqrt_m * options_.odom_sigma_m_per_sqrt_m;
    const double b = options_.odom_sigma_deg_per_sqrt_m * kDegToRad;
    cov_(0, 0) += a * travelled;
    cov_(1, 1) += a * travelled;
    cov_(5, 5) += b * b * travelled;
  }
  if (record.loop_closure) {
    frames_since_fix_ = 0;
    ever_localized_ = true;
  } else {
    ++frames_since_fix_;
  }
  last_position_ = position;
  has_last_ = true;
  sigma_xy_m_ = std::sqrt(std::max(
      0.0, LargestEigen2(cov_(0, 0), 0.5 * (cov_(0, 1) + cov_(1, 0)), cov_(1, 1))));
  if (record.loop_closure) {
    status_ = LocalizationStatus::kLocalized;
  } else {
    status_ = sigma_xy_m_ > options_.lost_sigma_m ? LocalizationStatus::kLost
                                                   : LocalizationStatus::kDeadReckoning;
  }
}

PoseLine PoseLineOf(const TickRecord& r, const PoseTracker& tracker) {
  PoseLine p;
  p.stamp_s = r.stamp_s;
  p.pose = r.pose;
  p.map_from_odom = r.map_from_odom;
  p.status = tracker.status();
  p.frames_since_fix = tracker.frames_since_fix();
  p.zone = r.zone.value;
  p.loop_closure = r.loop_closure;
  p.inliers = r.inliers;
  p.resident_keyframes = r.resident_keyframes;
  p.k_max = r.k_max;
  p.tick_ms = r.tick_ms;
  p.malformed = r.malformed_lines;
  p.covariance = tracker.covariance();
  return p;
}

std::size_t FormatPoseLine(const PoseLine& l, char* buf, std::size_t capacity) {
  TextLine t(buf, capacity);
  t.Str("pose").Sp().Fixed(l.stamp_s, 6);
  AppendPose(t, l.pose);
  t.Sp().I64(l.version);
  AppendPose(t, l.map_from_odom);
  t.Sp().Str(LocalizationStatusName(l.status)).Sp().U64(l.frames_since_fix);
  t.Sp().I64(l.zone).Sp().U64(l.loop_closure ? 1 : 0).Sp().U64(l.inliers);
  t.Sp().U64(l.resident_keyframes).Sp().U64(l.k_max).Sp().Fixed(l.tick_ms, 3);
  t.Sp().U64(l.malformed);
  for (int r = 0; r < 6; ++r) {
    for (int c = 0; c < 6; ++c) t.Sp().General(l.covariance(r, c), 6);
  }
  t.Char('\n');
  return t.ok() ? t.size() : 0;
}

bool ParsePoseLine(std::string_view text, PoseLine* out) {
  Tokens k(text);
  if (k.Next() != "pose") return false;
  if (!k.Number(&out->stamp_s) || !k.Pose(&out->pose)) return false;
  if (!k.Number(&out->version) || out->version != kPoseProtocolVersion) return false;
  if (!k.Pose(&out->map_from_odom)) return false;
  const std::string_view status = k.Next();
  if (status == "localized") {
    out->status = LocalizationStatus::kLocalized;
  } else if (status == "dead_reckoning") {
    out->status = LocalizationStatus::kDeadReckoning;
  } else if (status == "lost") {
    out->status = LocalizationStatus::kLost;
  } else {
    return false;
  }
  int closure = 0;
  if (!k.Number(&out->frames_since_fix) || !k.Number(&out->zone) || !k.Number(&closure) ||
      (closure != 0 && closure != 1) || !k.Number(&out->inliers) ||
      !k.Number(&out->resident_keyframes) || !k.Number(&out->k_max) || !k.Number(&out->tick_ms) ||
      !k.Number(&out->malformed)) {
    return false;
  }
  out->loop_closure = closure == 1;
  for (int r = 0; r < 6; ++r) {
    for (int c = 0; c < 6; ++c) {
      if (!k.Number(&out->covariance(r, c))) return false;
    }
  }
  return k.AtEnd();
}

std::size_t RouteAckMaxBytes(std::size_t zones) { return 64 + zones * 12; }

std::size_t FormatRouteAck(bool accepted, std::uint64_t waypoints, std::span<const ZoneId> zones,
                           char* buf, std::size_t capacity) {
  TextLine t(buf, capacity);
  t.Str("ack route ").Str(accepted ? "ok" : "rejected").Sp().U64(waypoints).Sp().U64(zones.size());
  for (ZoneId z : zones) t.Sp().I64(z.value);
  t.Char('\n');
  return t.ok() ? t.size() : 0;
}

std::size_t FormatBudgetAck(const char* outcome, std::uint64_t requested, std::uint32_t k_max,
                            std::uint32_t resident, std::uint32_t unloaded, char* buf,
                            std::size_t capacity) {
  TextLine t(buf, capacity);
  t.Str("ack budget ").Str(outcome).Sp().U64(requested).Sp().U64(k_max).Sp().U64(resident);
  t.Sp().U64(unloaded).Char('\n');
  return t.ok() ? t.size() : 0;
}

}  // namespace zm
