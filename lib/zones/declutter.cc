// Decluttering by dominant wall directions (see declutter.h). Straight runs are found in a copy
// of the grid rotated so that the dominant direction is the image x axis: a horizontal and a
// vertical line opening then find runs in both wall directions at once.
#include "zones/declutter.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <numbers>
#include <opencv2/imgproc.hpp>
#include <vector>

namespace zm {
namespace {

constexpr double kDegPerRad = 180.0 / std::numbers::pi;

// Odd lengths only: OpenCV anchors a kernel at its centre, and an even kernel's closing or
// opening shifts the result by a cell along it (an opening's wall end must be where the wall
// ends).
cv::Mat LineKernel(int length, bool horizontal) {
  const int n = std::max(1, length) | 1;
  return cv::Mat::ones(horizontal ? 1 : n, horizontal ? n : 1, CV_8U);
}

// Continues the runs of `runs` (rows of 255) along the rows: from each free end of a run, across
// at most `max_len` cells to the first cell of `walls`; the cells crossed are set in `*out`.
// A free end is the end of a thin wall: in the run's last column, `occupied` spans at most
// `max_thickness` cells across the run. The end of a run at a corner or a T (the perpendicular
// wall spans the column) or the face of a thick block (every column of it is a run) is no free
// end. Cells that are not wall (free, unknown, clutter, a stub shorter than a wall) are crossed:
// clutter standing in an opening must not leave a hole in it. A free end that meets no wall
// within `max_len` (an open hall) is not continued.
void ContinueRunsAlongRows(const cv::Mat& runs, const cv::Mat& occupied, const cv::Mat& walls,
                           int max_len, int max_thickness, cv::Mat* out) {
  const int rows = runs.rows, cols = runs.cols;
  // Across-run extent of occupied cells: the length of each column's vertical occupied run.
  cv::Mat across = cv::Mat::zeros(runs.size(), CV_32S);
  for (int c = 0; c < cols; ++c) {
    for (int r = 0; r < rows;) {
      if (occupied.at<std::uint8_t>(r, c) == 0) {
        ++r;
        continue;
      }
      const int a = r;
      while (r < rows && occupied.at<std::uint8_t>(r, c) != 0) ++r;
      for (int k = a; k < r; ++k) across.at<int>(k, c) = r - a;
    }
  }
  // `c` is a run's last cell, `inward` the step back into the run; the run's band is a cell
  // wider than the wall each side, and resampling a rotated grid can move an end by a cell.
  auto free_end = [&](int r, int c, int inward) {
    for (int back = 0; back < 3; ++back) {
      const int cc = c + back * inward;
      if (cc < 0 || cc >= cols) break;
      int t = 0;
      for (int rr = std::max(0, r - 1); rr <= std::min(rows - 1, r + 1); ++rr) {
        t = std::max(t, across.at<int>(rr, cc));
      }
      if (t > 0) return t <= max_thickness;
    }
    return false;
  };
  for (int r = 0; r < rows; ++r) {
    const std::uint8_t* run = runs.ptr<std::uint8_t>(r);
    const std::uint8_t* wall = walls.ptr<std::uint8_t>(r);
    std::uint8_t* o = out->ptr<std::uint8_t>(r);
    auto walk = [&](int start, int step) {
      int k = start;
      int n = 0;
      while (k >= 0 && k < cols && wall[k] == 0 && n <= max_len) k += step, ++n;
      if (n == 0 || n > max_len || k < 0 || k >= cols) return;
      for (int j = start; j != k; j += step) o[j] = 255;
    };
    for (int c = 0; c < cols;) {
      if (run[c] == 0) {
        ++c;
        continue;
      }
      const int a = c;
      while (c < cols && run[c] != 0) ++c;
      if (free_end(r, c - 1, -1)) walk(c, +1);
      if (free_end(r, a, +1)) walk(a - 1, -1);
    }
  }
}

// Wall runs, doorways and openings along the image x and y axes (see FindWalls), in
// `occupied`'s geometry.
WallEvidence AxisWalls(const cv::Mat& occupied, int min_length, int gap, int door, int opening,
                       int thickness) {
  WallEvidence out;
  out.walls = cv::Mat::zeros(occupied.size(), CV_8U);
  out.doorways = cv::Mat::zeros(occupied.size(), CV_8U);
  out.openings = cv::Mat::zeros(occupied.size(), CV_8U);
  cv::Mat runs[2];  // horizontal, vertical
  for (const bool horizontal : {true, false}) {
    cv::Mat& m = runs[horizontal ? 0 : 1];
    // Walls of a laser map are 1-2 cells thick and wander by a cell: thicken across the run
    // direction so that a slightly wavy wall still holds one straight line of cells.
    cv::dilate(occupied, m, LineKernel(3, !horizontal));
    if (gap > 0) cv::morphologyEx(m, m, cv::MORPH_CLOSE, LineKernel(gap + 1, horizontal));
    cv::morphologyEx(m, m, cv::MORPH_OPEN, LineKernel(min_length, horizontal));
    out.walls |= m;
    if (door > 0) {
      // Only runs of this direction are joined, and only along it: two parallel walls (the two
      // sides of a corridor) are never joined across.
      cv::Mat closed;
      cv::morphologyEx(m, closed, cv::MORPH_CLOSE, LineKernel(door + 1, horizontal));
      out.doorways |= closed & ~m;
    }
  }
  if (opening > 0) {
    // A run may end on a wall of either direction (a partition running into the outer wall),
    // or in a doorway: a wall that ends beside a door is continued across the door only, never
    // on through the corridor the door opens onto.
    const cv::Mat any_wall = (out.walls & occupied) | out.doorways;
    ContinueRunsAlongRows(runs[0], occupied, any_wall, opening, thickness, &out.openings);
    cv::Mat t_runs, t_occ, t_wall, t_out;
    cv::transpose(runs[1], t_runs);
    cv::transpose(occupied, t_occ);
    cv::transpose(any_wall, t_wall);
    t_out = cv::Mat::zeros(t_runs.size(), CV_8U);
    ContinueRunsAlongRows(t_runs, t_occ, t_wall, opening, thickness, &t_out);
    out.openings |= t_out.t();
  }
  return out;
}

}  // namespace

double DominantWallAngle(const cv::Mat& occupied) {
  cv::Mat f, gx, gy;
  occupied.convertTo(f, CV_32F, 1.0 / 255.0);
  cv::Sobel(f, gx, CV_32F, 1, 0, 3);
  cv::Sobel(f, gy, CV_32F, 0, 1, 3);
  // Gradient orientations folded modulo 90 degrees, 1-degree bins, weighted by magnitude: the
  // normal of a wall and of the walls perpendicular to it fall in the same bin.
  std::array<double, 90> hist{};
  for (int r = 0; r < f.rows; ++r) {
    const float* x = gx.ptr<float>(r);
    const float* y = gy.ptr<float>(r);
    for (int c = 0; c < f.cols; ++c) {
      const double mag = static_cast<double>(std::hypot(x[c], y[c]));
      if (mag < 1e-6) continue;
      double deg = static_cast<double>(std::atan2(y[c], x[c])) * kDegPerRad;
      deg = std::fmod(deg + 360.0, 90.0);
      hist[static_cast<std::size_t>(std::min(89.0, std::floor(deg)))] += mag;
    }
  }
  // Smooth circularly over +-2 degrees: digital walls spread their orientations.
  int best = 0;
  double best_v = -1.0;
  for (int b = 0; b < 90; ++b) {
    double v = 0.0;
    for (int k = -2; k <= 2; ++k) v += hist[static_cast<std::size_t>((b + k + 90) % 90)];
    if (v > best_v) best_v = v, best = b;
  }
  if (best_v <= 0.0) return 0.0;
  // Refine: magnitude-weighted mean of the bin centres within +-2 degrees of the peak.
  double sum = 0.0, weight = 0.0;
  for (int k = -2; k <= 2; ++k) {
    const double v = hist[static_cast<std::size_t>((best + k + 90) % 90)];
    sum += v * (best + k + 0.5);
    weight += v;
  }
  double deg = std::fmod(sum / weight + 90.0, 90.0);
  if (deg >= 45.0) deg -= 90.0;
  // Off the axes a thin digital line is a staircase whose Sobel orientations lean towards the
  // axes by a few degrees (up to ~7 for one-cell walls, declutter_test.cc); FindWalls' one-cell
  // tolerance across a run absorbs that for runs of about 1 m.
  return deg / kDegPerRad;
}

WallEvidence FindWalls(const cv::Mat& occupied, double angle_rad, int min_length_px,
                       int gap_px, int door_px, int opening_px, int thickness_px) {
  const double deg = angle_rad * kDegPerRad;
  WallEvidence out;
  if (std::abs(deg) < 1.0) {
    // Within a degree of the axes a run of 1 m (20 cells) drifts by less than half a cell.
    out = AxisWalls(occupied, min_length_px, gap_px, door_px, opening_px, thickness_px);
  } else {
    // Rotate so that walls at `angle_rad` lie along x, on a canvas holding the whole grid.
    const cv::Point2d centre(occupied.cols / 2.0, occupied.rows / 2.0);
    cv::Mat rot = cv::getRotationMatrix2D(centre, deg, 1.0);
    const double c = std::abs(std::cos(angle_rad)), s = std::abs(std::sin(angle_rad));
    const int w = static_cast<int>(std::ceil(occupied.cols * c + occupied.rows * s));
    const int h = static_cast<int>(std::ceil(occupied.cols * s + occupied.rows * c));
    rot.at<double>(0, 2) += w / 2.0 - centre.x;
    rot.at<double>(1, 2) += h / 2.0 - centre.y;
    cv::Mat rotated;
    cv::warpAffine(occupied, rotated, rot, cv::Size(w, h), cv::INTER_NEAREST,
                   cv::BORDER_CONSTANT, cv::Scalar(0));
    const WallEvidence r = AxisWalls(rotated, min_length_px, gap_px, door_px, opening_px,
                                      thickness_px);
    for (const auto& [from, to] : {std::pair{&r.walls, &out.walls},
                                   std::pair{&r.doorways, &out.doorways},
                                   std::pair{&r.openings, &out.openings}}) {
      cv::warpAffine(*from, *to, rot, occupied.size(), cv::INTER_NEAREST | cv::WARP_INVERSE_MAP,
                     cv::BORDER_CONSTANT, cv::Scalar(0));
      // Nearest-neighbour resampling there and back can shift a cell: widen by one.
      cv::dilate(*to, *to, cv::Mat::ones(3, 3, CV_8U));
    }
  }
  out.walls &= occupied;
  out.doorways &= ~occupied;
  out.openings &= ~out.walls;
  out.angle_rad = angle_rad;
  return out;
}

cv::Mat FillClutterIslands(const cv::Mat& free, const cv::Mat& walls) {
  cv::Mat not_free = ~free;
  cv::Mat labels, stats, centroids;
  const int n = cv::connectedComponentsWithStats(not_free, labels, stats, centroids, 8, CV_32S);
  std::vector<std::uint8_t> keep(static_cast<std::size_t>(n), 0);
  for (int i = 1; i < n; ++i) {
    const int x = stats.at<int>(i, cv::CC_STAT_LEFT), y = stats.at<int>(i, cv::CC_STAT_TOP);
    const int w = stats.at<int>(i, cv::CC_STAT_WIDTH), h = stats.at<int>(i, cv::CC_STAT_HEIGHT);
    const bool touches = x == 0 || y == 0 || x + w == free.cols || y + h == free.rows;
    keep[static_cast<std::size_t>(i)] = touches ? 1 : 0;
  }
  for (int r = 0; r < free.rows; ++r) {
    const int* l = labels.ptr<int>(r);
    const std::uint8_t* wl = walls.ptr<std::uint8_t>(r);
    for (int c = 0; c < free.cols; ++c) {
      if (l[c] > 0 && wl[c] != 0) keep[static_cast<std::size_t>(l[c])] = 1;
    }
  }
  cv::Mat out = free.clone();
  for (int r = 0; r < free.rows; ++r) {
    const int* l = labels.ptr<int>(r);
    std::uint8_t* o = out.ptr<std::uint8_t>(r);
    for (int c = 0; c < free.cols; ++c) {
      if (l[c] > 0 && keep[static_cast<std::size_t>(l[c])] == 0) o[c] = 255;
    }
  }
  return out;
}

}  // namespace zm
