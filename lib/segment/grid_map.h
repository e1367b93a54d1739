// Occupancy grids for automatic zones: loaded from a ROS map_server YAML (+ PGM/PNG image), a
// plain PNG floor plan, or an RTAB-Map database's optimized map (Admin.opt_map), and converted
// between pixels and map-frame metres.
//
// Convention (the ROS map_server one, kept for every source): `cells` is stored as an image,
// row 0 at the TOP; `origin_m` is the map-frame position of the bottom-left corner of the
// bottom-left cell, so map-frame x grows with the column and y grows UP (against the row).
// The centre of cell (col, row) is at
//   x = origin.x + (col + 0.5) * resolution,  y = origin.y + (rows - row - 0.5) * resolution.
// A plain PNG has origin (0, 0) and resolution 0.05 m/px unless told otherwise.
// Invariants of a loaded grid: cells is CV_8UC1, non-empty, every value is one of kCellFree,
// kCellOccupied, kCellUnknown; resolution_m > 0 and finite.
#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <cstdint>
#include <opencv2/core/mat.hpp>
#include <opencv2/core/types.hpp>
#include <string>

#include "common/status.h"

namespace zm {

inline constexpr std::uint8_t kCellOccupied = 0;
inline constexpr std::uint8_t kCellUnknown = 128;
inline constexpr std::uint8_t kCellFree = 255;

inline constexpr double kDefaultGridResolutionM = 0.05;

namespace segment_detail {
// A label, row or column (never negative where it indexes) as an index into the vectors the
// stages keep per label: one cast, named once for every stage.
[[nodiscard]] constexpr std::size_t Idx(int v) { return static_cast<std::size_t>(v); }

// Whether the cell at the rounded point p (x = column, y = row) is nonzero in `free` (CV_8UC1);
// outside it, not.
[[nodiscard]] bool FreeAt(const cv::Mat& free, cv::Point2d p);

// How wide free space stays past a border (issue 28: MergeChannels' median width test and the
// layout merge's channel_width_* features): the median, over the points centre + i x step
// (i = 1..steps), of the run of nonzero cells of `free` (CV_8UC1) along +-`along` through each
// point: 1 + the run each way, at most `cap` cells each way, 0 where the point itself is not
// free. Points are (x = column, y = row), taken at the rounded cell; outside `free` is not free.
[[nodiscard]] int MedianFreeRun(const cv::Mat& free, cv::Point2d centre, cv::Point2d along,
                                cv::Point2d step, int steps, int cap);
}  // namespace segment_detail

struct OccupancyGrid {
  cv::Mat cells;                                  // CV_8UC1, row 0 = top (largest y)
  double resolution_m = kDefaultGridResolutionM;  // metres per cell
  Eigen::Vector2d origin_m{0.0, 0.0};             // map-frame corner of the bottom-left cell

  [[nodiscard]] int rows() const { return cells.rows; }
  [[nodiscard]] int cols() const { return cells.cols; }
  // Map-frame metres of the centre of cell (col, row); fractional cells interpolate.
  [[nodiscard]] Eigen::Vector2d CellToMetres(double col, double row) const;
  // Continuous cell coordinates (col, row) of a map-frame point; the cell holding it is
  // (floor(col), floor(row)).
  [[nodiscard]] Eigen::Vector2d MetresToCell(const Eigen::Vector2d& p_m) const;
  // True and the cell indices when `p_m` lies on the grid.
  [[nodiscard]] bool CellOf(const Eigen::Vector2d& p_m, int* col, int* row) const;
};

// ROS map_server YAML: image, resolution, origin [x, y, yaw], negate, occupied_thresh,
// free_thresh, mode (trinary|scale|raw). The image path is relative to the YAML's folder.
// An unknown key, a missing required key, a non-positive resolution or a non-zero yaw is an error
// naming the file and the key.
[[nodiscard]] Result<OccupancyGrid> LoadGridYaml(const std::string& yaml_path);

// A plain image (PNG/PGM, grey or RGB(A)): white = free, black = occupied, anything between
// (and transparent pixels) = unknown. `resolution_m` must be positive.
[[nodiscard]] Result<OccupancyGrid> LoadGridImage(const std::string& image_path,
                                                  double resolution_m = kDefaultGridResolutionM);

// An image file as cv::imread reads it with `imread_flags`: NotFound when there is no such file,
// InvalidArgument naming the file when it is not a readable image. The one image reader of the
// grid loaders and the ground truth (score.h).
[[nodiscard]] Result<cv::Mat> ReadImageFile(const std::string& path, int imread_flags);

// Dispatches on the extension: .yaml/.yml -> LoadGridYaml, .db -> LoadRtabmapGrid, else an
// image. `resolution_m` > 0 overrides the resolution of an image or YAML.
[[nodiscard]] Result<OccupancyGrid> LoadOccupancyGrid(const std::string& path,
                                                      double resolution_m = 0.0);

// RTAB-Map database (plain sqlite3): Admin.opt_map is a zlib blob of rows x cols int8 cells
// (-1 unknown, 0 free, 100 occupied) followed by a 12-byte trailer (int32 rows, cols, OpenCV
// type); opt_map_x_min/opt_map_y_min/opt_map_resolution place it. In RTAB-Map cell (r, c) lies
// at (x_min + c * res, y_min + r * res), i.e. row 0 at the bottom: it is flipped on load. A
// database without a saved map is a NotFound error.
[[nodiscard]] Result<OccupancyGrid> LoadRtabmapGrid(const std::string& db_path);

// Decodes RTAB-Map's compressed-matrix blob (zlib data + rows, cols, type trailer) as int8
// cells into an OccupancyGrid placed at (x_min, y_min) with `resolution_m`. Exposed for tests.
[[nodiscard]] Result<OccupancyGrid> DecodeRtabmapMapBlob(const std::string& blob, double x_min_m,
                                                         double y_min_m, double resolution_m);

}  // namespace zm
