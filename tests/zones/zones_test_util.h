// Helpers for the zones tests: rectangles, zone sets built in code, keyframes at positions.
#pragma once

#include <doctest/doctest.h>

#include <string>
#include <vector>

#include "mapdb/map_db.h"
#include "zones/zone_set.h"

namespace zm::test {

inline std::vector<Eigen::Vector2d> Rect(double x0, double y0, double x1, double y1) {
  return {{x0, y0}, {x1, y0}, {x1, y1}, {x0, y1}};
}

// "r7": built by append, since GCC 12's -Wrestrict misfires on `"r" + std::to_string(i)` at -O3.
inline std::string Numbered(const char* prefix, int i) {
  std::string s = prefix;
  s += std::to_string(i);
  return s;
}

inline Zone MakeZone(std::string name, std::vector<Eigen::Vector2d> polygon, int floor = 0,
                     double z_min = -kUnboundedZM, double z_max = kUnboundedZM) {
  Zone z;
  z.name = std::move(name);
  z.polygon = std::move(polygon);
  z.floor = floor;
  z.z_min_m = z_min;
  z.z_max_m = z_max;
  return z;
}

inline ZoneSet MakeSet(std::vector<Zone> zones) {
  ZoneSet set;
  for (auto& z : zones) {
    const Status st = set.Add(std::move(z));
    REQUIRE_MESSAGE(st.ok(), st.ToString());
  }
  return set;
}

inline KeyframeMeta KeyframeAt(std::int64_t id, double x, double y, double z = 0.0) {
  KeyframeMeta k;
  k.id = KeyframeId{id};
  k.pose = PoseFromXYYaw(x, y, 0.0, z);
  return k;
}

// A GeoJSON FeatureCollection with one Polygon feature per (name, ring) pair; ring given as
// JSON text of the outer ring, e.g. "[[0,0],[1,0],[1,1],[0,0]]".
inline std::string FeatureCollection(const std::vector<std::pair<std::string, std::string>>& f,
                                     const std::string& extra_props = "") {
  std::string s = R"({"type":"FeatureCollection","features":[)";
  for (std::size_t i = 0; i < f.size(); ++i) {
    if (i) s += ",";
    s += R"({"type":"Feature","properties":{"name":")" + f[i].first + "\"" + extra_props +
         R"(},"geometry":{"type":"Polygon","coordinates":[)" + f[i].second + "]}}";
  }
  return s + "]}";
}

}  // namespace zm::test
