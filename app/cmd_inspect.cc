// `zonemap inspect MAP.db [--json]`: what a map holds (lib/import/map_inspect.h): per keyframe its
// id, zones, features, features with a 3-D point, bytes on disk and in a slot, images; the map's
// totals, camera, zones and vocabulary. Read-only.
#include <cstdio>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>

#include "commands.h"
#include "import/map_inspect.h"
#include "report_json.h"

namespace zm::app {
namespace {

nlohmann::json ZoneIds(const KeyframeInspection& k) {
  nlohmann::json a = nlohmann::json::array();
  for (const ZoneId z : k.zones) a.push_back(z.value);
  return a;
}

nlohmann::json ToJson(const MapInspection& m) {
  const MapMetadata& md = m.metadata;
  nlohmann::json kfs = nlohmann::json::array();
  for (const KeyframeInspection& k : m.keyframes) {
    kfs.push_back({{"id", k.id.value},
                   {"zone", k.zones.empty() ? nlohmann::json(nullptr) : nlohmann::json(k.zones.front().value)},
                   {"zones", ZoneIds(k)},
                   {"features", k.features},
                   {"points3d", k.points3d},
                   {"payload_bytes", k.payload_bytes},
                   {"resident_bytes", k.resident_bytes},
                   {"has_colour", k.has_colour},
                   {"has_depth", k.has_depth}});
  }
  nlohmann::json zones = nlohmann::json::array();
  for (const ZoneInspection& z : m.zones) {
    zones.push_back({{"id", z.zone.id.value},
                     {"name", z.zone.name},
                     {"kind", z.zone.kind},
                     {"floor", z.zone.floor},
                     {"keyframes", z.keyframes}});
  }
  nlohmann::json vocabulary = nullptr;
  if (m.vocabulary) {
    const VocabularyInspection& v = *m.vocabulary;
    vocabulary = {{"words", v.words},
                  {"nodes", v.nodes},
                  {"branching", v.branching},
                  {"depth", v.depth},
                  {"training_keyframes", v.training_keyframes},
                  {"memory_bytes", v.memory_bytes},
                  {"blob_bytes", v.blob_bytes}};
  }
  const bool has_camera = md.camera.fx > 0 && md.camera.width > 0;
  return {{"map", m.path},
          {"schema_version", m.schema_version},
          {"source", md.source},
          {"page_bytes", md.page_bytes},
          {"camera", has_camera ? CameraJson(md.camera) : nlohmann::json(nullptr)},
          {"totals",
           {{"keyframes", m.keyframes.size()},
            {"links", md.link_count},
            {"zones", m.zones.size()},
            {"features", m.features},
            {"points3d", m.points3d},
            {"payload_bytes", m.payload_bytes},
            {"resident_bytes", m.resident_bytes},
            {"largest_resident_bytes", md.largest_payload_bytes},
            {"keyframes_with_images", m.keyframes_with_images},
            {"keyframes_without_features", m.keyframes_without_features}}},
          {"vocabulary", vocabulary},
          {"zones", zones},
          {"keyframes", kfs}};
}

void PrintText(const MapInspection& m) {
  const MapMetadata& md = m.metadata;
  std::printf("%s: schema version %d, source '%s'\n", m.path.c_str(), m.schema_version,
              md.source.c_str());
  std::printf("  %zu keyframes, %llu links, %zu zones; %llu features, %llu with a 3-D point; "
              "%zu keyframes with colour and depth, %llu without features\n",
              m.keyframes.size(), static_cast<unsigned long long>(md.link_count), m.zones.size(),
              static_cast<unsigned long long>(m.features),
              static_cast<unsigned long long>(m.points3d),
              static_cast<std::size_t>(m.keyframes_with_images),
              static_cast<unsigned long long>(m.keyframes_without_features));
  std::printf("  payloads %.2f MB on disk, %.2f MB resident, largest keyframe %u bytes in a slot\n",
              static_cast<double>(m.payload_bytes) / 1e6,
              static_cast<double>(m.resident_bytes) / 1e6, md.largest_payload_bytes);
  if (md.camera.fx > 0) {
    std::printf("  camera %ux%u fx=%.2f fy=%.2f cx=%.2f cy=%.2f\n", md.camera.width,
                md.camera.height, md.camera.fx, md.camera.fy, md.camera.cx, md.camera.cy);
  } else {
    std::printf("  camera: none\n");
  }
  if (m.vocabulary) {
    const VocabularyInspection& v = *m.vocabulary;
    std::printf("  vocabulary %u words, %u nodes (k %u, L %u), trained on %u keyframes, %.2f MB in "
                "memory\n",
                v.words, v.nodes, v.branching, v.depth, v.training_keyframes,
                static_cast<double>(v.memory_bytes) / 1e6);
  } else {
    std::printf("  vocabulary: none (train one with `zonemap vocab %s`)\n", m.path.c_str());
  }
  for (const ZoneInspection& z : m.zones) {
    std::printf("  zone %d %s (%s, floor %d): %u keyframes\n", z.zone.id.value,
                z.zone.name.c_str(), z.zone.kind.c_str(), z.zone.floor, z.keyframes);
  }
  std::printf("  %10s %8s %8s %8s %10s %10s %6s\n", "keyframe", "zone", "features", "points3d",
              "disk_B", "slot_B", "images");
  for (const KeyframeInspection& k : m.keyframes) {
    const std::string zone = k.zones.empty() ? "-" : std::to_string(k.zones.front().value) +
                                                         (k.zones.size() > 1 ? "+" : "");
    std::printf("  %10lld %8s %8u %8u %10u %10u %6s\n", static_cast<long long>(k.id.value),
                zone.c_str(), k.features, k.points3d, k.payload_bytes, k.resident_bytes,
                k.has_colour && k.has_depth ? "rgb-d" : (k.has_colour ? "rgb" : (k.has_depth ? "d" : "-")));
  }
}

}  // namespace

void AddInspectCommand(CLI::App& app, CommandContext& ctx) {
  struct Opts {
    std::string map;
    bool json = false;
  };
  auto opts = std::make_shared<Opts>();
  auto* cmd = app.add_subcommand(
      "inspect", "Show what a map holds: per keyframe its features and 3-D points, the vocabulary");
  cmd->add_option("MAP", opts->map, "zonemap map database (read only)")
      ->required()
      ->check(CLI::ExistingFile);
  cmd->add_flag("--json", opts->json, "print one JSON object");
  cmd->callback([opts, &ctx] {
    auto m = InspectMap(opts->map);
    if (!m.ok()) {
      ctx.Fail("inspect", m.status());
      return;
    }
    if (opts->json) {
      std::printf("%s\n", ToJson(*m).dump(2).c_str());
    } else {
      PrintText(*m);
    }
  });
}

}  // namespace zm::app
