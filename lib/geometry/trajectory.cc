// TUM and KITTI trajectory I/O (see trajectory.h for the formats and evo compatibility).
#include "geometry/trajectory.h"

#include <array>
#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <sstream>

namespace zm {
namespace {

// Splits one line into numbers; separators are spaces, tabs and commas. Returns the count
// parsed, or -1 on a token that is not a number.
int ParseNumbers(std::string_view line, std::array<double, 16>* out) {
  int count = 0;
  std::size_t i = 0;
  while (i < line.size()) {
    const char c = line[i];
    if (c == ' ' || c == '\t' || c == ',' || c == '\r') {
      ++i;
      continue;
    }
    std::size_t j = i;
    while (j < line.size() && line[j] != ' ' && line[j] != '\t' && line[j] != ',' &&
           line[j] != '\r') {
      ++j;
    }
    if (count >= static_cast<int>(out->size())) return count + 1;  // too many: caller rejects
    const std::string token(line.substr(i, j - i));
    char* end = nullptr;
    errno = 0;
    const double v = std::strtod(token.c_str(), &end);
    if (end != token.c_str() + token.size() || errno == ERANGE) return -1;
    (*out)[static_cast<std::size_t>(count++)] = v;
    i = j;
  }
  return count;
}

}  // namespace

Result<TrajectoryFormat> ParseTrajectoryFormat(std::string_view name) {
  if (name == "tum") return TrajectoryFormat::kTum;
  if (name == "kitti") return TrajectoryFormat::kKitti;
  return InvalidArgument("unknown trajectory format '" + std::string(name) +
                         "' (expected tum or kitti)");
}

Result<Trajectory> ParseTrajectory(std::string_view text, TrajectoryFormat format,
                                   std::string_view name) {
  Trajectory traj;
  traj.has_stamps = format == TrajectoryFormat::kTum;
  const int expected = format == TrajectoryFormat::kTum ? 8 : 12;
  std::size_t line_no = 0;
  std::size_t pos = 0;
  std::array<double, 16> v{};
  while (pos < text.size()) {
    std::size_t eol = text.find('\n', pos);
    if (eol == std::string_view::npos) eol = text.size();
    std::string_view line = text.substr(pos, eol - pos);
    pos = eol + 1;
    ++line_no;
    const std::size_t first = line.find_first_not_of(" \t\r");
    if (first == std::string_view::npos || line[first] == '#') continue;
    const int n = ParseNumbers(line, &v);
    if (n != expected) {
      return InvalidArgument(std::string(name) + ":" + std::to_string(line_no) + ": expected " +
                             std::to_string(expected) + " numbers for " +
                             (format == TrajectoryFormat::kTum ? "TUM" : "KITTI") + ", got " +
                             (n < 0 ? std::string("a non-number") : std::to_string(n)));
    }
    Pose3 pose = Pose3::Identity();
    if (format == TrajectoryFormat::kTum) {
      Eigen::Quaterniond q(v[7], v[4], v[5], v[6]);  // w, x, y, z
      const double norm = q.norm();
      if (!(norm > 1e-12)) {
        return InvalidArgument(std::string(name) + ":" + std::to_string(line_no) +
                               ": zero quaternion");
      }
      q.coeffs() /= norm;
      pose.linear() = q.toRotationMatrix();
      pose.translation() = Eigen::Vector3d(v[1], v[2], v[3]);
      traj.Add(v[0], pose);
    } else {
      Eigen::Matrix3d r;
      r << v[0], v[1], v[2], v[4], v[5], v[6], v[8], v[9], v[10];
      pose.linear() = r;
      pose.translation() = Eigen::Vector3d(v[3], v[7], v[11]);
      traj.Add(static_cast<double>(traj.size()), pose);
    }
  }
  return traj;
}

Result<Trajectory> ReadTrajectory(const std::string& path, TrajectoryFormat format) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return NotFound("cannot open trajectory file " + path);
  std::ostringstream ss;
  ss << in.rdbuf();
  if (in.bad()) return IoError("cannot read trajectory file " + path);
  return ParseTrajectory(ss.str(), format, path);
}

std::string FormatTrajectory(const Trajectory& traj, TrajectoryFormat format) {
  std::string out;
  char buf[512];
  for (std::size_t i = 0; i < traj.size(); ++i) {
    const Pose3& p = traj.poses[i];
    const Eigen::Vector3d t = p.translation();
    int n = 0;
    if (format == TrajectoryFormat::kTum) {
      Eigen::Quaterniond q(p.linear());
      q.normalize();
      n = std::snprintf(buf, sizeof buf, "%.6f %.9f %.9f %.9f %.9f %.9f %.9f %.9f\n",
                        traj.stamps_s[i], t.x(), t.y(), t.z(), q.x(), q.y(), q.z(), q.w());
    } else {
      const Eigen::Matrix3d& r = p.linear();
      n = std::snprintf(buf, sizeof buf,
                        "%.9e %.9e %.9e %.9e %.9e %.9e %.9e %.9e %.9e %.9e %.9e %.9e\n", r(0, 0),
                        r(0, 1), r(0, 2), t.x(), r(1, 0), r(1, 1), r(1, 2), t.y(), r(2, 0), r(2, 1),
                        r(2, 2), t.z());
    }
    if (n > 0) out.append(buf, static_cast<std::size_t>(n));
  }
  return out;
}

Status WriteTrajectory(const std::string& path, const Trajectory& traj, TrajectoryFormat format) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  if (!out) return IoError("cannot create trajectory file " + path);
  if (format == TrajectoryFormat::kTum) out << "# timestamp tx ty tz qx qy qz qw\n";
  out << FormatTrajectory(traj, format);
  out.flush();
  if (!out) return IoError("cannot write trajectory file " + path);
  return Status::Ok();
}

}  // namespace zm
