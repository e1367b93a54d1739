// Keyframe membership (see annotate.h): containment, doorway band and nearest-zone fallback
// through the ZoneIndex's grid, then the optional oversize split, then one database write.
#include "zones/annotate.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <unordered_set>

#include "zones/polygon.h"
#include "zones/zone_index.h"

namespace zm {
namespace {

std::string SourceName(const ZoneSet& zones) {
  return zones.source().empty() ? std::string("zone set") : zones.source();
}

Status AnnotateLists(const ZoneSet& zones, std::span<const KeyframeMeta> keyframes,
                     AnnotationReport& report) {
  std::unordered_set<KeyframeId> present;
  present.reserve(keyframes.size());
  for (const KeyframeMeta& k : keyframes) present.insert(k.id);
  std::unordered_set<KeyframeId> listed;
  for (const Zone& z : zones.zones()) {
    for (KeyframeId k : zones.keyframes(z.id)) {
      if (!present.contains(k)) {
        return NotFound(SourceName(zones) + ": feature " + std::to_string(z.id.value) + " (\"" +
                        z.name + "\"): keyframe id " + std::to_string(k.value) +
                        " does not exist in the map (" + std::to_string(keyframes.size()) +
                        " keyframes)");
      }
      report.members.push_back({z.id, k});
      listed.insert(k);
    }
  }
  report.inside = listed.size();
  report.unassigned = keyframes.size() - listed.size();
  return Status::Ok();
}

// The nearest polygon zone to p: first among zones on p's floor, searched in growing radii
// through the grid; then, if its floor has none, among all zones.
ZoneId Nearest(const ZoneSet& zones, const ZoneIndex& index, const Eigen::Vector3d& p) {
  const Eigen::Vector2d xy = p.head<2>();
  ZoneId best = kNoZone;
  double best_d = std::numeric_limits<double>::infinity();
  for (double r = 1.0; r <= 1e5; r *= 2.0) {
    index.ForEachCandidateNear(p, r, [&](ZoneId z) {
      const double d = DistanceToBoundary(zones.zone(z).polygon, xy);
      if (d < best_d || (d == best_d && z < best)) {
        best_d = d;
        best = z;
      }
    });
    // Every zone closer than best_d has its bounding box within best_d, so it was a candidate.
    if (best != kNoZone && best_d <= r) return best;
  }
  for (const Zone& z : zones.zones()) {
    const double d = DistanceToBoundary(z.polygon, xy);
    if (d < best_d) {
      best_d = d;
      best = z.id;
    }
  }
  return best;
}

Status AnnotatePolygons(const ZoneSet& zones, std::span<const KeyframeMeta> keyframes,
                        double band_m, AnnotationReport& report) {
  const ZoneIndex index(zones);
  std::vector<ZoneId> joined;
  for (const KeyframeMeta& k : keyframes) {
    const Eigen::Vector3d p = k.pose.translation();
    if (!p.allFinite()) {
      return InvalidArgument("keyframe " + std::to_string(k.id.value) + " has a non-finite pose");
    }
    joined.clear();
    bool inside = false;
    index.ForEachCandidateNear(p, band_m, [&](ZoneId z) {
      const auto& ring = zones.zone(z).polygon;
      if (PointInPolygon(ring, p.head<2>())) {
        inside = true;
        joined.push_back(z);
      } else if (DistanceToBoundary(ring, p.head<2>()) <= band_m) {
        ++report.band_memberships;
        joined.push_back(z);
      }
    });
    if (inside) ++report.inside;
    if (joined.empty()) {
      joined.push_back(Nearest(zones, index, p));
      ++report.nearest;
    }
    for (ZoneId z : joined) report.members.push_back({z, k.id});
  }
  return Status::Ok();
}

}  // namespace

Result<AnnotationReport> AnnotateKeyframes(const ZoneSet& zones,
                                           std::span<const KeyframeMeta> keyframes,
                                           const AnnotateOptions& options) {
  if (zones.empty()) return InvalidArgument(SourceName(zones) + ": no zones to annotate with");
  if (!(options.band_m >= 0.0) || !std::isfinite(options.band_m)) {
    return InvalidArgument("annotate: band must be a finite distance >= 0 m");
  }
  AnnotationReport report;
  report.keyframes = keyframes.size();
  if (zones.has_keyframe_lists()) {
    ZM_RETURN_IF_ERROR(AnnotateLists(zones, keyframes, report));
  } else {
    ZM_RETURN_IF_ERROR(AnnotatePolygons(zones, keyframes, options.band_m, report));
  }
  std::sort(report.members.begin(), report.members.end(), [](const ZoneMember& a, const ZoneMember& b) {
    return a.zone != b.zone ? a.zone < b.zone : a.keyframe < b.keyframe;
  });
  report.zones = zones;
  if (options.max_zone_keyframes > 0) {
    ZM_ASSIGN_OR_RETURN(SplitResult split, SplitOversizeZones(zones, report.members, keyframes,
                                                              options.max_zone_keyframes));
    report.zones = std::move(split.zones);
    report.members = std::move(split.members);
    report.split = std::move(split.report);
  }
  report.counts.assign(report.zones.size(), 0);
  for (const ZoneMember& m : report.members) ++report.counts[static_cast<std::size_t>(m.zone.value)];
  if (options.warn_zone_keyframes > 0) {
    for (std::size_t i = 0; i < report.counts.size(); ++i) {
      if (report.counts[i] > options.warn_zone_keyframes) {
        report.over_budget.push_back(ZoneId{static_cast<std::int32_t>(i)});
      }
    }
  }
  return report;
}

Result<AnnotationReport> AnnotateDatabase(const std::string& db_path, const ZoneSet& zones,
                                          const AnnotateOptions& options) {
  ZM_ASSIGN_OR_RETURN(auto writer, MapDbWriter::OpenExisting(db_path));
  ZM_ASSIGN_OR_RETURN(std::vector<KeyframeMeta> keyframes, writer->Keyframes());
  if (keyframes.empty()) return FailedPrecondition(db_path + ": the map has no keyframes");
  ZM_ASSIGN_OR_RETURN(AnnotationReport report, AnnotateKeyframes(zones, keyframes, options));
  const std::vector<ZoneRecord> records = ToZoneRecords(report.zones);
  ZM_RETURN_IF_ERROR(writer->ReplaceZones(records, report.members).Annotate(db_path));
  ZM_RETURN_IF_ERROR(writer->Finish().Annotate(db_path));
  return report;
}

}  // namespace zm
