// `zonemap import-tum` (lib/import/tum_import.h) on TUM folders the test writes (no real
// recording can be downloaded here): keyframes by motion at the given poses, ORB features from
// the one extractor with points from depth, dense payloads, odometry links, zones, the
// vocabulary; gaps and unreadable images counted and reported, never a crash; OUT atomic.
#include "import/tum_import.h"

#include <doctest/doctest.h>

#include <filesystem>
#include <fstream>

#include "import/map_inspect.h"
#include "localization/camera.h"
#include "mapdb/mapdb_test_util.h"
#include "support/test_util.h"
#include "support/tum_folder_writer.h"

namespace zm {
namespace {

using test::Contains;

using test::TempDir;
using test::TumFolderSpec;
using test::WriteTumFolder;

TumImportOptions OptionsFor(const TumFolderSpec& s) {
  TumImportOptions o;
  o.folder.camera = test::TumTestCamera(s);
  o.keyframe_distance_m = 0.25;  // frames are 0.1 m apart: a keyframe every third frame
  o.vocabulary.vocabulary.branching = 6;
  o.vocabulary.vocabulary.depth = 3;
  return o;
}

TEST_CASE(
    "import-tum: keyframes by motion with ORB features, points from depth, zones, links and a "
    "vocabulary") {
  TempDir dir;
  TumFolderSpec spec;
  spec.frames = 12;
  const std::string poses = WriteTumFolder(dir.File("seq"), spec);
  const std::string out = dir.File("map.db");
  auto r = ImportTum(dir.File("seq"), poses, out, OptionsFor(spec));
  REQUIRE_MESSAGE(r.ok(), r.status().ToString());
  CHECK(r->frames == 12);
  CHECK(r->gaps == 0);
  CHECK(r->refused == 0);
  CHECK(r->frames_without_pose == 0);
  CHECK(r->keyframes == 4);  // frames 0, 3, 6, 9
  CHECK(r->links == 3);
  CHECK(r->zones >= 1);
  CHECK(r->features >= 4 * 200);
  CHECK(r->features_with_point == r->features);  // depth everywhere
  CHECK(r->vocabulary_trained);
  CHECK(r->vocabulary.training_keyframes == 4);
  CHECK(r->problems.empty());
  CHECK(std::filesystem::exists(out));
  CHECK_FALSE(std::filesystem::exists(out + ".tmp"));

  auto db = MapDb::Open(out);
  REQUIRE(db.ok());
  CHECK((*db)->metadata().camera.width == 320);
  CHECK((*db)->metadata().camera.fx == doctest::Approx(256.0));
  CHECK(Contains((*db)->metadata().source, "tum:"));
  auto kfs = (*db)->Keyframes();
  REQUIRE(kfs.ok());
  REQUIRE(kfs->size() == 4);
  for (std::size_t i = 0; i < 4; ++i) {
    // The stored pose is the body's; its camera is where groundtruth.txt put the colour camera.
    const Pose3 cam = CameraPoseInMap((*kfs)[i].pose);
    CHECK(cam.translation().x() == doctest::Approx(0.3 * static_cast<double>(i)));
    CHECK(cam.translation().z() == doctest::Approx(1.2));
    CHECK(cam.linear().isApprox(Eigen::Matrix3d::Identity(), 1e-9));
  }
  auto links = (*db)->Links();
  REQUIRE(links.ok());
  REQUIRE(links->size() == 3);
  CHECK((*links)[0].type == LinkType::kNeighbor);
  CHECK(((*kfs)[0].pose * (*links)[0].transform).isApprox((*kfs)[1].pose, 1e-9));

  // What inspect shows: real features, each with a 3-D point decoded from the stored depth.
  auto m = InspectMap(out);
  REQUIRE_MESSAGE(m.ok(), m.status().ToString());
  REQUIRE(m->keyframes.size() == 4);
  for (const KeyframeInspection& k : m->keyframes) {
    CAPTURE(k.id.value);
    CHECK(k.features >= 200);
    CHECK(k.points3d == k.features);
    CHECK(k.has_colour);
    CHECK(k.has_depth);
    CHECK_FALSE(k.zones.empty());
    CHECK(k.resident_bytes > k.payload_bytes);  // colour, depth, cloud decoded into the slot
  }
  CHECK(m->features == r->features);
  REQUIRE(m->vocabulary.has_value());
  CHECK(m->vocabulary->words == r->vocabulary.words);
  CHECK(m->vocabulary->training_keyframes == 4);
}

TEST_CASE(
    "import-tum: gaps, a missing, an unreadable, a truncated and a wrong-size image are refused "
    "frames") {
  TempDir dir;
  TumFolderSpec spec;
  spec.frames = 14;
  spec.depth_gaps = {1};
  spec.unreadable_colour = {3};   // candidate after 0: refused, 4 is the keyframe
  spec.truncated_depth = {7};     // candidate after 4: refused, 8 is the keyframe
  spec.missing_colour = {11};     // candidate after 8: refused, 12 is the keyframe
  spec.wrong_size_colour = {13};  // not a candidate (0.1 m after 12)
  const std::string poses = WriteTumFolder(dir.File("seq"), spec);
  const std::string out = dir.File("map.db");
  auto r = ImportTum(dir.File("seq"), poses, out, OptionsFor(spec));
  REQUIRE_MESSAGE(r.ok(), r.status().ToString());
  CHECK(r->gaps == 1);
  CHECK(r->frames == 13);
  CHECK(r->refused == 3);
  CHECK(r->keyframes == 4);  // frames 0, 4, 8, 12
  REQUIRE(r->problems.size() == 4);
  CHECK(Contains(r->problems[0], "(gap)"));
  CHECK(Contains(r->problems[1], "refused: colour image"));
  CHECK(Contains(r->problems[1], "cannot be decoded"));
  CHECK(Contains(r->problems[2], "refused: depth image"));
  CHECK(Contains(r->problems[3], "is missing"));
  auto db = MapDb::Open(out);
  REQUIRE(db.ok());
  auto kfs = (*db)->Keyframes();
  REQUIRE(kfs.ok());
  REQUIRE(kfs->size() == 4);
  CHECK(CameraPoseInMap((*kfs)[1].pose).translation().x() == doctest::Approx(0.4));
}

TEST_CASE(
    "import-tum: an existing OUT is refused and kept, and no pose for any frame leaves no output") {
  TempDir dir;
  TumFolderSpec spec;
  spec.frames = 4;
  const std::string poses = WriteTumFolder(dir.File("seq"), spec);
  const std::string out = dir.File("map.db");
  SUBCASE("existing output") {
    std::ofstream(out) << "keep me";
    auto r = ImportTum(dir.File("seq"), poses, out, OptionsFor(spec));
    REQUIRE_FALSE(r.ok());
    CHECK(r.status().code() == StatusCode::kFailedPrecondition);
    CHECK(Contains(r.status().message(), "already exists"));
    std::ifstream in(out);
    std::string text;
    std::getline(in, text);
    CHECK(text == "keep me");
  }
  SUBCASE("poses of another recording") {
    std::ofstream(dir.File("other.txt")) << "1.0 0 0 0 0 0 0 1\n2.0 1 0 0 0 0 0 1\n";
    auto r = ImportTum(dir.File("seq"), dir.File("other.txt"), out, OptionsFor(spec));
    REQUIRE_FALSE(r.ok());
    CHECK(Contains(r.status().message(), "no keyframe (4 frames, 4 without a pose in"));
    CHECK_FALSE(std::filesystem::exists(out));
    CHECK_FALSE(std::filesystem::exists(out + ".tmp"));
  }
}

}  // namespace
}  // namespace zm
