// Zone adjacency (see adjacency.h): touching polygons by a sweep over bounding boxes sorted by
// x, then links and shared keyframes through a keyframe -> zones map.
#include "zones/adjacency.h"

#include <algorithm>
#include <map>
#include <unordered_map>
#include <utility>

#include "zones/polygon.h"

namespace zm {

ZoneGraph::ZoneGraph(std::size_t zone_count, std::vector<ZoneEdge> edges)
    : edges_(std::move(edges)), offsets_(zone_count + 1, 0) {
  for (ZoneEdge& e : edges_) {
    if (e.b < e.a) std::swap(e.a, e.b);
  }
  std::sort(edges_.begin(), edges_.end(), [](const ZoneEdge& x, const ZoneEdge& y) {
    return x.a != y.a ? x.a < y.a : x.b < y.b;
  });
  for (const ZoneEdge& e : edges_) {
    ++offsets_[static_cast<std::size_t>(e.a.value) + 1];
    ++offsets_[static_cast<std::size_t>(e.b.value) + 1];
  }
  for (std::size_t i = 0; i < zone_count; ++i) offsets_[i + 1] += offsets_[i];
  neighbours_.resize(offsets_[zone_count]);
  std::vector<std::uint32_t> fill(offsets_.begin(), offsets_.end() - 1);
  for (const ZoneEdge& e : edges_) {
    neighbours_[fill[static_cast<std::size_t>(e.a.value)]++] = e.b;
    neighbours_[fill[static_cast<std::size_t>(e.b.value)]++] = e.a;
  }
  for (std::size_t i = 0; i < zone_count; ++i) {
    std::sort(neighbours_.begin() + offsets_[i], neighbours_.begin() + offsets_[i + 1]);
  }
}

std::span<const ZoneId> ZoneGraph::Neighbours(ZoneId zone) const {
  if (zone.value < 0 || static_cast<std::size_t>(zone.value) >= zone_count()) return {};
  const auto i = static_cast<std::size_t>(zone.value);
  return std::span<const ZoneId>(neighbours_).subspan(offsets_[i], offsets_[i + 1] - offsets_[i]);
}

bool ZoneGraph::Adjacent(ZoneId a, ZoneId b) const {
  const auto n = Neighbours(a);
  return std::binary_search(n.begin(), n.end(), b);
}

ZoneGraph BuildAdjacency(const ZoneSet& zones, std::span<const ZoneMember> memberships,
                         std::span<const LinkRecord> links, const AdjacencyOptions& options) {
  std::map<std::pair<std::int32_t, std::int32_t>, ZoneEdge> edges;
  auto edge = [&](ZoneId a, ZoneId b) -> ZoneEdge& {
    if (b < a) std::swap(a, b);
    ZoneEdge& e = edges[{a.value, b.value}];
    e.a = a;
    e.b = b;
    return e;
  };

  // Touching polygons: sweep bounding boxes in order of min x.
  struct Entry {
    ZoneId id;
    Box2 box;
  };
  std::vector<Entry> order;
  for (const Zone& z : zones.zones()) {
    if (!z.polygon.empty()) order.push_back({z.id, BoundingBox(z.polygon)});
  }
  std::sort(order.begin(), order.end(),
            [](const Entry& x, const Entry& y) { return x.box.min.x() < y.box.min.x(); });
  const double tol = options.touch_tolerance_m;
  for (std::size_t i = 0; i < order.size(); ++i) {
    const Zone& za = zones.zone(order[i].id);
    for (std::size_t j = i + 1; j < order.size(); ++j) {
      if (order[j].box.min.x() > order[i].box.max.x() + tol) break;
      if (!order[i].box.Overlaps(order[j].box, tol)) continue;
      const Zone& zb = zones.zone(order[j].id);
      if (!(za.z_min_m < zb.z_max_m && zb.z_min_m < za.z_max_m)) continue;  // other floor
      const bool touch = RingDistance(za.polygon, zb.polygon) <= tol ||
                         PointInPolygon(za.polygon, zb.polygon[0]) ||
                         PointInPolygon(zb.polygon, za.polygon[0]);
      if (touch) edge(za.id, zb.id).touching = true;
    }
  }

  // Keyframe -> zones, for shared keyframes and crossing links.
  std::unordered_map<KeyframeId, std::vector<ZoneId>> zones_of;
  zones_of.reserve(memberships.size());
  for (const ZoneMember& m : memberships) zones_of[m.keyframe].push_back(m.zone);
  for (const auto& [kf, zs] : zones_of) {
    for (std::size_t i = 0; i < zs.size(); ++i) {
      for (std::size_t j = i + 1; j < zs.size(); ++j) {
        if (zs[i] != zs[j]) ++edge(zs[i], zs[j]).shared_keyframes;
      }
    }
  }
  for (const LinkRecord& l : links) {
    const auto fa = zones_of.find(l.from);
    const auto fb = zones_of.find(l.to);
    if (fa == zones_of.end() || fb == zones_of.end()) continue;
    // A link counts for a pair when its endpoints are in different zones of the pair.
    for (ZoneId a : fa->second) {
      for (ZoneId b : fb->second) {
        if (a != b) ++edge(a, b).links;
      }
    }
  }

  std::vector<ZoneEdge> list;
  list.reserve(edges.size());
  for (const auto& [key, e] : edges) list.push_back(e);
  return ZoneGraph(zones.size(), std::move(list));
}

}  // namespace zm
