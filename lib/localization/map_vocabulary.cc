#include "localization/map_vocabulary.h"

#include <algorithm>
#include <chrono>
#include <cstring>
#include <memory>
#include <vector>

#include "common/clock.h"
#include "mapdb/map_scan.h"

namespace zm {

Status ValidateMapVocabularyOptions(const MapVocabularyOptions& options) {
  if (options.word_features == 0 || options.word_features > kMaxFeaturesPerKeyframe) {
    return InvalidArgument("vocabulary word_features " + std::to_string(options.word_features) +
                           ": must be in [1, " + std::to_string(kMaxFeaturesPerKeyframe) + "]");
  }
  return ValidateVocabularyOptions(options.vocabulary);
}

Result<TrainedMapVocabulary> TrainMapVocabulary(MapDb& map, const MapVocabularyOptions& options) {
  ZM_RETURN_IF_ERROR(ValidateMapVocabularyOptions(options));
  const auto t0 = std::chrono::steady_clock::now();
  ZM_ASSIGN_OR_RETURN(std::vector<KeyframeMeta> all, map.Keyframes());
  MapVocabularyReport report;
  report.map_keyframes = static_cast<std::uint32_t>(all.size());
  // An even spread over the id order (ids follow the trajectory), so a sample covers the map.
  std::vector<KeyframeMeta> sample;
  if (options.max_keyframes == 0 || options.max_keyframes >= all.size()) {
    sample = all;
  } else {
    sample.reserve(options.max_keyframes);
    for (std::uint64_t i = 0; i < options.max_keyframes; ++i) {
      sample.push_back(all[static_cast<std::size_t>(i * all.size() / options.max_keyframes)]);
    }
  }
  std::vector<Descriptor256> descriptors;
  std::vector<std::uint32_t> sizes;
  sizes.reserve(sample.size());
  ZM_RETURN_IF_ERROR(ScanKeyframes(map, sample, [&](const KeyframeMeta&, const KeyframeView& v) {
    const std::uint32_t n = std::min(v.feature_count, options.word_features);
    for (std::uint32_t i = 0; i < n; ++i) {
      Descriptor256 d;
      std::memcpy(d.data(), v.descriptor(i), kDescriptorBytes);
      descriptors.push_back(d);
    }
    sizes.push_back(n);
    if (n == 0) ++report.keyframes_without_features;
    return Status::Ok();
  }));
  report.training_keyframes = static_cast<std::uint32_t>(sizes.size());
  report.training_descriptors = descriptors.size();
  report.read_ms = MsSince(t0);
  if (descriptors.empty()) {
    return FailedPrecondition("no descriptor to train a vocabulary from: the " +
                              std::to_string(sizes.size()) +
                              " keyframes read hold no feature (a pose-only map?)");
  }
  const auto t1 = std::chrono::steady_clock::now();
  ZM_ASSIGN_OR_RETURN(Vocabulary vocabulary,
                      Vocabulary::Train(descriptors, sizes, options.vocabulary));
  report.train_ms = MsSince(t1);
  report.words = vocabulary.word_count();
  report.nodes = vocabulary.node_count();
  report.memory_bytes = vocabulary.memory_bytes();
  return TrainedMapVocabulary{std::move(vocabulary), report};
}

Result<MapVocabularyReport> TrainAndStoreMapVocabulary(const std::string& path,
                                                       const MapVocabularyOptions& options) {
  MapVocabularyReport report;
  std::vector<std::byte> blob;
  {
    ZM_ASSIGN_OR_RETURN(std::unique_ptr<MapDb> map, MapDb::Open(path));
    ZM_ASSIGN_OR_RETURN(TrainedMapVocabulary trained, TrainMapVocabulary(*map, options));
    report = trained.report;
    blob = trained.vocabulary.ToBlob();
  }  // the reader is closed before the writer opens the file
  report.blob_bytes = blob.size();
  {
    ZM_ASSIGN_OR_RETURN(std::unique_ptr<MapDbWriter> writer, MapDbWriter::OpenExisting(path));
    ZM_RETURN_IF_ERROR(writer->SetVocabulary(blob));
    ZM_RETURN_IF_ERROR(writer->Finish());
  }
  ZM_ASSIGN_OR_RETURN(std::unique_ptr<MapDb> check, MapDb::Open(path));
  ZM_ASSIGN_OR_RETURN(std::optional<std::vector<std::byte>> stored, check->VocabularyBlob());
  if (!stored || *stored != blob) {
    return IoError(path + ": the vocabulary read back differs from the one written");
  }
  return report;
}

Result<Vocabulary> ParseMapVocabulary(std::span<const std::byte> blob, const std::string& map_name) {
  auto vocabulary = Vocabulary::FromBlob(blob);
  if (!vocabulary.ok()) return vocabulary.status().Annotate("vocabulary of " + map_name);
  return vocabulary;
}

Result<std::optional<Vocabulary>> LoadMapVocabulary(const MapReader& map,
                                                    const std::string& map_name) {
  ZM_ASSIGN_OR_RETURN(std::optional<std::vector<std::byte>> blob, map.VocabularyBlob());
  if (!blob) return std::optional<Vocabulary>{};
  ZM_ASSIGN_OR_RETURN(Vocabulary vocabulary, ParseMapVocabulary(*blob, map_name));
  return std::optional<Vocabulary>(std::move(vocabulary));
}

}  // namespace zm
