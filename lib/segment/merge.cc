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

int MergeCorridors(cv::Mat* labels, const cv::Mat& dt, int label_count, double res,
                   const KindOptions& kinds, double border_ratio, double width_ratio) {
  if (border_ratio <= 0.0) return label_count;
  // Each pass can make a corridor of a piece that was not one (a stub joined to a corridor), so
  // passes repeat until nothing merges.
  for (;;) {
    if (label_count < 2) return label_count;
    const std::vector<SegmentInfo> info = DescribeSegments(*labels, dt, label_count, res, kinds);
    const auto narrow = [&](int l) { return info[Idx(l - 1)].width_m <= kinds.corridor_max_width_m; };
    const auto corridor = [&](int l) { return info[Idx(l - 1)].kind == "corridor"; };
    std::map<std::pair<int, int>, int> border;  // (smaller label, larger) -> cell pairs
    const auto count = [&](int a, int b) {
      if (b != 0 && a != b && narrow(a) && narrow(b) && (corridor(a) || corridor(b))) {
        ++border[std::minmax(a, b)];
      }
    };
    for (int r = 0; r < labels->rows; ++r) {
      const int* l = labels->ptr<int>(r);
      const int* below = r + 1 < labels->rows ? labels->ptr<int>(r + 1) : nullptr;
      for (int c = 0; c < labels->cols; ++c) {
        if (l[c] == 0) continue;
        if (c + 1 < labels->cols) count(l[c], l[c + 1]);
        if (below != nullptr) count(l[c], below[c]);
      }
    }
    Roots roots(label_count);
    bool merged = false;
    for (const auto& [pair, cells] : border) {
      const double narrower =
          std::min(info[Idx(pair.first - 1)].width_m, info[Idx(pair.second - 1)].width_m);
      const double wider =
          std::max(info[Idx(pair.first - 1)].width_m, info[Idx(pair.second - 1)].width_m);
      if (width_ratio > 0.0 && wider > width_ratio * narrower) continue;
      if (cells * res < border_ratio * narrower) continue;
      const int a = roots.Find(pair.first), b = roots.Find(pair.second);
      if (a != b) roots.Join(a, b), merged = true;
    }
    if (!merged) return label_count;
    // Every label to its root's, numbered densely 1..N in label order.
    std::vector<int> dense(Idx(label_count) + 1, 0);
    int next = 0;
    for (int l = 1; l <= label_count; ++l) {
      const int root = roots.Find(l);
      if (dense[Idx(root)] == 0) dense[Idx(root)] = ++next;
      dense[Idx(l)] = dense[Idx(root)];
    }
    for (int r = 0; r < labels->rows; ++r) {
      int* l = labels->ptr<int>(r);
      for (int c = 0; c < labels->cols; ++c) l[c] = dense[Idx(l[c])];
    }
    label_count = next;
  }
}

std::vector<SegmentInfo> DescribeSegments(const cv::Mat& labels, const cv::Mat& dt, int count,
                                          double res, const KindOptions& o) {
  std::vector<SegmentInfo> segments(Idx(count));
  std::vector<float> max_dt(Idx(count), 0.0f);
  for (int r = 0; r < labels.rows; ++r) {
    const int* l = labels.ptr<int>(r);
    const float* d = dt.ptr<float>(r);
    for (int c = 0; c < labels.cols; ++c) {
      if (l[c] == 0) continue;
      ++segments[Idx(l[c] - 1)].area_cells;
      max_dt[Idx(l[c] - 1)] = std::max(max_dt[Idx(l[c] - 1)], d[c]);
    }
  }
  for (int i = 0; i < count; ++i) {
    SegmentInfo& s = segments[Idx(i)];
    s.label = i + 1;
    s.area_m2 = s.area_cells * res * res;
    s.width_m = 2.0 * static_cast<double>(max_dt[Idx(i)]) * res;
    s.elongation = s.width_m > 0.0 ? s.area_m2 / (s.width_m * s.width_m) : 0.0;
    s.kind = (s.elongation >= o.corridor_elongation && s.width_m <= o.corridor_max_width_m)
                 ? "corridor"
                 : "room";
  }
  return segments;
}

}  // namespace zm
