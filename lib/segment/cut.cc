// The cut stage (cut.h): cleaning, wall evidence, the seed hierarchy and the watershed flood.
// OpenCV exceptions propagate to SegmentRooms, which turns them into a Status.
#include "segment/cut.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <map>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>
#include <queue>
#include <string>
#include <unordered_map>
#include <utility>
#include <vector>

namespace zm {
namespace {

using segment_detail::Idx;

cv::Mat Disk(int diameter) {
  const int d = std::max(1, diameter);
  return cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(d, d));
}

// Sets to `value` every 8-connected component of `mask` (255 = member) smaller than `max_area`
// that does not touch the image border.
void FillSmallInteriorComponents(const cv::Mat& mask, int max_area, cv::Mat* target,
                                 std::uint8_t value) {
  cv::Mat labels, stats, centroids;
  const int n = cv::connectedComponentsWithStats(mask, labels, stats, centroids, 8, CV_32S);
  std::vector<std::uint8_t> fill(Idx(n), 0);
  for (int i = 1; i < n; ++i) {
    const int x = stats.at<int>(i, cv::CC_STAT_LEFT), y = stats.at<int>(i, cv::CC_STAT_TOP);
    const int w = stats.at<int>(i, cv::CC_STAT_WIDTH), h = stats.at<int>(i, cv::CC_STAT_HEIGHT);
    const bool touches = x == 0 || y == 0 || x + w == mask.cols || y + h == mask.rows;
    fill[Idx(i)] = (!touches && stats.at<int>(i, cv::CC_STAT_AREA) < max_area) ? 1 : 0;
  }
  for (int r = 0; r < mask.rows; ++r) {
    const int* l = labels.ptr<int>(r);
    std::uint8_t* t = target->ptr<std::uint8_t>(r);
    for (int c = 0; c < mask.cols; ++c) {
      if (l[c] > 0 && fill[Idx(l[c])]) t[c] = value;
    }
  }
}

// The cleaned free-space mask (255 = free) of `cells`; `*walls` gets the wall evidence when
// decluttering is on (else empty masks).
cv::Mat CleanFreeSpace(const cv::Mat& cells, const CutOptions& o, double res, WallEvidence* walls) {
  cv::Mat occupied = cells == kCellOccupied;
  cv::Mat free_mask = cells == kCellFree;
  if (o.wall_min_length_m > 0.0) {
    // Furniture, people and unseen patches inside rooms hold no long straight wall: free.
    const WallCells wall_cells{.min_length = CellsFromMetres(o.wall_min_length_m, res),
                               .gap = CellsFromMetres(o.wall_line_gap_m, res),
                               .door = CellsFromMetres(o.door_max_width_m, res),
                               .opening = CellsFromMetres(o.opening_max_width_m, res),
                               .thickness = CellsFromMetres(o.opening_wall_max_thickness_m, res),
                               .stub = CellsFromMetres(o.wall_stub_min_length_m, res),
                               .facade = CellsFromMetres(o.facade_opening_max_width_m, res),
                               .mouth = CellsFromMetres(o.mouth_opening_max_width_m, res),
                               .facing = CellsFromMetres(o.facing_opening_max_width_m, res),
                               .corner = CellsFromMetres(o.corner_opening_max_width_m, res),
                               .cap = CellsFromMetres(o.cap_opening_max_width_m, res),
                               .end_min_extent = CellsFromMetres(o.opening_end_min_extent_m, res)};
    *walls = FindWalls(occupied, DominantWallAngle(occupied), wall_cells, free_mask);
    free_mask = FillClutterIslands(free_mask, walls->walls);
    occupied &= ~free_mask;
  } else {
    walls->walls = cv::Mat::zeros(cells.size(), CV_8U);
    walls->doorways = cv::Mat::zeros(cells.size(), CV_8U);
    walls->openings = cv::Mat::zeros(cells.size(), CV_8U);
    walls->opening_ids = cv::Mat::zeros(cells.size(), CV_32S);
    walls->opening_kinds = cv::Mat::zeros(cells.size(), CV_8U);
  }
  // Close gaps in walls (scan noise) so that rooms do not leak through them.
  const int gap = CellsFromMetres(o.wall_gap_close_m, res);
  if (gap > 0) cv::morphologyEx(occupied, occupied, cv::MORPH_CLOSE, Disk(gap + 1));
  free_mask &= ~occupied;
  // Small clutter (furniture, people, unknown patches) standing inside free space becomes free.
  const int clutter = static_cast<int>(o.clutter_area_m2 / (res * res));
  cv::Mat not_free = ~free_mask;
  FillSmallInteriorComponents(not_free, clutter, &free_mask, 255);
  // Drop laser rays and one-cell strands.
  const int ray = CellsFromMetres(o.ray_width_m, res);
  if (ray > 1) cv::morphologyEx(free_mask, free_mask, cv::MORPH_OPEN, Disk(ray));
  return free_mask;
}

struct LevelComponent {
  int area = 0;
  float max_dt = 0.0f;
  int parent = -1;  // component index at the previous level
  std::vector<int> children;
};

// Room seeds from the hierarchy of distance-transform thresholds (cut.h).
// Returns a CV_32S marker image (0 = no seed, 1..K).
cv::Mat FindSeeds(const cv::Mat& dt, const CutOptions& o, double res, int* seed_count) {
  std::vector<float> levels;
  for (double l = o.seed_min_level_m; l <= o.seed_max_level_m + 1e-9; l += o.seed_level_step_m) {
    levels.push_back(static_cast<float>(l / res));
  }
  const int min_area = std::max(1, static_cast<int>(o.seed_min_area_m2 / (res * res)));
  const float persistence = static_cast<float>(o.seed_min_persistence_m / res);
  // Only two label images are alive at a time (this level and the one below): memory stays at
  // a few bytes per cell however many levels there are. Seed levels are relabelled at the end
  // (connectedComponents is deterministic, so the component numbers match).
  // A level lies inside the one below it, so it is labelled inside the bounding box of the level
  // below only (`boxes[i]`; its label image is of the box's size): connectedComponents numbers
  // components in the raster order of their first cell, which the crop keeps.
  std::vector<cv::Rect> boxes(levels.size());
  if (!boxes.empty()) boxes[0] = cv::Rect(0, 0, dt.cols, dt.rows);
  auto label_level = [&](std::size_t i, cv::Mat* out) {
    cv::Mat mask = dt(boxes[i]) > static_cast<double>(levels[i]);
    return cv::connectedComponents(mask, *out, 4, CV_32S);
  };
  cv::Mat below, current;
  std::vector<std::vector<LevelComponent>> comps(levels.size());
  for (std::size_t i = 0; i < levels.size(); ++i) {
    const int n = label_level(i, &current);
    comps[i].resize(Idx(n));
    if (n <= 1) {
      levels.resize(i + 1);
      comps.resize(i + 1);
      break;
    }
    const cv::Rect box = boxes[i];
    const cv::Rect box_below = i > 0 ? boxes[i - 1] : box;
    int r0 = box.y + box.height, r1 = box.y - 1, c0 = box.x + box.width, c1 = box.x - 1;
    for (int r = box.y; r < box.y + box.height; ++r) {
      const int* l = current.ptr<int>(r - box.y);
      const int* lp = i > 0 ? below.ptr<int>(r - box_below.y) : nullptr;
      const float* d = dt.ptr<float>(r);
      for (int c = box.x; c < box.x + box.width; ++c) {
        const int label = l[c - box.x];
        if (label == 0) continue;
        r0 = std::min(r0, r), r1 = std::max(r1, r), c0 = std::min(c0, c), c1 = std::max(c1, c);
        LevelComponent& comp = comps[i][Idx(label)];
        ++comp.area;
        comp.max_dt = std::max(comp.max_dt, d[c]);
        if (lp != nullptr && comp.parent < 0) {
          comp.parent = lp[c - box_below.x];
          comps[i - 1][Idx(comp.parent)].children.push_back(label);
        }
      }
    }
    if (i + 1 < boxes.size()) boxes[i + 1] = cv::Rect(c0, r0, c1 - c0 + 1, r1 - r0 + 1);
    std::swap(below, current);
  }
  // Select(level, comp) -> seeds as (level, comp) pairs.
  std::vector<std::pair<std::size_t, int>> seeds;
  std::vector<std::pair<std::size_t, int>> tmp;
  auto select = [&](auto&& self, std::size_t level, int comp,
                    std::vector<std::pair<std::size_t, int>>* out) -> void {
    const LevelComponent& c = comps[level][Idx(comp)];
    std::vector<int> significant;
    if (level + 1 < comps.size()) {
      for (int child : c.children) {
        const LevelComponent& ch = comps[level + 1][Idx(child)];
        if (ch.area >= min_area && ch.max_dt - levels[level] >= persistence) {
          significant.push_back(child);
        }
      }
    }
    if (significant.size() >= 2) {
      for (int child : significant) self(self, level + 1, child, out);
      return;
    }
    if (significant.size() == 1) {
      std::vector<std::pair<std::size_t, int>> sub;
      self(self, level + 1, significant[0], &sub);
      if (sub.size() >= 2) {
        out->insert(out->end(), sub.begin(), sub.end());
        return;
      }
    }
    out->emplace_back(level, comp);  // a leaf: this (largest single) component is the seed
  };
  if (!comps.empty()) {
    for (int comp = 1; comp < static_cast<int>(comps[0].size()); ++comp) {
      tmp.clear();
      select(select, 0, comp, &tmp);
      seeds.insert(seeds.end(), tmp.begin(), tmp.end());
    }
  }
  cv::Mat markers = cv::Mat::zeros(dt.size(), CV_32S);
  // Seed ids per level for a single pass over each used level.
  std::map<std::size_t, std::unordered_map<int, int>> by_level;
  for (std::size_t s = 0; s < seeds.size(); ++s) {
    by_level[seeds[s].first][seeds[s].second] = static_cast<int>(s) + 1;
  }
  for (const auto& [level, ids] : by_level) {
    label_level(level, &current);
    const cv::Rect box = boxes[level];
    for (int r = 0; r < box.height; ++r) {
      const int* l = current.ptr<int>(r);
      int* m = markers.ptr<int>(box.y + r) + box.x;
      for (int c = 0; c < box.width; ++c) {
        if (l[c] == 0) continue;
        if (auto it = ids.find(l[c]); it != ids.end()) m[c] = it->second;
      }
    }
  }
  *seed_count = static_cast<int>(seeds.size());
  return markers;
}

// Priority flood (watershed on -dt) of the markers over free space, 4-connected: the highest
// clearance cells are claimed first, so two floods meet at the narrowest passage; among equal
// clearances the one queued first. A cell is queued once, by its first neighbour: a later
// entry of it would carry the same clearance and a later order, so it could only be popped
// after the cell was claimed (the queue stays up to 4x shorter, with the same result).
void Flood(const cv::Mat& free_mask, const cv::Mat& dt, cv::Mat* labels) {
  struct Entry {
    float dt;
    std::uint32_t order;  // at most one entry per cell, and cells are indexed by int
    int index, label;
  };
  auto claimed_later = [](const Entry& a, const Entry& b) {
    return a.dt < b.dt || (a.dt == b.dt && a.order > b.order);
  };
  std::priority_queue<Entry, std::vector<Entry>, decltype(claimed_later)> queue(claimed_later);
  std::uint32_t order = 0;
  const int cols = free_mask.cols, rows = free_mask.rows;
  cv::Mat queued = cv::Mat::zeros(free_mask.size(), CV_8U);
  auto push_neighbours = [&](int r, int c, int label) {
    const int dr[4] = {-1, 1, 0, 0}, dc[4] = {0, 0, -1, 1};
    for (int k = 0; k < 4; ++k) {
      const int nr = r + dr[k], nc = c + dc[k];
      if (nr < 0 || nc < 0 || nr >= rows || nc >= cols) continue;
      if (free_mask.at<std::uint8_t>(nr, nc) == 0 || labels->at<int>(nr, nc) != 0) continue;
      std::uint8_t& q = queued.at<std::uint8_t>(nr, nc);
      if (q != 0) continue;
      q = 1;
      queue.push({dt.at<float>(nr, nc), order++, nr * cols + nc, label});
    }
  };
  for (int r = 0; r < rows; ++r) {
    for (int c = 0; c < cols; ++c) {
      const int l = labels->at<int>(r, c);
      if (l != 0) push_neighbours(r, c, l);
    }
  }
  while (!queue.empty()) {
    const Entry e = queue.top();
    queue.pop();
    const int r = e.index / cols, c = e.index % cols;
    labels->at<int>(r, c) = e.label;
    push_neighbours(r, c, e.label);
  }
}

// Every region of `enclosed` (255 = free space with doorways and openings closed, so each
// 4-connected region is bounded by walls, doors and openings) that holds no marker and has at
// least `min_area` cells becomes a marker of its own, numbered after `*count`: a space enclosed
// by walls and doors is a room even when it is too narrow for any seed level (a closet, a
// passage), instead of being flooded from its neighbour through the door.
void AddSeedlessRooms(const cv::Mat& enclosed, int min_area, cv::Mat* markers, int* count) {
  cv::Mat regions, stats, centroids;
  const int n = cv::connectedComponentsWithStats(enclosed, regions, stats, centroids, 4, CV_32S);
  std::vector<int> id(Idx(n), 0);
  for (int i = 1; i < n; ++i) id[Idx(i)] = stats.at<int>(i, cv::CC_STAT_AREA) >= min_area ? 1 : 0;
  for (int r = 0; r < regions.rows; ++r) {
    const int* g = regions.ptr<int>(r);
    const int* m = markers->ptr<int>(r);
    for (int c = 0; c < regions.cols; ++c) {
      if (g[c] > 0 && m[c] != 0) id[Idx(g[c])] = 0;  // holds a seed
    }
  }
  for (int i = 1; i < n; ++i) {
    if (id[Idx(i)] != 0) id[Idx(i)] = ++*count;
  }
  for (int r = 0; r < regions.rows; ++r) {
    const int* g = regions.ptr<int>(r);
    int* m = markers->ptr<int>(r);
    for (int c = 0; c < regions.cols; ++c) {
      if (g[c] > 0 && id[Idx(g[c])] != 0) m[c] = id[Idx(g[c])];
    }
  }
}

}  // namespace

int CellsFromMetres(double m, double resolution_m) {
  return std::max(0, static_cast<int>(std::lround(m / resolution_m)));
}

Status CheckCutOptions(const CutOptions& o) {
  auto bad = [](const std::string& what) {
    return InvalidArgument("segmentation option " + what);
  };
  if (!(o.seed_level_step_m > 0.0)) return bad("seed_level_step_m must be > 0");
  if (!(o.seed_min_level_m > 0.0 && o.seed_max_level_m >= o.seed_min_level_m)) {
    return bad("seed levels must satisfy 0 < seed_min_level_m <= seed_max_level_m");
  }
  if ((o.seed_max_level_m - o.seed_min_level_m) / o.seed_level_step_m > 1000.0) {
    return bad("seed levels: at most 1000 levels");
  }
  if (o.seed_min_area_m2 < 0.0 || o.clutter_area_m2 < 0.0 || o.seedless_room_min_area_m2 < 0.0) {
    return bad("areas must be >= 0");
  }
  if (o.layout_line_max_m < 0.0 || o.layout_mouth_max_m < 0.0 || o.layout_facade_max_m < 0.0 ||
      o.layout_corner_max_m < 0.0 || o.layout_cap_max_m < 0.0 || o.layout_end_min_extent_m < 0.0 ||
      o.layout_seedless_min_area_m2 < 0.0 || o.layout_rough_corner_max_m < 0.0 ||
      o.layout_rough_cap_max_m < 0.0) {
    return bad("the layout_* lengths and areas must be >= 0");
  }
  if (!(o.layout_rough_face_share >= 0.0 && o.layout_rough_face_share <= 1.0)) {
    char got[32];
    std::snprintf(got, sizeof got, "%g", o.layout_rough_face_share);
    return bad(std::string("layout_rough_face_share is a share of wall faces: it must be in "
                           "[0, 1], got ") +
               got);
  }
  if (o.wall_min_length_m < 0.0 || o.wall_line_gap_m < 0.0 || o.door_max_width_m < 0.0 ||
      o.opening_max_width_m < 0.0 || o.facade_opening_max_width_m < 0.0 ||
      o.mouth_opening_max_width_m < 0.0 || o.facing_opening_max_width_m < 0.0 ||
      o.corner_opening_max_width_m < 0.0 || o.cap_opening_max_width_m < 0.0 ||
      o.opening_side_depth_m < 0.0 || o.wall_stub_min_length_m < 0.0 ||
      o.opening_wall_max_thickness_m < 0.0 || o.opening_end_min_extent_m < 0.0) {
    return bad(
        "wall_min_length_m, wall_stub_min_length_m, wall_line_gap_m, door_max_width_m "
        "and the opening_* options must be >= 0");
  }
  return Status::Ok();
}

GridFaceShares MeasureGridFaces(const cv::Mat& free, const cv::Mat& occupied) {
  const int rows = free.rows, cols = free.cols;
  auto is_free = [&](int r, int c) {
    return r >= 0 && c >= 0 && r < rows && c < cols && free.at<std::uint8_t>(r, c) != 0;
  };
  auto is_occ = [&](int r, int c) {
    return r >= 0 && c >= 0 && r < rows && c < cols && occupied.at<std::uint8_t>(r, c) != 0;
  };
  constexpr int kDr[4] = {0, 1, 0, -1}, kDc[4] = {1, 0, -1, 0};
  double border = 0, unknown = 0, faces = 0, straight = 0;
  for (int r = 0; r < rows; ++r) {
    const std::uint8_t* row = free.ptr<std::uint8_t>(r);
    for (int c = 0; c < cols; ++c) {
      if (row[c] == 0) continue;
      for (int k = 0; k < 4; ++k) {
        const int nr = r + kDr[k], nc = c + kDc[k];
        if (is_free(nr, nc)) continue;
        ++border;
        if (!is_occ(nr, nc)) {
          ++unknown;
          continue;
        }
        ++faces;
        bool on_run = true;
        for (int side : {-1, 1}) {
          const int sr = r + side * kDc[k], sc = c + side * kDr[k];
          on_run = on_run && is_free(sr, sc) && is_occ(sr + kDr[k], sc + kDc[k]);
        }
        if (on_run) ++straight;
      }
    }
  }
  GridFaceShares s;
  s.rough = 1.0 - straight / std::max(faces, 1.0);
  s.unknown_border = unknown / std::max(border, 1.0);
  return s;
}

double GridRoughFaceShare(const OccupancyGrid& grid) {
  return MeasureGridFaces(grid.cells == kCellFree, grid.cells == kCellOccupied).rough;
}

CutOptions LayoutPieceCut(const CutOptions& o, bool rough_grid) {
  // Which option each layout_* option stands in for when the layout pieces are cut.
  constexpr std::pair<double CutOptions::*, double CutOptions::*> kLayoutFor[] = {
      {&CutOptions::opening_max_width_m, &CutOptions::layout_line_max_m},
      {&CutOptions::facing_opening_max_width_m, &CutOptions::layout_line_max_m},
      {&CutOptions::mouth_opening_max_width_m, &CutOptions::layout_mouth_max_m},
      {&CutOptions::facade_opening_max_width_m, &CutOptions::layout_facade_max_m},
      {&CutOptions::corner_opening_max_width_m, &CutOptions::layout_corner_max_m},
      {&CutOptions::cap_opening_max_width_m, &CutOptions::layout_cap_max_m},
      {&CutOptions::opening_end_min_extent_m, &CutOptions::layout_end_min_extent_m},
      {&CutOptions::seedless_room_min_area_m2, &CutOptions::layout_seedless_min_area_m2},
  };
  CutOptions p = o;
  for (const auto& [field, layout] : kLayoutFor) p.*field = o.*layout;
  if (rough_grid) {
    p.corner_opening_max_width_m = o.layout_rough_corner_max_m;
    p.cap_opening_max_width_m = o.layout_rough_cap_max_m;
  }
  return p;
}

Pieces CutPieces(const OccupancyGrid& grid, const CutOptions& o) {
  const double res = grid.resolution_m;
  Pieces p;
  p.free_cleaned = CleanFreeSpace(grid.cells, o, res, &p.walls);
  if (!p.walls.opening_lines.empty()) {
    // Openings are measured in the space the robot moves in: cleaned, doorways closed.
    MeasureOpenings(p.free_cleaned & ~p.walls.doorways,
                    CellsFromMetres(o.opening_side_depth_m, res), &p.walls);
  }
  // Work inside the bounding box of free space (plus a border) only.
  cv::Rect box = cv::boundingRect(p.free_cleaned);
  if (box.area() <= 0) return p;
  p.box = cv::Rect(box.x - 2, box.y - 2, box.width + 4, box.height + 4) &
          cv::Rect(0, 0, grid.cols(), grid.rows());
  cv::Mat free_roi = p.free_cleaned(p.box);
  // Clearance with doorways closed: seeds never span a door, floods meet in it (its clearance
  // is 0) and no merge crosses it. Openings are closed too for seeds and floods (`dt_closed`);
  // whether one stays a border is decided by the merges with them open (`dt`).
  const cv::Mat open_space = free_roi & ~p.walls.doorways(p.box);
  cv::distanceTransform(open_space, p.dt, cv::DIST_L2, cv::DIST_MASK_5, CV_32F);
  p.openings = p.walls.openings(p.box) & open_space;
  if (cv::countNonZero(p.openings) > 0) {
    cv::distanceTransform(open_space & ~p.openings, p.dt_closed, cv::DIST_L2, cv::DIST_MASK_5,
                          CV_32F);
  } else {
    p.dt_closed = p.dt;
  }
  int seed_count = 0;
  p.labels = FindSeeds(p.dt_closed, o, res, &seed_count);
  if (o.seedless_room_min_area_m2 > 0.0) {
    AddSeedlessRooms(p.dt_closed > 0.0, static_cast<int>(o.seedless_room_min_area_m2 / (res * res)),
                     &p.labels, &seed_count);
  }
  Flood(free_roi, p.dt_closed, &p.labels);
  // Free areas no seed reached (too thin for any level) become pieces of their own; the merges
  // keep only those big enough.
  cv::Mat unreached = (p.labels == 0) & free_roi;
  cv::Mat extra;
  const int n_extra = cv::connectedComponents(unreached, extra, 4, CV_32S);
  for (int r = 0; r < p.labels.rows; ++r) {
    int* l = p.labels.ptr<int>(r);
    const int* e = extra.ptr<int>(r);
    for (int c = 0; c < p.labels.cols; ++c) {
      if (e[c] > 0) l[c] = seed_count + e[c];
    }
  }
  p.count = seed_count + std::max(0, n_extra - 1);
  return p;
}

}  // namespace zm
