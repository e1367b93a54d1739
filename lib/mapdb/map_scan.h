// Reading every keyframe of a map once, for offline tools (vocabulary training, `zonemap
// inspect`): each keyframe is loaded into one arena slot the way the run-time loads it (payload
// validated, dense part decoded, points from depth), handed to a visitor as a view, and its slot
// released before the next one. Memory: one slot of the map's largest resident keyframe.
#pragma once

#include <cstdint>
#include <functional>
#include <span>

#include "common/status.h"
#include "mapdb/keyframe_payload.h"
#include "mapdb/map_db.h"

namespace zm {

// Called once per keyframe, in the order given; the view is valid only during the call. A
// non-Ok return stops the scan with that status.
using KeyframeVisitor = std::function<Status(const KeyframeMeta& meta, const KeyframeView& view)>;

// Loads each of `keyframes` (MapDb::LoadKeyframes) and visits it. Errors name the keyframe.
[[nodiscard]] Status ScanKeyframes(MapDb& map, std::span<const KeyframeMeta> keyframes,
                                   const KeyframeVisitor& visit);

// What a keyframe view holds, counted (issue 26's `zonemap inspect`).
struct KeyframeContent {
  std::uint32_t features = 0;  // descriptors
  std::uint32_t points3d = 0;  // features with a finite 3-D point (on disk, or from depth)
  bool has_colour = false;     // a colour image (decoded, or carried in the dense bytes)
  bool has_depth = false;      // a depth image (decoded, or carried in the dense bytes)
};
[[nodiscard]] KeyframeContent CountKeyframeContent(const KeyframeView& view);

}  // namespace zm
