// Oversize zone splitting (see split.h): recursive principal-axis bisection of the members,
// polygon clipped along each cut.
#include "zones/split.h"

#include <algorithm>
#include <cmath>
#include <unordered_map>
#include <vector>

#include "zones/polygon.h"
#include "zones/principal_axis.h"

namespace zm {
namespace {

struct Item {
  KeyframeId id;
  Eigen::Vector2d xy;
};

struct Leaf {
  std::vector<Eigen::Vector2d> polygon;
  std::vector<KeyframeId> ids;
};

bool UsablePiece(const std::vector<Eigen::Vector2d>& ring) {
  return ring.size() >= 3 && !FindSelfIntersection(ring).has_value();
}

void Bisect(std::vector<Eigen::Vector2d> polygon, std::vector<Item> items, std::uint32_t max,
            std::vector<Leaf>& leaves, bool& shared) {
  const std::size_t n = items.size();
  if (n <= max) {
    Leaf leaf{std::move(polygon), {}};
    leaf.ids.reserve(n);
    for (const Item& it : items) leaf.ids.push_back(it.id);
    std::sort(leaf.ids.begin(), leaf.ids.end());
    leaves.push_back(std::move(leaf));
    return;
  }
  std::vector<Eigen::Vector2d> xy;
  xy.reserve(n);
  for (const Item& it : items) xy.push_back(it.xy);
  Eigen::Vector2d axis = PrincipalAxes(xy).col(1);
  if (!axis.allFinite() || axis.norm() < 0.5) axis = Eigen::Vector2d::UnitX();
  // An eigenvector's sign is arbitrary: fix it so part order (and names) are reproducible.
  if (std::abs(axis.x()) >= std::abs(axis.y()) ? axis.x() < 0.0 : axis.y() < 0.0) axis = -axis;
  std::stable_sort(items.begin(), items.end(),
                   [&](const Item& a, const Item& b) { return axis.dot(a.xy) < axis.dot(b.xy); });
  const std::size_t k = (n + max - 1) / max;  // parts still needed, >= 2
  const std::size_t k_left = k / 2;
  const std::size_t n_left = (n * k_left + k - 1) / k;  // <= k_left * max, rest <= (k-k_left)*max
  const double cut = 0.5 * (axis.dot(items[n_left - 1].xy) + axis.dot(items[n_left].xy));
  std::vector<Eigen::Vector2d> left_poly = polygon, right_poly = polygon;
  if (!polygon.empty()) {
    auto l = ClipToHalfPlane(polygon, axis, cut);
    auto r = ClipToHalfPlane(polygon, -axis, -cut);
    if (UsablePiece(l) && UsablePiece(r)) {
      left_poly = std::move(l);
      right_poly = std::move(r);
    } else {
      shared = true;
    }
  }
  std::vector<Item> right(items.begin() + static_cast<std::ptrdiff_t>(n_left), items.end());
  items.resize(n_left);
  Bisect(std::move(left_poly), std::move(items), max, leaves, shared);
  Bisect(std::move(right_poly), std::move(right), max, leaves, shared);
}

}  // namespace

Result<SplitResult> SplitOversizeZones(const ZoneSet& zones, std::span<const ZoneMember> members,
                                       std::span<const KeyframeMeta> keyframes,
                                       std::uint32_t max_keyframes) {
  if (max_keyframes == 0) return InvalidArgument("split: max_keyframes must be at least 1");
  std::unordered_map<KeyframeId, Eigen::Vector2d> position;
  position.reserve(keyframes.size());
  for (const KeyframeMeta& k : keyframes) position.emplace(k.id, k.pose.translation().head<2>());
  std::vector<std::vector<KeyframeId>> by_zone(zones.size());
  for (const ZoneMember& m : members) {
    if (m.zone.value < 0 || static_cast<std::size_t>(m.zone.value) >= zones.size()) {
      return InvalidArgument("split: a member names zone " + std::to_string(m.zone.value) + " of " +
                             std::to_string(zones.size()));
    }
    by_zone[static_cast<std::size_t>(m.zone.value)].push_back(m.keyframe);
  }

  SplitResult out;
  out.report.max_keyframes = max_keyframes;
  out.zones.set_source(zones.source());
  auto add = [&](Zone z, std::vector<KeyframeId> ids) -> Status {
    std::vector<KeyframeId> list;
    if (z.polygon.empty()) list = ids;
    ZM_RETURN_IF_ERROR(out.zones.Add(std::move(z), std::move(list)));
    const ZoneId id{static_cast<std::int32_t>(out.zones.size() - 1)};
    for (KeyframeId k : ids) out.members.push_back({id, k});
    return Status::Ok();
  };
  for (const Zone& zone : zones.zones()) {
    std::vector<KeyframeId>& ids = by_zone[static_cast<std::size_t>(zone.id.value)];
    std::sort(ids.begin(), ids.end());
    ids.erase(std::unique(ids.begin(), ids.end()), ids.end());
    if (ids.size() <= max_keyframes) {
      ZM_RETURN_IF_ERROR(add(zone, ids));
      continue;
    }
    std::vector<Item> items;
    items.reserve(ids.size());
    for (KeyframeId k : ids) {
      const auto it = position.find(k);
      if (it == position.end()) {
        return NotFound("split: zone \"" + zone.name + "\" holds keyframe " +
                        std::to_string(k.value) + ", which has no pose in the map");
      }
      items.push_back({k, it->second});
    }
    std::vector<Leaf> leaves;
    SplitEntry entry;
    entry.original = zone.name;
    entry.keyframes = static_cast<std::uint32_t>(ids.size());
    Bisect(zone.polygon, std::move(items), max_keyframes, leaves, entry.polygon_shared);
    for (std::size_t i = 0; i < leaves.size(); ++i) {
      Zone part = zone;
      part.name = zone.name + "/" + std::to_string(i + 1);
      part.polygon = std::move(leaves[i].polygon);
      entry.parts.push_back(part.name);
      entry.part_keyframes.push_back(static_cast<std::uint32_t>(leaves[i].ids.size()));
      ZM_RETURN_IF_ERROR(add(std::move(part), std::move(leaves[i].ids)));
    }
    out.report.entries.push_back(std::move(entry));
  }
  if (zones.initial_zone() != kNoZone) {
    const std::string& name = zones.zone(zones.initial_zone()).name;
    // A split initial zone starts in its first part.
    const ZoneId kept = out.zones.Find(name);
    ZM_RETURN_IF_ERROR(out.zones.SetInitialZone(kept != kNoZone ? name : name + "/1"));
  }
  return out;
}

}  // namespace zm
