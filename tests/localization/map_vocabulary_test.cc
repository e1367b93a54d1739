// A map's vocabulary (lib/localization/map_vocabulary.h): trained from the map's keyframes (the
// first word_features descriptors of each), stored in the database and read back bit-exactly;
// the same as training on those descriptors directly; a damaged blob in the database is one
// kCorrupt line naming the map.
#include "localization/map_vocabulary.h"

#include <doctest/doctest.h>

#include <cstring>
#include <string>
#include <vector>

#include "mapdb/map_scan.h"
#include "mapdb/mapdb_test_util.h"

namespace zm {
namespace {

using test::BuildMap;
using test::TempDir;

MapVocabularyOptions SmallOptions() {
  MapVocabularyOptions o;
  o.vocabulary.branching = 4;
  o.vocabulary.depth = 3;
  o.word_features = 15;  // fewer than every keyframe holds (21..32): the subset matters
  return o;
}

TEST_CASE("map vocabulary: trained from each keyframe's first word_features, stored, read back bit-exactly") {
  TempDir dir;
  const std::string path = dir.File("map.db");
  const test::BuiltMap built = BuildMap(path);
  const MapVocabularyOptions options = SmallOptions();

  auto report = TrainAndStoreMapVocabulary(path, options);
  REQUIRE_MESSAGE(report.ok(), report.status().ToString());
  CHECK(report->map_keyframes == 12);
  CHECK(report->training_keyframes == 12);
  CHECK(report->training_descriptors == 12u * 15u);
  CHECK(report->keyframes_without_features == 0);
  CHECK(report->words > 0);
  CHECK(report->nodes > report->words);

  // The reference: the same descriptors, straight from the payloads the test wrote.
  std::vector<Descriptor256> descriptors;
  std::vector<std::uint32_t> sizes;
  for (const auto& [id, payload] : built.payloads) {
    auto view = DecodePayload(payload);
    REQUIRE(view.ok());
    for (std::uint32_t i = 0; i < 15; ++i) {
      Descriptor256 d;
      std::memcpy(d.data(), view->descriptor(i), kDescriptorBytes);
      descriptors.push_back(d);
    }
    sizes.push_back(15);
  }
  auto reference = Vocabulary::Train(descriptors, sizes, options.vocabulary);
  REQUIRE(reference.ok());

  auto map = MapDb::Open(path);
  REQUIRE(map.ok());
  auto stored = (*map)->VocabularyBlob();
  REQUIRE(stored.ok());
  REQUIRE(stored->has_value());
  CHECK(**stored == reference->ToBlob());
  CHECK(report->blob_bytes == (*stored)->size());

  auto loaded = LoadMapVocabulary(**map, path);
  REQUIRE(loaded.ok());
  REQUIRE(loaded->has_value());
  CHECK((*loaded)->ToBlob() == reference->ToBlob());
  CHECK((*loaded)->word_count() == report->words);
  CHECK((*loaded)->memory_bytes() == report->memory_bytes);
}

TEST_CASE("map vocabulary: a sample of keyframes spread over the map") {
  TempDir dir;
  const std::string path = dir.File("map.db");
  BuildMap(path);
  MapVocabularyOptions options = SmallOptions();
  options.max_keyframes = 4;
  auto map = MapDb::Open(path);
  REQUIRE(map.ok());
  auto trained = TrainMapVocabulary(**map, options);
  REQUIRE(trained.ok());
  CHECK(trained->report.training_keyframes == 4);
  CHECK(trained->report.training_descriptors == 4u * 15u);
  CHECK(trained->vocabulary.training_keyframes() == 4);
}

TEST_CASE("map vocabulary: none stored is a value, a damaged one is one kCorrupt line") {
  TempDir dir;
  const std::string path = dir.File("map.db");
  BuildMap(path);
  {
    auto map = MapDb::Open(path);
    REQUIRE(map.ok());
    auto none = LoadMapVocabulary(**map, path);
    REQUIRE(none.ok());
    CHECK_FALSE(none->has_value());
  }
  REQUIRE(TrainAndStoreMapVocabulary(path, SmallOptions()).ok());
  std::vector<std::byte> blob;
  {
    auto map = MapDb::Open(path);
    REQUIRE(map.ok());
    auto b = (*map)->VocabularyBlob();
    REQUIRE(b.ok());
    REQUIRE(b->has_value());
    blob = **b;
  }
  std::string expect;
  SUBCASE("a flipped byte in the body") {
    blob[blob.size() / 2] ^= std::byte{0x10};
    expect = "vocabulary of " + path + ": vocabulary blob: body checksum mismatch";
  }
  SUBCASE("truncated") {
    blob.resize(blob.size() - 7);
    expect = "vocabulary of " + path + ": vocabulary blob: ";
  }
  {
    auto w = MapDbWriter::OpenExisting(path);
    REQUIRE(w.ok());
    REQUIRE((*w)->SetVocabulary(blob).ok());
    REQUIRE((*w)->Finish().ok());
  }
  auto map = MapDb::Open(path);
  REQUIRE(map.ok());
  auto loaded = LoadMapVocabulary(**map, path);
  REQUIRE_FALSE(loaded.ok());
  CHECK(loaded.status().code() == StatusCode::kCorrupt);
  INFO(loaded.status().message());
  CHECK(loaded.status().message().rfind(expect, 0) == 0);
  CHECK(loaded.status().message().find('\n') == std::string::npos);
}

TEST_CASE("map vocabulary: bad options are refused naming the field") {
  MapVocabularyOptions o;
  o.word_features = 0;
  CHECK(ValidateMapVocabularyOptions(o).message().find("word_features 0") != std::string::npos);
  o.word_features = 500;
  o.vocabulary.branching = 1;
  CHECK_FALSE(ValidateMapVocabularyOptions(o).ok());
}

}  // namespace
}  // namespace zm
