// The split stage (split.h): principal-axis cuts of segments and of keyframe cells.
#include "segment/split.h"

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <map>
#include <numbers>
#include <optional>
#include <string>
#include <utility>

#include "zones/polygon.h"
#include "zones/principal_axis.h"

namespace zm {
namespace {

using segment_detail::Idx;

}  // namespace

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
    const Eigen::Vector2d axis = PrincipalAxes(pts).col(1);
    const std::optional<double> cut = MedianCut(pts, axis);
    if (!cut) {
      return FailedPrecondition("zone " + std::to_string(label) + " holds " +
                                std::to_string(pts.size()) +
                                " keyframes at one spot, more than the limit " +
                                std::to_string(max_keyframes) + ": cannot split it in space");
    }
    const double threshold = *cut;
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
    for (const Eigen::Vector2d& p : pts) (p.dot(axis) > threshold ? high : low).push_back(p);
    work.emplace_back(label, std::move(low));
    work.emplace_back(new_label, std::move(high));
  }
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
      const Eigen::Matrix2d axes = PrincipalAxes(part.points);
      bool split_done = false;
      for (int axis_index : {1, 0}) {
        const Eigen::Vector2d axis = axes.col(axis_index);
        const std::optional<double> cut = MedianCut(part.points, axis);
        if (!cut) continue;
        const double t = *cut;
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
    z.id = ZoneId{static_cast<std::int32_t>(zones.size())};
    z.name = "area_" + std::to_string(zones.size() + 1);
    z.kind = "room";
    const ZRange band = FloorZRange(z.floor);  // floor 0's, as the file meant without a range
    z.z_min_m = band.min_m;
    z.z_max_m = band.max_m;
    z.polygon = std::move(ring);
    zones.push_back(std::move(z));
  }
  return zones;
}

}  // namespace zm
