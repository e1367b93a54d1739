// Builds the MapIndex: sort keyframes by id, CSR arrays for zones, links, adjacency and the grid.
#include "memory/map_index.h"

#include <algorithm>
#include <numeric>
#include <string>

namespace zm {
namespace {

// Fills offsets (size n+1) from per-bucket counts.
void PrefixSum(std::vector<std::uint32_t>& counts_then_offsets) {
  std::uint32_t run = 0;
  for (auto& c : counts_then_offsets) {
    const std::uint32_t here = c;
    c = run;
    run += here;
  }
}

}  // namespace

std::int64_t MapIndex::CellCoord(double v, double origin) const {
  return static_cast<std::int64_t>(std::floor((v - origin) / cell_m_));
}

Result<MapIndex> MapIndex::Build(const MapIndexInput& input) {
  MapIndex m;
  const std::size_t n = input.keyframes.size();
  if (n >= kNoKf) return OutOfRange("map has " + std::to_string(n) + " keyframes; limit is 2^32-2");
  if (input.zone_count < 0) return InvalidArgument("zone_count is negative");
  if (!(input.grid_cell_m > 0.0)) return InvalidArgument("grid_cell_m must be > 0");

  std::vector<std::uint32_t> order(n);
  std::iota(order.begin(), order.end(), 0U);
  std::sort(order.begin(), order.end(), [&](std::uint32_t a, std::uint32_t b) {
    return input.keyframes[a].id < input.keyframes[b].id;
  });
  m.ids_.reserve(n);
  m.positions_.reserve(n);
  m.weights_.reserve(n);
  m.payload_bytes_.reserve(n);
  for (std::uint32_t i : order) {
    const KeyframeMeta& kf = input.keyframes[i];
    if (!m.ids_.empty() && m.ids_.back() == kf.id) {
      return InvalidArgument("keyframe id " + std::to_string(kf.id.value) + " appears twice");
    }
    m.ids_.push_back(kf.id);
    m.positions_.push_back(kf.pose.translation());
    m.weights_.push_back(kf.weight);
    m.payload_bytes_.push_back(kf.payload_bytes);
  }

  // Zones <-> keyframes.
  m.zone_count_ = input.zone_count;
  const auto nz = static_cast<std::size_t>(input.zone_count);
  std::vector<std::pair<std::uint32_t, KfIndex>> pairs;
  pairs.reserve(input.members.size());
  for (const ZoneMember& zm : input.members) {
    if (zm.zone.value < 0 || zm.zone.value >= input.zone_count) {
      return InvalidArgument("zone member names zone " + std::to_string(zm.zone.value) +
                             "; zones are 0.." + std::to_string(input.zone_count - 1));
    }
    const KfIndex k = m.Find(zm.keyframe);
    if (k == kNoKf) {
      return InvalidArgument("zone " + std::to_string(zm.zone.value) + " names keyframe " +
                             std::to_string(zm.keyframe.value) + ", which is not in the map");
    }
    pairs.emplace_back(static_cast<std::uint32_t>(zm.zone.value), k);
  }
  std::sort(pairs.begin(), pairs.end());
  pairs.erase(std::unique(pairs.begin(), pairs.end()), pairs.end());
  m.zone_offsets_.assign(nz + 1, 0);
  m.kf_zone_offsets_.assign(n + 1, 0);
  for (const auto& [z, k] : pairs) {
    ++m.zone_offsets_[z];
    ++m.kf_zone_offsets_[k];
  }
  PrefixSum(m.zone_offsets_);
  PrefixSum(m.kf_zone_offsets_);
  m.zone_members_.resize(pairs.size());
  m.kf_zones_.resize(pairs.size());
  {
    std::vector<std::uint32_t> fill(m.kf_zone_offsets_.begin(), m.kf_zone_offsets_.end() - 1);
    for (std::size_t i = 0; i < pairs.size(); ++i) {
      const auto [z, k] = pairs[i];
      m.zone_members_[i] = k;  // pairs are sorted by (zone, index)
      m.kf_zones_[fill[k]++] = ZoneId{static_cast<std::int32_t>(z)};
    }
  }
  for (std::size_t z = 0; z < nz; ++z) {
    m.max_zone_size_ = std::max(m.max_zone_size_, m.zone_offsets_[z + 1] - m.zone_offsets_[z]);
  }

  // Link graph, both directions, deduplicated per (from, to, type).
  std::vector<std::pair<KfIndex, GraphEdge>> half;
  half.reserve(input.links.size() * 2);
  for (const LinkRecord& l : input.links) {
    const KfIndex a = m.Find(l.from);
    const KfIndex b = m.Find(l.to);
    if (a == kNoKf || b == kNoKf || a == b) {
      ++m.dropped_links_;
      continue;
    }
    half.push_back({a, GraphEdge{b, l.type}});
    half.push_back({b, GraphEdge{a, l.type}});
  }
  auto edge_less = [](const auto& x, const auto& y) {
    if (x.first != y.first) return x.first < y.first;
    if (x.second.to != y.second.to) return x.second.to < y.second.to;
    return x.second.type < y.second.type;
  };
  std::sort(half.begin(), half.end(), edge_less);
  half.erase(std::unique(half.begin(), half.end(),
                         [](const auto& x, const auto& y) {
                           return x.first == y.first && x.second.to == y.second.to &&
                                  x.second.type == y.second.type;
                         }),
             half.end());
  m.edge_offsets_.assign(n + 1, 0);
  for (const auto& e : half) ++m.edge_offsets_[e.first];
  PrefixSum(m.edge_offsets_);
  m.edges_.reserve(half.size());
  for (const auto& e : half) m.edges_.push_back(e.second);

  // Zone adjacency (symmetrised, deduplicated).
  std::vector<std::pair<std::int32_t, std::int32_t>> adj;
  for (std::size_t a = 0; a < input.zone_adjacency.size(); ++a) {
    if (a >= nz) return InvalidArgument("zone adjacency has more rows than zones");
    for (ZoneId b : input.zone_adjacency[a]) {
      if (b.value < 0 || b.value >= input.zone_count) {
        return InvalidArgument("zone adjacency names zone " + std::to_string(b.value) +
                               "; zones are 0.." + std::to_string(input.zone_count - 1));
      }
      if (static_cast<std::size_t>(b.value) == a) continue;
      adj.emplace_back(static_cast<std::int32_t>(a), b.value);
      adj.emplace_back(b.value, static_cast<std::int32_t>(a));
    }
  }
  std::sort(adj.begin(), adj.end());
  adj.erase(std::unique(adj.begin(), adj.end()), adj.end());
  m.adj_offsets_.assign(nz + 1, 0);
  for (const auto& [a, b] : adj) ++m.adj_offsets_[static_cast<std::size_t>(a)];
  PrefixSum(m.adj_offsets_);
  m.adj_.reserve(adj.size());
  for (const auto& [a, b] : adj) m.adj_.push_back(ZoneId{b});

  // Static grid over x, y. The cell grows if the bounding box would need too many cells.
  m.cell_m_ = input.grid_cell_m;
  if (n > 0) {
    m.bbox_min_ = m.bbox_max_ = m.positions_[0].head<2>();
    for (const auto& p : m.positions_) {
      m.bbox_min_ = m.bbox_min_.cwiseMin(p.head<2>());
      m.bbox_max_ = m.bbox_max_.cwiseMax(p.head<2>());
    }
    constexpr double kMaxCells = 4.0e6;
    const Eigen::Vector2d extent = m.bbox_max_ - m.bbox_min_;
    while ((extent.x() / m.cell_m_ + 1.0) * (extent.y() / m.cell_m_ + 1.0) > kMaxCells) {
      m.cell_m_ *= 2.0;
    }
    m.cells_x_ = m.CellCoord(m.bbox_max_.x(), m.bbox_min_.x()) + 1;
    m.cells_y_ = m.CellCoord(m.bbox_max_.y(), m.bbox_min_.y()) + 1;
  }
  const auto cells = static_cast<std::size_t>(m.cells_x_ * m.cells_y_);
  m.cell_offsets_.assign(cells + 1, 0);
  std::vector<std::size_t> cell_of(n);
  for (KfIndex k = 0; k < n; ++k) {
    const std::int64_t cx = m.CellCoord(m.positions_[k].x(), m.bbox_min_.x());
    const std::int64_t cy = m.CellCoord(m.positions_[k].y(), m.bbox_min_.y());
    cell_of[k] = static_cast<std::size_t>(cy * m.cells_x_ + cx);
    ++m.cell_offsets_[cell_of[k]];
  }
  PrefixSum(m.cell_offsets_);
  m.cell_items_.resize(n);
  {
    std::vector<std::uint32_t> fill(m.cell_offsets_.begin(), m.cell_offsets_.end() - 1);
    for (KfIndex k = 0; k < n; ++k) m.cell_items_[fill[cell_of[k]]++] = k;
  }
  return m;
}

KfIndex MapIndex::Find(KeyframeId id) const {
  auto it = std::lower_bound(ids_.begin(), ids_.end(), id);
  if (it == ids_.end() || *it != id) return kNoKf;
  return static_cast<KfIndex>(it - ids_.begin());
}

std::span<const KfIndex> MapIndex::ZoneMembers(ZoneId z) const {
  if (z.value < 0 || z.value >= zone_count_) return {};
  return {zone_members_.data() + zone_offsets_[Uz(z)], zone_offsets_[Uz(z) + 1] - zone_offsets_[Uz(z)]};
}

std::uint32_t MapIndex::ZoneSize(ZoneId z) const {
  if (z.value < 0 || z.value >= zone_count_) return 0;
  return zone_offsets_[Uz(z) + 1] - zone_offsets_[Uz(z)];
}

std::span<const ZoneId> MapIndex::ZonesOf(KfIndex k) const {
  return {kf_zones_.data() + kf_zone_offsets_[k], kf_zone_offsets_[k + 1] - kf_zone_offsets_[k]};
}

std::span<const GraphEdge> MapIndex::Edges(KfIndex k) const {
  return {edges_.data() + edge_offsets_[k], edge_offsets_[k + 1] - edge_offsets_[k]};
}

std::span<const ZoneId> MapIndex::AdjacentZones(ZoneId z) const {
  if (z.value < 0 || z.value >= zone_count_) return {};
  return {adj_.data() + adj_offsets_[Uz(z)], adj_offsets_[Uz(z) + 1] - adj_offsets_[Uz(z)]};
}

}  // namespace zm
