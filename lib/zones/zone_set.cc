// Zone files (see zone_set.h): parsing GeoJSON and the paper's keyframe lists with one clear
// error per bad input (file, feature index, what is wrong), writing GeoJSON, and the
// conversions to the database's ZoneRecord. nlohmann::json exceptions stop at this adapter.
#include "zones/zone_set.h"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <nlohmann/json.hpp>
#include <set>
#include <sstream>

#include "zones/polygon.h"

namespace zm {
namespace {

// ordered_json keeps the file's key order, so keyframe-list zone ids follow the file.
using json = nlohmann::ordered_json;

std::string Where(std::string_view source, std::size_t feature, std::string_view name = {}) {
  std::string s(source);
  s += ": feature " + std::to_string(feature);
  if (!name.empty()) s += " (\"" + std::string(name) + "\")";
  return s;
}

// Parses JSON and refuses duplicate keys in any object (nlohmann would silently keep the last,
// dropping a zone of the keyframe-list format).
Result<json> ParseStrict(std::string_view text, std::string_view source) {
  std::vector<std::set<std::string>> keys;
  std::string duplicate;
  json::parser_callback_t cb = [&](int /*depth*/, json::parse_event_t event, json& parsed) {
    switch (event) {
      case json::parse_event_t::object_start:
        keys.emplace_back();
        break;
      case json::parse_event_t::object_end:
        if (!keys.empty()) keys.pop_back();
        break;
      case json::parse_event_t::key:
        if (!keys.empty() && parsed.is_string() &&
            !keys.back().insert(parsed.get<std::string>()).second && duplicate.empty()) {
          duplicate = parsed.get<std::string>();
        }
        break;
      default:
        break;
    }
    return true;
  };
  try {
    json j = json::parse(text.begin(), text.end(), cb);
    if (!duplicate.empty()) {
      return InvalidArgument(std::string(source) + ": duplicate key \"" + duplicate +
                             "\" in one JSON object (zone names must be unique)");
    }
    return j;
  } catch (const json::exception& e) {
    return InvalidArgument(std::string(source) + ": not valid JSON: " + e.what());
  }
}

Result<std::vector<Eigen::Vector2d>> ParseRing(const json& ring, const std::string& where) {
  if (!ring.is_array()) return InvalidArgument(where + ": the outer ring is not an array");
  std::vector<Eigen::Vector2d> pts;
  pts.reserve(ring.size());
  for (std::size_t i = 0; i < ring.size(); ++i) {
    const json& pos = ring[i];
    if (!pos.is_array() || pos.size() < 2) {
      return InvalidArgument(where + ": position " + std::to_string(i) +
                             " of the outer ring is not an [x, y] array");
    }
    if (!pos[0].is_number() || !pos[1].is_number()) {
      return InvalidArgument(where + ": position " + std::to_string(i) +
                             " of the outer ring has a non-numeric coordinate");
    }
    const Eigen::Vector2d p(pos[0].get<double>(), pos[1].get<double>());
    if (!std::isfinite(p.x()) || !std::isfinite(p.y())) {
      return InvalidArgument(where + ": position " + std::to_string(i) +
                             " of the outer ring is not finite");
    }
    pts.push_back(p);
  }
  if (pts.size() < 4) {
    return InvalidArgument(where + ": the outer ring has " + std::to_string(pts.size()) +
                           " positions; a closed ring needs at least 4 (first repeated last)");
  }
  if (pts.front() != pts.back()) {
    return InvalidArgument(where +
                           ": the outer ring is not closed (its last position differs "
                           "from its first)");
  }
  pts.pop_back();
  // Repeated consecutive positions are legal GeoJSON; drop them.
  std::vector<Eigen::Vector2d> out;
  out.reserve(pts.size());
  for (const auto& p : pts) {
    if (out.empty() || out.back() != p) out.push_back(p);
  }
  while (out.size() > 1 && out.front() == out.back()) out.pop_back();
  return out;
}

Result<ZoneSet> ParseGeoJson(const json& root, std::string_view source) {
  const std::string src(source);
  if (!root.contains("features") || !root["features"].is_array()) {
    return InvalidArgument(src + ": a FeatureCollection needs a \"features\" array");
  }
  double floor_height = kDefaultFloorHeightM;
  if (root.contains("floor_height_m")) {
    if (!root["floor_height_m"].is_number() || !(root["floor_height_m"].get<double>() > 0.0)) {
      return InvalidArgument(src + ": \"floor_height_m\" must be a positive number");
    }
    floor_height = root["floor_height_m"].get<double>();
  }
  const json& features = root["features"];
  if (features.empty()) return InvalidArgument(src + ": the FeatureCollection has no features");
  ZoneSet set;
  for (std::size_t i = 0; i < features.size(); ++i) {
    const json& f = features[i];
    std::string where = Where(source, i);
    if (!f.is_object()) return InvalidArgument(where + ": not a JSON object");
    const json props =
        f.contains("properties") && f["properties"].is_object() ? f["properties"] : json::object();
    Zone zone;
    if (!props.contains("name") || !props["name"].is_string() ||
        props["name"].get<std::string>().empty()) {
      return InvalidArgument(where + ": needs a non-empty string property \"name\"");
    }
    zone.name = props["name"].get<std::string>();
    where = Where(source, i, zone.name);
    if (props.contains("kind")) {
      if (!props["kind"].is_string()) return InvalidArgument(where + ": \"kind\" must be a string");
      zone.kind = props["kind"].get<std::string>();
    }
    const bool has_floor = props.contains("floor");
    if (has_floor) {
      if (!props["floor"].is_number_integer()) {
        return InvalidArgument(where + ": \"floor\" must be an integer");
      }
      zone.floor = props["floor"].get<int>();
      const ZRange band = FloorZRange(zone.floor, floor_height);
      zone.z_min_m = band.min_m;
      zone.z_max_m = band.max_m;
    }
    for (const char* key : {"z_min", "z_max"}) {
      if (!props.contains(key)) continue;
      const bool is_min = std::string_view(key) == "z_min";
      if (props[key].is_null()) {  // explicitly unbounded (how WriteGeoJson says "every z")
        (is_min ? zone.z_min_m : zone.z_max_m) = is_min ? -kUnboundedZM : kUnboundedZM;
        continue;
      }
      if (!props[key].is_number()) {
        return InvalidArgument(where + ": \"" + key + "\" must be a number (metres)");
      }
      (is_min ? zone.z_min_m : zone.z_max_m) = props[key].get<double>();
    }
    if (!f.contains("geometry") || !f["geometry"].is_object()) {
      return InvalidArgument(where + ": has no geometry object");
    }
    const json& g = f["geometry"];
    if (!g.contains("type") || g["type"] != "Polygon") {
      return InvalidArgument(where + ": geometry must be a Polygon (got " +
                             (g.contains("type") ? g["type"].dump() : std::string("none")) + ")");
    }
    if (!g.contains("coordinates") || !g["coordinates"].is_array() || g["coordinates"].empty()) {
      return InvalidArgument(where + ": the Polygon has no coordinates");
    }
    if (g["coordinates"].size() > 1) {
      return InvalidArgument(where + ": polygons with holes are not supported (" +
                             std::to_string(g["coordinates"].size() - 1) +
                             " inner rings); split the zone instead");
    }
    ZM_ASSIGN_OR_RETURN(zone.polygon, ParseRing(g["coordinates"][0], where));
    ZM_RETURN_IF_ERROR(set.Add(std::move(zone), {}, where));
  }
  return set;
}

Result<ZoneSet> ParseKeyframeLists(const json& root, std::string_view source) {
  const std::string src(source);
  const json& zones = root["zones"];
  if (!zones.is_object()) return InvalidArgument(src + ": \"zones\" must be an object");
  if (zones.empty()) return InvalidArgument(src + ": \"zones\" is empty");
  ZoneSet set;
  std::size_t i = 0;
  for (auto it = zones.begin(); it != zones.end(); ++it, ++i) {
    const std::string where = Where(source, i, it.key());
    if (!it.value().is_array()) {
      return InvalidArgument(where + ": the zone's value must be an array of keyframe ids");
    }
    std::vector<KeyframeId> ids;
    ids.reserve(it.value().size());
    for (std::size_t k = 0; k < it.value().size(); ++k) {
      const json& v = it.value()[k];
      if (!v.is_number_integer()) {
        return InvalidArgument(where + ": entry " + std::to_string(k) +
                               " is not an integer keyframe id");
      }
      ids.push_back(KeyframeId{v.get<std::int64_t>()});
    }
    Zone zone;
    zone.name = it.key();
    zone.kind = "zone";
    ZM_RETURN_IF_ERROR(set.Add(std::move(zone), std::move(ids), where));
  }
  if (root.contains("initial_zone")) {
    if (!root["initial_zone"].is_string()) {
      return InvalidArgument(src + ": \"initial_zone\" must be a zone name");
    }
    ZM_RETURN_IF_ERROR(set.SetInitialZone(root["initial_zone"].get<std::string>()).Annotate(src));
  }
  return set;
}

}  // namespace

double Zone::AreaM2() const { return polygon.empty() ? 0.0 : std::abs(SignedArea(polygon)); }

Status ZoneSet::Add(Zone zone, std::vector<KeyframeId> keyframes, std::string_view where) {
  const std::string w = where.empty() ? "zone \"" + zone.name + "\"" : std::string(where);
  if (zone.name.empty()) return InvalidArgument(w + ": zone name is empty");
  if (Find(zone.name) != kNoZone) {
    return InvalidArgument(w + ": duplicate zone name \"" + zone.name + "\" (first used by zone " +
                           std::to_string(Find(zone.name).value) + ")");
  }
  if (!(zone.z_min_m < zone.z_max_m)) {
    return InvalidArgument(w + ": empty z range [" + std::to_string(zone.z_min_m) + ", " +
                           std::to_string(zone.z_max_m) + ")");
  }
  const bool is_list = zone.polygon.empty();
  if (!zones_.empty() && is_list != has_lists_) {
    return InvalidArgument(w + ": a zone set cannot mix polygon zones and keyframe-list zones");
  }
  if (!is_list) {
    if (!keyframes.empty()) return InvalidArgument(w + ": a polygon zone takes no keyframe list");
    if (zone.polygon.size() < 3) {
      return InvalidArgument(w + ": the polygon has " + std::to_string(zone.polygon.size()) +
                             " distinct vertices; at least 3 are needed");
    }
    if (auto hit = FindSelfIntersection(zone.polygon)) {
      return InvalidArgument(w + ": the polygon intersects itself (edges " +
                             std::to_string(hit->first) + " and " + std::to_string(hit->second) +
                             ")");
    }
    if (std::abs(SignedArea(zone.polygon)) <= 1e-9) {
      return InvalidArgument(w + ": the polygon has zero area");
    }
  }
  std::sort(keyframes.begin(), keyframes.end());
  keyframes.erase(std::unique(keyframes.begin(), keyframes.end()), keyframes.end());
  if (zones_.size() >= static_cast<std::size_t>(INT32_MAX)) {
    return OutOfRange(w + ": more than 2^31-1 zones");
  }
  zone.id = ZoneId{static_cast<std::int32_t>(zones_.size())};
  has_lists_ = is_list;
  by_name_.emplace(zone.name, zone.id);
  zones_.push_back(std::move(zone));
  lists_.push_back(std::move(keyframes));
  return Status::Ok();
}

ZoneId ZoneSet::Find(std::string_view name) const {
  const auto it = by_name_.find(std::string(name));
  return it == by_name_.end() ? kNoZone : it->second;
}

Status ZoneSet::SetInitialZone(std::string_view name) {
  const ZoneId id = Find(name);
  if (id == kNoZone) {
    return NotFound("initial_zone \"" + std::string(name) + "\" is not one of the " +
                    std::to_string(zones_.size()) + " zones");
  }
  initial_zone_ = id;
  return Status::Ok();
}

Result<ZoneSet> ParseZoneJson(std::string_view text, std::string_view source_name) {
  const std::string src(source_name);
  if (text.find_first_not_of(" \t\r\n") == std::string_view::npos) {
    return InvalidArgument(src +
                           ": empty file (expected a GeoJSON FeatureCollection or a "
                           "{\"zones\": {...}} keyframe-list object)");
  }
  ZM_ASSIGN_OR_RETURN(json root, ParseStrict(text, source_name));
  if (!root.is_object()) return InvalidArgument(src + ": the top level is not a JSON object");
  if (root.contains("type")) {
    if (root["type"] != "FeatureCollection") {
      return InvalidArgument(src + ": GeoJSON type " + root["type"].dump() +
                             " is not supported; expected a FeatureCollection");
    }
    ZM_ASSIGN_OR_RETURN(ZoneSet set, ParseGeoJson(root, source_name));
    set.set_source(src);
    return set;
  }
  if (root.contains("zones")) {
    ZM_ASSIGN_OR_RETURN(ZoneSet set, ParseKeyframeLists(root, source_name));
    set.set_source(src);
    return set;
  }
  return InvalidArgument(src +
                         ": neither a GeoJSON FeatureCollection nor a keyframe-list "
                         "object with \"zones\"");
}

Result<ZoneSet> LoadZoneFile(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return NotFound(path + ": cannot open zone file");
  std::ostringstream ss;
  ss << in.rdbuf();
  if (in.bad()) return IoError(path + ": read failed");
  return ParseZoneJson(ss.str(), path);
}

ZRange FloorZRange(int floor, double floor_height_m) {
  return {(floor - 0.5) * floor_height_m, (floor + 0.5) * floor_height_m};
}

std::string ZonesToGeoJson(std::span<const Zone> zones) {
  json features = json::array();
  for (const Zone& z : zones) {
    json ring = json::array();
    for (const auto& p : z.polygon) ring.push_back({p.x(), p.y()});
    if (!z.polygon.empty()) ring.push_back({z.polygon[0].x(), z.polygon[0].y()});
    json props = {{"name", z.name}, {"kind", z.kind}, {"floor", z.floor}};
    // Always explicit, so reading back does not derive a range from the floor.
    props["z_min"] = z.z_min_m > -kUnboundedZM ? json(z.z_min_m) : json(nullptr);
    props["z_max"] = z.z_max_m < kUnboundedZM ? json(z.z_max_m) : json(nullptr);
    features.push_back({{"type", "Feature"},
                        {"properties", props},
                        {"geometry", {{"type", "Polygon"}, {"coordinates", json::array({ring})}}}});
  }
  json root = {{"type", "FeatureCollection"}, {"features", features}};
  return root.dump(1) + "\n";
}

std::string ToGeoJsonText(const ZoneSet& zones) { return ZonesToGeoJson(zones.zones()); }

Status WriteGeoJson(const ZoneSet& zones, const std::string& path) {
  if (zones.has_keyframe_lists()) {
    return InvalidArgument(path + ": keyframe-list zones have no polygons to write as GeoJSON");
  }
  return WriteZonesGeoJson(zones.zones(), path);
}

Status WriteZonesGeoJson(std::span<const Zone> zones, const std::string& path) {
  for (const Zone& z : zones) {
    if (z.polygon.empty()) {
      return InvalidArgument(path + ": zone \"" + z.name + "\" has no polygon to write as GeoJSON");
    }
  }
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  if (!out) return IoError(path + ": cannot open for writing");
  out << ZonesToGeoJson(zones);
  out.close();
  if (!out) return IoError(path + ": write failed");
  return Status::Ok();
}

ZoneRecord ToZoneRecord(const Zone& zone) {
  ZoneRecord r;
  r.id = zone.id;
  r.name = zone.name;
  r.kind = zone.kind;
  r.floor = zone.floor;
  r.z_min_m = zone.z_min_m;
  r.z_max_m = zone.z_max_m;
  r.polygon.reserve(zone.polygon.size());
  for (const auto& p : zone.polygon) r.polygon.push_back({p.x(), p.y()});
  return r;
}

std::vector<ZoneRecord> ToZoneRecords(const ZoneSet& zones) {
  std::vector<ZoneRecord> out;
  out.reserve(zones.size());
  for (const Zone& z : zones.zones()) out.push_back(ToZoneRecord(z));
  return out;
}

Result<ZoneSet> ZoneSetFromRecords(std::span<const ZoneRecord> records,
                                   std::span<const ZoneMember> members) {
  std::vector<std::vector<KeyframeId>> lists(records.size());
  for (const ZoneMember& m : members) {
    if (m.zone.value < 0 || static_cast<std::size_t>(m.zone.value) >= records.size()) {
      return Corrupt("zone member of keyframe " + std::to_string(m.keyframe.value) +
                     " names zone " + std::to_string(m.zone.value) + " of " +
                     std::to_string(records.size()));
    }
    lists[static_cast<std::size_t>(m.zone.value)].push_back(m.keyframe);
  }
  ZoneSet set;
  for (std::size_t i = 0; i < records.size(); ++i) {
    const ZoneRecord& r = records[i];
    const std::string where = "database zone " + std::to_string(i) + " (\"" + r.name + "\")";
    if (r.id.value != static_cast<std::int32_t>(i)) {
      return Corrupt(where + ": has id " + std::to_string(r.id.value) + "; ids must be dense");
    }
    Zone z;
    z.name = r.name;
    z.kind = r.kind;
    z.floor = r.floor;
    z.z_min_m = r.z_min_m;
    z.z_max_m = r.z_max_m;
    z.polygon.reserve(r.polygon.size());
    for (const auto& p : r.polygon) z.polygon.emplace_back(p[0], p[1]);
    std::vector<KeyframeId> list;
    if (z.polygon.empty()) list = std::move(lists[i]);
    ZM_RETURN_IF_ERROR(set.Add(std::move(z), std::move(list), where));
  }
  return set;
}

}  // namespace zm
