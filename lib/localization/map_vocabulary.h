// A map's visual vocabulary (issue 26): trained from the map's own keyframes, stored in its
// database (schema version 2, MapDbWriter::SetVocabulary), loaded and validated once at start.
//
// Training takes, of every keyframe (or of `max_keyframes` spread evenly over the id order), the
// first `word_features` descriptors: the extractor orders a keyframe's features strongest first,
// so these are the bag-of-words subset (RTAB-Map's Kp/MaxFeatures) -- the same subset the loop
// quantizes. The IDF is then over the training keyframes (vocabulary.h).
//
// lib/mapdb stores the bytes and knows nothing of their meaning; the validation is
// Vocabulary::FromBlob, here, so a damaged blob is one kCorrupt line naming the map.
#pragma once

#include <cstdint>
#include <optional>
#include <string>

#include "common/status.h"
#include "localization/vocabulary.h"
#include "mapdb/map_db.h"

namespace zm {

struct MapVocabularyOptions {
  VocabularyOptions vocabulary;        // k, L, iterations, seed
  std::uint32_t word_features = 500;   // per keyframe: the strongest (OrbOptions::word_features)
  std::uint32_t max_keyframes = 0;     // training sample, spread over the map; 0 = every keyframe
};

// Checks the ranges (word_features in [1, kMaxFeaturesPerKeyframe], the vocabulary's options).
[[nodiscard]] Status ValidateMapVocabularyOptions(const MapVocabularyOptions& options);

struct MapVocabularyReport {
  std::uint32_t words = 0;
  std::uint32_t nodes = 0;
  std::uint64_t memory_bytes = 0;          // Vocabulary::memory_bytes()
  std::uint64_t blob_bytes = 0;            // as stored
  std::uint32_t map_keyframes = 0;
  std::uint32_t training_keyframes = 0;    // keyframes sampled (with or without features)
  std::uint32_t keyframes_without_features = 0;
  std::uint64_t training_descriptors = 0;
  double read_ms = 0.0;                    // reading the keyframes
  double train_ms = 0.0;                   // Vocabulary::Train
};

struct TrainedMapVocabulary {
  Vocabulary vocabulary;
  MapVocabularyReport report;
};

// Trains a vocabulary from `map`'s keyframes (read with ScanKeyframes). FailedPrecondition
// when the sampled keyframes hold no descriptor at all.
[[nodiscard]] Result<TrainedMapVocabulary> TrainMapVocabulary(MapDb& map,
                                                              const MapVocabularyOptions& options);

// Trains from the map at `path` and stores the vocabulary in it (replacing any), then checks
// that what the file now holds reads back as the same bytes.
[[nodiscard]] Result<MapVocabularyReport> TrainAndStoreMapVocabulary(
    const std::string& path, const MapVocabularyOptions& options);

// The map's vocabulary, validated; nullopt when the map has none. A damaged blob is kCorrupt
// naming `map_name` ("vocabulary of MAP: body checksum mismatch").
[[nodiscard]] Result<std::optional<Vocabulary>> LoadMapVocabulary(const MapReader& map,
                                                                  const std::string& map_name);

}  // namespace zm
