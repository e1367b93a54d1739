// A map's semantic zones: named polygons (rooms, corridors, lobbies) with a kind and a floor,
// read from GeoJSON or from the paper's keyframe-list format, written back as GeoJSON, and
// converted to and from the map database's ZoneRecord.
//
// Invariants of a ZoneSet: zone ids are dense 0..N-1 in file order; names are unique; every
// polygon is a simple (non-self-intersecting) ring of at least 3 distinct vertices with non-zero
// area, stored without the repeated closing vertex; z_min_m < z_max_m. Keyframe-list sets (the
// paper's format) have no polygons; each zone carries its keyframe ids, sorted and unique.
//
// File formats (docs/zones.md):
//   GeoJSON FeatureCollection of Polygon features, properties `name` (required, unique),
//   `kind` (default "room"), `floor` (integer, default 0), optional `z_min`/`z_max` (metres;
//   null = unbounded on that side).
//   A zone with `floor` but no z range spans [floor*H - H/2, floor*H + H/2) where H is the
//   collection's `floor_height_m` (default 3 m); without `floor` or z range it spans every z.
//   Keyframe lists: {"initial_zone": "L1", "zones": {"L1": [1, 7, 8], "H1": [...]}}.
#pragma once

#include <Eigen/Core>
#include <span>
#include <string>
#include <string_view>
#include <unordered_map>
#include <utility>
#include <vector>

#include "common/ids.h"
#include "common/status.h"
#include "mapdb/map_db.h"

namespace zm {

inline constexpr double kDefaultFloorHeightM = 3.0;
inline constexpr double kUnboundedZM = 1e9;  // matches ZoneRecord's "no z range"

struct Zone {
  ZoneId id = kNoZone;
  std::string name;
  std::string kind = "room";
  int floor = 0;
  double z_min_m = -kUnboundedZM;
  double z_max_m = kUnboundedZM;
  std::vector<Eigen::Vector2d> polygon;  // outer ring, metres, map frame; empty for list zones

  [[nodiscard]] bool ContainsZ(double z) const { return z >= z_min_m && z < z_max_m; }
  [[nodiscard]] double AreaM2() const;  // 0 without a polygon
};

class ZoneSet {
 public:
  ZoneSet() = default;

  // Appends a zone, giving it the next id. Checks the invariants above (polygon simplicity,
  // unique name, z range); `where` prefixes errors ("zones.geojson: feature 3"). A zone without
  // a polygon is a keyframe-list zone and `keyframes` is its list (sorted and deduplicated
  // here); a polygon zone takes no list. A set holds one kind or the other, never both.
  Status Add(Zone zone, std::vector<KeyframeId> keyframes = {}, std::string_view where = "");

  [[nodiscard]] std::size_t size() const { return zones_.size(); }
  [[nodiscard]] bool empty() const { return zones_.empty(); }
  [[nodiscard]] const std::vector<Zone>& zones() const { return zones_; }
  [[nodiscard]] const Zone& zone(ZoneId id) const {
    return zones_[static_cast<std::size_t>(id.value)];
  }
  // kNoZone if no zone has that name.
  [[nodiscard]] ZoneId Find(std::string_view name) const;

  // True when the set came from the keyframe-list format (no polygons).
  [[nodiscard]] bool has_keyframe_lists() const { return has_lists_; }
  [[nodiscard]] const std::vector<KeyframeId>& keyframes(ZoneId id) const {
    return lists_[static_cast<std::size_t>(id.value)];
  }

  // The zone the robot starts in (paper format's `initial_zone`), kNoZone if unknown.
  [[nodiscard]] ZoneId initial_zone() const { return initial_zone_; }
  Status SetInitialZone(std::string_view name);

  // Where the set came from (a file path), for error messages; empty if built in code.
  [[nodiscard]] const std::string& source() const { return source_; }
  void set_source(std::string source) { source_ = std::move(source); }

 private:
  std::vector<Zone> zones_;
  std::vector<std::vector<KeyframeId>> lists_;  // parallel to zones_
  std::unordered_map<std::string, ZoneId> by_name_;
  bool has_lists_ = false;
  ZoneId initial_zone_ = kNoZone;
  std::string source_;
};

// Reads a zone file, detecting GeoJSON or keyframe lists. Errors name the file and the feature.
[[nodiscard]] Result<ZoneSet> LoadZoneFile(const std::string& path);
// Parses zone JSON text; `source_name` names it in errors.
[[nodiscard]] Result<ZoneSet> ParseZoneJson(std::string_view text, std::string_view source_name);
// The z range of a zone on `floor` whose file gives none: [floor*H - H/2, floor*H + H/2) for
// floor height H.
struct ZRange {
  double min_m = -kUnboundedZM;
  double max_m = kUnboundedZM;
};
[[nodiscard]] ZRange FloorZRange(int floor, double floor_height_m = kDefaultFloorHeightM);

// The one GeoJSON writer: a FeatureCollection of Polygon features (rings closed, as the format
// requires) with properties name, kind, floor, z_min and z_max (null = unbounded on that side;
// always written, so reading back never derives a range from the floor). Every zone must have a
// polygon. The zone files of `zonemap zones` and of the offline segmentation are both this.
[[nodiscard]] std::string ZonesToGeoJson(std::span<const Zone> zones);
[[nodiscard]] Status WriteZonesGeoJson(std::span<const Zone> zones, const std::string& path);
// The same for a set; keyframe-list sets have no geometry and are refused.
Status WriteGeoJson(const ZoneSet& zones, const std::string& path);
[[nodiscard]] std::string ToGeoJsonText(const ZoneSet& zones);

// Conversions to and from the map database's zone table.
[[nodiscard]] ZoneRecord ToZoneRecord(const Zone& zone);
[[nodiscard]] std::vector<ZoneRecord> ToZoneRecords(const ZoneSet& zones);
// Rebuilds a set from database records (ids must be dense 0..N-1 in order). Zones without a
// polygon are keyframe-list zones; their lists come from `members`.
[[nodiscard]] Result<ZoneSet> ZoneSetFromRecords(std::span<const ZoneRecord> records,
                                                 std::span<const ZoneMember> members = {});

}  // namespace zm
