// Decluttering by dominant wall directions (see declutter.h). Straight runs are found in a copy
// of the grid rotated so that the dominant direction is the image x axis: a horizontal and a
// vertical line opening then find runs in both wall directions at once.
#include "segment/declutter.h"

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

// Whether a run ends freely (the end of a thin wall), for runs along the rows: in the run's
// last column, `occupied` spans at most `max_thickness` cells across the run. The end of a run
// at a corner or a T (the perpendicular wall spans the column) or the face of a thick block
// (every column of it is a run) is no free end.
class FreeEnds {
 public:
  FreeEnds(const cv::Mat& occupied, int max_thickness)
      : across_(cv::Mat::zeros(occupied.size(), CV_32S)), max_thickness_(max_thickness) {
    // Across-run extent of occupied cells: the length of each column's vertical occupied run.
    for (int c = 0; c < occupied.cols; ++c) {
      for (int r = 0; r < occupied.rows;) {
        if (occupied.at<std::uint8_t>(r, c) == 0) {
          ++r;
          continue;
        }
        const int a = r;
        while (r < occupied.rows && occupied.at<std::uint8_t>(r, c) != 0) ++r;
        for (int k = a; k < r; ++k) across_.at<int>(k, c) = r - a;
      }
    }
  }
  // `c` is a run's last cell in row `r`, `inward` the step back into the run; the run's band is
  // a cell wider than the wall each side, and resampling a rotated grid can move an end by a
  // cell.
  [[nodiscard]] bool At(int r, int c, int inward) const {
    for (int back = 0; back < 3; ++back) {
      const int cc = c + back * inward;
      if (cc < 0 || cc >= across_.cols) break;
      int t = 0;
      for (int rr = std::max(0, r - 1); rr <= std::min(across_.rows - 1, r + 1); ++rr) {
        t = std::max(t, across_.at<int>(rr, cc));
      }
      if (t > 0) return t <= max_thickness_;
    }
    return false;
  }
  // `c` is a run's last cell in row `r`, `inward` the step back into the run: the run ends at a
  // corner or a T of a thin wall. The end column is spanned further across than `max_thickness`
  // (the perpendicular wall), and within `look` cells back the run's own wall is at most
  // `max_thickness` thick. The face of a thick block (thick all along) is no such end.
  [[nodiscard]] bool Corner(int r, int c, int inward, int look) const {
    if (across_.at<int>(r, c) <= max_thickness_) return false;
    for (int back = 1; back <= look; ++back) {
      const int cc = c + back * inward;
      if (cc < 0 || cc >= across_.cols) break;
      const int t = across_.at<int>(r, cc);
      if (t == 0) return false;
      if (t <= max_thickness_) return true;
    }
    return false;
  }

 private:
  cv::Mat across_;
  int max_thickness_;
};

// Which run ends belong to a small occupied component (see WallCells::end_min_extent): the
// components of `occupied` dilated by a cell (8-connected), small when their bounding box is
// under `min_extent` cells along both axes. Empty (nothing small) when `min_extent` is 0.
class SmallEnds {
 public:
  SmallEnds(const cv::Mat& occupied, int min_extent) {
    if (min_extent <= 0) return;
    cv::Mat grown, stats, centroids;
    cv::dilate(occupied, grown, cv::Mat::ones(3, 3, CV_8U));
    const int n = cv::connectedComponentsWithStats(grown, ids_, stats, centroids, 8, CV_32S);
    small_.assign(static_cast<std::size_t>(n), 0);
    for (int i = 1; i < n; ++i) {
      const bool small = stats.at<int>(i, cv::CC_STAT_WIDTH) < min_extent &&
                         stats.at<int>(i, cv::CC_STAT_HEIGHT) < min_extent;
      small_[static_cast<std::size_t>(i)] = small ? 1 : 0;
    }
  }
  // The transposed view (runs along the columns are walked as rows of the transpose).
  [[nodiscard]] SmallEnds Transposed() const {
    SmallEnds t;
    if (!ids_.empty()) t.ids_ = ids_.t();
    t.small_ = small_;
    return t;
  }
  // `c` is a run's last cell in row `r`, `inward` the step back into the run: the first labelled
  // cell within three cells back (a run's band is a cell wider than its wall) decides.
  [[nodiscard]] bool At(int r, int c, int inward) const {
    if (ids_.empty()) return false;
    for (int back = 0; back < 3; ++back) {
      const int cc = c + back * inward;
      if (cc < 0 || cc >= ids_.cols) break;
      const int id = ids_.at<int>(r, cc);
      if (id > 0) return small_[static_cast<std::size_t>(id)] != 0;
    }
    return false;
  }

 private:
  SmallEnds() = default;
  cv::Mat ids_;
  std::vector<std::uint8_t> small_;
};

// Calls f(first, last) for each run of nonzero cells of the row `run` (`cols` long).
template <typename F>
void ForEachRun(const std::uint8_t* run, int cols, F f) {
  for (int c = 0; c < cols;) {
    if (run[c] == 0) {
      ++c;
      continue;
    }
    const int a = c;
    while (c < cols && run[c] != 0) ++c;
    f(a, c - 1);
  }
}

// Continues the runs of `runs` (rows of 255) along the rows: from each free end of a run, across
// at most `max_len` cells to the first cell of `walls`; the cells crossed are set in `*out`.
// A free end is the end of a thin wall: in the run's last column, `occupied` spans at most
// `max_thickness` cells across the run. The end of a run at a corner or a T (the perpendicular
// wall spans the column) or the face of a thick block (every column of it is a run) is no free
// end. Cells that are not wall (free, unknown, clutter, a stub shorter than a wall) are crossed:
// clutter standing in an opening must not leave a hole in it. A free end that meets no wall
// within `max_len` (an open hall) is not continued.
// Corners (`corner_len` > 0, needs `free`): a thin wall's run that ends at a corner or a T, with
// free space just beyond it, is continued the same way across at most `corner_len` cells: the
// wall's line extended past the room it bounds into the space beyond (a closet or WC set into a
// room's corner, whose open side is the line of the wall beside it).
void ContinueRunsAlongRows(const cv::Mat& runs, const FreeEnds& ends, const SmallEnds& small,
                           const cv::Mat& walls, const cv::Mat& free, int max_len,
                           int max_thickness, int facing_len, int corner_len, cv::Mat* out) {
  const int rows = runs.rows, cols = runs.cols;
  auto free_end = [&](int r, int c, int inward) { return ends.At(r, c, inward); };
  const bool corners = corner_len > 0 && !free.empty();
  for (int r = 0; r < rows; ++r) {
    const std::uint8_t* run = runs.ptr<std::uint8_t>(r);
    const std::uint8_t* wall = walls.ptr<std::uint8_t>(r);
    const std::uint8_t* fr = corners ? free.ptr<std::uint8_t>(r) : nullptr;
    std::uint8_t* o = out->ptr<std::uint8_t>(r);
    auto walk = [&](int start, int step, int len, int facing, std::uint8_t kind) {
      int k = start;
      int n = 0;
      const int reach = std::max(len, facing);
      while (k >= 0 && k < cols && wall[k] == 0 && n <= reach) k += step, ++n;
      if (n == 0 || n > reach || k < 0 || k >= cols) return;
      // Beyond an opening's width only to the free end of a collinear run facing this one: the
      // two halves of one wall with a wide sliding door between them.
      if (n > len && (run[k] == 0 || !free_end(r, k, step))) return;
      for (int j = start; j != k; j += step) o[j] |= kind;
    };
    // The perpendicular wall at a corner is at most a thick wall's width (a block is not).
    const int look = 3 * max_thickness;
    auto corner = [&](int c, int inward) {
      const int beyond = c - inward;
      return corners && beyond >= 0 && beyond < cols && fr[beyond] != 0 &&
             ends.Corner(r, c, inward, look);
    };
    ForEachRun(run, cols, [&](int a, int last) {
      if (small.At(r, last, -1)) {
      } else if (free_end(r, last, -1)) {
        walk(last + 1, +1, max_len, facing_len, kOpeningFreeEnd);
      } else if (corner(last, -1)) {
        walk(last + 1, +1, corner_len, 0, kOpeningCorner);
      }
      if (small.At(r, a, +1)) {
      } else if (free_end(r, a, +1)) {
        walk(a - 1, -1, max_len, facing_len, kOpeningFreeEnd);
      } else if (corner(a, +1)) {
        walk(a - 1, -1, corner_len, 0, kOpeningCorner);
      }
    });
  }
}

// End caps (`cap_len` > 0): from the free end of each thin run of `runs` (rows of 255), the line
// across the wall's end, perpendicular to it, on either side: from just past the wall through
// free space to the first cell of `walls` at most `cap_len` cells away. The cells crossed are
// set to kOpeningCap in `*out_t`, which is transposed (a line along a column of the grid is a
// row there). The front of a closet whose side wall ends where its door closes lies on one.
// Ends whose wall goes on within `jamb_gap` beyond them (a door's jambs) are not capped.
void CapRunEnds(const cv::Mat& runs, const cv::Mat& occupied, const FreeEnds& ends,
                const SmallEnds& small, const cv::Mat& walls, const cv::Mat& free,
                int max_thickness, int cap_len, int jamb_gap, cv::Mat* out_t) {
  const int rows = runs.rows, cols = runs.cols;
  auto cap = [&](int r0, int c, int step) {
    int r = r0;
    // Past the wall's own cells, then through anything that is not wall.
    for (int k = 0; k <= max_thickness + 1 && r >= 0 && r < rows && occupied.at<std::uint8_t>(r, c);
         ++k) {
      r += step;
    }
    if (r < 0 || r >= rows || free.at<std::uint8_t>(r, c) == 0) return;
    const int start = r;
    int n = 0;
    while (r >= 0 && r < rows && walls.at<std::uint8_t>(r, c) == 0 && n <= cap_len) r += step, ++n;
    if (n == 0 || n > cap_len || r < 0 || r >= rows) return;
    for (int j = start; j != r; j += step) out_t->at<std::uint8_t>(c, j) |= kOpeningCap;
  };
  for (int r = 0; r < rows; ++r) {
    ForEachRun(runs.ptr<std::uint8_t>(r), cols, [&](int a, int last) {
      // The band's top row caps upwards, its bottom row downwards; both at the end column.
      for (const auto& [end, inward] : {std::pair{last, -1}, std::pair{a, +1}}) {
        if (!ends.At(r, end, inward) || small.At(r, end, inward)) continue;
        // A door's jamb: the wall's line goes on within `jamb_gap` (a run along it, a cell of
        // slack across: laser walls are ragged). The door explains the end, and a line across
        // it would cut the corridor or room the door opens onto at every door.
        bool jamb = false;
        for (int k = 1, cc = end - inward; !jamb && k <= jamb_gap && cc >= 0 && cc < cols;
             ++k, cc -= inward) {
          for (int rr = std::max(0, r - 1); rr <= std::min(rows - 1, r + 1); ++rr) {
            jamb = jamb || runs.at<std::uint8_t>(rr, cc) != 0;
          }
        }
        if (jamb) continue;
        if (r == 0 || runs.at<std::uint8_t>(r - 1, end) == 0) cap(r, end, -1);
        if (r == rows - 1 || runs.at<std::uint8_t>(r + 1, end) == 0) cap(r, end, +1);
      }
    });
  }
}

// What lies beyond one side of a wall piece in one of its columns, past at most `thickness`
// occupied cells.
enum class Beyond { kOther, kFree, kOutside };

// Per piece: how many of its columns have free space on both sides, and how many free space on
// one side and the outside on the other.
struct SideCounts {
  int columns = 0;
  int free_both = 0;
  int facade = 0;
};

// Keeps the pieces of `*pieces` (rows of 255, one piece per 8-connected component) for which
// `keep(SideCounts)` holds. `outside` may be empty (nothing is the outside); an unknown cell that
// is not the outside (a piece of furniture's inside, its shadow) ends the look as kOther.
template <typename Keep>
void KeepPieces(const cv::Mat& occupied, const cv::Mat& free, const cv::Mat& outside, int thickness,
                Keep keep, cv::Mat* pieces) {
  cv::Mat ids, stats, centroids;
  const int n = cv::connectedComponentsWithStats(*pieces, ids, stats, centroids, 8, CV_32S);
  const int rows = pieces->rows;
  auto beyond = [&](int r, int c, int step) {
    for (int k = 0; k <= thickness + 1 && r >= 0 && r < rows; ++k, r += step) {
      if (free.at<std::uint8_t>(r, c) != 0) return Beyond::kFree;
      if (!outside.empty() && outside.at<std::uint8_t>(r, c) != 0) return Beyond::kOutside;
      if (occupied.at<std::uint8_t>(r, c) == 0) return Beyond::kOther;
    }
    return Beyond::kOther;
  };
  std::vector<std::uint8_t> kept(static_cast<std::size_t>(n), 0);
  for (int i = 1; i < n; ++i) {
    const int x = stats.at<int>(i, cv::CC_STAT_LEFT), y = stats.at<int>(i, cv::CC_STAT_TOP);
    const int w = stats.at<int>(i, cv::CC_STAT_WIDTH), h = stats.at<int>(i, cv::CC_STAT_HEIGHT);
    SideCounts counts;
    for (int c = x; c < x + w; ++c) {
      int top = -1, bottom = -1;
      for (int r = y; r < y + h; ++r) {
        if (ids.at<int>(r, c) != i) continue;
        if (top < 0) top = r;
        bottom = r;
      }
      if (top < 0) continue;
      ++counts.columns;
      const Beyond above = beyond(top - 1, c, -1), below = beyond(bottom + 1, c, +1);
      if (above == Beyond::kFree && below == Beyond::kFree) ++counts.free_both;
      if ((above == Beyond::kFree && below == Beyond::kOutside) ||
          (above == Beyond::kOutside && below == Beyond::kFree)) {
        ++counts.facade;
      }
    }
    kept[static_cast<std::size_t>(i)] = keep(counts) ? 255 : 0;
  }
  for (int r = 0; r < rows; ++r) {
    const int* id = ids.ptr<int>(r);
    std::uint8_t* o = pieces->ptr<std::uint8_t>(r);
    for (int c = 0; c < pieces->cols; ++c) o[c] = kept[static_cast<std::size_t>(id[c])];
  }
}

// Keeps the pieces of `*runs` that have free space on both sides across at least half of their
// columns. A partition between two doors is seen from both rooms; the outline of furniture or
// clutter against a wall has unknown cells (its inside, its shadow) or more obstacles on one
// side.
void KeepFreeOnBothSides(const cv::Mat& occupied, const cv::Mat& free, int thickness,
                         cv::Mat* runs) {
  KeepPieces(
      occupied, free, cv::Mat(), thickness,
      [](const SideCounts& s) { return 2 * s.free_both >= s.columns; }, runs);
}

// Unknown cells (neither free nor occupied) 8-connected to the grid's border through unknown
// cells: the outside of the building (and, in a rotated copy, the canvas around it). Walls do not
// connect: an unknown closet or shaft behind a wall is inside.
cv::Mat OutsideMask(const cv::Mat& free, const cv::Mat& occupied) {
  cv::Mat ids;
  const cv::Mat unknown = (free == 0) & (occupied == 0);
  const int n = cv::connectedComponents(unknown, ids, 8, CV_32S);
  std::vector<std::uint8_t> border(static_cast<std::size_t>(n), 0);
  for (int r = 0; r < ids.rows; ++r) {
    const int* id = ids.ptr<int>(r);
    const bool edge_row = r == 0 || r == ids.rows - 1;
    for (int c = 0; c < ids.cols; ++c) {
      if (id[c] > 0 && (edge_row || c == 0 || c == ids.cols - 1)) {
        border[static_cast<std::size_t>(id[c])] = 255;
      }
    }
  }
  cv::Mat out(free.size(), CV_8U);
  for (int r = 0; r < ids.rows; ++r) {
    const int* id = ids.ptr<int>(r);
    std::uint8_t* o = out.ptr<std::uint8_t>(r);
    for (int c = 0; c < ids.cols; ++c) o[c] = border[static_cast<std::size_t>(id[c])];
  }
  return out;
}

// Keeps the pieces of `*pieces` that are facade: across at least three columns, free space on
// one side and the outside on the other, and free on both sides across fewer columns. The
// building's exterior wall, seen from a room; not a partition (free both sides) nor furniture
// (its unknown inside is enclosed). Three columns, not a share: a short piece between the
// building's corner and a balcony's side wall has walls beyond most of it (and may poke a cell or
// two into the balcony).
void KeepFacade(const cv::Mat& occupied, const cv::Mat& free, const cv::Mat& outside, int thickness,
                cv::Mat* pieces) {
  KeepPieces(
      occupied, free, outside, thickness,
      [](const SideCounts& s) { return s.facade >= 3 && s.free_both < s.facade; }, pieces);
}

// The facade continued across the mouths of the building's protrusions (a balcony, a loggia, a
// bay), in rows: gaps of more than `min_gap` and at most `max_gap` cells between two collinear
// facade pieces at least `piece` long, where the gap holds no occupied cell and none of the
// outside (a window or a door in the exterior wall opens onto the outside: no mouth; a notch in
// the outline runs through the outside: no mouth either).
cv::Mat FacadeGapsAlongRows(const cv::Mat& occupied, const cv::Mat& free, const cv::Mat& outside,
                            int piece, int min_gap, int max_gap, int thickness) {
  cv::Mat pieces;
  cv::dilate(occupied, pieces, LineKernel(3, false));
  cv::morphologyEx(pieces, pieces, cv::MORPH_OPEN, LineKernel(piece, true));
  KeepFacade(occupied, free, outside, thickness, &pieces);
  cv::Mat closed;
  cv::morphologyEx(pieces, closed, cv::MORPH_CLOSE, LineKernel(max_gap + 1, true));
  cv::Mat gaps = closed & ~pieces & ~occupied;
  cv::Mat ids, stats, centroids;
  const int n = cv::connectedComponentsWithStats(gaps, ids, stats, centroids, 8, CV_32S);
  std::vector<std::uint8_t> keep(static_cast<std::size_t>(n), 255);
  for (int r = 0; r < ids.rows; ++r) {
    const int* id = ids.ptr<int>(r);
    const std::uint8_t* out = outside.ptr<std::uint8_t>(r);
    for (int c = 0; c < ids.cols; ++c) {
      if (id[c] > 0 && out[c] != 0) keep[static_cast<std::size_t>(id[c])] = 0;
    }
  }
  for (int i = 1; i < n; ++i) {
    if (stats.at<int>(i, cv::CC_STAT_WIDTH) <= min_gap) keep[static_cast<std::size_t>(i)] = 0;
  }
  for (int r = 0; r < ids.rows; ++r) {
    const int* id = ids.ptr<int>(r);
    std::uint8_t* g = gaps.ptr<std::uint8_t>(r);
    for (int c = 0; c < ids.cols; ++c) g[c] = id[c] > 0 ? keep[static_cast<std::size_t>(id[c])] : 0;
  }
  return gaps;
}

// The mouth between the aligned free ends of two parallel runs along the rows (a closet or a
// wardrobe whose whole front is a door, a recess, a corridor's end): runs whose free ends point
// the same way, within `tol` columns of each other and more than `min_gap` and at most `max_gap`
// rows apart, each the other's nearest such end, with nothing occupied and none of `outside`
// on the column between the two walls. Set in `*out` as a band of three columns across the
// rows between them (so it crosses the rows, perpendicular to the runs).
void AlignedEndMouthsAlongRows(const cv::Mat& runs, const cv::Mat& occupied,
                               const FreeEnds& free_ends, const SmallEnds& small,
                               const cv::Mat& outside, int min_gap, int max_gap, int tol,
                               cv::Mat* out) {
  struct End {
    int row, col, dir;  // dir: +1 the run lies left of the end (a right end), -1 right of it
  };
  cv::Mat ids, stats, centroids;
  const int n = cv::connectedComponentsWithStats(runs, ids, stats, centroids, 8, CV_32S);
  std::vector<End> ends;
  for (int i = 1; i < n; ++i) {
    const int x = stats.at<int>(i, cv::CC_STAT_LEFT), y = stats.at<int>(i, cv::CC_STAT_TOP);
    const int w = stats.at<int>(i, cv::CC_STAT_WIDTH), h = stats.at<int>(i, cv::CC_STAT_HEIGHT);
    const int mid = y + h / 2;
    if (free_ends.At(mid, x, +1) && !small.At(mid, x, +1)) ends.push_back({mid, x, -1});
    if (free_ends.At(mid, x + w - 1, -1) && !small.At(mid, x + w - 1, -1)) {
      ends.push_back({mid, x + w - 1, +1});
    }
  }
  // The end's nearest partner above and below (same direction, aligned within `tol`).
  auto partner = [&](std::size_t i, int side) {
    std::size_t best = ends.size();
    int best_d = max_gap + 1;
    for (std::size_t j = 0; j < ends.size(); ++j) {
      if (j == i || ends[j].dir != ends[i].dir) continue;
      if (std::abs(ends[j].col - ends[i].col) > tol) continue;
      const int d = (ends[j].row - ends[i].row) * side;
      if (d > min_gap && d < best_d) best = j, best_d = d;
    }
    return best;
  };
  for (std::size_t i = 0; i < ends.size(); ++i) {
    const std::size_t j = partner(i, +1);
    if (j == ends.size() || partner(j, -1) != i) continue;
    const End& a = ends[i];
    const End& b = ends[j];
    // The mouth runs at the outer of the two end columns, where both walls have ended.
    const int c = a.dir > 0 ? std::max(a.col, b.col) : std::min(a.col, b.col);
    // Skip the two walls' own cells at either end, then nothing may stand in the mouth.
    int lo = a.row, hi = b.row;
    while (lo < hi && occupied.at<std::uint8_t>(lo, c) != 0) ++lo;
    while (hi > lo && occupied.at<std::uint8_t>(hi, c) != 0) --hi;
    if (hi - lo + 1 <= min_gap) continue;
    bool clear = true;
    for (int r = lo; r <= hi && clear; ++r) {
      clear = occupied.at<std::uint8_t>(r, c) == 0 && outside.at<std::uint8_t>(r, c) == 0;
    }
    if (!clear) continue;
    for (int r = lo; r <= hi; ++r) {
      for (int cc = std::max(0, c - 1); cc <= std::min(out->cols - 1, c + 1); ++cc) {
        if (occupied.at<std::uint8_t>(r, cc) == 0) out->at<std::uint8_t>(r, cc) = 255;
      }
    }
  }
}

// Wall runs, doorways and openings along the image x and y axes (see FindWalls), in
// `occupied`'s geometry.
WallEvidence AxisWalls(const cv::Mat& occupied, const cv::Mat& free, const WallCells& cells) {
  const int min_length = cells.min_length, gap = cells.gap, door = cells.door;
  const int opening = cells.opening, thickness = cells.thickness, stub = cells.stub;
  const int facade = cells.facade, mouth = cells.mouth, facing = cells.facing;
  WallEvidence out;
  out.walls = cv::Mat::zeros(occupied.size(), CV_8U);
  out.doorways = cv::Mat::zeros(occupied.size(), CV_8U);
  out.openings = cv::Mat::zeros(occupied.size(), CV_8U);
  cv::Mat runs[2];  // horizontal, vertical
  cv::Mat stubs[2];
  for (const bool horizontal : {true, false}) {
    cv::Mat& m = runs[horizontal ? 0 : 1];
    // Walls of a laser map are 1-2 cells thick and wander by a cell: thicken across the run
    // direction so that a slightly wavy wall still holds one straight line of cells.
    cv::dilate(occupied, m, LineKernel(3, !horizontal));
    if (gap > 0) cv::morphologyEx(m, m, cv::MORPH_CLOSE, LineKernel(gap + 1, horizontal));
    if (stub > 0 && stub < min_length) {
      // No gap closing for stubs: dotted clutter must not become a short wall.
      cv::Mat& st = stubs[horizontal ? 0 : 1];
      cv::dilate(occupied, st, LineKernel(3, !horizontal));
      cv::morphologyEx(st, st, cv::MORPH_OPEN, LineKernel(stub, horizontal));
      if (!free.empty()) {
        if (horizontal) {
          KeepFreeOnBothSides(occupied, free, thickness, &st);
        } else {
          cv::Mat t_st = st.t(), t_occ = occupied.t(), t_free = free.t();
          KeepFreeOnBothSides(t_occ, t_free, thickness, &t_st);
          st = t_st.t();
        }
      }
    }
    cv::morphologyEx(m, m, cv::MORPH_OPEN, LineKernel(min_length, horizontal));
    out.walls |= m;
  }
  if (stub > 0 && stub < min_length) {
    // Short straight pieces joined to the wall structure (a wall between two doors, a door
    // frame's return) are walls for doors and openings; a free-standing piece of the same
    // length (a bench, a shelf) is not. Joined: in one 8-connected component of the occupied
    // cells, a cell of slack allowed, with a run of the full length; or collinear with such a
    // piece or run across at most a door (the middle piece of a wall between two doors).
    cv::Mat joined, ids;
    cv::dilate(occupied, joined, cv::Mat::ones(3, 3, CV_8U));
    if (door > 0) {
      for (const bool horizontal : {true, false}) {
        const int i = horizontal ? 0 : 1;
        cv::Mat closed;
        cv::morphologyEx(runs[i] | stubs[i], closed, cv::MORPH_CLOSE,
                         LineKernel(door + 1, horizontal));
        joined |= closed;
      }
    }
    const int n = cv::connectedComponents(joined, ids, 8, CV_32S);
    std::vector<std::uint8_t> anchored(static_cast<std::size_t>(n), 0);
    for (int r = 0; r < ids.rows; ++r) {
      const int* id = ids.ptr<int>(r);
      const std::uint8_t* w = out.walls.ptr<std::uint8_t>(r);
      for (int c = 0; c < ids.cols; ++c) {
        if (w[c] != 0 && id[c] > 0) anchored[static_cast<std::size_t>(id[c])] = 255;
      }
    }
    cv::Mat keep = cv::Mat::zeros(occupied.size(), CV_8U);
    for (int r = 0; r < ids.rows; ++r) {
      const int* id = ids.ptr<int>(r);
      std::uint8_t* k = keep.ptr<std::uint8_t>(r);
      for (int c = 0; c < ids.cols; ++c) k[c] = anchored[static_cast<std::size_t>(id[c])];
    }
    for (int i = 0; i < 2; ++i) runs[i] |= stubs[i] & keep;
  }
  for (const bool horizontal : {true, false}) {
    const cv::Mat& m = runs[horizontal ? 0 : 1];
    if (door > 0) {
      // Only runs of this direction are joined, and only along it: two parallel walls (the two
      // sides of a corridor) are never joined across.
      cv::Mat closed;
      cv::morphologyEx(m, closed, cv::MORPH_CLOSE, LineKernel(door + 1, horizontal));
      out.doorways |= closed & ~m;
    }
  }
  out.opening_ids = cv::Mat::zeros(occupied.size(), CV_32S);
  out.opening_kinds = cv::Mat::zeros(occupied.size(), CV_8U);
  if (opening > 0 || facade > 0 || mouth > 0 || cells.corner > 0 || cells.cap > 0) {
    cv::Mat t_runs, t_occ;
    cv::transpose(runs[1], t_runs);
    cv::transpose(occupied, t_occ);
    // Where walls end freely, along the rows and (transposed) along the columns: once for the
    // mouths, the continuations and the caps.
    const FreeEnds row_ends(occupied, thickness), col_ends(t_occ, thickness);
    const SmallEnds row_small(occupied, cells.end_min_extent);
    const SmallEnds col_small = row_small.Transposed();
    cv::Mat outside, t_outside;
    if ((facade > 0 || mouth > 0) && !free.empty()) {
      outside = OutsideMask(free, occupied);
      cv::transpose(outside, t_outside);
    }
    cv::Mat row_out = cv::Mat::zeros(occupied.size(), CV_8U);
    cv::Mat t_out = cv::Mat::zeros(t_runs.size(), CV_8U);
    cv::Mat mouths = cv::Mat::zeros(occupied.size(), CV_8U);
    if (mouth > 0 && !free.empty()) {
      // Mouths between aligned wall ends cross the runs' direction: those of the row runs are
      // column bands (into the transposed openings), those of the column runs row bands.
      cv::Mat cols_out = cv::Mat::zeros(occupied.size(), CV_8U);
      AlignedEndMouthsAlongRows(runs[0], occupied, row_ends, row_small, outside, gap, mouth, 2,
                                &cols_out);
      cv::Mat rows_out_t = cv::Mat::zeros(t_runs.size(), CV_8U);
      AlignedEndMouthsAlongRows(t_runs, t_occ, col_ends, col_small, t_outside, gap, mouth, 2,
                                &rows_out_t);
      mouths = cols_out | rows_out_t.t();
      t_out |= cv::Mat(cols_out.t()) & cv::Scalar(kOpeningMouth);
      row_out |= cv::Mat(rows_out_t.t()) & cv::Scalar(kOpeningMouth);
    }
    // A run may end on a wall of either direction (a partition running into the outer wall),
    // in a doorway or in a mouth: a wall that ends beside a door is continued across the door
    // only, never on through the corridor the door opens onto, and a wall whose end a mouth
    // joins to its neighbour (a wardrobe's side) is not continued past the mouth.
    const cv::Mat any_wall = ((runs[0] | runs[1]) & occupied) | out.doorways | mouths;
    cv::Mat t_free;
    if (!free.empty()) cv::transpose(free, t_free);
    ContinueRunsAlongRows(runs[0], row_ends, row_small, any_wall, free, opening, thickness, facing,
                          cells.corner, &row_out);
    cv::Mat t_wall;
    cv::transpose(any_wall, t_wall);
    ContinueRunsAlongRows(t_runs, col_ends, col_small, t_wall, t_free, opening, thickness, facing,
                          cells.corner, &t_out);
    if (cells.cap > 0 && !free.empty()) {
      // Gaps up to two doors' width (a double door with its frame) are doors in a wall.
      const int jamb_gap = 2 * door;
      CapRunEnds(runs[0], occupied, row_ends, row_small, any_wall, free, thickness, cells.cap,
                 jamb_gap, &t_out);
      cv::Mat caps = cv::Mat::zeros(occupied.size(), CV_8U);
      CapRunEnds(t_runs, t_occ, col_ends, col_small, t_wall, t_free, thickness, cells.cap, jamb_gap,
                 &caps);
      row_out |= caps;
    }
    if (facade > 0 && !free.empty()) {
      // The facade across a protrusion's mouth is an opening too: a candidate border that the
      // segmentation keeps only where it constricts (a balcony behind a full-width slider), not
      // where it does not (a bay window of the room itself).
      const int piece = std::max(3, stub > 0 ? stub : min_length);
      row_out |= FacadeGapsAlongRows(occupied, free, outside, piece, gap, facade, thickness) &
                 cv::Scalar(kOpeningFacade);
      t_out |= FacadeGapsAlongRows(t_occ, t_free, t_outside, piece, gap, facade, thickness) &
               cv::Scalar(kOpeningFacade);
    }
    out.opening_kinds = row_out | t_out.t();
    out.openings = out.opening_kinds != 0;
    // Each band of continued rows (a wall is a few cells thick) is one opening: its line runs
    // along the band's middle from end to end.
    for (const bool transposed : {false, true}) {
      cv::Mat ids, stats, centroids;
      const int n = cv::connectedComponentsWithStats(transposed ? t_out : row_out, ids, stats,
                                                     centroids, 8, CV_32S);
      const int first = static_cast<int>(out.opening_lines.size());
      for (int i = 1; i < n; ++i) {
        const int x = stats.at<int>(i, cv::CC_STAT_LEFT), y = stats.at<int>(i, cv::CC_STAT_TOP);
        const int w = stats.at<int>(i, cv::CC_STAT_WIDTH);
        const int h = stats.at<int>(i, cv::CC_STAT_HEIGHT);
        const float mid = static_cast<float>(y) + 0.5f * static_cast<float>(h - 1);
        OpeningLine line;
        line.from = cv::Point2f(static_cast<float>(x), mid);
        line.to = cv::Point2f(static_cast<float>(x + w - 1), mid);
        if (transposed) {
          line.from = cv::Point2f(line.from.y, line.from.x);
          line.to = cv::Point2f(line.to.y, line.to.x);
        }
        line.thickness_px = static_cast<float>(h);
        out.opening_lines.push_back(line);
      }
      if (transposed) ids = ids.t();
      for (int r = 0; r < ids.rows; ++r) {
        const int* id = ids.ptr<int>(r);
        int* o = out.opening_ids.ptr<int>(r);
        for (int c = 0; c < ids.cols; ++c) {
          if (id[c] > 0) o[c] = first + id[c];
        }
      }
    }
  }
  return out;
}

// std::lround's rounding (halves away from zero) without its library call, the hot step of
// MeasureOpenings: exact, as a float plus or minus 0.5 is exact in double and truncation is
// floor (ceil) for non-negative (negative) values.
int RoundHalfAway(float v) {
  const double d = static_cast<double>(v);
  return static_cast<int>(static_cast<long long>(d >= 0.0 ? d + 0.5 : d - 0.5));
}

bool IsFree(const cv::Mat& free, cv::Point2f q) {
  const int c = RoundHalfAway(q.x), r = RoundHalfAway(q.y);
  return r >= 0 && c >= 0 && r < free.rows && c < free.cols && free.at<std::uint8_t>(r, c) != 0;
}

// How far the free run through `p` reaches along `dir` (a unit vector): the last free step, in
// half-cell steps (a rotated line misses no cell it crosses). -1 when `p` is not free.
float FreeReach(const cv::Mat& free, cv::Point2f p, cv::Point2f dir) {
  if (!IsFree(free, p)) return -1.0f;
  float t = 0.5f;
  while (IsFree(free, p + t * dir)) t += 0.5f;
  return t - 0.5f;
}

// The free half-cell steps of the line through `origin` along `dir` (a unit vector), each step
// looked at once: MeasureOpenings counts them over about twenty overlapping intervals per point.
class HalfStepFreeCounts {
 public:
  HalfStepFreeCounts(const cv::Mat& free, cv::Point2f origin, cv::Point2f dir)
      : free_(&free), origin_(origin), dir_(dir) {}
  // Free steps at t = -behind, -behind + 0.5, ..., ahead (both >= 0, multiples of 0.5), the
  // same points as `origin + t * dir` stepped from -behind.
  int Count(float behind, float ahead) {
    const auto b = static_cast<std::size_t>(2.0f * behind);
    const auto a = static_cast<std::size_t>(2.0f * ahead);
    Extend(&ahead_, a + 1, 0.5f);
    Extend(&behind_, b + 1, -0.5f);
    return ahead_[a] + behind_[b];
  }

 private:
  // counts[j]: free steps at t = step, 2 step, ..., j step, and t = 0 too when step > 0.
  void Extend(std::vector<int>* counts, std::size_t size, float step) {
    while (counts->size() < size) {
      const std::size_t j = counts->size();
      const bool at_zero = j == 0;
      const int here =
          (at_zero && step < 0.0f)
              ? 0
              : (IsFree(*free_, origin_ + (step * static_cast<float>(j)) * dir_) ? 1 : 0);
      counts->push_back((at_zero ? 0 : counts->back()) + here);
    }
  }

  const cv::Mat* free_;
  cv::Point2f origin_, dir_;
  std::vector<int> ahead_, behind_;
};

float Median(std::vector<float>* v) {
  if (v->empty()) return 0.0f;
  auto m = v->begin() + static_cast<std::ptrdiff_t>(v->size() / 2);
  std::nth_element(v->begin(), m, v->end());
  return *m;
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
      if (x[c] == 0.0f && y[c] == 0.0f) continue;  // most cells: no hypot call
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

WallEvidence FindWalls(const cv::Mat& occupied, double angle_rad, const WallCells& cells,
                       const cv::Mat& free) {
  const double deg = angle_rad * kDegPerRad;
  WallEvidence out;
  if (std::abs(deg) < 1.0) {
    // Within a degree of the axes a run of 1 m (20 cells) drifts by less than half a cell.
    out = AxisWalls(occupied, free, cells);
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
    cv::warpAffine(occupied, rotated, rot, cv::Size(w, h), cv::INTER_NEAREST, cv::BORDER_CONSTANT,
                   cv::Scalar(0));
    cv::Mat rotated_free;
    if (!free.empty()) {
      cv::warpAffine(free, rotated_free, rot, cv::Size(w, h), cv::INTER_NEAREST,
                     cv::BORDER_CONSTANT, cv::Scalar(0));
    }
    const WallEvidence r = AxisWalls(rotated, rotated_free, cells);
    for (const auto& [from, to] :
         {std::pair{&r.walls, &out.walls}, std::pair{&r.doorways, &out.doorways},
          std::pair{&r.openings, &out.openings}, std::pair{&r.opening_kinds, &out.opening_kinds}}) {
      cv::warpAffine(*from, *to, rot, occupied.size(), cv::INTER_NEAREST | cv::WARP_INVERSE_MAP,
                     cv::BORDER_CONSTANT, cv::Scalar(0));
      // Nearest-neighbour resampling there and back can shift a cell: widen by one.
      cv::dilate(*to, *to, cv::Mat::ones(3, 3, CV_8U));
    }
    // Opening ids likewise (OpenCV dilates no CV_32S: through float, exact for any id count
    // a grid can hold).
    cv::Mat ids;
    cv::warpAffine(r.opening_ids, ids, rot, occupied.size(),
                   cv::INTER_NEAREST | cv::WARP_INVERSE_MAP, cv::BORDER_CONSTANT, cv::Scalar(0));
    ids.convertTo(ids, CV_32F);
    cv::dilate(ids, ids, cv::Mat::ones(3, 3, CV_8U));
    ids.convertTo(out.opening_ids, CV_32S);
    cv::Mat back;
    cv::invertAffineTransform(rot, back);
    auto unrotate = [&](cv::Point2f p) {
      const double x = static_cast<double>(p.x), y = static_cast<double>(p.y);
      return cv::Point2f(static_cast<float>(back.at<double>(0, 0) * x + back.at<double>(0, 1) * y +
                                            back.at<double>(0, 2)),
                         static_cast<float>(back.at<double>(1, 0) * x + back.at<double>(1, 1) * y +
                                            back.at<double>(1, 2)));
    };
    out.opening_lines = r.opening_lines;
    for (OpeningLine& line : out.opening_lines) {
      line.from = unrotate(line.from);
      line.to = unrotate(line.to);
    }
  }
  out.walls &= occupied;
  out.doorways &= ~occupied;
  out.openings &= ~out.walls;
  out.opening_ids.setTo(0, out.openings == 0);
  out.opening_kinds.setTo(0, out.openings == 0);
  out.angle_rad = angle_rad;
  return out;
}

void MeasureOpenings(const cv::Mat& free, int side_depth_px, WallEvidence* evidence) {
  for (OpeningLine& line : evidence->opening_lines) {
    const cv::Point2f d = line.to - line.from;
    const float len = std::hypot(d.x, d.y);
    const cv::Point2f dir = len > 0.0f ? d * (1.0f / len) : cv::Point2f(1.0f, 0.0f);
    const cv::Point2f normal(-dir.y, dir.x);
    const int first = static_cast<int>(std::ceil(0.5f * line.thickness_px)) + 1;
    constexpr float kAt[3] = {0.25f, 0.5f, 0.75f};
    HalfStepFreeCounts on_line_free[3] = {{free, line.from + kAt[0] * d, dir},
                                          {free, line.from + kAt[1] * d, dir},
                                          {free, line.from + kAt[2] * d, dir}};
    for (int side = 0; side < 2; ++side) {
      const float sign = side == 0 ? -1.0f : 1.0f;
      std::vector<float> widths, shares;
      for (int i = 0; i < 3; ++i) {
        const cv::Point2f on_line = line.from + kAt[i] * d;
        for (int k = first; k <= std::max(first, side_depth_px); ++k) {
          const cv::Point2f p = on_line + sign * static_cast<float>(k) * normal;
          const float ahead = FreeReach(free, p, dir);
          if (ahead < 0.0f) continue;
          const float behind = FreeReach(free, p, -dir);
          widths.push_back(ahead + behind + 1.0f);
          // The line itself over the same interval: free cells are the opening (and whatever
          // else is open on it), the rest is wall.
          const int open = on_line_free[i].Count(behind, ahead);
          const int all = static_cast<int>(2.0f * (behind + ahead)) + 1;
          shares.push_back(static_cast<float>(open) / static_cast<float>(std::max(1, all)));
        }
      }
      line.side_px[side] = Median(&widths);
      line.open_share[side] = Median(&shares);
    }
  }
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
