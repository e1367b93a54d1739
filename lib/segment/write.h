// The write stage of room segmentation: segments as polygon zones, as a GeoJSON zone file, and
// as a colour PNG to look at.
#pragma once

#include <span>
#include <string>
#include <vector>

#include "common/status.h"
#include "segment/grid_map.h"
#include "segment/option_field.h"
#include "segment/segment_info.h"
#include "zones/zone_set.h"

namespace zm {

struct OutlineOptions {
  double simplify_tolerance_m = 0.10;  // approxPolyDP tolerance for polygons
};

inline constexpr OptionField<OutlineOptions> kOutlineOptionFields[] = {
    {"simplify_tolerance_m", &OutlineOptions::simplify_tolerance_m},
};

[[nodiscard]] Status CheckOutlineOptions(const OutlineOptions& o);

// One polygon zone per segment (largest outer contour through the boundary cells' centres,
// simplified, always a simple counter-clockwise ring, in map-frame metres), named
// "<kind>_<n>", floor 0 with floor 0's z range (FloorZRange: what the zone file meant when it
// gave no range). Segments whose outline has < 3 vertices are skipped.
[[nodiscard]] Result<std::vector<Zone>> SegmentationToZones(const Segmentation& seg,
                                                            const OccupancyGrid& grid,
                                                            const OutlineOptions& options = {});

// Writes the segments as a colour PNG over the grid (occupied black, unknown grey, free but in
// no segment white, each segment one colour): for looking at a result, not for reading back.
[[nodiscard]] Status WriteSegmentationPng(const std::string& path, const OccupancyGrid& grid,
                                          const Segmentation& seg);

// The zone file is written by the zones module's one GeoJSON writer (zones/zone_set.h,
// WriteZonesGeoJson).

}  // namespace zm
