#include "segment/layout_merge.h"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <map>
#include <optional>
#include <opencv2/imgproc.hpp>
#include <random>
#include <unordered_map>
#include <utility>

#include "segment/declutter.h"

namespace zm {
namespace {

using segment_detail::Idx;

constexpr int kRayMaxWallCells = 7;  // a wall up to 0.35 m thick at 0.05 m/cell
constexpr int kEndSupportCells = 8;  // 0.4 m beyond each end of a border
constexpr int kEndSupportHalfWidth = 2;

struct Piece {
  double area = 0;            // cells (counts kept as doubles: exact, and the features are ratios)
  float peak = 0.0f;          // cells
  double perimeter = 0;       // cell edges to anything not this piece
  double open_perimeter = 0;  // cell edges to other pieces
  double umin = 1e18, umax = -1e18, vmin = 1e18, vmax = -1e18;
  std::unordered_map<int, long> gt;    // ground-truth room -> cells (traces only)
  std::unordered_map<int, long> rule;  // rule segment -> cells
};

struct Contact {
  double edges = 0;            // 4-neighbour cell edges between the two
  double rays = 0;             // rays across a wall, from either side
  double rule_same_edges = 0;  // edges whose two cells lie in one rule segment
  // Edges on a doorway, then on an opening of each OpeningKind bit (either cell).
  std::array<double, 1 + kOpeningKindCount> kind_edges{};
  float clearance = 0.0f;  // cells
  std::vector<int> cells;  // border cells of either side (row * cols + col)
  double probability = 0.0;
  bool traced = false;  // its current features are in the trace already
};

using PairKey = std::pair<int, int>;  // (smaller label, larger label)

struct Frame {
  double cos_a, sin_a;
  double U(int r, int c) const { return c * cos_a + r * sin_a; }
  double V(int r, int c) const { return -c * sin_a + r * cos_a; }
  cv::Point Cell(double u, double v) const {  // inverse rotation, rounded
    return {static_cast<int>(std::lround(u * cos_a - v * sin_a)),
            static_cast<int>(std::lround(u * sin_a + v * cos_a))};
  }
};

int Majority(const std::unordered_map<int, long>& histogram) {
  int best = 0;
  long most = 0;
  for (const auto& [room, n] : histogram) {
    if (n > most || (n == most && room < best)) {
      best = room;
      most = n;
    }
  }
  return best;
}

double Elongation(double du, double dv) {
  return (std::max(du, dv) + 1.0) / (std::min(du, dv) + 1.0);
}

double Rectangularity(double area, double du, double dv) {
  return static_cast<double>(area) / std::max(1.0, (du + 1.0) * (dv + 1.0));
}

// A border's line in the walls' frame: along u or v, its two ends and its median offset across.
struct BorderLine {
  bool along_u = true;
  double lo_end = 0.0, hi_end = 0.0;  // along the line
  double mid = 0.0;                   // across it
  double straightness = 0.0;          // its thickness across, cells
};

BorderLine LineOf(const std::vector<int>& cells, int cols, const Frame& f) {
  std::vector<double> us, vs;
  us.reserve(cells.size());
  vs.reserve(cells.size());
  for (int id : cells) {
    us.push_back(f.U(id / cols, id % cols));
    vs.push_back(f.V(id / cols, id % cols));
  }
  const auto [umin, umax] = std::minmax_element(us.begin(), us.end());
  const auto [vmin, vmax] = std::minmax_element(vs.begin(), vs.end());
  BorderLine line;
  line.along_u = (*vmax - *vmin) <= (*umax - *umin);
  line.lo_end = line.along_u ? *umin : *vmin;
  line.hi_end = line.along_u ? *umax : *vmax;
  line.straightness = (line.along_u ? *vmax - *vmin : *umax - *umin) + 1.0;
  std::vector<double>& across = line.along_u ? vs : us;
  std::nth_element(across.begin(), across.begin() + static_cast<long>(across.size() / 2),
                   across.end());
  line.mid = across[across.size() / 2];
  return line;
}

// What lies beyond each end of a border, along its line.
struct BorderEnds {
  double support[2] = {0.0, 0.0};  // share of the kEndSupportCells steps where some cell within
                                   // kEndSupportHalfWidth across the line is occupied
  // The first such cell (nearest step, then nearest the line); none where there is none.
  std::array<std::optional<cv::Point>, 2> first;
  double straightness = 0.0;  // the border's thickness across its line, cells
};

BorderEnds EndsOf(const std::vector<int>& cells, const cv::Mat& occupied, const Frame& f) {
  const BorderLine line = LineOf(cells, occupied.cols, f);
  const bool along_u = line.along_u;
  const double lo_end = line.lo_end, hi_end = line.hi_end, mid = line.mid;
  auto cell_at = [&](double along, double off) {
    return along_u ? f.Cell(along, mid + off) : f.Cell(mid + off, along);
  };
  auto occupied_at = [&](cv::Point p) {
    return p.x >= 0 && p.y >= 0 && p.x < occupied.cols && p.y < occupied.rows &&
           occupied.at<std::uint8_t>(p.y, p.x) != 0;
  };
  BorderEnds ends;
  ends.straightness = line.straightness;
  for (int side = 0; side < 2; ++side) {
    int hits = 0;
    for (int k = 1; k <= kEndSupportCells; ++k) {
      const double along = side == 0 ? lo_end - k : hi_end + k;
      // Nearest the line first: 0, -1, +1, -2, +2.
      for (int i = 0; i <= 2 * kEndSupportHalfWidth; ++i) {
        const int off = (i % 2 == 1) ? -(i + 1) / 2 : i / 2;
        const cv::Point p = cell_at(along, off);
        if (occupied_at(p)) {
          ++hits;
          if (!ends.first[Idx(side)]) ends.first[Idx(side)] = p;
          break;
        }
      }
    }
    ends.support[side] = static_cast<double>(hits) / kEndSupportCells;
  }
  return ends;
}

constexpr double kChannelDepthM = 2.0;   // how far past the border the channel features look
constexpr double kChannelStepM = 0.1;    // ...at this spacing
constexpr double kChannelRatioCap = 4.0;  // a free run stops at this x the border's length

// channel_width_near / _far (kLayoutFeatureNames): on each side of the border, the median
// (segment_detail::MedianFreeRun) over the steps of the free run along its line through its
// centre, over its length.
std::array<double, 2> ChannelWidths(const std::vector<int>& cells, const cv::Mat& free,
                                    const Frame& f, double res) {
  const BorderLine line = LineOf(cells, free.cols, f);
  const double length = line.hi_end - line.lo_end + 1.0;
  const double centre = 0.5 * (line.lo_end + line.hi_end);
  const int cap = static_cast<int>(std::ceil(kChannelRatioCap * length));
  const int steps = std::max(1, static_cast<int>(std::lround(kChannelDepthM / kChannelStepM)));
  const double stride = kChannelStepM / res;
  // The frame's (u, v) as image points: the border's centre, its line and its normal.
  const auto image = [&](double along, double across) {
    return line.along_u ? cv::Point2d(along * f.cos_a - across * f.sin_a,
                                      along * f.sin_a + across * f.cos_a)
                        : cv::Point2d(across * f.cos_a - along * f.sin_a,
                                      across * f.sin_a + along * f.cos_a);
  };
  const cv::Point2d mid = image(centre, line.mid);
  const cv::Point2d along = image(1.0, 0.0), normal = image(0.0, stride);
  std::array<double, 2> ratio{};
  for (std::size_t side = 0; side < 2; ++side) {
    const cv::Point2d step = side == 0 ? -normal : normal;
    const int median = segment_detail::MedianFreeRun(free, mid, along, step, steps, cap);
    ratio[side] = std::min(median / length, kChannelRatioCap);
  }
  const auto off_one = [](double r) { return r > 0.0 ? std::abs(std::log(r)) : 1e9; };
  if (off_one(ratio[0]) > off_one(ratio[1])) std::swap(ratio[0], ratio[1]);
  return ratio;
}

// Features of the whole map, the same for every pair.
struct MapContext {
  double free_m2 = 0.0;
  double rule_segment_m2 = 0.0;
  double specks_per_100m2 = 0.0;
  double blobs_per_100m2 = 0.0;
  double loose_occupied_share = 0.0;
  double rough_face_share = 0.0;
  double unknown_border_share = 0.0;
  bool rough_cut = false;
};

constexpr double kSpeckMaxM = 0.25;  // map-level features (kLayoutFeatureNames)
constexpr double kBlobMaxM = 1.5;

constexpr double kEndExtentCapM = 8.0;  // end_extent_* (kLayoutFeatureNames)

// The grid's occupied cells as 8-connected components, each with its extent (the larger side of
// its bounding box, metres): labelled once per map, for MapContext and the end_extent features.
struct OccupiedParts {
  cv::Mat component;            // CV_32SC1, 0 = not occupied
  std::vector<double> extent_m;  // per component label
};

OccupiedParts LabelOccupied(const cv::Mat& occupied, double res, MapContext* map) {
  OccupiedParts parts;
  cv::Mat stats, centroids;
  const int n = cv::connectedComponentsWithStats(occupied != 0, parts.component, stats, centroids,
                                                 8, CV_32S);
  parts.extent_m.assign(Idx(std::max(n, 1)), 0.0);
  double specks = 0, blobs = 0, loose = 0, all = 0;
  for (int i = 1; i < n; ++i) {
    const double extent =
        std::max(stats.at<int>(i, cv::CC_STAT_WIDTH), stats.at<int>(i, cv::CC_STAT_HEIGHT)) * res;
    parts.extent_m[Idx(i)] = extent;
    const double cells = stats.at<int>(i, cv::CC_STAT_AREA);
    all += cells;
    if (extent <= kSpeckMaxM + 1e-9) {
      ++specks;
    } else if (extent <= kBlobMaxM + 1e-9) {
      ++blobs;
    }
    if (extent <= kBlobMaxM + 1e-9) loose += cells;
  }
  const double per_100m2 = 100.0 / std::max(map->free_m2, 1.0);
  map->specks_per_100m2 = specks * per_100m2;
  map->blobs_per_100m2 = blobs * per_100m2;
  map->loose_occupied_share = loose / std::max(all, 1.0);
  return parts;
}

// end_extent_min_m / _max_m: the extent of the occupied component at each end of the border
// (its first occupied cell, EndsOf), capped; 0 where nothing is occupied beyond an end.
std::array<double, 2> EndExtents(const BorderEnds& ends, const OccupiedParts& parts) {
  std::array<double, 2> e{};
  for (int side = 0; side < 2; ++side) {
    const std::optional<cv::Point>& p = ends.first[Idx(side)];
    if (!p) continue;
    const int label = parts.component.at<int>(*p);
    e[Idx(side)] = std::min(parts.extent_m[Idx(label)], kEndExtentCapM);
  }
  if (e[0] > e[1]) std::swap(e[0], e[1]);
  return e;
}

// visibility, visibility_s (kLayoutFeatureNames): the first's index, the lattice, the samples.
constexpr int kVisibilityFeature = kLayoutFeatureCount - 2;
constexpr double kVisibilitySampleM = 0.5;
constexpr int kVisibilityMaxSamples = 16;   // at most this many per piece (a bit mask each)
static_assert(kVisibilityMaxSamples <= 32, "a piece's samples are bits of a std::uint32_t");
constexpr double kVisibilityMaxM = 15.0;

// Lines of sight between the cut's pieces, sampled once per piece and computed per pair of
// pieces when a feature first asks for it: a merged piece's visibility is the sum over its
// pieces', so no line is traced twice however the merges go.
class Visibility {
 public:
  // `see_through`: CV_8UC1, nonzero where a line of sight passes. `dt`: the pieces' clearance.
  Visibility(const cv::Mat& labels, int n, const cv::Mat& dt, cv::Mat see_through, double res)
      : see_through_(std::move(see_through)),
        max_cells_(kVisibilityMaxM / res),
        samples_(Idx(n) + 1) {
    const int step = std::max(1, static_cast<int>(std::lround(kVisibilitySampleM / res)));
    std::vector<std::pair<float, cv::Point>> peak(Idx(n) + 1, {-1.0f, cv::Point()});
    for (int r = 0; r < labels.rows; ++r) {
      const int* l = labels.ptr<int>(r);
      for (int c = 0; c < labels.cols; ++c) {
        if (l[c] <= 0 || l[c] > n) continue;
        PieceSamples& p = samples_[Idx(l[c])];
        p.area += 1.0;
        p.box |= cv::Rect(c, r, 1, 1);
        const float d = dt.at<float>(r, c);
        if (d > peak[Idx(l[c])].first) peak[Idx(l[c])] = {d, cv::Point(c, r)};
        if (r % step == 0 && c % step == 0) p.points.emplace_back(c, r);
      }
    }
    for (int i = 1; i <= n; ++i) {
      PieceSamples& p = samples_[Idx(i)];
      if (p.area == 0.0) continue;
      if (p.points.empty()) p.points.push_back(peak[Idx(i)].second);
      if (p.points.size() > kVisibilityMaxSamples) {  // evenly over the lattice's row order
        std::vector<cv::Point> kept;
        for (std::size_t k = 0; k < kVisibilityMaxSamples; ++k) {
          kept.push_back(p.points[k * p.points.size() / kVisibilityMaxSamples]);
        }
        p.points = std::move(kept);
      }
      p.weight = p.area / static_cast<double>(p.points.size());
    }
  }

  // visibility and visibility_s of two merged pieces, given their cut pieces; S is `small`.
  std::array<double, 2> Of(const std::vector<int>& small, const std::vector<int>& large) {
    double seen = 0.0, area_s = 0.0, area_l = 0.0, seen_s = 0.0;
    for (int j : large) area_l += samples_[Idx(j)].area;
    for (int i : small) {
      const PieceSamples& p = samples_[Idx(i)];
      area_s += p.area;
      std::uint32_t sees = 0;
      for (int j : large) {
        const Pair& v = Get(i, j);
        seen += v.seen;
        sees |= i < j ? v.first_sees : v.second_sees;
      }
      seen_s += p.weight * static_cast<double>(std::popcount(sees));
    }
    return {seen / std::max(area_s * area_l, 1.0), seen_s / std::max(area_s, 1.0)};
  }

 private:
  struct PieceSamples {
    std::vector<cv::Point> points;
    double area = 0.0;   // cells
    double weight = 0.0;  // cells per sample
    cv::Rect box;
  };
  struct Pair {
    double seen = 0.0;  // sum of weight x weight over the sample pairs in sight (cells^2)
    std::uint32_t first_sees = 0, second_sees = 0;  // per sample of the lower / higher label
  };

  bool InSight(cv::Point a, cv::Point b) const {
    cv::LineIterator it(see_through_, a, b, 8);
    for (int k = 0; k < it.count; ++k, ++it) {
      if (**it == 0) return false;
    }
    return true;
  }

  const Pair& Get(int i, int j) {
    if (i > j) std::swap(i, j);
    const std::uint64_t key = (static_cast<std::uint64_t>(i) << 32) | static_cast<std::uint32_t>(j);
    const auto found = memo_.find(key);
    if (found != memo_.end()) return found->second;
    Pair& v = memo_[key];
    const PieceSamples& a = samples_[Idx(i)];
    const PieceSamples& b = samples_[Idx(j)];
    const cv::Rect& p = a.box;
    const cv::Rect& q = b.box;
    const int dx = std::max({0, q.x - (p.x + p.width), p.x - (q.x + q.width)});
    const int dy = std::max({0, q.y - (p.y + p.height), p.y - (q.y + q.height)});
    if (std::hypot(dx, dy) > max_cells_) return v;
    for (std::size_t s = 0; s < a.points.size(); ++s) {
      for (std::size_t t = 0; t < b.points.size(); ++t) {
        const cv::Point d = a.points[s] - b.points[t];
        if (std::hypot(d.x, d.y) > max_cells_ || !InSight(a.points[s], b.points[t])) continue;
        v.seen += a.weight * b.weight;
        v.first_sees |= 1u << s;
        v.second_sees |= 1u << t;
      }
    }
    return v;
  }

  cv::Mat see_through_;
  double max_cells_;
  std::vector<PieceSamples> samples_;
  std::unordered_map<std::uint64_t, Pair> memo_;
};

std::array<float, kLayoutFeatureCount> Features(const Piece& pa, const Piece& pb, const Contact& c,
                                                const cv::Mat& occupied, const cv::Mat& free,
                                                const Frame& f, double res,
                                                const MapContext& map,
                                                const OccupiedParts& parts,
                                                const std::array<double, 2>& visibility) {
  const bool a_small = pa.area <= pb.area;
  const Piece& s = a_small ? pa : pb;
  const Piece& l = a_small ? pb : pa;
  const double open = c.edges * res;
  const double wall = 0.5 * c.rays * res;
  const double peak_s = static_cast<double>(s.peak) * res;
  const double peak_l = static_cast<double>(l.peak) * res;
  const double cc = static_cast<double>(c.clearance) * res;
  const double perim_s = std::max(s.perimeter * res, 1e-3);
  const double du_s = s.umax - s.umin, dv_s = s.vmax - s.vmin;
  const double ext_max = std::max(du_s, dv_s) * res + res,
               ext_min = std::min(du_s, dv_s) * res + res;
  const double rect_s = Rectangularity(s.area, du_s, dv_s);
  const double rect_l = Rectangularity(l.area, l.umax - l.umin, l.vmax - l.vmin);
  const double du_u = std::max(s.umax, l.umax) - std::min(s.umin, l.umin);
  const double dv_u = std::max(s.vmax, l.vmax) - std::min(s.vmin, l.vmin);
  const double rect_u = Rectangularity(s.area + l.area, du_u, dv_u);
  const BorderEnds ends = EndsOf(c.cells, occupied, f);
  const auto extents = EndExtents(ends, parts);
  const auto channel = ChannelWidths(c.cells, free, f, res);
  auto per_edge = [&](double n) { return n / std::max(c.edges, 1.0); };
  const double values[kLayoutFeatureCount] = {
      open,
      wall,
      open / std::max(open + wall, 1e-9),
      s.area * res * res,
      l.area * res * res,
      peak_s,
      peak_l,
      cc,
      cc / std::max(peak_s, 1e-3),
      cc / std::max(peak_l, 1e-3),
      open / perim_s,
      wall / perim_s,
      s.open_perimeter * res / perim_s,
      open / std::max(ext_max, 1e-3),
      open / std::max(ext_min, 1e-3),
      rect_s,
      rect_l,
      rect_u,
      rect_u - std::max(rect_s, rect_l),
      std::min(ends.support[0], ends.support[1]),
      std::max(ends.support[0], ends.support[1]),
      ends.straightness * res,
      Elongation(du_s, dv_s),
      Elongation(l.umax - l.umin, l.vmax - l.vmin),
      Elongation(du_u, dv_u),
      (Majority(s.rule) != 0 && Majority(s.rule) == Majority(l.rule)) ? 1.0 : 0.0,
      per_edge(c.rule_same_edges),
      map.free_m2,
      map.rule_segment_m2,
      per_edge(c.kind_edges[0]),
      per_edge(c.kind_edges[1]),
      per_edge(c.kind_edges[2]),
      per_edge(c.kind_edges[3]),
      per_edge(c.kind_edges[4]),
      per_edge(c.kind_edges[5]),
      map.specks_per_100m2,
      map.blobs_per_100m2,
      map.loose_occupied_share,
      map.rough_face_share,
      map.unknown_border_share,
      map.rough_cut ? 1.0 : 0.0,
      channel[0],
      channel[1],
      extents[0],
      extents[1],
      visibility[0],
      visibility[1]};
  std::array<float, kLayoutFeatureCount> x{};
  for (int i = 0; i < kLayoutFeatureCount; ++i) x[Idx(i)] = static_cast<float>(values[i]);
  return x;
}

}  // namespace

Result<int> MergeLayoutPieces(const LayoutMergeInputs& in, const LayoutMergeModel& model,
                              double threshold, const LayoutMergeTrace& trace) {
  cv::Mat& labels = *in.labels;
  if (labels.type() != CV_32SC1 || in.occupied.size() != labels.size() ||
      in.occupied.type() != CV_8UC1) {
    return InvalidArgument(
        "layout merge: labels must be CV_32SC1 and occupied CV_8UC1 of "
        "the same size");
  }
  if (trace.ground_truth != nullptr && trace.ground_truth->type() != CV_32SC1) {
    return InvalidArgument("layout merge: ground truth must be CV_32SC1");
  }
  const bool has_rules = !in.rule_labels.empty();
  if (has_rules && (in.rule_labels.type() != CV_32SC1 || in.rule_labels.size() != labels.size())) {
    return InvalidArgument("layout merge: rule labels must be CV_32SC1 of the labels' size");
  }
  for (const cv::Mat* m : {&in.doorways, &in.opening_kinds}) {
    if (!m->empty() && (m->type() != CV_8UC1 || m->size() != labels.size())) {
      return InvalidArgument(
          "layout merge: doorways and opening kinds must be CV_8UC1 of the "
          "labels' size");
    }
  }
  if (!in.free.empty() && (in.free.type() != CV_8UC1 || in.free.size() != labels.size())) {
    return InvalidArgument("layout merge: free cells must be CV_8UC1 of the labels' size");
  }
  const int rows = labels.rows, cols = labels.cols, n = in.count;
  // Bit 0 a doorway, bits 1.. the OpeningKind bits, of one cell.
  auto kind_bits = [&](int r, int c) {
    int bits = 0;
    if (!in.doorways.empty() && in.doorways.at<std::uint8_t>(r, c) != 0) bits |= 1;
    if (!in.opening_kinds.empty()) bits |= in.opening_kinds.at<std::uint8_t>(r, c) << 1;
    return bits;
  };
  const double res = in.resolution_m;
  const Frame frame{std::cos(in.wall_angle_rad), std::sin(in.wall_angle_rad)};
  cv::Mat dt;
  cv::distanceTransform(labels > 0, dt, cv::DIST_L2, cv::DIST_MASK_PRECISE, CV_32F);

  std::vector<Piece> pieces(Idx(n) + 1);
  std::map<PairKey, Contact> pairs;
  auto at = [&](int r, int c) {
    return (r < 0 || c < 0 || r >= rows || c >= cols) ? -1 : labels.at<int>(r, c);
  };
  auto occ = [&](int r, int c) {
    return r >= 0 && c >= 0 && r < rows && c < cols && in.occupied.at<std::uint8_t>(r, c) != 0;
  };
  constexpr int kDr[4] = {0, 1, 0, -1}, kDc[4] = {1, 0, -1, 0};
  for (int r = 0; r < rows; ++r) {
    for (int c = 0; c < cols; ++c) {
      const int a = labels.at<int>(r, c);
      if (a <= 0 || a > n) continue;
      Piece& p = pieces[Idx(a)];
      const float d = dt.at<float>(r, c);
      ++p.area;
      p.peak = std::max(p.peak, d);
      const double u = frame.U(r, c), v = frame.V(r, c);
      p.umin = std::min(p.umin, u);
      p.umax = std::max(p.umax, u);
      p.vmin = std::min(p.vmin, v);
      p.vmax = std::max(p.vmax, v);
      if (trace.ground_truth != nullptr) {
        const int gr = r + in.offset.y, gc = c + in.offset.x;
        if (gr >= 0 && gc >= 0 && gr < trace.ground_truth->rows && gc < trace.ground_truth->cols) {
          const int g = trace.ground_truth->at<int>(gr, gc);
          if (g > 0) ++p.gt[g];
        }
      }
      const int rule_here = has_rules ? in.rule_labels.at<int>(r, c) : 0;
      if (rule_here > 0) ++p.rule[rule_here];
      int across[4] = {0, 0, 0, 0};  // pieces reached by a ray from this cell (deduplicated)
      int n_across = 0;
      for (int k = 0; k < 4; ++k) {
        const int b = at(r + kDr[k], c + kDc[k]);
        if (b != a) ++p.perimeter;
        if (b > 0 && b != a) {
          ++p.open_perimeter;
          Contact& ct = pairs[{std::min(a, b), std::max(a, b)}];
          if (k < 2) {  // right and down: each edge once
            ++ct.edges;
            if (rule_here > 0 && in.rule_labels.at<int>(r + kDr[k], c + kDc[k]) == rule_here) {
              ++ct.rule_same_edges;
            }
            const int bits = kind_bits(r, c) | kind_bits(r + kDr[k], c + kDc[k]);
            for (std::size_t i = 0; i < ct.kind_edges.size(); ++i) {
              if ((bits >> i) & 1) ++ct.kind_edges[i];
            }
          }
          if (ct.cells.empty() || ct.cells.back() != r * cols + c) ct.cells.push_back(r * cols + c);
          ct.clearance = std::max(ct.clearance, d);
        }
        if (!occ(r + kDr[k], c + kDc[k])) continue;
        // A ray across the wall: the first cell that is not occupied, within the thickest wall.
        for (int s = 2; s <= kRayMaxWallCells + 1; ++s) {
          const int rr = r + s * kDr[k], cc = c + s * kDc[k];
          if (occ(rr, cc)) continue;
          const int t = at(rr, cc);
          if (t > 0 && t != a && std::find(across, across + n_across, t) == across + n_across) {
            across[n_across++] = t;
          }
          break;
        }
      }
      for (int i = 0; i < n_across; ++i) {
        ++pairs[{std::min(a, across[i]), std::max(a, across[i])}].rays;
      }
    }
  }
  // The grid's free cells (the pieces and the rim they leave along the walls), or the pieces.
  const cv::Mat free = in.free.empty() ? cv::Mat(labels > 0) : in.free;
  MapContext context;
  OccupiedParts parts;
  {
    double cells = 0.0;
    std::unordered_map<int, long> rule_cells;
    for (const Piece& p : pieces) {
      cells += p.area;
      for (const auto& [seg, k] : p.rule) rule_cells[seg] += k;
    }
    context.free_m2 = cells * res * res;
    parts = LabelOccupied(in.occupied, res, &context);
    // The wall faces on the grid's own free cells (the pieces leave a rim of free cells along
    // the walls out) against the occupied cells no piece took.
    const GridFaceShares faces =
        MeasureGridFaces(free, in.occupied);
    context.rough_face_share = faces.rough;
    context.unknown_border_share = faces.unknown_border;
    context.rough_cut = in.rough_cut;
    context.rule_segment_m2 = rule_cells.empty()
                                  ? context.free_m2
                                  : context.free_m2 / static_cast<double>(rule_cells.size());
  }
  // Rays alone (a wall with no opening) do not make neighbours: only pieces that touch merge.
  for (auto it = pairs.begin(); it != pairs.end();) {
    it = it->second.edges == 0.0 ? pairs.erase(it) : std::next(it);
  }
  // The lines of sight cost a tenth of a hospital's segmentation: traced only for a trace (every
  // feature is training data) or a model whose trees ask for them; otherwise both are 0.
  std::optional<Visibility> visibility;
  if (trace.csv != nullptr || model.Uses(kVisibilityFeature) || model.Uses(kVisibilityFeature + 1)) {
    // Lines of sight pass free cells, pieces and clutter (occupied components a robot sees past).
    cv::Mat see_through = (labels > 0) | (free != 0);
    for (int r = 0; r < rows; ++r) {
      const int* comp = parts.component.ptr<int>(r);
      std::uint8_t* out = see_through.ptr<std::uint8_t>(r);
      for (int c = 0; c < cols; ++c) {
        if (comp[c] > 0 && parts.extent_m[Idx(comp[c])] <= kBlobMaxM + 1e-9) out[c] = 255;
      }
    }
    visibility.emplace(labels, n, dt, std::move(see_through), res);
  }
  std::vector<std::vector<int>> members(Idx(n) + 1);  // the cut's pieces in each merged one
  for (int i = 1; i <= n; ++i) members[Idx(i)] = {i};
  auto features = [&](const PairKey& k, const Contact& c) {
    const bool first_small = pieces[Idx(k.first)].area <= pieces[Idx(k.second)].area;
    const auto& small = members[Idx(first_small ? k.first : k.second)];
    const auto& large = members[Idx(first_small ? k.second : k.first)];
    return Features(pieces[Idx(k.first)], pieces[Idx(k.second)], c, in.occupied, free, frame, res,
                    context, parts,
                    visibility ? visibility->Of(small, large) : std::array<double, 2>{});
  };
  for (auto& [k, c] : pairs) c.probability = model.Probability(features(k, c));

  std::vector<int> parent(Idx(n) + 1);
  for (int i = 0; i <= n; ++i) parent[Idx(i)] = i;
  std::mt19937 rng(0);
  for (int step = 0; !pairs.empty(); ++step) {
    const PairKey* chosen = nullptr;
    if (trace.csv != nullptr || trace.oracle) {
      std::vector<const PairKey*> same;
      for (auto& [k, c] : pairs) {
        const bool one_room =
            Majority(pieces[Idx(k.first)].gt) != 0 &&
            Majority(pieces[Idx(k.first)].gt) == Majority(pieces[Idx(k.second)].gt);
        if (one_room) same.push_back(&k);
        if (trace.csv != nullptr && !c.traced) {
          // Each state of a pair once: a pair the last merge did not touch is unchanged.
          c.traced = true;
          std::fprintf(trace.csv, "%d,%d", step, one_room ? 1 : 0);
          for (float v : features(k, c)) std::fprintf(trace.csv, ",%.6g", static_cast<double>(v));
          std::fprintf(trace.csv, "\n");
        }
      }
      if (trace.oracle) {
        if (same.empty()) break;
        chosen = same[std::uniform_int_distribution<std::size_t>(0, same.size() - 1)(rng)];
      }
    }
    if (!trace.oracle) {
      double best = threshold;
      for (const auto& [k, c] : pairs) {
        if (c.probability >= best) {
          best = c.probability;
          chosen = &k;
        }
      }
      if (chosen == nullptr) break;
    }
    const int a = chosen->first, b = chosen->second;  // b joins a
    Piece& pa = pieces[Idx(a)];
    Piece& pb = pieces[Idx(b)];
    const double shared = pairs.at(*chosen).edges;
    pa.area += pb.area;
    pa.peak = std::max(pa.peak, pb.peak);
    pa.perimeter += pb.perimeter - 2 * shared;
    pa.open_perimeter += pb.open_perimeter - 2 * shared;
    pa.umin = std::min(pa.umin, pb.umin);
    pa.umax = std::max(pa.umax, pb.umax);
    pa.vmin = std::min(pa.vmin, pb.vmin);
    pa.vmax = std::max(pa.vmax, pb.vmax);
    for (const auto& [room, cells] : pb.gt) pa.gt[room] += cells;
    for (const auto& [seg, cells] : pb.rule) pa.rule[seg] += cells;
    parent[Idx(b)] = a;
    members[Idx(a)].insert(members[Idx(a)].end(), members[Idx(b)].begin(), members[Idx(b)].end());
    members[Idx(b)].clear();
    pairs.erase(PairKey{a, b});
    // Every border of b becomes a border of a.
    std::vector<std::pair<int, Contact>> moved;
    for (auto it = pairs.begin(); it != pairs.end();) {
      if (it->first.first == b || it->first.second == b) {
        moved.emplace_back(it->first.first == b ? it->first.second : it->first.first,
                           std::move(it->second));
        it = pairs.erase(it);
      } else {
        ++it;
      }
    }
    for (auto& [other, c] : moved) {
      Contact& into = pairs[{std::min(a, other), std::max(a, other)}];
      into.edges += c.edges;
      into.rule_same_edges += c.rule_same_edges;
      for (std::size_t i = 0; i < into.kind_edges.size(); ++i)
        into.kind_edges[i] += c.kind_edges[i];
      into.rays += c.rays;
      into.clearance = std::max(into.clearance, c.clearance);
      into.cells.insert(into.cells.end(), c.cells.begin(), c.cells.end());
    }
    for (auto& [k, c] : pairs) {
      if (k.first == a || k.second == a) {
        c.probability = model.Probability(features(k, c));
        c.traced = false;
      }
    }
  }
  // Relabel: each piece to its root, roots numbered 1..m in label order.
  std::vector<int> root_label(Idx(n) + 1, 0);
  int m = 0;
  auto root = [&](int x) {
    while (parent[Idx(x)] != x) x = parent[Idx(x)];
    return x;
  };
  std::vector<int> lut(Idx(n) + 1, 0);
  for (int i = 1; i <= n; ++i) {
    if (pieces[Idx(i)].area == 0) continue;
    const int rt = root(i);
    if (root_label[Idx(rt)] == 0) root_label[Idx(rt)] = ++m;
    lut[Idx(i)] = root_label[Idx(rt)];
  }
  for (int r = 0; r < rows; ++r) {
    int* l = labels.ptr<int>(r);
    for (int c = 0; c < cols; ++c) {
      if (l[c] > 0 && l[c] <= n) l[c] = lut[Idx(l[c])];
    }
  }
  return m;
}

}  // namespace zm
