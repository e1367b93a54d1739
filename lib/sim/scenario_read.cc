// Reading a written scenario back: scenario.json (LoadScenario) and route.json (LoadRoute), for
// the harness, the bench and the tools. The writer is scenario.cc; the formats are docs/sim.md's.
#include <cstdint>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>

#include "sim/scenario.h"

namespace zm::sim {

namespace {

Result<nlohmann::json> ReadJson(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return NotFound("cannot open " + path);
  try {
    return nlohmann::json::parse(in);
  } catch (const nlohmann::json::exception& e) {
    return InvalidArgument(path + " is not valid JSON: " + e.what());
  }
}

}  // namespace

Result<ScenarioInfo> LoadScenario(const std::string& dir) {
  const std::string path = dir + "/scenario.json";
  ZM_ASSIGN_OR_RETURN(nlohmann::json j, ReadJson(path));
  try {
    if (j.value("format", "") != "zonemap scenario")
      return InvalidArgument(path + " is not a zonemap scenario file");
    if (j.value("version", 0) != 1) {
      return FailedPrecondition(path + " has version " + std::to_string(j.value("version", 0)) +
                                ", expected 1");
    }
    ScenarioInfo s;
    s.dir = dir;
    s.kind = j.at("kind").get<std::string>();
    s.seed = j.at("seed").get<std::uint64_t>();
    s.floors = j.at("floors").get<int>();
    s.area_m2 = j.at("area_m2").get<double>();
    const auto& c = j.at("counts");
    s.keyframes = c.at("keyframes").get<std::uint64_t>();
    s.frames = c.at("frames").get<std::uint64_t>();
    s.zones = c.at("zones").get<std::uint64_t>();
    s.rate_hz = j.at("localization").at("rate_hz").get<double>();
    const auto& cam = j.at("camera");
    s.camera.fx = cam.at("fx").get<double>();
    s.camera.fy = cam.at("fy").get<double>();
    s.camera.cx = cam.at("cx").get<double>();
    s.camera.cy = cam.at("cy").get<double>();
    s.camera.width = cam.at("width").get<std::uint32_t>();
    s.camera.height = cam.at("height").get<std::uint32_t>();
    s.keyframe_bytes_max = j.at("keyframe_bytes").at("max").get<std::uint32_t>();
    if (j.contains("dense") && j.at("dense").contains("footprint_scale")) {
      s.footprint_scale = j.at("dense").at("footprint_scale").get<double>();
    }
    // Scenarios from before dense keyframes have no resident section: resident = on disk.
    s.resident_bytes_max = j.contains("resident_bytes")
                               ? j.at("resident_bytes").at("max").get<std::uint32_t>()
                               : s.keyframe_bytes_max;
    if (j.contains("features")) s.features = j.at("features").value("source", "oracle");
    const auto& f = j.at("files");
    const auto file = [&](const char* key) { return dir + "/" + f.at(key).get<std::string>(); };
    s.map_db = file("map_db");
    s.zones_geojson = file("zones");
    s.frames_bin = file("frames");
    s.mapping_gt = file("mapping_gt");
    s.localization_gt = file("localization_gt");
    s.route_json = file("route");
    s.map_yaml = file("map_yaml");
    return s;
  } catch (const nlohmann::json::exception& e) {
    return InvalidArgument(path + ": missing or mistyped field: " + e.what());
  }
}

Result<Route> LoadRoute(const std::string& path) {
  ZM_ASSIGN_OR_RETURN(nlohmann::json j, ReadJson(path));
  try {
    if (j.value("format", "") != "zonemap route")
      return InvalidArgument(path + " is not a zonemap route file");
    Route r;
    for (const auto& t : j.at("tasks")) {
      r.tasks.push_back({t.at("goal_zone").get<std::string>(),
                         t.at("start_frame").get<std::uint64_t>(),
                         t.at("end_frame").get<std::uint64_t>()});
    }
    for (const auto& z : j.at("zones")) {
      r.zones.push_back({z.at("zone").get<std::string>(), z.at("first_frame").get<std::uint64_t>(),
                         z.at("last_frame").get<std::uint64_t>()});
    }
    return r;
  } catch (const nlohmann::json::exception& e) {
    return InvalidArgument(path + ": missing or mistyped field: " + e.what());
  }
}

}  // namespace zm::sim
