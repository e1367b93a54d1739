#include "import/map_inspect.h"

#include <algorithm>
#include <memory>
#include <unordered_map>

#include "localization/map_vocabulary.h"
#include "mapdb/map_scan.h"

namespace zm {

Result<MapInspection> InspectMap(const std::string& path) {
  ZM_ASSIGN_OR_RETURN(std::unique_ptr<MapDb> map, MapDb::Open(path));
  MapInspection out;
  out.path = path;
  out.schema_version = map->schema_version();
  out.metadata = map->metadata();
  ZM_ASSIGN_OR_RETURN(std::vector<ZoneRecord> zones, map->Zones());
  ZM_ASSIGN_OR_RETURN(std::vector<ZoneMember> members, map->ZoneMembers());
  std::unordered_map<std::int64_t, std::vector<ZoneId>> zones_of;
  out.zones.reserve(zones.size());
  for (ZoneRecord& z : zones) out.zones.push_back(ZoneInspection{std::move(z), 0});
  for (const ZoneMember& m : members) {
    zones_of[m.keyframe.value].push_back(m.zone);
    if (m.zone.value >= 0 && static_cast<std::size_t>(m.zone.value) < out.zones.size()) {
      ++out.zones[static_cast<std::size_t>(m.zone.value)].keyframes;
    }
  }
  ZM_ASSIGN_OR_RETURN(std::vector<KeyframeMeta> keyframes, map->Keyframes());
  out.keyframes.reserve(keyframes.size());
  ZM_RETURN_IF_ERROR(ScanKeyframes(*map, keyframes, [&](const KeyframeMeta& meta,
                                                        const KeyframeView& view) {
    const KeyframeContent c = CountKeyframeContent(view);
    KeyframeInspection k;
    k.id = meta.id;
    if (auto it = zones_of.find(meta.id.value); it != zones_of.end()) {
      k.zones = it->second;
      std::sort(k.zones.begin(), k.zones.end(),
                [](ZoneId a, ZoneId b) { return a.value < b.value; });
    }
    k.features = c.features;
    k.points3d = c.points3d;
    k.payload_bytes = view.total_bytes;
    k.resident_bytes = meta.payload_bytes;
    k.has_colour = c.has_colour;
    k.has_depth = c.has_depth;
    out.features += k.features;
    out.points3d += k.points3d;
    out.payload_bytes += k.payload_bytes;
    out.resident_bytes += k.resident_bytes;
    if (k.has_colour && k.has_depth) ++out.keyframes_with_images;
    if (k.features == 0) ++out.keyframes_without_features;
    out.keyframes.push_back(std::move(k));
    return Status::Ok();
  }));
  ZM_ASSIGN_OR_RETURN(std::optional<std::vector<std::byte>> blob, map->VocabularyBlob());
  if (blob) {
    ZM_ASSIGN_OR_RETURN(const Vocabulary vocabulary, ParseMapVocabulary(*blob, path));
    VocabularyInspection v;
    v.words = vocabulary.word_count();
    v.nodes = vocabulary.node_count();
    v.branching = vocabulary.branching();
    v.depth = vocabulary.depth();
    v.training_keyframes = vocabulary.training_keyframes();
    v.memory_bytes = vocabulary.memory_bytes();
    v.blob_bytes = blob->size();
    out.vocabulary = v;
  }
  return out;
}

}  // namespace zm
