// The merge stage (merge.h): the rule merges and each segment's kind. Every merge keeps labels
// in 1..label_count until MergeSmallSegments renumbers them densely.
#include "segment/merge.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <numeric>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include "segment/declutter.h"

namespace zm {
namespace {

using segment_detail::FreeAt;
using segment_detail::Idx;

// Merged labels 1..count as a forest (path halving): each merge hangs one root under another,
// and Relabel gives every labelled cell its root.
class Roots {
 public:
  explicit Roots(int count) : parent_(Idx(count) + 1) {
    std::iota(parent_.begin(), parent_.end(), 0);
  }
  int Find(int x) {
    while (parent_[Idx(x)] != x) x = parent_[Idx(x)] = parent_[Idx(parent_[Idx(x)])];
    return x;
  }
  void Join(int root, int into) { parent_[Idx(root)] = into; }
  void Relabel(cv::Mat* labels) {
    for (int r = 0; r < labels->rows; ++r) {
      int* l = labels->ptr<int>(r);
      for (int c = 0; c < labels->cols; ++c) {
        if (l[c] != 0) l[c] = Find(l[c]);
      }
    }
  }

 private:
  std::vector<int> parent_;
};

// Calls f(a, pa, b, pb) once for each pair of 4-neighbouring cells pa, pb (pb right of or below
// pa) whose labels a, b are different and both non-zero: every merge below reads a segment's
// borders from this one walk, in the same row-major order.
template <class F>
void ForEachBorderPair(const cv::Mat& labels, F&& f) {
  for (int r = 0; r < labels.rows; ++r) {
    const int* l = labels.ptr<int>(r);
    const int* below = r + 1 < labels.rows ? labels.ptr<int>(r + 1) : nullptr;
    for (int c = 0; c < labels.cols; ++c) {
      if (l[c] == 0) continue;
      if (c + 1 < labels.cols && l[c + 1] != 0 && l[c + 1] != l[c]) {
        f(l[c], cv::Point(c, r), l[c + 1], cv::Point(c + 1, r));
      }
      if (below != nullptr && below[c] != 0 && below[c] != l[c]) {
        f(l[c], cv::Point(c, r), below[c], cv::Point(c, r + 1));
      }
    }
  }
}

// Each label's largest value of `dt` (index = label, 0 unused).
std::vector<float> PeakPerLabel(const cv::Mat& labels, const cv::Mat& dt, int label_count) {
  std::vector<float> peak(Idx(label_count) + 1, 0.0f);
  for (int r = 0; r < labels.rows; ++r) {
    const int* l = labels.ptr<int>(r);
    const float* d = dt.ptr<float>(r);
    for (int c = 0; c < labels.cols; ++c) {
      if (l[c] != 0) peak[Idx(l[c])] = std::max(peak[Idx(l[c])], d[c]);
    }
  }
  return peak;
}

// Cell pairs along each border (ForEachBorderPair), keyed (smaller label, larger).
std::map<std::pair<int, int>, int> BorderLengths(const cv::Mat& labels) {
  std::map<std::pair<int, int>, int> border;
  ForEachBorderPair(labels,
                    [&](int a, cv::Point, int b, cv::Point) { ++border[std::minmax(a, b)]; });
  return border;
}

// Renumbers `labels` 1..N: label l takes the number of its representative rep(l) (0 drops its
// cells), numbers handed out in label order; a representative none of whose labels has a cell
// gets none, so N counts only segments that exist. Returns N.
template <class Rep>
int RelabelDense(cv::Mat* labels, int label_count, Rep rep) {
  std::vector<int> final_label(Idx(label_count) + 1, 0);
  std::vector<bool> has_cells(Idx(label_count) + 1, false);
  for (int r = 0; r < labels->rows; ++r) {
    const int* l = labels->ptr<int>(r);
    for (int c = 0; c < labels->cols; ++c) has_cells[Idx(l[c])] = true;
  }
  int next = 0;
  for (int l = 1; l <= label_count; ++l) {
    if (!has_cells[Idx(l)]) continue;
    const int t = rep(l);
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
  std::vector<float> peak = PeakPerLabel(*labels, dt, label_count);
  std::map<std::pair<int, int>, float> saddle;
  ForEachBorderPair(*labels, [&](int a, cv::Point pa, int b, cv::Point pb) {
    float& s = saddle[std::minmax(a, b)];
    s = std::max({s, std::min(dt.at<float>(pa), dt.at<float>(pb))});
  });
  Roots roots(label_count);
  for (;;) {
    // The most open border first; recompute over current roots.
    std::map<std::pair<int, int>, float> current;
    for (const auto& [key, s] : saddle) {
      int a = roots.Find(key.first), b = roots.Find(key.second);
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
    roots.Join(best_pair.second, best_pair.first);
    peak[Idx(best_pair.first)] = std::max(peak[Idx(best_pair.first)], peak[Idx(best_pair.second)]);
  }
  roots.Relabel(labels);
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
  std::vector<float> peak = PeakPerLabel(*labels, dt_closed, label_count);
  ForEachBorderPair(*labels, [&](int a, cv::Point pa, int b, cv::Point pb) {
    if (openings.at<std::uint8_t>(pa) == 0 && openings.at<std::uint8_t>(pb) == 0) return;
    const std::pair<int, int> key = std::minmax(a, b);
    float& s = saddle[key];
    s = std::max({s, std::min(dt_open.at<float>(pa), dt_open.at<float>(pb))});
    std::map<int, int>& v = votes[key];
    if (const int id = opening_ids.at<int>(pa); id > 0) ++v[id];
    if (const int id = opening_ids.at<int>(pb); id > 0) ++v[id];
  });
  std::map<std::pair<int, int>, double> local;  // Constriction() of the border's main opening
  for (const auto& [key, v] : votes) {
    int main_id = 0, most = 0;
    for (const auto& [id, n] : v) {
      if (n > most) main_id = id, most = n;
    }
    local[key] = constriction(main_id);
  }
  Roots roots(label_count);
  for (;;) {
    std::map<std::pair<int, int>, std::pair<float, double>> current;
    for (const auto& [key, s] : saddle) {
      int a = roots.Find(key.first), b = roots.Find(key.second);
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
    roots.Join(best_pair.second, best_pair.first);
    // The merged space is at least as open as the opening it merged across: two strips cut
    // from one room by a wall's continuation are, together, the room again, and a wardrobe
    // off it is measured against the room, not against a strip.
    peak[Idx(best_pair.first)] = std::max(
        {peak[Idx(best_pair.first)], peak[Idx(best_pair.second)], current[best_pair].first});
  }
  roots.Relabel(labels);
}

}  // namespace

Status CheckRuleMergeOptions(const RuleMergeOptions& o) {
  if (o.min_room_area_m2 < 0.0) {
    return InvalidArgument("segmentation option areas must be >= 0");
  }
  if (o.opening_merge_ratio < 0.0 || o.opening_local_ratio < 0.0) {
    return InvalidArgument(
        "segmentation option wall_min_length_m, wall_stub_min_length_m, wall_line_gap_m, "
        "door_max_width_m and the opening_* options must be >= 0");
  }
  return Status::Ok();
}

Status CheckLearnedMergeOptions(const LearnedMergeOptions& o) {
  if (!(o.layout_merge_threshold >= 0.0 && o.layout_merge_threshold <= 1.0)) {
    return InvalidArgument(
        "segmentation option layout_merge_threshold must be in [0, 1] (0 = the rule merges)");
  }
  if (o.layout_channel_before_model != 0.0 && o.layout_channel_before_model != 1.0) {
    char got[32];
    std::snprintf(got, sizeof got, "%g", o.layout_channel_before_model);
    return InvalidArgument(
        std::string("segmentation option layout_channel_before_model must be 0 (after the "
                    "model) or 1 (before it), got ") +
        got);
  }
  for (const OptionField<LearnedMergeOptions>& f : kLearnedMergeOptionFields) {
    if (!(o.*f.field >= 0.0)) {
      char got[32];
      std::snprintf(got, sizeof got, "%g", o.*f.field);
      return InvalidArgument(std::string("segmentation option ") + f.name + " must be >= 0, got " +
                             got);
    }
  }
  return Status::Ok();
}

int MergeByRules(const RuleMergeOptions& o, double door_max_width_m, double res, Pieces* p) {
  MergeAcrossOpenings(&p->labels, p->dt, p->dt_closed, p->openings, p->walls.opening_ids(p->box),
                      p->walls.opening_lines, p->count, o.opening_merge_ratio,
                      o.opening_local_ratio, static_cast<float>(door_max_width_m / res));
  MergeOpenBorders(&p->labels, p->dt_closed, p->count, o.merge_open_border_ratio,
                   static_cast<float>(0.5 * o.merge_min_opening_m / res),
                   o.merge_no_constriction_ratio);
  const int min_area = static_cast<int>(o.min_room_area_m2 / (res * res));
  return MergeSmallSegments(&p->labels, p->count, min_area);
}

int MergeSmallSegments(cv::Mat* labels, int label_count, int min_area) {
  std::vector<int> area(Idx(label_count) + 1, 0);
  for (int r = 0; r < labels->rows; ++r) {
    const int* l = labels->ptr<int>(r);
    for (int c = 0; c < labels->cols; ++c) ++area[Idx(l[c])];
  }
  std::vector<std::map<int, int>> border(Idx(label_count) + 1);
  for (const auto& [pair, len] : BorderLengths(*labels)) {
    border[Idx(pair.first)][pair.second] = len;
    border[Idx(pair.second)][pair.first] = len;
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
  // Each label to the end of its chain of merges (0 when a link was dropped).
  return RelabelDense(labels, label_count, [&](int l) {
    while (l != 0 && !alive[Idx(l)]) l = target[Idx(l)];
    return l;
  });
}

int MergeCorridors(cv::Mat* labels, const cv::Mat& dt, int label_count, double res,
                   const KindOptions& kinds, double border_ratio, double width_ratio) {
  if (border_ratio <= 0.0) return label_count;
  // Each pass can make a corridor of a piece that was not one (a stub joined to a corridor), so
  // passes repeat until nothing merges.
  for (;;) {
    if (label_count < 2) return label_count;
    const std::vector<SegmentInfo> info = DescribeSegments(*labels, dt, label_count, res, kinds);
    const auto width = [&](int l) { return info[Idx(l - 1)].width_m; };
    const auto narrow = [&](int l) { return width(l) <= kinds.corridor_max_width_m; };
    const auto corridor = [&](int l) { return info[Idx(l - 1)].kind == "corridor"; };
    Roots roots(label_count);
    bool merged = false;
    for (const auto& [pair, cells] : BorderLengths(*labels)) {
      const auto [a, b] = pair;
      if (!narrow(a) || !narrow(b) || !(corridor(a) || corridor(b))) continue;
      const double narrower = std::min(width(a), width(b));
      if (width_ratio > 0.0 && std::max(width(a), width(b)) > width_ratio * narrower) continue;
      if (cells * res < border_ratio * narrower) continue;
      const int ra = roots.Find(a), rb = roots.Find(b);
      if (ra != rb) roots.Join(ra, rb), merged = true;
    }
    if (!merged) return label_count;
    label_count = RelabelDense(labels, label_count, [&](int l) { return roots.Find(l); });
  }
}

namespace {

// MergeChannels' fixed shape tests (issue 28, fifteenth round's plan).
constexpr double kChannelStraightCells = 3.0;  // a border's cells across its line, at most
constexpr double kChannelPresence = 0.7;       // share of its length with a cell pair on it
constexpr double kChannelSteps = 0.8;          // share of the steps along the normal that pass
constexpr double kChannelEndProbeM = 0.25;     // how far beyond a border's end a wall may be

// One border between two segments: where its cell pairs meet (cell-pair midpoints) and the sum
// of the steps from the smaller label's cell to the larger's (which way the larger lies).
struct ChannelBorder {
  std::vector<cv::Point2f> mid;
  cv::Point2f toward_second{0.0f, 0.0f};
};

// Whether a channel runs on from the border [end_a, end_b] along unit `d` for `steps` cells:
// the centre line free and, within `probe` cells beyond each end (along the border's direction
// `t`, away from the border), some cell not free.
bool RunsOn(const cv::Mat& free, cv::Point2f end_a, cv::Point2f end_b, cv::Point2f t,
            cv::Point2f d, int steps, int probe) {
  const cv::Point2f centre = 0.5f * (end_a + end_b);
  int pass = 0;
  for (int v = 1; v <= steps; ++v) {
    const cv::Point2f along = d * static_cast<float>(v);
    if (!FreeAt(free, centre + along)) continue;
    bool wall_a = false, wall_b = false;
    for (int k = 1; k <= probe && !(wall_a && wall_b); ++k) {
      const cv::Point2f out = t * static_cast<float>(k);
      wall_a = wall_a || !FreeAt(free, end_a + along - out);
      wall_b = wall_b || !FreeAt(free, end_b + along + out);
    }
    if (wall_a && wall_b) ++pass;
  }
  return pass >= kChannelSteps * steps;
}

// Whether the free space keeps the border's width along unit `d` for `steps` cells: its median
// free run across `t` (segment_detail::MedianFreeRun, at most `max_ratio` x the border's length
// each way) within [kChannelMinWidthRatio, max_ratio] x that length in cells.
bool KeepsWidth(const cv::Mat& free, cv::Point2f end_a, cv::Point2f end_b, cv::Point2f t,
                cv::Point2f d, int steps, double length, double max_ratio) {
  const cv::Point2f centre = 0.5f * (end_a + end_b);
  const int cap = static_cast<int>(std::ceil(max_ratio * length)) + 1;
  const double median = segment_detail::MedianFreeRun(free, centre, t, d, steps, cap);
  return median >= kChannelMinWidthRatio * length && median <= max_ratio * length;
}

}  // namespace

int MergeChannels(cv::Mat* labels, const cv::Mat& free, int label_count, double res,
                  double depth_m, double min_width_m, double median_width_ratio) {
  if (depth_m <= 0.0 || label_count < 2) return label_count;
  std::map<std::pair<int, int>, ChannelBorder> borders;
  ForEachBorderPair(*labels, [&](int a, cv::Point pa, int b, cv::Point pb) {
    ChannelBorder& border = borders[std::minmax(a, b)];
    border.mid.emplace_back(0.5f * (cv::Point2f(pa) + cv::Point2f(pb)));
    border.toward_second += a < b ? cv::Point2f(pb - pa) : cv::Point2f(pa - pb);
  });
  const int steps = std::max(1, static_cast<int>(std::lround(depth_m / res)));
  const int probe = std::max(1, static_cast<int>(std::lround(kChannelEndProbeM / res)));
  Roots roots(label_count);
  bool merged = false;
  for (const auto& [pair, border] : borders) {
    const std::vector<cv::Point2f>& m = border.mid;
    if (m.size() < 2) continue;
    // The border's line: its cells' principal direction t and normal n (toward the second).
    cv::Point2f mean(0.0f, 0.0f);
    for (const cv::Point2f& p : m) mean += p;
    mean *= 1.0f / static_cast<float>(m.size());
    double sxx = 0.0, sxy = 0.0, syy = 0.0;
    for (const cv::Point2f& p : m) {
      const double qx = static_cast<double>(p.x - mean.x), qy = static_cast<double>(p.y - mean.y);
      sxx += qx * qx, sxy += qx * qy, syy += qy * qy;
    }
    const double angle = 0.5 * std::atan2(2.0 * sxy, sxx - syy);
    const cv::Point2f t(static_cast<float>(std::cos(angle)), static_cast<float>(std::sin(angle)));
    cv::Point2f n(-t.y, t.x);
    if (n.dot(border.toward_second) < 0.0f) n = -n;
    float umin = 0.0f, umax = 0.0f, wmin = 0.0f, wmax = 0.0f;
    for (const cv::Point2f& p : m) {
      const float u = (p - mean).dot(t), w = (p - mean).dot(n);
      umin = std::min(umin, u), umax = std::max(umax, u);
      wmin = std::min(wmin, w), wmax = std::max(wmax, w);
    }
    if (static_cast<double>(wmax - wmin) > kChannelStraightCells) continue;
    const double length_cells = static_cast<double>(umax - umin) + 1.0;
    const double width_m = length_cells * res;
    if (width_m < min_width_m || width_m > kMaxChannelWidthM) continue;
    std::vector<bool> present(static_cast<std::size_t>(length_cells) + 1, false);
    for (const cv::Point2f& p : m) {
      present[static_cast<std::size_t>((p - mean).dot(t) - umin)] = true;
    }
    const auto cells_present = std::count(present.begin(), present.end(), true);
    if (static_cast<double>(cells_present) < kChannelPresence * length_cells) {
      continue;
    }
    const cv::Point2f end_a = mean + t * umin, end_b = mean + t * umax;
    const auto channel = [&](cv::Point2f d) {
      return median_width_ratio > 0.0
                 ? KeepsWidth(free, end_a, end_b, t, d, steps, length_cells, median_width_ratio)
                 : RunsOn(free, end_a, end_b, t, d, steps, probe);
    };
    if (!channel(n) && !channel(-n)) continue;
    const int ra = roots.Find(pair.first), rb = roots.Find(pair.second);
    if (ra != rb) roots.Join(ra, rb), merged = true;
  }
  if (!merged) return label_count;
  return RelabelDense(labels, label_count, [&](int l) { return roots.Find(l); });
}

std::vector<SegmentInfo> DescribeSegments(const cv::Mat& labels, const cv::Mat& dt, int count,
                                          double res, const KindOptions& o) {
  std::vector<SegmentInfo> segments(Idx(count));
  const std::vector<float> max_dt = PeakPerLabel(labels, dt, count);
  for (int r = 0; r < labels.rows; ++r) {
    const int* l = labels.ptr<int>(r);
    for (int c = 0; c < labels.cols; ++c) {
      if (l[c] != 0) ++segments[Idx(l[c] - 1)].area_cells;
    }
  }
  for (int i = 0; i < count; ++i) {
    SegmentInfo& s = segments[Idx(i)];
    s.label = i + 1;
    s.area_m2 = s.area_cells * res * res;
    s.width_m = 2.0 * static_cast<double>(max_dt[Idx(i) + 1]) * res;
    s.elongation = s.width_m > 0.0 ? s.area_m2 / (s.width_m * s.width_m) : 0.0;
    s.kind = (s.elongation >= o.corridor_elongation && s.width_m <= o.corridor_max_width_m)
                 ? "corridor"
                 : "room";
  }
  return segments;
}

}  // namespace zm
