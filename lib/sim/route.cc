// A* planning and trajectory sampling (see route.h).
#include "sim/route.h"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>
#include <queue>

namespace zm::sim {

Planner::Planner(const SimGrid& grid, double robot_radius_m) : grid_(&grid), radius_m_(robot_radius_m) {
  cv::Mat free_mask(grid.rows, grid.cols, CV_8UC1);
  for (int r = 0; r < grid.rows; ++r) {
    auto* row = free_mask.ptr<std::uint8_t>(r);
    for (int c = 0; c < grid.cols; ++c) row[c] = grid.Free(c, r) ? 255 : 0;
  }
  cv::Mat dist;
  cv::distanceTransform(free_mask, dist, cv::DIST_L2, cv::DIST_MASK_5);
  clearance_m_.resize(grid.cells.size());
  for (int r = 0; r < grid.rows; ++r) {
    const float* row = dist.ptr<float>(r);
    for (int c = 0; c < grid.cols; ++c) {
      clearance_m_[grid.Index(c, r)] = row[c] * static_cast<float>(grid.resolution_m);
    }
  }
  factor_ = std::max(1, static_cast<int>(std::lround(0.2 / grid.resolution_m)));
  cx_ = grid.cols / factor_;
  cy_ = grid.rows / factor_;
  const std::size_t n = static_cast<std::size_t>(cx_) * static_cast<std::size_t>(cy_);
  coarse_clear_m_.assign(n, 0.0f);
  for (int j = 0; j < cy_; ++j) {
    for (int i = 0; i < cx_; ++i) {
      const int c = i * factor_ + factor_ / 2, r = j * factor_ + factor_ / 2;
      const float cl = clearance_m_[grid.Index(c, r)];
      if (static_cast<double>(cl) >= radius_m_) coarse_clear_m_[static_cast<std::size_t>(j * cx_ + i)] = cl;
    }
  }
  // Connected components (8-connected, like the search).
  component_.assign(n, -1);
  std::int32_t next = 0;
  std::vector<int> stack;
  for (std::size_t s = 0; s < n; ++s) {
    if (coarse_clear_m_[s] <= 0.0f || component_[s] >= 0) continue;
    component_[s] = next;
    stack.push_back(static_cast<int>(s));
    while (!stack.empty()) {
      const int u = stack.back();
      stack.pop_back();
      const int ui = u % cx_, uj = u / cx_;
      for (int dj = -1; dj <= 1; ++dj) {
        for (int di = -1; di <= 1; ++di) {
          const int vi = ui + di, vj = uj + dj;
          if ((di == 0 && dj == 0) || vi < 0 || vj < 0 || vi >= cx_ || vj >= cy_) continue;
          const auto v = static_cast<std::size_t>(vj * cx_ + vi);
          if (coarse_clear_m_[v] <= 0.0f || component_[v] >= 0) continue;
          component_[v] = next;
          stack.push_back(static_cast<int>(v));
        }
      }
    }
    ++next;
  }
  g_.assign(n, 0.0f);
  parent_.assign(n, -1);
  stamp_.assign(n, 0);
}

Eigen::Vector2d Planner::Centre(int idx) const {
  const int i = idx % cx_, j = idx / cx_;
  return grid_->CellCentre(i * factor_ + factor_ / 2, j * factor_ + factor_ / 2);
}

bool Planner::Clear(const Eigen::Vector2d& p) const {
  int c, r;
  grid_->CellOf(p, &c, &r);
  return grid_->InBounds(c, r) && static_cast<double>(clearance_m_[grid_->Index(c, r)]) >= radius_m_;
}

int Planner::Snap(const Eigen::Vector2d& p) const {
  int c, r;
  grid_->CellOf(p, &c, &r);
  const int i0 = c / factor_, j0 = r / factor_;
  // Nearest traversable coarse cell within 3 m, searching rings outwards.
  const int max_ring = static_cast<int>(3.0 / (factor_ * grid_->resolution_m)) + 1;
  for (int ring = 0; ring <= max_ring; ++ring) {
    int best = -1;
    double best_d = 1e18;
    for (int j = j0 - ring; j <= j0 + ring; ++j) {
      for (int i = i0 - ring; i <= i0 + ring; ++i) {
        if (std::max(std::abs(i - i0), std::abs(j - j0)) != ring) continue;
        if (i < 0 || j < 0 || i >= cx_ || j >= cy_) continue;
        const int idx = j * cx_ + i;
        if (coarse_clear_m_[static_cast<std::size_t>(idx)] <= 0.0f) continue;
        const double d = (Centre(idx) - p).squaredNorm();
        if (d < best_d) {
          best_d = d;
          best = idx;
        }
      }
    }
    if (best >= 0) return best;
  }
  return -1;
}

bool Planner::Connected(const Eigen::Vector2d& from, const Eigen::Vector2d& p) const {
  const int a = Snap(from), b = Snap(p);
  return a >= 0 && b >= 0 && component_[static_cast<std::size_t>(a)] == component_[static_cast<std::size_t>(b)];
}

bool Planner::SegmentClear(const Eigen::Vector2d& a, const Eigen::Vector2d& b) const {
  const double len = (b - a).norm();
  const double step = grid_->resolution_m;
  const int n = std::max(1, static_cast<int>(std::ceil(len / step)));
  for (int k = 0; k <= n; ++k) {
    if (!Clear(a + (b - a) * (static_cast<double>(k) / n))) return false;
  }
  return true;
}

std::vector<Eigen::Vector2d> Planner::Plan(const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
  const int s = Snap(a), t = Snap(b);
  if (s < 0 || t < 0 || component_[static_cast<std::size_t>(s)] != component_[static_cast<std::size_t>(t)]) return {};
  ++search_;
  const double cell = factor_ * grid_->resolution_m;
  const Eigen::Vector2d goal = Centre(t);
  const auto h = [&](int idx) {
    const Eigen::Vector2d d = (Centre(idx) - goal).cwiseAbs() / cell;
    return static_cast<float>(cell * (std::max(d.x(), d.y()) + (std::numbers::sqrt2 - 1.0) * std::min(d.x(), d.y())));
  };
  using Item = std::pair<float, int>;
  std::priority_queue<Item, std::vector<Item>, std::greater<>> open;
  const auto S = [](int i) { return static_cast<std::size_t>(i); };
  g_[S(s)] = 0.0f;
  parent_[S(s)] = -1;
  stamp_[S(s)] = search_;
  open.emplace(h(s), s);
  while (!open.empty()) {
    const auto [fu, u] = open.top();
    open.pop();
    if (u == t) break;
    if (fu - h(u) > g_[S(u)] + 1e-4f) continue;  // stale entry
    const int ui = u % cx_, uj = u / cx_;
    for (int dj = -1; dj <= 1; ++dj) {
      for (int di = -1; di <= 1; ++di) {
        const int vi = ui + di, vj = uj + dj;
        if ((di == 0 && dj == 0) || vi < 0 || vj < 0 || vi >= cx_ || vj >= cy_) continue;
        const int v = vj * cx_ + vi;
        const float cl = coarse_clear_m_[S(v)];
        if (cl <= 0.0f) continue;
        if (di != 0 && dj != 0 &&
            (coarse_clear_m_[S(uj * cx_ + vi)] <= 0.0f || coarse_clear_m_[S(vj * cx_ + ui)] <= 0.0f)) {
          continue;  // no corner cutting
        }
        const float len = static_cast<float>(cell * ((di != 0 && dj != 0) ? std::numbers::sqrt2 : 1.0));
        const float penalty = 1.0f + 3.0f * std::max(0.0f, 0.8f - cl);
        const float g = g_[S(u)] + len * penalty;
        if (stamp_[S(v)] == search_ && g >= g_[S(v)]) continue;
        stamp_[S(v)] = search_;
        g_[S(v)] = g;
        parent_[S(v)] = u;
        open.emplace(g + h(v), v);
      }
    }
  }
  if (stamp_[S(t)] != search_) return {};
  std::vector<Eigen::Vector2d> raw;
  for (int v = t; v >= 0; v = parent_[S(v)]) raw.push_back(Centre(v));
  std::reverse(raw.begin(), raw.end());
  if (Clear(a)) raw.front() = a;
  if (Clear(b)) raw.back() = b;
  // Shortcut: from each kept point, jump to the farthest point before the first blocked segment.
  std::vector<Eigen::Vector2d> path = {raw.front()};
  std::size_t i = 0;
  while (i + 1 < raw.size()) {
    std::size_t j = i + 1;
    while (j + 1 < raw.size() && SegmentClear(raw[i], raw[j + 1])) ++j;
    path.push_back(raw[j]);
    i = j;
  }
  return path;
}

TrajectoryBuilder::TrajectoryBuilder(const MotionOptions& motion, double period_s,
                                     double camera_height_m, double floor_height_m)
    : motion_(motion), period_s_(period_s), camera_height_m_(camera_height_m),
      floor_height_m_(floor_height_m) {}

void TrajectoryBuilder::Start(int floor, const Eigen::Vector2d& xy, double yaw) {
  cur_ = {0.0, floor, xy.x(), xy.y(), yaw, floor * floor_height_m_ + camera_height_m_};
  samples_.push_back(cur_);
  next_sample_t_ = period_s_;
}

void TrajectoryBuilder::Move(const PoseSample& end, double duration) {
  const PoseSample start = cur_;
  const double t0 = start.t_s, t1 = t0 + duration;
  while (next_sample_t_ <= t1 + 1e-12) {
    const double a = duration > 0.0 ? (next_sample_t_ - t0) / duration : 1.0;
    PoseSample s;
    s.t_s = next_sample_t_;
    s.floor = a < 0.5 ? start.floor : end.floor;
    s.x = start.x + a * (end.x - start.x);
    s.y = start.y + a * (end.y - start.y);
    s.yaw = std::remainder(start.yaw + a * (end.yaw - start.yaw), 2.0 * std::numbers::pi);
    s.z = start.z + a * (end.z - start.z);
    samples_.push_back(s);
    next_sample_t_ += period_s_;
  }
  cur_ = end;
  cur_.t_s = t1;
  cur_.yaw = std::remainder(end.yaw, 2.0 * std::numbers::pi);
}

void TrajectoryBuilder::TurnTo(double yaw) {
  const double delta = std::remainder(yaw - cur_.yaw, 2.0 * std::numbers::pi);
  if (std::abs(delta) < 1e-9) return;
  Spin(delta);
}

void TrajectoryBuilder::Spin(double angle_rad) {
  PoseSample end = cur_;
  end.yaw = cur_.yaw + angle_rad;  // unwrapped: Move interpolates through the whole turn
  Move(end, std::abs(angle_rad) / (motion_.turn_rate_dps * std::numbers::pi / 180.0));
}

void TrajectoryBuilder::Drive(const std::vector<Eigen::Vector2d>& path) {
  for (const Eigen::Vector2d& p : path) {
    const Eigen::Vector2d d = p - Eigen::Vector2d(cur_.x, cur_.y);
    const double len = d.norm();
    if (len < 1e-6) continue;
    TurnTo(std::atan2(d.y(), d.x()));
    PoseSample end = cur_;
    end.x = p.x();
    end.y = p.y();
    Move(end, len / motion_.speed_mps);
  }
}

void TrajectoryBuilder::ChangeFloor(int floor) {
  PoseSample end = cur_;
  end.floor = floor;
  end.z = floor * floor_height_m_ + camera_height_m_;
  Move(end, std::abs(end.z - cur_.z) / motion_.elevator_speed_mps);
}

}  // namespace zm::sim
