// Trajectories (stamped SE(3) poses) and their file formats, as evo reads and writes them.
//
//   TUM:   one pose a line, "stamp tx ty tz qx qy qz qw" (quaternion w last), '#' comments,
//          fields separated by spaces, tabs or commas. The quaternion is normalised on read
//          (evo's quaternion_matrix does the same), so a slightly non-unit file is accepted.
//   KITTI: one pose a line, the 3x4 row-major matrix [R | t] (12 numbers), no stamps; on read
//          the stamps are the line indices 0, 1, 2, ... and has_stamps is false.
//
// Invariant: stamps_s.size() == poses.size(). Readers never throw; a bad line is an error
// naming the file and the line number.
#pragma once

#include <string>
#include <string_view>
#include <vector>

#include "common/status.h"
#include "geometry/pose.h"

namespace zm {

enum class TrajectoryFormat { kTum, kKitti };

struct Trajectory {
  std::vector<double> stamps_s;  // seconds; KITTI: pose indices
  std::vector<Pose3> poses;      // T_world_body (or camera), metres
  bool has_stamps = true;        // false for KITTI (pair by index, never by time)

  [[nodiscard]] std::size_t size() const { return poses.size(); }
  void Add(double stamp_s, const Pose3& pose) {
    stamps_s.push_back(stamp_s);
    poses.push_back(pose);
  }
};

// Parses text in the given format; `name` labels errors (usually the path).
[[nodiscard]] Result<Trajectory> ParseTrajectory(std::string_view text, TrajectoryFormat format,
                                                 std::string_view name = "trajectory");
[[nodiscard]] Result<Trajectory> ReadTrajectory(const std::string& path, TrajectoryFormat format);
// Formats with 9 significant decimals (stamps with 6), enough to round-trip to < 1e-9 m.
[[nodiscard]] std::string FormatTrajectory(const Trajectory& traj, TrajectoryFormat format);
[[nodiscard]] Status WriteTrajectory(const std::string& path, const Trajectory& traj,
                                     TrajectoryFormat format);

// "tum" / "kitti" -> format; anything else is an error naming the accepted values.
[[nodiscard]] Result<TrajectoryFormat> ParseTrajectoryFormat(std::string_view name);

}  // namespace zm
