// The simulator's occupancy grid and the ray casting that every observation and depth image
// rests on. One grid per floor.
//
// Convention: cells are stored bottom-up (index = row * cols + col with row 0 at the SMALLEST y),
// so cell (col, row) covers x in [origin.x + col*res, origin.x + (col+1)*res) and y likewise;
// exports (map.pgm, which is top-down like every image) flip the rows. Values follow the zones
// module's grids: kCellFree (255), kCellOccupied (0), kCellUnknown (128). Anything that is not
// free blocks a ray (unknown space is opaque: walls of real maps often contain unknown cells).
//
// Invariants: cells.size() == cols * rows; resolution_m > 0. Off-grid cells block.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <string>
#include <vector>

#include "common/status.h"
#include "segment/grid_map.h"

namespace zm::sim {

struct SimGrid {
  int cols = 0;
  int rows = 0;
  double resolution_m = 0.05;
  Eigen::Vector2d origin_m{0.0, 0.0};  // map-frame corner of cell (0, 0) (bottom-left)
  std::vector<std::uint8_t> cells;     // bottom-up, see the file comment

  static SimGrid Filled(int cols, int rows, double resolution_m, Eigen::Vector2d origin_m,
                        std::uint8_t value);

  [[nodiscard]] bool InBounds(int c, int r) const { return c >= 0 && r >= 0 && c < cols && r < rows; }
  [[nodiscard]] std::size_t Index(int c, int r) const {
    return static_cast<std::size_t>(r) * static_cast<std::size_t>(cols) + static_cast<std::size_t>(c);
  }
  [[nodiscard]] std::uint8_t At(int c, int r) const { return InBounds(c, r) ? cells[Index(c, r)] : kCellUnknown; }
  [[nodiscard]] bool Free(int c, int r) const { return At(c, r) == kCellFree; }
  void Set(int c, int r, std::uint8_t v) {
    if (InBounds(c, r)) cells[Index(c, r)] = v;
  }
  // Continuous cell coordinates of a map point (cell (c, r) holds [c, c+1) x [r, r+1)).
  [[nodiscard]] Eigen::Vector2d ToCell(const Eigen::Vector2d& p) const { return (p - origin_m) / resolution_m; }
  [[nodiscard]] Eigen::Vector2d CellCentre(int c, int r) const {
    return origin_m + resolution_m * Eigen::Vector2d(c + 0.5, r + 0.5);
  }
  // The cell holding p (may be off the grid).
  void CellOf(const Eigen::Vector2d& p, int* c, int* r) const;
  [[nodiscard]] bool FreeAt(const Eigen::Vector2d& p) const {
    int c, r;
    CellOf(p, &c, &r);
    return Free(c, r);
  }
  [[nodiscard]] double width_m() const { return cols * resolution_m; }
  [[nodiscard]] double height_m() const { return rows * resolution_m; }
};

// Distance (metres) from `from` along the unit direction `dir` to the first non-free cell, or
// max_range_m if none is met first. A ray starting in a non-free cell returns 0.
[[nodiscard]] double CastRay(const SimGrid& grid, const Eigen::Vector2d& from,
                             const Eigen::Vector2d& dir, double max_range_m);

// CastRay with where it stopped: the first non-free cell and whether the ray entered it through
// a face of constant x (else constant y). hit is false (and the cell meaningless) when nothing was
// met within max_range_m.
struct RayHit {
  double distance_m = 0.0;
  int col = 0;
  int row = 0;
  bool x_face = false;
  bool hit = false;
};
[[nodiscard]] RayHit CastRayHit(const SimGrid& grid, const Eigen::Vector2d& from,
                                const Eigen::Vector2d& dir, double max_range_m);

// True when every cell the segment a-b passes through is free (both end cells included). Where
// the segment passes exactly through a cell corner both side cells must be free, so the test is
// conservative: it never reports a line of sight that grazes an occupied cell.
[[nodiscard]] bool LineOfSight(const SimGrid& grid, const Eigen::Vector2d& a, const Eigen::Vector2d& b);

// Writes the grid in ROS map_server format: <stem>.pgm (P5, top row first; free 254,
// occupied 0, unknown 205) and <stem>.yaml (image, resolution, origin, negate 0,
// occupied_thresh 0.65, free_thresh 0.196, mode trinary).
Status WriteRosMap(const SimGrid& grid, const std::string& dir, const std::string& stem);

// Converts to the zones module's top-down grid (for automatic segmentation and annotation).
[[nodiscard]] OccupancyGrid ToOccupancyGrid(const SimGrid& grid);

}  // namespace zm::sim
