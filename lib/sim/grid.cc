// Occupancy grid, ray casting (Amanatides-Woo traversal) and ROS map export; see grid.h.
#include "sim/grid.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <limits>

namespace zm::sim {

SimGrid SimGrid::Filled(int cols, int rows, double resolution_m, Eigen::Vector2d origin_m,
                        std::uint8_t value) {
  SimGrid g;
  g.cols = cols;
  g.rows = rows;
  g.resolution_m = resolution_m;
  g.origin_m = origin_m;
  g.cells.assign(static_cast<std::size_t>(cols) * static_cast<std::size_t>(rows), value);
  return g;
}

void SimGrid::CellOf(const Eigen::Vector2d& p, int* c, int* r) const {
  const Eigen::Vector2d g = ToCell(p);
  *c = static_cast<int>(std::floor(g.x()));
  *r = static_cast<int>(std::floor(g.y()));
}

namespace {

// Walks the cells of the ray from `a` (cell units) along `d` (cell units per unit t) for t in
// [0, t_end]. Calls visit(c, r, t_enter) for every cell; stops early when visit returns false.
// At an exact corner crossing it also visits both side cells. Returns false if stopped.
template <class Visit>
bool Traverse(const Eigen::Vector2d& a, const Eigen::Vector2d& d, double t_end, Visit&& visit) {
  int c = static_cast<int>(std::floor(a.x()));
  int r = static_cast<int>(std::floor(a.y()));
  const int step_c = d.x() > 0 ? 1 : (d.x() < 0 ? -1 : 0);
  const int step_r = d.y() > 0 ? 1 : (d.y() < 0 ? -1 : 0);
  constexpr double kInf = std::numeric_limits<double>::infinity();
  const double dt_c = step_c != 0 ? 1.0 / std::abs(d.x()) : kInf;
  const double dt_r = step_r != 0 ? 1.0 / std::abs(d.y()) : kInf;
  double t_c = step_c > 0 ? (c + 1 - a.x()) * dt_c : (step_c < 0 ? (a.x() - c) * dt_c : kInf);
  double t_r = step_r > 0 ? (r + 1 - a.y()) * dt_r : (step_r < 0 ? (a.y() - r) * dt_r : kInf);
  if (!visit(c, r, 0.0)) return false;
  constexpr double kTie = 1e-9;
  while (true) {
    const double t = std::min(t_c, t_r);
    if (t > t_end) return true;
    if (std::abs(t_c - t_r) < kTie) {
      // Through a corner: the two side cells count too.
      if (!visit(c + step_c, r, t) || !visit(c, r + step_r, t)) return false;
      c += step_c;
      r += step_r;
      t_c += dt_c;
      t_r += dt_r;
    } else if (t_c < t_r) {
      c += step_c;
      t_c += dt_c;
    } else {
      r += step_r;
      t_r += dt_r;
    }
    if (!visit(c, r, t)) return false;
  }
}

}  // namespace

double CastRay(const SimGrid& grid, const Eigen::Vector2d& from, const Eigen::Vector2d& dir,
               double max_range_m) {
  const Eigen::Vector2d a = grid.ToCell(from);
  const double t_end = max_range_m / grid.resolution_m;
  double hit = max_range_m;
  Traverse(a, dir, t_end, [&](int c, int r, double t) {
    if (grid.Free(c, r)) return true;
    hit = std::min(max_range_m, t * grid.resolution_m);
    return false;
  });
  return hit;
}

RayHit CastRayHit(const SimGrid& grid, const Eigen::Vector2d& from, const Eigen::Vector2d& dir,
                  double max_range_m) {
  const Eigen::Vector2d a = grid.ToCell(from);
  const double t_end = max_range_m / grid.resolution_m;
  RayHit hit;
  hit.distance_m = max_range_m;
  int last_col = static_cast<int>(std::floor(a.x()));
  Traverse(a, dir, t_end, [&](int c, int r, double t) {
    if (grid.Free(c, r)) {
      last_col = c;
      return true;
    }
    hit.distance_m = std::min(max_range_m, t * grid.resolution_m);
    hit.col = c;
    hit.row = r;
    hit.x_face = c != last_col;
    hit.hit = true;
    return false;
  });
  return hit;
}

bool LineOfSight(const SimGrid& grid, const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
  const Eigen::Vector2d ca = grid.ToCell(a);
  const Eigen::Vector2d cb = grid.ToCell(b);
  const Eigen::Vector2d d = cb - ca;
  const double len = d.norm();
  if (len < 1e-12) return grid.Free(static_cast<int>(std::floor(ca.x())), static_cast<int>(std::floor(ca.y())));
  return Traverse(ca, d / len, len, [&](int c, int r, double) { return grid.Free(c, r); });
}

Status WriteRosMap(const SimGrid& grid, const std::string& dir, const std::string& stem) {
  const std::string pgm_path = dir + "/" + stem + ".pgm";
  const std::string yaml_path = dir + "/" + stem + ".yaml";
  {
    std::ofstream out(pgm_path, std::ios::binary);
    if (!out) return IoError("cannot create " + pgm_path);
    out << "P5\n# zonemap sim occupancy grid, " << grid.resolution_m << " m/px\n"
        << grid.cols << ' ' << grid.rows << "\n255\n";
    std::vector<char> row(static_cast<std::size_t>(grid.cols));
    for (int r = grid.rows - 1; r >= 0; --r) {
      for (int c = 0; c < grid.cols; ++c) {
        const std::uint8_t v = grid.cells[grid.Index(c, r)];
        row[static_cast<std::size_t>(c)] =
            static_cast<char>(v == kCellFree ? 254 : (v == kCellOccupied ? 0 : 205));
      }
      out.write(row.data(), static_cast<std::streamsize>(row.size()));
    }
    if (!out) return IoError("cannot write " + pgm_path);
  }
  std::ofstream yaml(yaml_path);
  if (!yaml) return IoError("cannot create " + yaml_path);
  char buf[512];
  std::snprintf(buf, sizeof(buf),
                "image: %s.pgm\nresolution: %.6f\norigin: [%.6f, %.6f, 0.0]\nnegate: 0\n"
                "occupied_thresh: 0.65\nfree_thresh: 0.196\nmode: trinary\n",
                stem.c_str(), grid.resolution_m, grid.origin_m.x(), grid.origin_m.y());
  yaml << buf;
  if (!yaml) return IoError("cannot write " + yaml_path);
  return Status::Ok();
}

OccupancyGrid ToOccupancyGrid(const SimGrid& grid) {
  OccupancyGrid out;
  out.cells.create(grid.rows, grid.cols, CV_8UC1);
  for (int r = 0; r < grid.rows; ++r) {
    std::uint8_t* dst = out.cells.ptr<std::uint8_t>(grid.rows - 1 - r);
    for (int c = 0; c < grid.cols; ++c) dst[c] = grid.cells[grid.Index(c, r)];
  }
  out.resolution_m = grid.resolution_m;
  out.origin_m = grid.origin_m;
  return out;
}

}  // namespace zm::sim
