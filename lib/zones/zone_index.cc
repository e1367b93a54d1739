// ZoneIndex (see zone_index.h): building the per-floor grids once, then allocation-free lookups.
#include "zones/zone_index.h"

#include <algorithm>
#include <cmath>
#include <map>

namespace zm {
namespace {

// Approximate inradius: the deepest of 16x16 sample points of the bounding box.
double ApproxInradius(std::span<const Eigen::Vector2d> ring, const Box2& box) {
  constexpr int kSamples = 16;
  double best = 0.0;
  const Eigen::Vector2d size = box.max - box.min;
  for (int iy = 0; iy < kSamples; ++iy) {
    for (int ix = 0; ix < kSamples; ++ix) {
      const Eigen::Vector2d p = box.min + Eigen::Vector2d(size.x() * (ix + 0.5) / kSamples,
                                                          size.y() * (iy + 0.5) / kSamples);
      if (PointInPolygon(ring, p)) best = std::max(best, DistanceToBoundary(ring, p));
    }
  }
  return best;
}

}  // namespace

ZoneIndex::ZoneIndex(const ZoneSet& zones, ZoneIndexOptions options) : options_(options) {
  zones_.resize(zones.size());
  std::map<int, std::vector<std::int32_t>> by_floor;
  for (const Zone& z : zones.zones()) {
    IndexedZone& iz = zones_[static_cast<std::size_t>(z.id.value)];
    iz.z_min_m = z.z_min_m;
    iz.z_max_m = z.z_max_m;
    if (z.polygon.empty()) continue;
    iz.ring = z.polygon;
    iz.box = BoundingBox(iz.ring);
    iz.hysteresis_m = std::min(options_.hysteresis_m, 0.5 * ApproxInradius(iz.ring, iz.box));
    by_floor[z.floor].push_back(z.id.value);
  }
  for (auto& [floor, ids] : by_floor) {
    Layer layer;
    Box2 box = zones_[static_cast<std::size_t>(ids[0])].box;
    layer.z_min_m = zones_[static_cast<std::size_t>(ids[0])].z_min_m;
    layer.z_max_m = zones_[static_cast<std::size_t>(ids[0])].z_max_m;
    std::vector<double> extents;
    extents.reserve(ids.size());
    for (std::int32_t id : ids) {
      const IndexedZone& iz = zones_[static_cast<std::size_t>(id)];
      box.min = box.min.cwiseMin(iz.box.min);
      box.max = box.max.cwiseMax(iz.box.max);
      layer.z_min_m = std::min(layer.z_min_m, iz.z_min_m);
      layer.z_max_m = std::max(layer.z_max_m, iz.z_max_m);
      extents.push_back(std::max((iz.box.max - iz.box.min).maxCoeff(), 1e-3));
    }
    std::nth_element(extents.begin(), extents.begin() + static_cast<std::ptrdiff_t>(extents.size() / 2),
                     extents.end());
    const Eigen::Vector2d size = (box.max - box.min).cwiseMax(1e-3);
    double cell = 0.5 * extents[extents.size() / 2];
    // Keep the grid within its cell budget.
    const double max_cells = static_cast<double>(options_.max_cells_per_layer);
    if ((size.x() / cell) * (size.y() / cell) > max_cells) {
      cell = std::sqrt(size.x() * size.y() / max_cells);
    }
    layer.cell_m = cell;
    layer.inv_cell = 1.0 / cell;
    layer.origin = box.min;
    layer.nx = std::max(1, static_cast<std::int32_t>(std::ceil(size.x() / cell)));
    layer.ny = std::max(1, static_cast<std::int32_t>(std::ceil(size.y() / cell)));
    const auto ncell = static_cast<std::size_t>(layer.nx) * static_cast<std::size_t>(layer.ny);
    // Two passes (count, then fill) over each zone's covered cells: CSR without per-cell vectors.
    auto cell_range = [&](const Box2& b, std::int32_t& x0, std::int32_t& x1, std::int32_t& y0,
                          std::int32_t& y1) {
      auto idx = [&](double v, double o, std::int32_t n) {
        return static_cast<std::int32_t>(
            std::clamp(std::floor((v - o) * layer.inv_cell), 0.0, static_cast<double>(n - 1)));
      };
      x0 = idx(b.min.x(), layer.origin.x(), layer.nx);
      x1 = idx(b.max.x(), layer.origin.x(), layer.nx);
      y0 = idx(b.min.y(), layer.origin.y(), layer.ny);
      y1 = idx(b.max.y(), layer.origin.y(), layer.ny);
    };
    std::vector<std::uint32_t> counts(ncell + 1, 0);
    for (std::int32_t id : ids) {
      std::int32_t x0, x1, y0, y1;
      IndexedZone& iz = zones_[static_cast<std::size_t>(id)];
      cell_range(iz.box, x0, x1, y0, y1);
      iz.cell_x0 = x0;
      iz.cell_y0 = y0;
      for (std::int32_t cy = y0; cy <= y1; ++cy) {
        for (std::int32_t cx = x0; cx <= x1; ++cx) {
          ++counts[static_cast<std::size_t>(cy) * static_cast<std::size_t>(layer.nx) +
                   static_cast<std::size_t>(cx) + 1];
        }
      }
    }
    for (std::size_t c = 0; c < ncell; ++c) counts[c + 1] += counts[c];
    layer.cell_begin = counts;
    layer.cell_zones.resize(counts[ncell]);
    // ids ascend, so each cell's list comes out sorted.
    for (std::int32_t id : ids) {
      std::int32_t x0, x1, y0, y1;
      cell_range(zones_[static_cast<std::size_t>(id)].box, x0, x1, y0, y1);
      for (std::int32_t cy = y0; cy <= y1; ++cy) {
        for (std::int32_t cx = x0; cx <= x1; ++cx) {
          const auto c = static_cast<std::size_t>(cy) * static_cast<std::size_t>(layer.nx) +
                         static_cast<std::size_t>(cx);
          layer.cell_zones[counts[c]++] = id;
        }
      }
    }
    layers_.push_back(std::move(layer));
  }
}

std::int64_t ZoneIndex::CellOf(const Layer& layer, const Eigen::Vector2d& p) const {
  const double fx = std::floor((p.x() - layer.origin.x()) * layer.inv_cell);
  const double fy = std::floor((p.y() - layer.origin.y()) * layer.inv_cell);
  // Written so NaN coordinates fall out too. A point on the grid's far edge joins the last cell.
  if (!(fx >= 0.0 && fy >= 0.0 && fx <= layer.nx && fy <= layer.ny)) return -1;
  const auto cx = std::min(static_cast<std::int64_t>(fx), std::int64_t{layer.nx} - 1);
  const auto cy = std::min(static_cast<std::int64_t>(fy), std::int64_t{layer.ny} - 1);
  return cy * layer.nx + cx;
}

bool ZoneIndex::Inside(std::int32_t zone, const Eigen::Vector3d& p) const {
  const IndexedZone& iz = zones_[static_cast<std::size_t>(zone)];
  const Eigen::Vector2d xy = p.head<2>();
  return !iz.ring.empty() && p.z() >= iz.z_min_m && p.z() < iz.z_max_m && iz.box.Contains(xy) &&
         PointInPolygon(iz.ring, xy);
}

std::span<const std::int32_t> ZoneIndex::CellZones(const Layer& layer,
                                                   const Eigen::Vector3d& p) const {
  if (p.z() < layer.z_min_m || p.z() >= layer.z_max_m) return {};
  const std::int64_t c = CellOf(layer, p.head<2>());
  if (c < 0) return {};
  const auto cu = static_cast<std::size_t>(c);
  return std::span<const std::int32_t>(layer.cell_zones)
      .subspan(layer.cell_begin[cu], layer.cell_begin[cu + 1] - layer.cell_begin[cu]);
}

ZoneId ZoneIndex::Lookup(const Eigen::Vector3d& p) const {
  std::int32_t best = -1;
  for (const Layer& layer : layers_) {
    for (const std::int32_t z : CellZones(layer, p)) {
      if (best >= 0 && z > best) break;
      if (Inside(z, p)) {
        best = z;
        break;
      }
    }
  }
  return best < 0 ? kNoZone : ZoneId{best};
}

double ZoneIndex::Depth(ZoneId zone, const Eigen::Vector3d& p) const {
  if (zone.value < 0 || static_cast<std::size_t>(zone.value) >= zones_.size()) return -1.0;
  if (!Inside(zone.value, p)) return -1.0;
  return DistanceToBoundary(zones_[static_cast<std::size_t>(zone.value)].ring, p.head<2>());
}

ZoneId ZoneIndex::GetZone(const Pose3& pose, ZoneId current) const {
  const Eigen::Vector3d p = pose.translation();
  if (current == kNoZone) return Lookup(p);
  if (current.value >= 0 && static_cast<std::size_t>(current.value) < zones_.size() &&
      Inside(current.value, p)) {
    return current;
  }
  std::int32_t best = -1;
  double best_margin = 0.0;
  for (const Layer& layer : layers_) {
    for (const std::int32_t z : CellZones(layer, p)) {
      if (!Inside(z, p)) continue;
      const IndexedZone& iz = zones_[static_cast<std::size_t>(z)];
      const double margin = DistanceToBoundary(iz.ring, p.head<2>()) - iz.hysteresis_m;
      if (margin > 0.0 && (best < 0 || margin > best_margin)) {
        best = z;
        best_margin = margin;
      }
    }
  }
  return best < 0 ? current : ZoneId{best};
}

std::size_t ZoneIndex::cell_count() const {
  std::size_t n = 0;
  for (const Layer& l : layers_) n += l.cell_begin.size() - 1;
  return n;
}

std::size_t ZoneIndex::candidate_entries() const {
  std::size_t n = 0;
  for (const Layer& l : layers_) n += l.cell_zones.size();
  return n;
}

}  // namespace zm
