// Keyframe membership: which zones each keyframe of the map belongs to, written to the map
// database with the zones in one transaction (`zonemap zones annotate`).
//
// Rules for polygon zones (only zones whose z range holds the keyframe's z count):
//  - a keyframe belongs to every zone that contains it (overlapping zones are allowed);
//  - a keyframe within `band_m` of another zone's boundary joins that zone too, so a doorway is
//    resident on both sides;
//  - a keyframe in no zone and no band joins the nearest zone on its floor (by distance to the
//    boundary), or the nearest zone of any floor if its floor has none.
// Keyframe-list zones (the paper's format) use their lists as given; a listed id that is not in
// the map is an error naming the file and the zone; unlisted keyframes are counted, not guessed.
// Zones over `max_zone_keyframes` are then split (split.h) so every zone fits the budget.
#pragma once

#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "common/param.h"
#include "common/status.h"
#include "mapdb/map_db.h"
#include "zones/split.h"
#include "zones/zone_set.h"

namespace zm {

// The doorway band, declared once: `zonemap zones annotate --band`, the simulator's annotation
// (sim::ScenarioOptions::annotate_band_m) and the public API's HostMap::doorway_band_m (checked
// equal at compile time in api/zone_manager.cc) take it from here.
inline constexpr Param<double> kDoorwayBandParam{
    "band", 0.5, 0.0, 50.0,
    "doorway band in metres: keyframes this close to another zone join it too"};

struct AnnotateOptions {
  double band_m = kDoorwayBandParam.default_value;  // doorway band: join neighbours this close
  std::uint32_t warn_zone_keyframes = 0;   // report zones holding more (0 = no budget)
  std::uint32_t max_zone_keyframes = 0;    // split zones holding more (0 = never split)
};

struct AnnotationReport {
  ZoneSet zones;                      // the zones as written (after any split)
  std::vector<ZoneMember> members;    // by zone, then keyframe
  std::vector<std::uint32_t> counts;  // members per zone, index = ZoneId
  std::uint64_t keyframes = 0;        // keyframes annotated
  std::uint64_t inside = 0;           // keyframes inside at least one zone
  std::uint64_t band_memberships = 0;  // extra memberships from the boundary band
  std::uint64_t nearest = 0;          // keyframes outside every zone and band, given the nearest
  std::uint64_t unassigned = 0;       // keyframes in no zone (keyframe-list files only)
  std::vector<ZoneId> over_budget;    // zones with more than warn_zone_keyframes members
  SplitReport split;                  // what max_zone_keyframes split
};

// Assigns keyframes to zones (no database).
[[nodiscard]] Result<AnnotationReport> AnnotateKeyframes(const ZoneSet& zones,
                                                         std::span<const KeyframeMeta> keyframes,
                                                         const AnnotateOptions& options);

// Reads the keyframes of the database at db_path, annotates them, and replaces its zones and
// memberships in one transaction. On error the database keeps its previous zones.
[[nodiscard]] Result<AnnotationReport> AnnotateDatabase(const std::string& db_path,
                                                        const ZoneSet& zones,
                                                        const AnnotateOptions& options);

}  // namespace zm
