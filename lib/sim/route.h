// Robot motion for the simulated runs: an A* planner per floor (8-connected, on a coarse grid of
// ~0.2 m cells whose centres have at least the robot radius of clearance, with a cost that keeps
// paths off the walls, then shortcut where the straight line keeps the clearance), and a
// trajectory builder that turns in place to each leg's heading and drives it at constant speed,
// sampled at a fixed period.
//
// Invariants: every path point lies in a cell with clearance >= robot radius (start and goal are
// snapped to the nearest such cell); samples are equally spaced in time; yaw is continuous
// between samples (turns take time); a floor change happens only at the elevator (xy fixed).
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <vector>

#include "geometry/pose.h"
#include "sim/building.h"

namespace zm::sim {

class Planner {
 public:
  Planner(const SimGrid& grid, double robot_radius_m);

  // Polyline from a to b (metres), empty when b is not reachable from a.
  [[nodiscard]] std::vector<Eigen::Vector2d> Plan(const Eigen::Vector2d& a, const Eigen::Vector2d& b);
  // True when p snaps to a traversable cell connected to `from`.
  [[nodiscard]] bool Connected(const Eigen::Vector2d& from, const Eigen::Vector2d& p) const;
  // True when the fine cell at p has at least the robot radius of clearance.
  [[nodiscard]] bool Clear(const Eigen::Vector2d& p) const;

 private:
  [[nodiscard]] int Snap(const Eigen::Vector2d& p) const;  // coarse index or -1
  [[nodiscard]] Eigen::Vector2d Centre(int idx) const;
  [[nodiscard]] bool SegmentClear(const Eigen::Vector2d& a, const Eigen::Vector2d& b) const;

  const SimGrid* grid_;
  double radius_m_;
  int factor_ = 1;     // fine cells per coarse cell side
  int cx_ = 0, cy_ = 0;  // coarse size
  std::vector<float> clearance_m_;  // fine, bottom-up like the grid
  std::vector<float> coarse_clear_m_;  // coarse: clearance at the centre fine cell, 0 = blocked
  std::vector<std::int32_t> component_;  // coarse connected components (-1 blocked)
  // A* scratch, reused between calls.
  std::vector<float> g_;
  std::vector<std::int32_t> parent_;
  std::vector<std::uint32_t> stamp_;
  std::uint32_t search_ = 0;
};

struct PoseSample {
  double t_s = 0.0;
  int floor = 0;
  double x = 0.0, y = 0.0, yaw = 0.0, z = 0.0;  // z: body height in the map frame
  [[nodiscard]] Pose3 pose() const { return PoseFromXYYaw(x, y, yaw, z); }
};

struct MotionOptions {
  double speed_mps = 0.8;
  double turn_rate_dps = 45.0;
  double elevator_speed_mps = 1.0;
};

class TrajectoryBuilder {
 public:
  TrajectoryBuilder(const MotionOptions& motion, double period_s, double camera_height_m,
                    double floor_height_m);
  void Start(int floor, const Eigen::Vector2d& xy, double yaw);
  // Follows the polyline (its first point is the current position or close to it).
  void Drive(const std::vector<Eigen::Vector2d>& path);
  void Spin(double angle_rad);
  void ChangeFloor(int floor);

  [[nodiscard]] const std::vector<PoseSample>& samples() const { return samples_; }
  [[nodiscard]] Eigen::Vector2d position() const { return {cur_.x, cur_.y}; }
  [[nodiscard]] int floor() const { return cur_.floor; }
  [[nodiscard]] double time() const { return cur_.t_s; }

 private:
  // Advances the state to `end` linearly over `duration` seconds, emitting due samples.
  void Move(const PoseSample& end, double duration);
  void TurnTo(double yaw);

  MotionOptions motion_;
  double period_s_;
  double camera_height_m_;
  double floor_height_m_;
  PoseSample cur_;
  double next_sample_t_ = 0.0;
  std::vector<PoseSample> samples_;
};

}  // namespace zm::sim
