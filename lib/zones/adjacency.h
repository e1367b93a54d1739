// The zone adjacency graph: which zones a robot can pass between directly. Two zones are
// neighbours when their polygons touch or overlap (boundaries within `touch_tolerance_m`, z
// ranges overlapping), when a pose-graph link joins a keyframe of one to a keyframe of the
// other, or when they share a keyframe (a doorway keyframe in both). The predictive memory
// policy prefetches along it.
//
// Invariants: undirected, no self-loops; Neighbours(z) is sorted and allocation-free to read;
// edges() lists each pair once with a < b, sorted.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "common/ids.h"
#include "mapdb/map_db.h"
#include "zones/zone_set.h"

namespace zm {

struct AdjacencyOptions {
  double touch_tolerance_m = 0.05;  // boundaries this close count as touching
};

struct ZoneEdge {
  ZoneId a, b;                       // a < b
  bool touching = false;             // polygons touch or overlap
  std::uint32_t links = 0;           // pose-graph links crossing between them
  std::uint32_t shared_keyframes = 0;  // keyframes that belong to both
};

class ZoneGraph {
 public:
  ZoneGraph() = default;
  // Builds the neighbour lists from edges (each pair once, any order).
  ZoneGraph(std::size_t zone_count, std::vector<ZoneEdge> edges);

  [[nodiscard]] std::size_t zone_count() const {
    return offsets_.empty() ? 0 : offsets_.size() - 1;
  }
  [[nodiscard]] std::span<const ZoneId> Neighbours(ZoneId zone) const;
  [[nodiscard]] bool Adjacent(ZoneId a, ZoneId b) const;
  [[nodiscard]] const std::vector<ZoneEdge>& edges() const { return edges_; }

 private:
  std::vector<ZoneEdge> edges_;
  std::vector<std::uint32_t> offsets_;  // zone_count + 1
  std::vector<ZoneId> neighbours_;
};

[[nodiscard]] ZoneGraph BuildAdjacency(const ZoneSet& zones, std::span<const ZoneMember> memberships,
                                       std::span<const LinkRecord> links,
                                       const AdjacencyOptions& options = {});

}  // namespace zm
