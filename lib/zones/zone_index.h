// GetZone: which zone a pose is in, in constant average time whatever the number of zones, with
// boundary hysteresis so a robot driving along a shared edge does not flip between two zones.
//
// Layout: zones are grouped into layers by floor; each layer has a uniform grid over its
// bounding box whose cell lists (CSR arrays, sorted by zone id) the zones whose bounding box
// overlaps the cell. A lookup finds the pose's layer(s) by z, its cell, and tests point-in-
// polygon only against that cell's candidates. The cell size is about half the median zone
// extent, so a cell holds a handful of candidates for tiled rooms.
//
// Invariants: built once, immutable after; Lookup/GetZone/Depth allocate nothing and take no
// locks. Keyframe-list zones (no polygon) are never returned by a lookup.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <span>
#include <vector>

#include "common/ids.h"
#include "geometry/pose.h"
#include "zones/polygon.h"
#include "zones/zone_set.h"

namespace zm {

struct ZoneIndexOptions {
  // A pose switches from its current zone to another only when it is more than this far inside
  // the other zone. A zone too narrow for that (half its approximate inradius is smaller) uses
  // half its inradius instead, so every zone can still be entered.
  double hysteresis_m = 0.5;
  // Upper bound on grid cells per layer (memory: 4 bytes per cell plus candidate lists).
  std::uint32_t max_cells_per_layer = 1u << 22;
};

class ZoneIndex {
 public:
  ZoneIndex() = default;
  explicit ZoneIndex(const ZoneSet& zones, ZoneIndexOptions options = {});

  // The zone containing p (x, y, and z for the floor), lowest id if several overlap; kNoZone
  // outside every zone.
  [[nodiscard]] ZoneId Lookup(const Eigen::Vector3d& p) const;

  // The zone the robot is in given its previous zone `current` (kNoZone at start):
  //  - inside `current` (and on its floor): stay;
  //  - inside another zone and more than the hysteresis inside it: that zone (the deepest if
  //    several qualify);
  //  - otherwise (near a boundary, or outside every zone): stay in `current`;
  //  - with current == kNoZone: simply the containing zone (Lookup).
  [[nodiscard]] ZoneId GetZone(const Pose3& pose, ZoneId current) const;

  // Distance from p to the zone's boundary when p is inside it (on its floor), else -1.
  [[nodiscard]] double Depth(ZoneId zone, const Eigen::Vector3d& p) const;

  // Calls fn(ZoneId) once per polygon zone on p's floor whose bounding box comes within
  // `radius_m` of p (a candidate set for near-boundary queries; callers test exactly).
  // Allocation-free.
  template <class Fn>
  void ForEachCandidateNear(const Eigen::Vector3d& p, double radius_m, Fn&& fn) const;

  [[nodiscard]] std::size_t zone_count() const { return zones_.size(); }
  [[nodiscard]] const ZoneIndexOptions& options() const { return options_; }
  // Hysteresis actually applied to a zone (see ZoneIndexOptions::hysteresis_m).
  [[nodiscard]] double ZoneHysteresis(ZoneId zone) const {
    return zones_[static_cast<std::size_t>(zone.value)].hysteresis_m;
  }
  // For benchmarks and reports: cells and candidate entries over all layers.
  [[nodiscard]] std::size_t cell_count() const;
  [[nodiscard]] std::size_t candidate_entries() const;

 private:
  struct IndexedZone {
    std::vector<Eigen::Vector2d> ring;  // empty for list zones
    Box2 box;
    double z_min_m = 0, z_max_m = 0;
    double hysteresis_m = 0;
    std::int32_t cell_x0 = 0, cell_y0 = 0;  // first grid cell of its bounding box in its layer
  };
  struct Layer {
    double z_min_m = 0, z_max_m = 0;  // union of its zones' z ranges
    Eigen::Vector2d origin{0, 0};
    double cell_m = 1.0, inv_cell = 1.0;
    std::int32_t nx = 0, ny = 0;
    std::vector<std::uint32_t> cell_begin;  // nx*ny + 1 offsets into cell_zones
    std::vector<std::int32_t> cell_zones;   // zone ids, sorted within a cell
  };

  [[nodiscard]] bool Inside(std::int32_t zone, const Eigen::Vector3d& p) const;
  // Cell of p in the layer, or -1 outside its grid.
  [[nodiscard]] std::int64_t CellOf(const Layer& layer, const Eigen::Vector2d& p) const;
  // The candidate zones of p's cell in the layer (ids ascending): empty when p is outside the
  // layer's z range or its grid.
  [[nodiscard]] std::span<const std::int32_t> CellZones(const Layer& layer,
                                                        const Eigen::Vector3d& p) const;

  ZoneIndexOptions options_;
  std::vector<IndexedZone> zones_;
  std::vector<Layer> layers_;
};

template <class Fn>
void ZoneIndex::ForEachCandidateNear(const Eigen::Vector3d& p, double radius_m, Fn&& fn) const {
  const Eigen::Vector2d xy = p.head<2>();
  for (const Layer& layer : layers_) {
    if (p.z() < layer.z_min_m || p.z() >= layer.z_max_m || layer.nx == 0) continue;
    const Eigen::Vector2d lo = (xy.array() - radius_m - layer.origin.array()) * layer.inv_cell;
    const Eigen::Vector2d hi = (xy.array() + radius_m - layer.origin.array()) * layer.inv_cell;
    if (!(hi.x() >= 0 && hi.y() >= 0 && lo.x() < layer.nx && lo.y() < layer.ny)) continue;
    const auto clampi = [](double v, std::int32_t n) {
      return static_cast<std::int32_t>(std::clamp(std::floor(v), 0.0, static_cast<double>(n - 1)));
    };
    const std::int32_t qx0 = clampi(lo.x(), layer.nx), qx1 = clampi(hi.x(), layer.nx);
    const std::int32_t qy0 = clampi(lo.y(), layer.ny), qy1 = clampi(hi.y(), layer.ny);
    for (std::int32_t cy = qy0; cy <= qy1; ++cy) {
      for (std::int32_t cx = qx0; cx <= qx1; ++cx) {
        const auto c = static_cast<std::size_t>(cy) * static_cast<std::size_t>(layer.nx) +
                       static_cast<std::size_t>(cx);
        for (std::uint32_t k = layer.cell_begin[c]; k < layer.cell_begin[c + 1]; ++k) {
          const std::int32_t z = layer.cell_zones[k];
          const IndexedZone& iz = zones_[static_cast<std::size_t>(z)];
          // A zone spans a rectangle of cells: report it only from the first cell that both
          // its rectangle and the query's share, so each zone is reported once, with no scratch.
          if (cx != std::max(iz.cell_x0, qx0) || cy != std::max(iz.cell_y0, qy0)) continue;
          if (p.z() < iz.z_min_m || p.z() >= iz.z_max_m) continue;
          if (!iz.box.Overlaps(Box2{xy, xy}, radius_m)) continue;
          fn(ZoneId{z});
        }
      }
    }
  }
}

}  // namespace zm
