// The split stage of automatic zones: segments, or keyframe cells when there is no grid, cut
// along the principal axis of their keyframes until each holds at most a given number of them.
#pragma once

#include <Eigen/Core>
#include <span>
#include <vector>

#include "common/status.h"
#include "segment/grid_map.h"
#include "segment/segment_info.h"
#include "zones/zone_set.h"

namespace zm {

// Splits every segment holding more than `max_keyframes` of `positions_m` (map frame) in two
// along the principal axis of its keyframes at their median, recursively, until each part
// holds at most `max_keyframes`. Keyframes off the grid or outside every segment are ignored.
// Labels of split parts are appended; kinds are kept. max_keyframes must be >= 1.
[[nodiscard]] Status SplitOversizeSegments(const OccupancyGrid& grid,
                                           std::span<const Eigen::Vector2d> positions_m,
                                           int max_keyframes, Segmentation* seg);

// Zones from keyframe positions alone (no grid): keyframes are bucketed into square cells of
// `cell_size_m`; a cell holding more than `max_keyframes` is split along the principal axis of
// its keyframes at the median, recursively. Each part becomes one zone: the convex hull of its
// keyframes grown by `margin_m`, clipped to its cell part, so zones never overlap and each
// contains its keyframes. Zones are named "area_<n>", kind "room", floor 0 with floor 0's z
// range (FloorZRange).
struct KeyframeZoneOptions {
  double cell_size_m = 8.0;
  int max_keyframes = 200;
  double margin_m = 0.5;
};
[[nodiscard]] Result<std::vector<Zone>> ZonesFromKeyframes(
    std::span<const Eigen::Vector2d> positions_m, const KeyframeZoneOptions& options = {});

}  // namespace zm
