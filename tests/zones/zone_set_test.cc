// Zone files: GeoJSON and keyframe-list parsing, one clear error per bad input (file, feature
// index), GeoJSON and database-record round trips.
#include <doctest/doctest.h>

#include <cstdio>
#include <filesystem>
#include <fstream>

#include "zones/zone_set.h"
#include "zones_test_util.h"

namespace zm {
namespace {

using test::FeatureCollection;

const char* kSquare = "[[0,0],[4,0],[4,3],[0,3],[0,0]]";

std::string ErrorOf(std::string_view text) {
  auto r = ParseZoneJson(text, "z.geojson");
  REQUIRE_FALSE(r.ok());
  return r.status().message();
}

TEST_CASE("GeoJSON zones keep file order, kinds, floors and z ranges") {
  const std::string text = R"({"type":"FeatureCollection","floor_height_m":4.0,"features":[
    {"type":"Feature","properties":{"name":"Ward3","kind":"ward","floor":1},
     "geometry":{"type":"Polygon","coordinates":[[[0,0],[10,0],[10,5],[0,5],[0,0]]]}},
    {"type":"Feature","properties":{"name":"Lobby","z_min":-1,"z_max":2.5},
     "geometry":{"type":"Polygon","coordinates":[[[0,0,0],[3,0,0],[3,3,0],[0,3,0],[0,0,0]]]}}]})";
  auto r = ParseZoneJson(text, "z.geojson");
  REQUIRE_MESSAGE(r.ok(), r.status().ToString());
  REQUIRE(r->size() == 2);
  const Zone& ward = r->zone(ZoneId{0});
  CHECK(ward.name == "Ward3");
  CHECK(ward.kind == "ward");
  CHECK(ward.floor == 1);
  CHECK(ward.z_min_m == doctest::Approx(2.0));
  CHECK(ward.z_max_m == doctest::Approx(6.0));
  CHECK(ward.polygon.size() == 4);  // closing vertex dropped
  CHECK(ward.AreaM2() == doctest::Approx(50.0));
  const Zone& lobby = r->zone(ZoneId{1});
  CHECK(lobby.kind == "room");
  CHECK(lobby.z_min_m == -1.0);
  CHECK(lobby.z_max_m == 2.5);
  CHECK(r->Find("Lobby") == ZoneId{1});
  CHECK(r->Find("nope") == kNoZone);
  CHECK_FALSE(r->has_keyframe_lists());
}

TEST_CASE("keyframe-list zones keep file order, lists and the initial zone") {
  auto r = ParseZoneJson(R"({"initial_zone":"L1","zones":{"L1":[8,1,7,7],"H1":[2,3],"A":[]}})",
                         "paper.json");
  REQUIRE_MESSAGE(r.ok(), r.status().ToString());
  REQUIRE(r->has_keyframe_lists());
  REQUIRE(r->size() == 3);
  CHECK(r->zone(ZoneId{0}).name == "L1");
  CHECK(r->zone(ZoneId{1}).name == "H1");
  CHECK(r->keyframes(ZoneId{0}) == std::vector<KeyframeId>{KeyframeId{1}, KeyframeId{7}, KeyframeId{8}});
  CHECK(r->initial_zone() == ZoneId{0});
  CHECK(r->source() == "paper.json");
}

TEST_CASE("bad zone files each give one clear error naming the file and the feature") {
  SUBCASE("empty file") {
    CHECK(ErrorOf("").find("z.geojson: empty file") == 0);
    CHECK(ErrorOf("  \n").find("empty file") != std::string::npos);
  }
  SUBCASE("self-intersecting polygon (a bow tie)") {
    const auto m = ErrorOf(FeatureCollection(
        {{"A", kSquare}, {"Bow", "[[0,0],[4,4],[4,0],[0,4],[0,0]]"}}));
    CHECK(m.find("z.geojson: feature 1 (\"Bow\")") == 0);
    CHECK(m.find("intersects itself") != std::string::npos);
  }
  SUBCASE("unclosed ring") {
    const auto m = ErrorOf(FeatureCollection({{"A", "[[0,0],[4,0],[4,3],[0,3]]"}}));
    CHECK(m.find("feature 0 (\"A\")") != std::string::npos);
    CHECK(m.find("not closed") != std::string::npos);
  }
  SUBCASE("non-numeric coordinates") {
    const auto m = ErrorOf(FeatureCollection({{"A", kSquare}, {"B", "[[0,0],[\"4\",0],[4,3],[0,0]]"}}));
    CHECK(m.find("feature 1 (\"B\")") != std::string::npos);
    CHECK(m.find("position 1") != std::string::npos);
    CHECK(m.find("non-numeric") != std::string::npos);
  }
  SUBCASE("duplicate names in GeoJSON") {
    const auto m = ErrorOf(FeatureCollection({{"A", kSquare}, {"B", kSquare}, {"A", kSquare}}));
    CHECK(m.find("feature 2 (\"A\")") != std::string::npos);
    CHECK(m.find("duplicate zone name") != std::string::npos);
  }
  SUBCASE("duplicate names in keyframe lists") {
    const auto m = ErrorOf(R"({"zones":{"L1":[1],"H1":[2],"L1":[3]}})");
    CHECK(m.find("duplicate key \"L1\"") != std::string::npos);
  }
  SUBCASE("non-integer keyframe id") {
    const auto m = ErrorOf(R"({"zones":{"L1":[1],"H1":[2, 2.5]}})");
    CHECK(m.find("feature 1 (\"H1\"): entry 1") != std::string::npos);
  }
  SUBCASE("unknown initial zone") {
    CHECK(ErrorOf(R"({"initial_zone":"X","zones":{"L1":[1]}})").find("initial_zone \"X\"") !=
          std::string::npos);
  }
  SUBCASE("too few positions, holes, other geometry, missing name, no features, not JSON") {
    CHECK(ErrorOf(FeatureCollection({{"A", "[[0,0],[1,0],[0,0]]"}})).find("at least 4") !=
          std::string::npos);
    CHECK(ErrorOf(FeatureCollection({{"A", std::string(kSquare) + ",[[1,1],[2,1],[2,2],[1,1]]"}}))
              .find("holes") != std::string::npos);
    CHECK(ErrorOf(R"({"type":"FeatureCollection","features":[{"type":"Feature","properties":{"name":"P"},"geometry":{"type":"Point","coordinates":[0,0]}}]})")
              .find("must be a Polygon") != std::string::npos);
    CHECK(ErrorOf(R"({"type":"FeatureCollection","features":[{"type":"Feature","properties":{},"geometry":null}]})")
              .find("feature 0: needs a non-empty string property \"name\"") != std::string::npos);
    CHECK(ErrorOf(R"({"type":"FeatureCollection","features":[]})").find("no features") !=
          std::string::npos);
    CHECK(ErrorOf("{\"type\":").find("not valid JSON") != std::string::npos);
    CHECK(ErrorOf("[1,2]").find("not a JSON object") != std::string::npos);
  }
  SUBCASE("zero area") {
    CHECK(ErrorOf(FeatureCollection({{"A", "[[0,0],[1,0],[2,0],[0,0]]"}})).find("feature 0") !=
          std::string::npos);
  }
}

TEST_CASE("a missing file is a clear error") {
  auto r = LoadZoneFile("/nonexistent/zones.geojson");
  REQUIRE_FALSE(r.ok());
  CHECK(r.status().message().find("/nonexistent/zones.geojson") != std::string::npos);
}

TEST_CASE("GeoJSON and database records round-trip") {
  ZoneSet set = test::MakeSet({test::MakeZone("A", test::Rect(0, 0, 4, 3)),
                               test::MakeZone("B", test::Rect(4, 0, 8, 3), 1, 1.5, 4.5)});
  const auto path = (std::filesystem::temp_directory_path() / "zm_zone_set_test.geojson").string();
  REQUIRE(WriteGeoJson(set, path).ok());
  auto back = LoadZoneFile(path);
  std::filesystem::remove(path);
  REQUIRE_MESSAGE(back.ok(), back.status().ToString());
  REQUIRE(back->size() == 2);
  CHECK(back->zone(ZoneId{1}).floor == 1);
  CHECK(back->zone(ZoneId{1}).z_min_m == 1.5);
  CHECK(back->zone(ZoneId{0}).z_min_m == -kUnboundedZM);
  CHECK(back->zone(ZoneId{1}).polygon == set.zone(ZoneId{1}).polygon);

  const auto records = ToZoneRecords(set);
  REQUIRE(records.size() == 2);
  CHECK(records[1].polygon.size() == 4);
  auto again = ZoneSetFromRecords(records);
  REQUIRE(again.ok());
  CHECK(again->zone(ZoneId{1}).name == "B");
  CHECK(again->zone(ZoneId{1}).polygon == set.zone(ZoneId{1}).polygon);

  // List zones come back with their members.
  std::vector<ZoneRecord> lists(1);
  lists[0].id = ZoneId{0};
  lists[0].name = "L1";
  const std::vector<ZoneMember> members = {{ZoneId{0}, KeyframeId{5}}, {ZoneId{0}, KeyframeId{2}}};
  auto from_lists = ZoneSetFromRecords(lists, members);
  REQUIRE(from_lists.ok());
  CHECK(from_lists->keyframes(ZoneId{0}) == std::vector<KeyframeId>{KeyframeId{2}, KeyframeId{5}});
  CHECK_FALSE(WriteGeoJson(*from_lists, path).ok());
}

}  // namespace
}  // namespace zm
