// Oversize zones: a zone holding more keyframes than the budget allows cannot be loaded whole
// (docs/design.md), so it is split offline into compact sub-zones that each fit.
//
// Method: recursive bisection along the principal axis of the zone's keyframe positions. With
// k = ceil(n / max) parts still needed, the first floor(k/2) parts' share of the keyframes (in
// order along the axis) goes to one side, the rest to the other, so every leaf ends with at most
// `max_keyframes` and the parts are as few as the budget allows. The polygon is clipped by the
// cut line (midway between the two keyframes on either side of it). If clipping a concave room
// would give an empty or self-touching piece, both sides keep the parent polygon (overlapping
// zones are allowed) and the report says so. Sub-zones are named "<name>/1", "<name>/2", ... in
// axis order and take the parent's kind and floor.
//
// Invariants: every keyframe of a split zone belongs to exactly one of its parts; zones that fit
// are copied unchanged; ids stay dense, parts replace their parent in place.
#pragma once

#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "common/status.h"
#include "mapdb/map_db.h"
#include "zones/zone_set.h"

namespace zm {

struct SplitEntry {
  std::string original;                     // the oversize zone's name
  std::uint32_t keyframes = 0;              // its member count
  std::vector<std::string> parts;           // names of the sub-zones
  std::vector<std::uint32_t> part_keyframes;  // their member counts
  bool polygon_shared = false;              // some cut could not clip the polygon cleanly
};

struct SplitReport {
  std::uint32_t max_keyframes = 0;
  std::vector<SplitEntry> entries;  // one per zone that was split
};

struct SplitResult {
  ZoneSet zones;
  std::vector<ZoneMember> members;  // by zone, then keyframe
  SplitReport report;
};

// Splits every zone with more than `max_keyframes` members. `keyframes` gives the positions of
// the members (a member missing from it is an error). max_keyframes must be >= 1.
[[nodiscard]] Result<SplitResult> SplitOversizeZones(const ZoneSet& zones,
                                                     std::span<const ZoneMember> members,
                                                     std::span<const KeyframeMeta> keyframes,
                                                     std::uint32_t max_keyframes);

}  // namespace zm
