// What a map database holds, keyframe by keyframe (`zonemap inspect`, issue 26): per keyframe its
// zones, its features and how many of them have a 3-D point (stored, or from the dense depth at
// the keypoint, as the run-time decodes it), its bytes on disk and in a slot, whether it carries
// images; the map's totals, camera and zones; the vocabulary's size or its absence. Each
// keyframe is read once through one arena slot (ScanKeyframes), so a map of any size is
// inspected in the memory of its largest keyframe.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "common/status.h"
#include "mapdb/map_db.h"

namespace zm {

struct KeyframeInspection {
  KeyframeId id;
  std::vector<ZoneId> zones;       // ascending; empty when in no zone
  std::uint32_t features = 0;
  std::uint32_t points3d = 0;      // features with a finite 3-D point
  std::uint32_t payload_bytes = 0;   // the blob on disk
  std::uint32_t resident_bytes = 0;  // in a slot once decoded
  bool has_colour = false;
  bool has_depth = false;
};

struct ZoneInspection {
  ZoneRecord zone;
  std::uint32_t keyframes = 0;
};

struct VocabularyInspection {
  std::uint32_t words = 0;
  std::uint32_t nodes = 0;
  std::uint32_t branching = 0;
  std::uint32_t depth = 0;
  std::uint32_t training_keyframes = 0;
  std::uint64_t memory_bytes = 0;  // Vocabulary::memory_bytes()
  std::uint64_t blob_bytes = 0;    // as stored
};

struct MapInspection {
  std::string path;
  int schema_version = 0;
  MapMetadata metadata;
  std::vector<KeyframeInspection> keyframes;  // by id
  std::vector<ZoneInspection> zones;          // by id
  std::optional<VocabularyInspection> vocabulary;
  // Totals over the keyframes.
  std::uint64_t features = 0;
  std::uint64_t points3d = 0;
  std::uint64_t payload_bytes = 0;
  std::uint64_t resident_bytes = 0;
  std::uint64_t keyframes_with_images = 0;  // colour and depth
  std::uint64_t keyframes_without_features = 0;
};

// Reads the map at `path` (read-only). A damaged keyframe or vocabulary is the reader's error.
[[nodiscard]] Result<MapInspection> InspectMap(const std::string& path);

}  // namespace zm
