// Room segmentation of occupancy grids (distance-transform seed hierarchy + watershed flood),
// oversize splits by keyframe count, polygonisation, keyframe-only zones and scoring. See
// segmentation.h for the method and invariants; OpenCV exceptions become Status values here.
#include "zones/segmentation.h"

#include <Eigen/Dense>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <numbers>
#include <numeric>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <queue>
#include <tuple>
#include <unordered_map>

#include "zones/declutter.h"
#include "zones/layout_merge.h"
#include "zones/polygon.h"

namespace zm {
namespace {

std::size_t Idx(int v) { return static_cast<std::size_t>(v); }

int CellsFromMetres(double m, double res) {
  return std::max(0, static_cast<int>(std::lround(m / res)));
}

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
cv::Mat CleanFreeSpace(const cv::Mat& cells, const SegmentOptions& o, double res,
                       WallEvidence* walls) {
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
                               .cap = CellsFromMetres(o.cap_opening_max_width_m, res)};
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

// Room seeds from the hierarchy of distance-transform thresholds (see segmentation.h).
// Returns a CV_32S marker image (0 = no seed, 1..K).
cv::Mat FindSeeds(const cv::Mat& dt, const SegmentOptions& o, double res, int* seed_count) {
  std::vector<float> levels;
  for (double l = o.seed_min_level_m; l <= o.seed_max_level_m + 1e-9; l += o.seed_level_step_m) {
    levels.push_back(static_cast<float>(l / res));
  }
  const int min_area = std::max(1, static_cast<int>(o.seed_min_area_m2 / (res * res)));
  const float persistence = static_cast<float>(o.seed_min_persistence_m / res);
  // Only two label images are alive at a time (this level and the one below): memory stays at
  // a few bytes per cell however many levels there are. Seed levels are relabelled at the end
  // (connectedComponents is deterministic, so the component numbers match).
  auto label_level = [&](std::size_t i, cv::Mat* out) {
    cv::Mat mask = dt > levels[i];
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
    for (int r = 0; r < dt.rows; ++r) {
      const int* l = current.ptr<int>(r);
      const int* lp = i > 0 ? below.ptr<int>(r) : nullptr;
      const float* d = dt.ptr<float>(r);
      for (int c = 0; c < dt.cols; ++c) {
        if (l[c] == 0) continue;
        LevelComponent& comp = comps[i][Idx(l[c])];
        ++comp.area;
        comp.max_dt = std::max(comp.max_dt, d[c]);
        if (lp != nullptr && comp.parent < 0) {
          comp.parent = lp[c];
          comps[i - 1][Idx(lp[c])].children.push_back(l[c]);
        }
      }
    }
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
    for (int r = 0; r < dt.rows; ++r) {
      const int* l = current.ptr<int>(r);
      int* m = markers.ptr<int>(r);
      for (int c = 0; c < dt.cols; ++c) {
        if (l[c] == 0) continue;
        if (auto it = ids.find(l[c]); it != ids.end()) m[c] = it->second;
      }
    }
  }
  *seed_count = static_cast<int>(seeds.size());
  return markers;
}

// Priority flood (watershed on -dt) of the markers over free space, 4-connected: the highest
// clearance cells are claimed first, so two floods meet at the narrowest passage.
void Flood(const cv::Mat& free_mask, const cv::Mat& dt, cv::Mat* labels) {
  using Entry = std::tuple<float, std::int64_t, int, int>;  // dt, -order, index, label
  std::priority_queue<Entry> queue;
  std::int64_t order = 0;
  const int cols = free_mask.cols, rows = free_mask.rows;
  auto push_neighbours = [&](int r, int c, int label) {
    const int dr[4] = {-1, 1, 0, 0}, dc[4] = {0, 0, -1, 1};
    for (int k = 0; k < 4; ++k) {
      const int nr = r + dr[k], nc = c + dc[k];
      if (nr < 0 || nc < 0 || nr >= rows || nc >= cols) continue;
      if (free_mask.at<std::uint8_t>(nr, nc) == 0 || labels->at<int>(nr, nc) != 0) continue;
      queue.emplace(dt.at<float>(nr, nc), -order++, nr * cols + nc, label);
    }
  };
  for (int r = 0; r < rows; ++r) {
    for (int c = 0; c < cols; ++c) {
      const int l = labels->at<int>(r, c);
      if (l != 0) push_neighbours(r, c, l);
    }
  }
  while (!queue.empty()) {
    const auto [d, ord, index, label] = queue.top();
    queue.pop();
    (void)d;
    (void)ord;
    const int r = index / cols, c = index % cols;
    if (labels->at<int>(r, c) != 0) continue;
    labels->at<int>(r, c) = label;
    push_neighbours(r, c, label);
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

// Merges segments smaller than `min_area` into the neighbour sharing the longest border
// (dropping isolated ones), then renumbers labels 1..N. Returns N.
int MergeSmallSegments(cv::Mat* labels, int label_count, int min_area) {
  std::vector<int> area(Idx(label_count) + 1, 0);
  std::vector<std::map<int, int>> border(Idx(label_count) + 1);
  for (int r = 0; r < labels->rows; ++r) {
    const int* l = labels->ptr<int>(r);
    const int* below = r + 1 < labels->rows ? labels->ptr<int>(r + 1) : nullptr;
    for (int c = 0; c < labels->cols; ++c) {
      if (l[c] == 0) continue;
      ++area[Idx(l[c])];
      if (c + 1 < labels->cols && l[c + 1] != 0 && l[c + 1] != l[c]) {
        ++border[Idx(l[c])][l[c + 1]];
        ++border[Idx(l[c + 1])][l[c]];
      }
      if (below != nullptr && below[c] != 0 && below[c] != l[c]) {
        ++border[Idx(l[c])][below[c]];
        ++border[Idx(below[c])][l[c]];
      }
    }
  }
  std::vector<int> target(Idx(label_count) + 1);
  std::iota(target.begin(), target.end(), 0);
  std::vector<bool> alive(Idx(label_count) + 1, true);
  alive[0] = false;
  for (;;) {
    int smallest = -1;
    for (int l = 1; l <= label_count; ++l) {
      if (alive[Idx(l)] && area[Idx(l)] < min_area &&
          (smallest < 0 || area[Idx(l)] < area[Idx(smallest)])) {
        smallest = l;
      }
    }
    if (smallest < 0) break;
    alive[Idx(smallest)] = false;
    int best = 0, best_len = 0;
    for (const auto& [n, len] : border[Idx(smallest)]) {
      if (len > best_len) best = n, best_len = len;
    }
    target[Idx(smallest)] = best;  // 0 = dropped
    if (best == 0) continue;
    area[Idx(best)] += area[Idx(smallest)];
    for (const auto& [n, len] : border[Idx(smallest)]) {
      border[Idx(n)].erase(smallest);
      if (n == best) continue;
      border[Idx(best)][n] += len;
      border[Idx(n)][best] += len;
    }
    border[Idx(smallest)].clear();
  }
  // Resolve chains of merges and renumber densely.
  std::vector<int> final_label(Idx(label_count) + 1, 0);
  int next = 0;
  for (int l = 1; l <= label_count; ++l) {
    int t = l;
    while (t != 0 && !alive[Idx(t)]) {
      if (target[Idx(t)] == t) {
        t = 0;
        break;
      }
      t = target[Idx(t)];
    }
    if (t == 0) continue;
    if (final_label[Idx(t)] == 0) final_label[Idx(t)] = ++next;
    final_label[Idx(l)] = final_label[Idx(t)];
  }
  for (int r = 0; r < labels->rows; ++r) {
    int* l = labels->ptr<int>(r);
    for (int c = 0; c < labels->cols; ++c) l[c] = final_label[Idx(l[c])];
  }
  return next;
}

// Merges neighbouring segments whose shared border is not a constriction: the widest point of
// the border (the largest clearance on it, `saddle`) is at least `ratio` of the smaller of the
// two segments' own largest clearance (`peak`). Doors are narrow against both rooms; a split
// through the middle of one open room is not. Labels stay in 1..label_count (some unused).
void MergeOpenBorders(cv::Mat* labels, const cv::Mat& dt, int label_count, double ratio,
                      float min_saddle, double no_constriction_ratio) {
  if ((ratio <= 0.0 && no_constriction_ratio <= 0.0) || label_count < 2) return;
  std::vector<float> peak(Idx(label_count) + 1, 0.0f);
  std::map<std::pair<int, int>, float> saddle;
  auto note = [&](int a, int b, float d) {
    if (a > b) std::swap(a, b);
    float& s = saddle[{a, b}];
    s = std::max(s, d);
  };
  for (int r = 0; r < labels->rows; ++r) {
    const int* l = labels->ptr<int>(r);
    const int* below = r + 1 < labels->rows ? labels->ptr<int>(r + 1) : nullptr;
    const float* d = dt.ptr<float>(r);
    const float* dbelow = below != nullptr ? dt.ptr<float>(r + 1) : nullptr;
    for (int c = 0; c < labels->cols; ++c) {
      if (l[c] == 0) continue;
      peak[Idx(l[c])] = std::max(peak[Idx(l[c])], d[c]);
      if (c + 1 < labels->cols && l[c + 1] != 0 && l[c + 1] != l[c]) {
        note(l[c], l[c + 1], std::min(d[c], d[c + 1]));
      }
      if (below != nullptr && below[c] != 0 && below[c] != l[c]) {
        note(l[c], below[c], std::min(d[c], dbelow[c]));
      }
    }
  }
  std::vector<int> parent(Idx(label_count) + 1);
  std::iota(parent.begin(), parent.end(), 0);
  auto find = [&](int x) {
    while (parent[Idx(x)] != x) x = parent[Idx(x)] = parent[Idx(parent[Idx(x)])];
    return x;
  };
  for (;;) {
    // The most open border first; recompute over current roots.
    std::map<std::pair<int, int>, float> current;
    for (const auto& [key, s] : saddle) {
      int a = find(key.first), b = find(key.second);
      if (a == b) continue;
      if (a > b) std::swap(a, b);
      float& v = current[{a, b}];
      v = std::max(v, s);
    }
    double best = 0.0;
    std::pair<int, int> best_pair{0, 0};
    for (const auto& [key, s] : current) {
      const float lo = std::min(peak[Idx(key.first)], peak[Idx(key.second)]);
      const double q = lo > 0.0f ? static_cast<double>(s / lo) : 0.0;
      const bool open = ratio > 0.0 && q >= ratio && s >= min_saddle;
      const bool same_space = no_constriction_ratio > 0.0 && q >= no_constriction_ratio;
      if ((open || same_space) && q > best) best = q, best_pair = key;
    }
    if (best_pair.first == 0) break;
    parent[Idx(best_pair.second)] = best_pair.first;
    peak[Idx(best_pair.first)] = std::max(peak[Idx(best_pair.first)], peak[Idx(best_pair.second)]);
  }
  for (int r = 0; r < labels->rows; ++r) {
    int* l = labels->ptr<int>(r);
    for (int c = 0; c < labels->cols; ++c) {
      if (l[c] != 0) l[c] = find(l[c]);
    }
  }
}

// Merges neighbours whose shared border runs through an opening (a wall continued across a gap,
// declutter.h) that constricts neither of them, by either of two rules (each off at 0):
// - global (`peak_ratio`): the border's largest clearance in the free space with openings open
//   (`dt_open`) is at least this x the larger of the two segments' peak clearance with openings
//   closed (`dt_closed`);
// - local (`local_ratio`): the opening's Constriction() (its span against the free width just
//   either side of it, declutter.h) is at least this, for the opening that holds most of the
//   border; an opening no wider than a door (`door_px`) counts 0.
// A corridor cut where an aligned wall crosses it is as wide there as beside the cut; a
// partition between two rooms with wall on at least one side of the opening is narrower than
// the room beside it. Most open first; a merged segment's peak is the larger of the two and of
// the opening's clearance. Labels stay in 1..label_count (some unused).
void MergeAcrossOpenings(cv::Mat* labels, const cv::Mat& dt_open, const cv::Mat& dt_closed,
                         const cv::Mat& openings, const cv::Mat& opening_ids,
                         std::span<const OpeningLine> lines, int label_count, double peak_ratio,
                         double local_ratio, float door_px) {
  if ((peak_ratio <= 0.0 && local_ratio <= 0.0) || label_count < 2) return;
  std::vector<float> peak(Idx(label_count) + 1, 0.0f);
  std::map<std::pair<int, int>, float> saddle;
  // Border cells per opening id, per pair: the opening holding most of the border decides
  // (another opening's end touching the border at a corner must not: a wall continued past a
  // wardrobe's front would otherwise open it).
  std::map<std::pair<int, int>, std::map<int, int>> votes;
  // An opening no wider than a door (a wall end continued to the next wall across at most
  // door_px) is a door: it never merges, however open it is against the space beside it (a
  // door is as wide as the gap it is in).
  auto constriction = [&](int id) {
    if (id <= 0 || Idx(id) > lines.size()) return 0.0;
    const OpeningLine& line = lines[Idx(id - 1)];
    const cv::Point2f d = line.to - line.from;
    if (std::hypot(d.x, d.y) + 1.0f <= door_px) return 0.0;
    return line.Constriction();
  };
  auto note = [&](int a, int b, float d, int id_a, int id_b) {
    if (a > b) std::swap(a, b);
    float& s = saddle[{a, b}];
    s = std::max(s, d);
    std::map<int, int>& v = votes[{a, b}];
    if (id_a > 0) ++v[id_a];
    if (id_b > 0) ++v[id_b];
  };
  for (int r = 0; r < labels->rows; ++r) {
    const int* l = labels->ptr<int>(r);
    const int* below = r + 1 < labels->rows ? labels->ptr<int>(r + 1) : nullptr;
    const float* d = dt_open.ptr<float>(r);
    const float* dbelow = below != nullptr ? dt_open.ptr<float>(r + 1) : nullptr;
    const float* dc = dt_closed.ptr<float>(r);
    const std::uint8_t* op = openings.ptr<std::uint8_t>(r);
    const std::uint8_t* opbelow = below != nullptr ? openings.ptr<std::uint8_t>(r + 1) : nullptr;
    const int* id = opening_ids.ptr<int>(r);
    const int* idbelow = below != nullptr ? opening_ids.ptr<int>(r + 1) : nullptr;
    for (int c = 0; c < labels->cols; ++c) {
      if (l[c] == 0) continue;
      peak[Idx(l[c])] = std::max(peak[Idx(l[c])], dc[c]);
      if (c + 1 < labels->cols && l[c + 1] != 0 && l[c + 1] != l[c] &&
          (op[c] != 0 || op[c + 1] != 0)) {
        note(l[c], l[c + 1], std::min(d[c], d[c + 1]), id[c], id[c + 1]);
      }
      if (below != nullptr && below[c] != 0 && below[c] != l[c] &&
          (op[c] != 0 || opbelow[c] != 0)) {
        note(l[c], below[c], std::min(d[c], dbelow[c]), id[c], idbelow[c]);
      }
    }
  }
  std::map<std::pair<int, int>, double> local;  // Constriction() of the border's main opening
  for (const auto& [key, v] : votes) {
    int main_id = 0, most = 0;
    for (const auto& [id, n] : v) {
      if (n > most) main_id = id, most = n;
    }
    local[key] = constriction(main_id);
  }
  std::vector<int> parent(Idx(label_count) + 1);
  std::iota(parent.begin(), parent.end(), 0);
  auto find = [&](int x) {
    while (parent[Idx(x)] != x) x = parent[Idx(x)] = parent[Idx(parent[Idx(x)])];
    return x;
  };
  for (;;) {
    std::map<std::pair<int, int>, std::pair<float, double>> current;
    for (const auto& [key, s] : saddle) {
      int a = find(key.first), b = find(key.second);
      if (a == b) continue;
      if (a > b) std::swap(a, b);
      auto& v = current[{a, b}];
      v.first = std::max(v.first, s);
      v.second = std::max(v.second, local[key]);
    }
    // Every rule that is on must hold; the most open first.
    double best = 0.0;
    std::pair<int, int> best_pair{0, 0};
    for (const auto& [key, v] : current) {
      const float hi = std::max(peak[Idx(key.first)], peak[Idx(key.second)]);
      const double q = hi > 0.0f ? static_cast<double>(v.first / hi) : 0.0;
      if (peak_ratio > 0.0 && q < peak_ratio) continue;
      if (local_ratio > 0.0 && v.second < local_ratio) continue;
      const double order = peak_ratio > 0.0 ? q : v.second;
      if (order > best) best = order, best_pair = key;
    }
    if (best_pair.first == 0) break;
    parent[Idx(best_pair.second)] = best_pair.first;
    // The merged space is at least as open as the opening it merged across: two strips cut
    // from one room by a wall's continuation are, together, the room again, and a wardrobe
    // off it is measured against the room, not against a strip.
    peak[Idx(best_pair.first)] = std::max(
        {peak[Idx(best_pair.first)], peak[Idx(best_pair.second)], current[best_pair].first});
  }
  for (int r = 0; r < labels->rows; ++r) {
    int* l = labels->ptr<int>(r);
    for (int c = 0; c < labels->cols; ++c) {
      if (l[c] != 0) l[c] = find(l[c]);
    }
  }
}

void Describe(const cv::Mat& labels, const cv::Mat& dt, int count, double res,
              const SegmentOptions& o, std::vector<SegmentInfo>* out) {
  out->assign(Idx(count), SegmentInfo{});
  std::vector<float> max_dt(Idx(count), 0.0f);
  for (int r = 0; r < labels.rows; ++r) {
    const int* l = labels.ptr<int>(r);
    const float* d = dt.ptr<float>(r);
    for (int c = 0; c < labels.cols; ++c) {
      if (l[c] == 0) continue;
      ++(*out)[Idx(l[c] - 1)].area_cells;
      max_dt[Idx(l[c] - 1)] = std::max(max_dt[Idx(l[c] - 1)], d[c]);
    }
  }
  for (int i = 0; i < count; ++i) {
    SegmentInfo& s = (*out)[Idx(i)];
    s.label = i + 1;
    s.area_m2 = s.area_cells * res * res;
    s.width_m = 2.0 * static_cast<double>(max_dt[Idx(i)]) * res;
    s.elongation = s.width_m > 0.0 ? s.area_m2 / (s.width_m * s.width_m) : 0.0;
    s.kind = (s.elongation >= o.corridor_elongation && s.width_m <= o.corridor_max_width_m)
                 ? "corridor"
                 : "room";
  }
}

Status CheckOptions(const SegmentOptions& o) {
  auto bad = [](const char* what) {
    return InvalidArgument(std::string("segmentation option ") + what);
  };
  if (!(o.seed_level_step_m > 0.0)) return bad("seed_level_step_m must be > 0");
  if (!(o.seed_min_level_m > 0.0 && o.seed_max_level_m >= o.seed_min_level_m)) {
    return bad("seed levels must satisfy 0 < seed_min_level_m <= seed_max_level_m");
  }
  if ((o.seed_max_level_m - o.seed_min_level_m) / o.seed_level_step_m > 1000.0) {
    return bad("seed levels: at most 1000 levels");
  }
  if (o.min_room_area_m2 < 0.0 || o.seed_min_area_m2 < 0.0 || o.clutter_area_m2 < 0.0 ||
      o.seedless_room_min_area_m2 < 0.0) {
    return bad("areas must be >= 0");
  }
  if (o.simplify_tolerance_m < 0.0) return bad("simplify_tolerance_m must be >= 0");
  if (!(o.layout_merge_threshold >= 0.0 && o.layout_merge_threshold <= 1.0)) {
    return bad("layout_merge_threshold must be in [0, 1] (0 = the rule merges)");
  }
  if (o.layout_line_max_m < 0.0 || o.layout_mouth_max_m < 0.0 || o.layout_facade_max_m < 0.0 ||
      o.layout_corner_max_m < 0.0 || o.layout_cap_max_m < 0.0 ||
      o.layout_seedless_min_area_m2 < 0.0 || o.layout_min_area_m2 < 0.0) {
    return bad("the layout_* lengths and areas must be >= 0");
  }
  if (o.wall_min_length_m < 0.0 || o.wall_line_gap_m < 0.0 || o.door_max_width_m < 0.0 ||
      o.opening_max_width_m < 0.0 || o.opening_merge_ratio < 0.0 ||
      o.facade_opening_max_width_m < 0.0 || o.mouth_opening_max_width_m < 0.0 ||
      o.facing_opening_max_width_m < 0.0 || o.corner_opening_max_width_m < 0.0 ||
      o.cap_opening_max_width_m < 0.0 || o.opening_local_ratio < 0.0 ||
      o.opening_side_depth_m < 0.0 || o.wall_stub_min_length_m < 0.0 ||
      o.opening_wall_max_thickness_m < 0.0) {
    return bad(
        "wall_min_length_m, wall_stub_min_length_m, wall_line_gap_m, door_max_width_m "
        "and the opening_* options must be >= 0");
  }
  return Status::Ok();
}

}  // namespace

Status SetSegmentOption(const std::string& key_value, SegmentOptions* options) {
  const auto eq = key_value.find('=');
  if (eq == std::string::npos) {
    return InvalidArgument("segmentation option '" + key_value + "': expected KEY=VALUE");
  }
  const std::string key = key_value.substr(0, eq);
  const std::string text = key_value.substr(eq + 1);
  double value = 0.0;
  try {
    std::size_t used = 0;
    value = std::stod(text, &used);
    if (used != text.size() || !std::isfinite(value)) throw std::invalid_argument(text);
  } catch (const std::exception&) {
    return InvalidArgument("segmentation option '" + key + "': '" + text + "' is not a number");
  }
  const std::pair<const char*, double SegmentOptions::*> fields[] = {
      {"wall_gap_close_m", &SegmentOptions::wall_gap_close_m},
      {"ray_width_m", &SegmentOptions::ray_width_m},
      {"clutter_area_m2", &SegmentOptions::clutter_area_m2},
      {"wall_min_length_m", &SegmentOptions::wall_min_length_m},
      {"wall_line_gap_m", &SegmentOptions::wall_line_gap_m},
      {"door_max_width_m", &SegmentOptions::door_max_width_m},
      {"opening_max_width_m", &SegmentOptions::opening_max_width_m},
      {"facade_opening_max_width_m", &SegmentOptions::facade_opening_max_width_m},
      {"mouth_opening_max_width_m", &SegmentOptions::mouth_opening_max_width_m},
      {"facing_opening_max_width_m", &SegmentOptions::facing_opening_max_width_m},
      {"corner_opening_max_width_m", &SegmentOptions::corner_opening_max_width_m},
      {"cap_opening_max_width_m", &SegmentOptions::cap_opening_max_width_m},
      {"opening_wall_max_thickness_m", &SegmentOptions::opening_wall_max_thickness_m},
      {"opening_merge_ratio", &SegmentOptions::opening_merge_ratio},
      {"opening_local_ratio", &SegmentOptions::opening_local_ratio},
      {"wall_stub_min_length_m", &SegmentOptions::wall_stub_min_length_m},
      {"opening_side_depth_m", &SegmentOptions::opening_side_depth_m},
      {"seedless_room_min_area_m2", &SegmentOptions::seedless_room_min_area_m2},
      {"seed_min_level_m", &SegmentOptions::seed_min_level_m},
      {"seed_level_step_m", &SegmentOptions::seed_level_step_m},
      {"seed_max_level_m", &SegmentOptions::seed_max_level_m},
      {"seed_min_area_m2", &SegmentOptions::seed_min_area_m2},
      {"seed_min_persistence_m", &SegmentOptions::seed_min_persistence_m},
      {"merge_open_border_ratio", &SegmentOptions::merge_open_border_ratio},
      {"merge_min_opening_m", &SegmentOptions::merge_min_opening_m},
      {"merge_no_constriction_ratio", &SegmentOptions::merge_no_constriction_ratio},
      {"min_room_area_m2", &SegmentOptions::min_room_area_m2},
      {"corridor_elongation", &SegmentOptions::corridor_elongation},
      {"corridor_max_width_m", &SegmentOptions::corridor_max_width_m},
      {"simplify_tolerance_m", &SegmentOptions::simplify_tolerance_m},
      {"layout_merge_threshold", &SegmentOptions::layout_merge_threshold},
      {"layout_line_max_m", &SegmentOptions::layout_line_max_m},
      {"layout_mouth_max_m", &SegmentOptions::layout_mouth_max_m},
      {"layout_facade_max_m", &SegmentOptions::layout_facade_max_m},
      {"layout_corner_max_m", &SegmentOptions::layout_corner_max_m},
      {"layout_cap_max_m", &SegmentOptions::layout_cap_max_m},
      {"layout_seedless_min_area_m2", &SegmentOptions::layout_seedless_min_area_m2},
      {"layout_min_area_m2", &SegmentOptions::layout_min_area_m2},
  };
  std::string known;
  for (const auto& [name, field] : fields) {
    if (key == name) {
      options->*field = value;
      return CheckOptions(*options);
    }
    known += (known.empty() ? "" : ", ") + std::string(name);
  }
  return InvalidArgument("unknown segmentation option '" + key + "' (known: " + known + ")");
}

Status WriteSegmentationPng(const std::string& path, const OccupancyGrid& grid,
                            const Segmentation& seg) {
  if (seg.labels.size() != grid.cells.size()) {
    return InvalidArgument("segmentation and grid differ in size");
  }
  cv::Mat img(grid.cells.size(), CV_8UC3);
  for (int r = 0; r < img.rows; ++r) {
    const std::uint8_t* g = grid.cells.ptr<std::uint8_t>(r);
    const int* l = seg.labels.ptr<int>(r);
    auto* out = img.ptr<cv::Vec3b>(r);
    for (int c = 0; c < img.cols; ++c) {
      if (l[c] > 0) {
        // A fixed hash of the label: neighbours get unrelated, reproducible colours.
        const auto h = static_cast<std::uint32_t>(l[c]) * 2654435761u;
        out[c] = cv::Vec3b(static_cast<std::uint8_t>(64 + (h >> 8) % 192),
                           static_cast<std::uint8_t>(64 + (h >> 16) % 192),
                           static_cast<std::uint8_t>(64 + (h >> 24) % 192));
      } else {
        const std::uint8_t v = g[c] == kCellOccupied ? 0 : (g[c] == kCellFree ? 255 : 160);
        out[c] = cv::Vec3b(v, v, v);
      }
    }
  }
  try {
    if (!cv::imwrite(path, img)) return IoError(path + ": cannot write the PNG");
  } catch (const cv::Exception& e) {
    return IoError(path + ": OpenCV could not write it: " + e.what());
  }
  return Status::Ok();
}

namespace {

// The options the layout pieces are cut with: every thin wall end continued across the building,
// wide mouths and facades, small enclosed spaces their own pieces, and none of the rule merges
// (the learned merge decides instead).
SegmentOptions LayoutPieceOptions(const SegmentOptions& o) {
  SegmentOptions p = o;
  p.opening_max_width_m = o.layout_line_max_m;
  p.facing_opening_max_width_m = o.layout_line_max_m;
  p.mouth_opening_max_width_m = o.layout_mouth_max_m;
  p.facade_opening_max_width_m = o.layout_facade_max_m;
  p.corner_opening_max_width_m = o.layout_corner_max_m;
  p.cap_opening_max_width_m = o.layout_cap_max_m;
  p.seedless_room_min_area_m2 = o.layout_seedless_min_area_m2;
  p.opening_merge_ratio = 0.0;
  p.opening_local_ratio = 0.0;
  p.merge_open_border_ratio = 0.0;
  p.merge_no_constriction_ratio = 0.0;
  return p;
}

}  // namespace

Result<Segmentation> SegmentRooms(const OccupancyGrid& grid, const SegmentOptions& options) {
  return SegmentRooms(grid, options, DefaultLayoutMergeModel());
}

Result<Segmentation> SegmentRooms(const OccupancyGrid& grid, const SegmentOptions& given,
                                  const LayoutMergeModel& model, const LayoutMergeTrace& trace) {
  const auto t0 = std::chrono::steady_clock::now();
  if (grid.cells.empty() || grid.cells.type() != CV_8UC1) {
    return InvalidArgument("occupancy grid is empty or not 8-bit single-channel");
  }
  if (!(grid.resolution_m > 0.0)) {
    return InvalidArgument("occupancy grid resolution must be > 0, got " +
                           std::to_string(grid.resolution_m));
  }
  ZM_RETURN_IF_ERROR(CheckOptions(given));
  const bool layout = given.layout_merge_threshold > 0.0;
  const SegmentOptions options = layout ? LayoutPieceOptions(given) : given;
  const double res = grid.resolution_m;
  Segmentation seg;
  try {
    WallEvidence walls;
    seg.free_cleaned = CleanFreeSpace(grid.cells, options, res, &walls);
    if (!walls.opening_lines.empty()) {
      // Openings are measured in the space the robot moves in: cleaned, doorways closed.
      MeasureOpenings(seg.free_cleaned & ~walls.doorways,
                      CellsFromMetres(options.opening_side_depth_m, res), &walls);
    }
    seg.wall_angle_rad = walls.angle_rad;
    seg.labels = cv::Mat::zeros(grid.cells.size(), CV_32S);
    // Work inside the bounding box of free space (plus a border) only.
    cv::Rect box = cv::boundingRect(seg.free_cleaned);
    if (box.area() > 0) {
      box = cv::Rect(box.x - 2, box.y - 2, box.width + 4, box.height + 4) &
            cv::Rect(0, 0, grid.cols(), grid.rows());
      cv::Mat free_roi = seg.free_cleaned(box);
      // Clearance with doorways closed: seeds never span a door, floods meet in it (its
      // clearance is 0) and no merge crosses it. Openings are closed too for seeds and floods
      // (`dt_closed`); whether one stays a border is decided below with them open (`dt`).
      cv::Mat dt, dt_closed;
      const cv::Mat open_space = free_roi & ~walls.doorways(box);
      cv::distanceTransform(open_space, dt, cv::DIST_L2, cv::DIST_MASK_5, CV_32F);
      const cv::Mat openings = walls.openings(box) & open_space;
      if (cv::countNonZero(openings) > 0) {
        cv::distanceTransform(open_space & ~openings, dt_closed, cv::DIST_L2, cv::DIST_MASK_5,
                              CV_32F);
      } else {
        dt_closed = dt;
      }
      int seed_count = 0;
      cv::Mat labels = FindSeeds(dt_closed, options, res, &seed_count);
      if (options.seedless_room_min_area_m2 > 0.0) {
        AddSeedlessRooms(dt_closed > 0.0f,
                         static_cast<int>(options.seedless_room_min_area_m2 / (res * res)), &labels,
                         &seed_count);
      }
      Flood(free_roi, dt_closed, &labels);
      // Free areas no seed reached (too thin for any level) become segments of their own; the
      // merge below keeps only those big enough.
      cv::Mat unreached = (labels == 0) & free_roi;
      cv::Mat extra;
      const int n_extra = cv::connectedComponents(unreached, extra, 4, CV_32S);
      for (int r = 0; r < labels.rows; ++r) {
        int* l = labels.ptr<int>(r);
        const int* e = extra.ptr<int>(r);
        for (int c = 0; c < labels.cols; ++c) {
          if (e[c] > 0) l[c] = seed_count + e[c];
        }
      }
      const int label_count = seed_count + std::max(0, n_extra - 1);
      if (layout) {
        LayoutMergeInputs in;
        in.labels = &labels;
        in.count = MergeSmallSegments(&labels, label_count, 0);  // numbers pieces densely
        in.occupied = (grid.cells(box) == kCellOccupied) & (labels == 0);
        in.resolution_m = res;
        in.wall_angle_rad = walls.angle_rad;
        in.offset = box.tl();
        // The rule merges' segmentation of the same grid is the model's second opinion: they
        // were chosen on office buildings, where their corridors and halls are right.
        SegmentOptions rule_options = given;
        rule_options.layout_merge_threshold = 0.0;
        ZM_ASSIGN_OR_RETURN(const Segmentation rules, SegmentRooms(grid, rule_options));
        in.rule_labels = rules.labels(box).clone();
        in.doorways = walls.doorways(box);  // views: `walls` outlives the merge
        in.opening_kinds = walls.opening_kinds(box);
        ZM_ASSIGN_OR_RETURN(const int merged,
                            MergeLayoutPieces(in, model, given.layout_merge_threshold, trace));
        // Specks and slivers the model left alone (a laser map's stray free cells) are no zone
        // of their own, as in the rule merges.
        const int count = MergeSmallSegments(
            &labels, merged, static_cast<int>(given.layout_min_area_m2 / (res * res)));
        Describe(labels, dt, count, res, options, &seg.segments);
        labels.copyTo(seg.labels(box));
        seg.runtime_ms =
            std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0)
                .count();
        return seg;
      }
      MergeAcrossOpenings(&labels, dt, dt_closed, openings, walls.opening_ids(box),
                          walls.opening_lines, label_count, options.opening_merge_ratio,
                          options.opening_local_ratio,
                          static_cast<float>(options.door_max_width_m / res));
      MergeOpenBorders(&labels, dt_closed, label_count, options.merge_open_border_ratio,
                       static_cast<float>(0.5 * options.merge_min_opening_m / res),
                       options.merge_no_constriction_ratio);
      const int min_area = static_cast<int>(options.min_room_area_m2 / (res * res));
      const int count = MergeSmallSegments(&labels, label_count, min_area);
      Describe(labels, dt, count, res, options, &seg.segments);
      labels.copyTo(seg.labels(box));
    }
  } catch (const cv::Exception& e) {
    return Internal(std::string("room segmentation: OpenCV failed: ") + e.what());
  }
  seg.runtime_ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  return seg;
}

Status SplitOversizeSegments(const OccupancyGrid& grid,
                             std::span<const Eigen::Vector2d> positions_m, int max_keyframes,
                             Segmentation* seg) {
  if (max_keyframes < 1) {
    return InvalidArgument("max keyframes per zone must be >= 1, got " +
                           std::to_string(max_keyframes));
  }
  if (seg->labels.size() != grid.cells.size()) {
    return InvalidArgument("segmentation and grid differ in size");
  }
  // Keyframes of each label, as cell coordinates.
  std::map<int, std::vector<Eigen::Vector2d>> members;
  for (const Eigen::Vector2d& p : positions_m) {
    int col = 0, row = 0;
    if (!grid.CellOf(p, &col, &row)) continue;
    const int l = seg->labels.at<int>(row, col);
    if (l > 0) members[l].push_back(grid.MetresToCell(p));
  }
  std::vector<std::pair<int, std::vector<Eigen::Vector2d>>> work(members.begin(), members.end());
  while (!work.empty()) {
    auto [label, pts] = std::move(work.back());
    work.pop_back();
    if (static_cast<int>(pts.size()) <= max_keyframes) continue;
    Eigen::Vector2d mean = Eigen::Vector2d::Zero();
    for (const auto& p : pts) mean += p;
    mean /= static_cast<double>(pts.size());
    Eigen::Matrix2d cov = Eigen::Matrix2d::Zero();
    for (const auto& p : pts) cov += (p - mean) * (p - mean).transpose();
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> eig(cov);
    Eigen::Vector2d axis = eig.eigenvectors().col(1);
    std::vector<double> proj;
    proj.reserve(pts.size());
    for (const auto& p : pts) proj.push_back(p.dot(axis));
    std::vector<double> sorted = proj;
    std::sort(sorted.begin(), sorted.end());
    // Split between two distinct projections nearest the median.
    const std::size_t n = sorted.size();
    std::size_t split = 0;
    for (std::size_t off = 0; off < n && split == 0; ++off) {
      for (std::size_t k : {n / 2 + off, n / 2 - std::min(off, n / 2)}) {
        if (k >= 1 && k < n && sorted[k - 1] < sorted[k]) {
          split = k;
          break;
        }
      }
    }
    if (split == 0) {
      return FailedPrecondition("zone " + std::to_string(label) + " holds " + std::to_string(n) +
                                " keyframes at one spot, more than the limit " +
                                std::to_string(max_keyframes) + ": cannot split it in space");
    }
    const double threshold = 0.5 * (sorted[split - 1] + sorted[split]);
    const int new_label = static_cast<int>(seg->segments.size()) + 1;
    SegmentInfo info = seg->segments[Idx(label - 1)];
    info.label = new_label;
    info.area_cells = 0;
    int kept = 0;
    for (int r = 0; r < seg->labels.rows; ++r) {
      int* l = seg->labels.ptr<int>(r);
      for (int c = 0; c < seg->labels.cols; ++c) {
        if (l[c] != label) continue;
        // Cell centres are at (c + 0.5, r + 0.5) in MetresToCell's continuous coordinates.
        if (Eigen::Vector2d(c + 0.5, r + 0.5).dot(axis) > threshold) {
          l[c] = new_label;
          ++info.area_cells;
        } else {
          ++kept;
        }
      }
    }
    seg->segments[Idx(label - 1)].area_cells = kept;
    seg->segments[Idx(label - 1)].area_m2 = kept * grid.resolution_m * grid.resolution_m;
    info.area_m2 = info.area_cells * grid.resolution_m * grid.resolution_m;
    seg->segments.push_back(info);
    std::vector<Eigen::Vector2d> low, high;
    for (std::size_t i = 0; i < pts.size(); ++i)
      (proj[i] > threshold ? high : low).push_back(pts[i]);
    work.emplace_back(label, std::move(low));
    work.emplace_back(new_label, std::move(high));
  }
  return Status::Ok();
}

Result<std::vector<Zone>> SegmentationToZones(const Segmentation& seg, const OccupancyGrid& grid,
                                              const SegmentOptions& options) {
  std::vector<Zone> zones;
  std::map<std::string, int> per_kind;
  const double eps_px = options.simplify_tolerance_m / grid.resolution_m;
  try {
    for (const SegmentInfo& s : seg.segments) {
      cv::Mat mask = seg.labels == s.label;
      std::vector<std::vector<cv::Point>> contours;
      cv::findContours(mask, contours, cv::RETR_EXTERNAL, cv::CHAIN_APPROX_NONE);
      if (contours.empty()) continue;
      const auto largest = std::max_element(
          contours.begin(), contours.end(),
          [](const auto& a, const auto& b) { return cv::contourArea(a) < cv::contourArea(b); });
      std::vector<Eigen::Vector2d> ring;
      // Simplify; halve the tolerance while the outline self-intersects; last resort the hull.
      for (double eps = eps_px;; eps *= 0.5) {
        std::vector<cv::Point> approx;
        if (eps < 0.25) {
          cv::convexHull(*largest, approx);
        } else {
          cv::approxPolyDP(*largest, approx, eps, true);
        }
        ring.clear();
        for (const cv::Point& p : approx) ring.push_back(grid.CellToMetres(p.x, p.y));
        if (eps < 0.25 ||
            (ring.size() >= 3 && !FindSelfIntersection(ring) && std::abs(SignedArea(ring)) > 0.0)) {
          break;
        }
      }
      if (ring.size() < 3 || std::abs(SignedArea(ring)) <= 0.0) continue;
      if (SignedArea(ring) < 0.0) std::reverse(ring.begin(), ring.end());  // GeoJSON: CCW
      Zone z;
      z.id = ZoneId(static_cast<std::int32_t>(zones.size()));
      z.name = s.kind + "_" + std::to_string(++per_kind[s.kind]);
      z.kind = s.kind;
      z.floor = 0;
      z.polygon = std::move(ring);
      zones.push_back(std::move(z));
    }
  } catch (const cv::Exception& e) {
    return Internal(std::string("zone polygons: OpenCV failed: ") + e.what());
  }
  return zones;
}

std::string ZonesToGeoJson(std::span<const Zone> zones) {
  nlohmann::json features = nlohmann::json::array();
  for (const Zone& z : zones) {
    nlohmann::json ring = nlohmann::json::array();
    for (const auto& p : z.polygon) ring.push_back({p.x(), p.y()});
    if (!z.polygon.empty()) ring.push_back({z.polygon.front().x(), z.polygon.front().y()});
    features.push_back({{"type", "Feature"},
                        {"properties", {{"name", z.name}, {"kind", z.kind}, {"floor", z.floor}}},
                        {"geometry", {{"type", "Polygon"}, {"coordinates", {ring}}}}});
  }
  nlohmann::json doc = {{"type", "FeatureCollection"}, {"features", features}};
  return doc.dump(1);
}

Status WriteZonesGeoJson(const std::string& path, std::span<const Zone> zones) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  if (!out) return IoError(path + ": cannot open for writing");
  out << ZonesToGeoJson(zones) << '\n';
  out.flush();
  if (!out) return IoError(path + ": write failed");
  return Status::Ok();
}

namespace {

// Convex hull (Andrew's monotone chain), counter-clockwise, no repeated vertex.
std::vector<Eigen::Vector2d> ConvexHull(std::vector<Eigen::Vector2d> pts) {
  std::sort(pts.begin(), pts.end(), [](const auto& a, const auto& b) {
    return a.x() < b.x() || (a.x() == b.x() && a.y() < b.y());
  });
  if (pts.size() < 3) return pts;
  std::vector<Eigen::Vector2d> hull(2 * pts.size());
  auto cross = [](const Eigen::Vector2d& o, const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
    return (a.x() - o.x()) * (b.y() - o.y()) - (a.y() - o.y()) * (b.x() - o.x());
  };
  std::size_t k = 0;
  for (const auto& p : pts) {
    while (k >= 2 && cross(hull[k - 2], hull[k - 1], p) <= 0) --k;
    hull[k++] = p;
  }
  for (std::size_t i = pts.size() - 1, t = k + 1; i-- > 0;) {
    while (k >= t && cross(hull[k - 2], hull[k - 1], pts[i]) <= 0) --k;
    hull[k++] = pts[i];
  }
  hull.resize(k - 1);
  return hull;
}

struct CellPart {
  std::vector<Eigen::Vector2d> region;  // convex, CCW: the part of the cell this zone owns
  std::vector<Eigen::Vector2d> points;
};

}  // namespace

Result<std::vector<Zone>> ZonesFromKeyframes(std::span<const Eigen::Vector2d> positions_m,
                                             const KeyframeZoneOptions& options) {
  if (!(options.cell_size_m > 0.0) || options.max_keyframes < 1 || options.margin_m < 0.0) {
    return InvalidArgument(
        "keyframe zones: need cell_size_m > 0, max_keyframes >= 1, "
        "margin_m >= 0");
  }
  std::map<std::pair<std::int64_t, std::int64_t>, std::vector<Eigen::Vector2d>> cells;
  for (const auto& p : positions_m) {
    if (!p.allFinite()) return InvalidArgument("keyframe zones: a keyframe position is not finite");
    cells[{static_cast<std::int64_t>(std::floor(p.x() / options.cell_size_m)),
           static_cast<std::int64_t>(std::floor(p.y() / options.cell_size_m))}]
        .push_back(p);
  }
  std::vector<CellPart> done;
  std::vector<CellPart> work;
  for (auto& [key, pts] : cells) {
    const double x0 = static_cast<double>(key.first) * options.cell_size_m;
    const double y0 = static_cast<double>(key.second) * options.cell_size_m;
    const double s = options.cell_size_m;
    work.push_back({{{x0, y0}, {x0 + s, y0}, {x0 + s, y0 + s}, {x0, y0 + s}}, std::move(pts)});
    while (!work.empty()) {
      CellPart part = std::move(work.back());
      work.pop_back();
      if (static_cast<int>(part.points.size()) <= options.max_keyframes) {
        done.push_back(std::move(part));
        continue;
      }
      Eigen::Vector2d mean = Eigen::Vector2d::Zero();
      for (const auto& p : part.points) mean += p;
      mean /= static_cast<double>(part.points.size());
      Eigen::Matrix2d cov = Eigen::Matrix2d::Zero();
      for (const auto& p : part.points) cov += (p - mean) * (p - mean).transpose();
      Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> eig(cov);
      bool split_done = false;
      for (int axis_index : {1, 0}) {
        const Eigen::Vector2d axis = eig.eigenvectors().col(axis_index);
        std::vector<double> sorted;
        for (const auto& p : part.points) sorted.push_back(p.dot(axis));
        std::sort(sorted.begin(), sorted.end());
        const std::size_t n = sorted.size();
        std::size_t split = 0;
        for (std::size_t off = 0; off < n && split == 0; ++off) {
          for (std::size_t k : {n / 2 + off, n / 2 - std::min(off, n / 2)}) {
            if (k >= 1 && k < n && sorted[k - 1] < sorted[k]) {
              split = k;
              break;
            }
          }
        }
        if (split == 0) continue;
        const double t = 0.5 * (sorted[split - 1] + sorted[split]);
        CellPart low{ClipToHalfPlane(part.region, axis, t), {}};
        CellPart high{ClipToHalfPlane(part.region, -axis, -t), {}};
        for (const auto& p : part.points) (p.dot(axis) <= t ? low : high).points.push_back(p);
        work.push_back(std::move(low));
        work.push_back(std::move(high));
        split_done = true;
        break;
      }
      if (!split_done) {
        return FailedPrecondition("keyframe zones: " + std::to_string(part.points.size()) +
                                  " keyframes at one position exceed the limit of " +
                                  std::to_string(options.max_keyframes) + " per zone");
      }
    }
  }
  std::vector<Zone> zones;
  for (const CellPart& part : done) {
    if (part.points.empty()) continue;
    // Hull of the keyframes grown by the margin (an octagon around each), clipped to the part.
    std::vector<Eigen::Vector2d> grown;
    const double m = std::max(options.margin_m, 1e-3);
    for (const auto& p : part.points) {
      for (int k = 0; k < 8; ++k) {
        const double a = k * std::numbers::pi / 4.0 + std::numbers::pi / 8.0;
        grown.emplace_back(p.x() + m * std::cos(a), p.y() + m * std::sin(a));
      }
    }
    std::vector<Eigen::Vector2d> ring = ConvexHull(std::move(grown));
    const auto& reg = part.region;
    for (std::size_t i = 0; i < reg.size() && ring.size() >= 3; ++i) {
      const Eigen::Vector2d a = reg[i], b = reg[(i + 1) % reg.size()];
      const Eigen::Vector2d normal(b.y() - a.y(), a.x() - b.x());  // outward for a CCW region
      ring = ClipToHalfPlane(ring, normal, normal.dot(a));
    }
    if (ring.size() < 3 || std::abs(SignedArea(ring)) < 1e-9) continue;
    if (SignedArea(ring) < 0.0) std::reverse(ring.begin(), ring.end());
    Zone z;
    z.id = ZoneId(static_cast<std::int32_t>(zones.size()));
    z.name = "area_" + std::to_string(zones.size() + 1);
    z.kind = "room";
    z.polygon = std::move(ring);
    zones.push_back(std::move(z));
  }
  return zones;
}

Result<cv::Mat> LoadGroundTruthLabels(const std::string& path, int min_room_cells) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) return NotFound(path + ": no such file");
  cv::Mat img;
  try {
    img = cv::imread(path, cv::IMREAD_COLOR);
  } catch (const cv::Exception& e) {
    return InvalidArgument(path + ": OpenCV could not read it: " + e.what());
  }
  if (img.empty()) return NotFound(path + ": missing or not a readable image");
  cv::Mat labels = cv::Mat::zeros(img.size(), CV_32S);
  std::unordered_map<std::uint32_t, int> ids;
  for (int r = 0; r < img.rows; ++r) {
    const cv::Vec3b* p = img.ptr<cv::Vec3b>(r);
    int* l = labels.ptr<int>(r);
    for (int c = 0; c < img.cols; ++c) {
      if (p[c][0] <= 20 && p[c][1] <= 20 && p[c][2] <= 20) continue;
      const std::uint32_t key =
          (std::uint32_t{p[c][0]} << 16) | (std::uint32_t{p[c][1]} << 8) | std::uint32_t{p[c][2]};
      auto [it, inserted] = ids.emplace(key, static_cast<int>(ids.size()) + 1);
      l[c] = it->second;
    }
  }
  // Colours covering fewer than min_room_cells are stray edge pixels of the hand drawing.
  std::vector<int> count(ids.size() + 1, 0);
  for (int r = 0; r < labels.rows; ++r) {
    const int* l = labels.ptr<int>(r);
    for (int c = 0; c < labels.cols; ++c) ++count[Idx(l[c])];
  }
  std::vector<int> renumber(ids.size() + 1, 0);
  int next = 0;
  for (std::size_t i = 1; i < count.size(); ++i) {
    if (count[i] >= min_room_cells) renumber[i] = ++next;
  }
  for (int r = 0; r < labels.rows; ++r) {
    int* l = labels.ptr<int>(r);
    for (int c = 0; c < labels.cols; ++c) l[c] = renumber[Idx(l[c])];
  }
  return labels;
}

Result<SegmentationScore> ScoreSegmentation(const cv::Mat& predicted, const cv::Mat& ground_truth) {
  if (predicted.type() != CV_32SC1 || ground_truth.type() != CV_32SC1) {
    return InvalidArgument("scoring needs two CV_32SC1 label images");
  }
  const int rows = std::min(predicted.rows, ground_truth.rows);
  const int cols = std::min(predicted.cols, ground_truth.cols);
  std::map<std::pair<int, int>, std::int64_t> overlap;  // (pred, gt) -> cells
  std::map<int, std::int64_t> pred_area, gt_area;       // restricted to cells in both
  std::map<int, std::int64_t> gt_full, pred_full;       // every cell
  std::map<int, bool> gt_present, pred_present;
  std::int64_t total = 0;
  for (int r = 0; r < rows; ++r) {
    const int* p = predicted.ptr<int>(r);
    const int* g = ground_truth.ptr<int>(r);
    for (int c = 0; c < cols; ++c) {
      if (g[c] > 0) gt_present[g[c]] = true, ++gt_full[g[c]];
      if (p[c] > 0) pred_present[p[c]] = true, ++pred_full[p[c]];
      if (p[c] <= 0 || g[c] <= 0) continue;
      ++overlap[{p[c], g[c]}];
      ++pred_area[p[c]];
      ++gt_area[g[c]];
      ++total;
    }
  }
  SegmentationScore score;
  score.gt_rooms = static_cast<int>(gt_present.size());
  score.predicted_segments = static_cast<int>(pred_present.size());
  if (total == 0) return score;
  std::map<int, std::int64_t> best_for_pred, best_for_gt;
  std::map<int, double> best_iou, best_iou_full;
  for (const auto& [key, n] : overlap) {
    const auto [p, g] = key;
    best_for_pred[p] = std::max(best_for_pred[p], n);
    best_for_gt[g] = std::max(best_for_gt[g], n);
    const double iou = static_cast<double>(n) / static_cast<double>(pred_area[p] + gt_area[g] - n);
    best_iou[g] = std::max(best_iou[g], iou);
    const double full = static_cast<double>(n) / static_cast<double>(pred_full[p] + gt_full[g] - n);
    best_iou_full[g] = std::max(best_iou_full[g], full);
  }
  std::int64_t sum_p = 0, sum_g = 0;
  for (const auto& [p, n] : best_for_pred) sum_p += n;
  for (const auto& [g, n] : best_for_gt) sum_g += n;
  score.precision = static_cast<double>(sum_p) / static_cast<double>(total);
  score.recall = static_cast<double>(sum_g) / static_cast<double>(total);
  double iou_sum = 0.0;
  for (const auto& [g, iou] : best_iou) iou_sum += iou;
  score.mean_iou = score.gt_rooms > 0 ? iou_sum / score.gt_rooms : 0.0;
  double full_sum = 0.0;
  for (const auto& [g, iou] : best_iou_full) full_sum += iou;
  score.mean_iou_full = score.gt_rooms > 0 ? full_sum / score.gt_rooms : 0.0;
  return score;
}

}  // namespace zm
