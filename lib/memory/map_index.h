// MapIndex: everything the memory policies decide on, built once at start from metadata only
// (no payload, no SQL): keyframes in dense index order with id -> index lookup, zone membership
// in both directions as CSR arrays, the link graph (both directions), zone adjacency and a
// static 2-D grid over keyframe positions for radius queries.
//
// Invariants:
//   - dense indices are 0..keyframe_count()-1, ordered by ascending KeyframeId;
//   - ZoneMembers(z) is sorted by index and holds no duplicates; ZonesOf(k) likewise;
//   - every link endpoint is a known keyframe (links to unknown ids, e.g. RTAB-Map landmarks,
//     are dropped at build and counted in dropped_links());
//   - nothing here changes after Build(), so every query is const and allocation-free.
#pragma once

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <span>
#include <vector>

#include "common/ids.h"
#include "common/status.h"
#include "mapdb/map_db.h"

namespace zm {

// Dense keyframe index inside one MapIndex (0..N-1). Policies and the WorkingSet work on these;
// KeyframeIds appear only at the edges (the database, the localizer).
using KfIndex = std::uint32_t;
inline constexpr KfIndex kNoKf = std::numeric_limits<KfIndex>::max();

struct MapIndexInput {
  std::span<const KeyframeMeta> keyframes;  // any order; ids must be unique
  std::span<const LinkRecord> links;        // each edge once or twice; both are fine
  std::span<const ZoneMember> members;      // (zone, keyframe); a keyframe may be in many zones
  std::int32_t zone_count = 0;              // zones are 0..zone_count-1
  std::span<const std::vector<ZoneId>> zone_adjacency;  // [zone] -> neighbours; empty = unknown
  double grid_cell_m = 10.0;                // cell of the static radius-query grid
};

struct GraphEdge {
  KfIndex to = kNoKf;
  LinkKind type = LinkKind::kNeighbor;
};

class MapIndex {
 public:
  // Validates and indexes. Errors name the offending id and the limit.
  [[nodiscard]] static Result<MapIndex> Build(const MapIndexInput& input);

  [[nodiscard]] std::uint32_t keyframe_count() const { return static_cast<std::uint32_t>(ids_.size()); }
  [[nodiscard]] std::int32_t zone_count() const { return zone_count_; }
  // kNoKf when the id is not in the map. O(log N), no allocation.
  [[nodiscard]] KfIndex Find(KeyframeId id) const;
  [[nodiscard]] KeyframeId id(KfIndex k) const { return ids_[k]; }
  [[nodiscard]] const Eigen::Vector3d& position(KfIndex k) const { return positions_[k]; }
  [[nodiscard]] std::int32_t weight(KfIndex k) const { return weights_[k]; }
  [[nodiscard]] std::uint32_t payload_bytes(KfIndex k) const { return payload_bytes_[k]; }

  [[nodiscard]] std::span<const KfIndex> ZoneMembers(ZoneId z) const;
  [[nodiscard]] std::uint32_t ZoneSize(ZoneId z) const;
  [[nodiscard]] std::uint32_t ZoneOffset(ZoneId z) const { return zone_offsets_[Uz(z)]; }
  [[nodiscard]] std::span<const ZoneId> ZonesOf(KfIndex k) const;
  [[nodiscard]] std::span<const GraphEdge> Edges(KfIndex k) const;
  [[nodiscard]] std::span<const ZoneId> AdjacentZones(ZoneId z) const;
  // Sum of all zone sizes (a keyframe in two zones counts twice).
  [[nodiscard]] std::uint32_t total_memberships() const {
    return static_cast<std::uint32_t>(zone_members_.size());
  }
  [[nodiscard]] std::uint32_t max_zone_size() const { return max_zone_size_; }
  [[nodiscard]] std::uint32_t dropped_links() const { return dropped_links_; }
  [[nodiscard]] const Eigen::Vector2d& bbox_min() const { return bbox_min_; }
  [[nodiscard]] const Eigen::Vector2d& bbox_max() const { return bbox_max_; }

  // Calls f(k, distance_m) for every keyframe within radius_m (3-D) of center, in no particular
  // order. Cost is proportional to the keyframes in the cells the circle overlaps, not to N.
  template <class F>
  void ForEachWithin(const Eigen::Vector3d& center, double radius_m, F&& f) const;

 private:
  static std::size_t Uz(ZoneId z) { return static_cast<std::size_t>(z.value); }
  std::int64_t CellCoord(double v, double origin) const;

  std::vector<KeyframeId> ids_;  // sorted ascending
  std::vector<Eigen::Vector3d> positions_;
  std::vector<std::int32_t> weights_;
  std::vector<std::uint32_t> payload_bytes_;
  std::int32_t zone_count_ = 0;
  std::vector<std::uint32_t> zone_offsets_;  // zone_count+1
  std::vector<KfIndex> zone_members_;
  std::vector<std::uint32_t> kf_zone_offsets_;  // N+1
  std::vector<ZoneId> kf_zones_;
  std::vector<std::uint32_t> edge_offsets_;  // N+1
  std::vector<GraphEdge> edges_;
  std::vector<std::uint32_t> adj_offsets_;  // zone_count+1
  std::vector<ZoneId> adj_;
  std::uint32_t max_zone_size_ = 0;
  std::uint32_t dropped_links_ = 0;
  // Static grid: cells_x_ * cells_y_ cells of cell_m_, CSR over keyframe indices.
  double cell_m_ = 10.0;
  Eigen::Vector2d bbox_min_ = Eigen::Vector2d::Zero();
  Eigen::Vector2d bbox_max_ = Eigen::Vector2d::Zero();
  std::int64_t cells_x_ = 1, cells_y_ = 1;
  std::vector<std::uint32_t> cell_offsets_;
  std::vector<KfIndex> cell_items_;
};

template <class F>
void MapIndex::ForEachWithin(const Eigen::Vector3d& center, double radius_m, F&& f) const {
  if (ids_.empty() || radius_m < 0.0) return;
  const std::int64_t x0 = CellCoord(center.x() - radius_m, bbox_min_.x());
  const std::int64_t x1 = CellCoord(center.x() + radius_m, bbox_min_.x());
  const std::int64_t y0 = CellCoord(center.y() - radius_m, bbox_min_.y());
  const std::int64_t y1 = CellCoord(center.y() + radius_m, bbox_min_.y());
  const double r2 = radius_m * radius_m;
  for (std::int64_t cy = std::max<std::int64_t>(y0, 0); cy <= std::min(y1, cells_y_ - 1); ++cy) {
    for (std::int64_t cx = std::max<std::int64_t>(x0, 0); cx <= std::min(x1, cells_x_ - 1); ++cx) {
      const auto cell = static_cast<std::size_t>(cy * cells_x_ + cx);
      for (std::uint32_t i = cell_offsets_[cell]; i < cell_offsets_[cell + 1]; ++i) {
        const KfIndex k = cell_items_[i];
        const double d2 = (positions_[k] - center).squaredNorm();
        if (d2 <= r2) f(k, std::sqrt(d2));
      }
    }
  }
}

}  // namespace zm
