// `zonemap inspect` (lib/import/map_inspect.h) on a small map: per keyframe its zones, features,
// 3-D points and bytes; the totals; the vocabulary's size once one is stored, its absence before.
#include "import/map_inspect.h"

#include <doctest/doctest.h>

#include "localization/map_vocabulary.h"
#include "mapdb/mapdb_test_util.h"

namespace zm {
namespace {

TEST_CASE("inspect: a small map's keyframes, zones, totals and vocabulary") {
  test::TempDir dir;
  const std::string path = dir.File("map.db");
  const test::BuiltMap built = test::BuildMap(path);  // 12 keyframes, 20 + id features each
  auto before = InspectMap(path);
  REQUIRE_MESSAGE(before.ok(), before.status().ToString());
  CHECK(before->schema_version == kMapDbSchemaVersion);
  CHECK_FALSE(before->vocabulary.has_value());
  REQUIRE(before->keyframes.size() == 12);
  std::uint64_t features = 0;
  for (const KeyframeInspection& k : before->keyframes) {
    CAPTURE(k.id.value);
    CHECK(k.features == 20 + k.id.value);
    CHECK(k.points3d == k.features);  // every stored point is finite
    CHECK(k.payload_bytes == built.payloads.at(k.id.value).size());
    CHECK(k.resident_bytes == k.payload_bytes);  // nothing to decode
    CHECK_FALSE(k.has_colour);
    features += k.features;
  }
  CHECK(before->features == features);
  CHECK(before->points3d == features);
  // Zones {1..5}, {5..8}, {9..12}: keyframe 5 is in two.
  REQUIRE(before->keyframes[4].zones.size() == 2);
  CHECK(before->keyframes[4].zones[0] == ZoneId{0});
  CHECK(before->keyframes[4].zones[1] == ZoneId{1});
  REQUIRE(before->zones.size() == 3);
  CHECK(before->zones[1].keyframes == 4);
  CHECK(before->zones[0].zone.name == "zone0");

  MapVocabularyOptions o;
  o.vocabulary.branching = 4;
  o.vocabulary.depth = 2;
  auto trained = TrainAndStoreMapVocabulary(path, o);
  REQUIRE(trained.ok());
  auto after = InspectMap(path);
  REQUIRE(after.ok());
  REQUIRE(after->vocabulary.has_value());
  CHECK(after->vocabulary->words == trained->words);
  CHECK(after->vocabulary->nodes == trained->nodes);
  CHECK(after->vocabulary->branching == 4);
  CHECK(after->vocabulary->memory_bytes == trained->memory_bytes);
  CHECK(after->vocabulary->blob_bytes == trained->blob_bytes);
}

TEST_CASE("inspect: a map that does not exist is one clear error") {
  auto m = InspectMap("/nonexistent/map.db");
  REQUIRE_FALSE(m.ok());
  CHECK(m.status().code() == StatusCode::kNotFound);
}

}  // namespace
}  // namespace zm
