// RTAB-Map import on databases built here in RTAB-Map's schema: a single RGB-D node (JPEG colour,
// PNG or RVL depth, features, calibration), a map of hundreds of pose-only nodes with doubly
// stored links and optimized poses, and damaged blobs that must fail cleanly and atomically.
#include "import/rtabmap_import.h"

#include <doctest/doctest.h>

#include <cmath>
#include <filesystem>
#include <functional>
#include <numbers>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "mapdb/keyframe_payload.h"
#include "mapdb/mapdb_test_util.h"
#include "import/rtabmap_test_util.h"
#include "mapdb/rvl.h"
#include "import/map_inspect.h"
#include "support/tum_folder_writer.h"

namespace zm {
namespace {

using test::Blob;
using test::RtabDb;
using test::TempDir;

Blob Encode(const cv::Mat& m, const char* ext) {
  std::vector<uchar> buf;
  REQUIRE(cv::imencode(ext, m, buf));
  Blob b(buf.size());
  std::memcpy(b.data(), buf.data(), buf.size());
  return b;
}

cv::Mat Depth() {
  cv::Mat d(48, 64, CV_16UC1);
  for (int r = 0; r < d.rows; ++r)
    for (int c = 0; c < d.cols; ++c) d.at<std::uint16_t>(r, c) = (c % 9 == 0) ? 0 : static_cast<std::uint16_t>(800 + r * 10 + c);
  return d;
}

Blob RvlOf(const cv::Mat& d) {
  DepthImage16 img{static_cast<std::uint32_t>(d.cols), static_cast<std::uint32_t>(d.rows), {}};
  img.pixels.assign(d.ptr<std::uint16_t>(), d.ptr<std::uint16_t>() + d.total());
  return EncodeRvlDepth(img);
}

// Loads keyframe `id` of `path` into a fresh slot and hands its view to `check`.
template <class Fn>
void WithKeyframe(const std::string& path, std::int64_t id, Fn&& check) {
  auto db = MapDb::Open(path);
  REQUIRE_MESSAGE(db.ok(), db.status().ToString());
  Arena arena = test::MakeArena(2, (*db)->metadata().largest_payload_bytes);
  test::RecordingSink sink;
  const KeyframeId ids[] = {KeyframeId{id}};
  auto st = (*db)->LoadKeyframes(ids, arena, sink);
  REQUIRE_MESSAGE(st.ok(), st.status().ToString());
  auto view = DecodePayload(arena.Slot(sink.loaded()[0].slot), {}, true);
  REQUIRE(view.ok());
  check(**db, *view);
}

TEST_CASE("one RGB-D node: features move to the map frame, images are kept and valid") {
  TempDir dir;
  const std::string in = dir.File("rtabmap.db"), out = dir.File("map.db");
  const Pose3 pose = PoseFromXYYaw(1.0, 2.0, std::numbers::pi / 2, 0.5);
  cv::Mat colour(48, 64, CV_8UC3, cv::Scalar(10, 120, 200));
  const Blob jpeg = Encode(colour, ".jpg");
  const cv::Mat depth = Depth();
  std::string depth_kind;
  Blob depth_blob, image_blob = jpeg;
  SUBCASE("PNG depth") { depth_kind = "png", depth_blob = Encode(depth, ".png"); }
  SUBCASE("RVL depth") { depth_kind = "rvl", depth_blob = RvlOf(depth); }
  SUBCASE("RVL depth, no image") { depth_kind = "rvl-only", depth_blob = RvlOf(depth), image_blob.clear(); }
  {
    RtabDb r(in, test::kRtabmapSchema023);
    r.AddNode(7, 3, test::PoseBlob(pose));
    r.Run("INSERT INTO Data(id, image, depth, calibration) VALUES(7, ?, ?, ?)", image_blob, depth_blob,
          test::CalibrationBlob(525, 526, 319.5, 239.5, 640, 480));
    const auto feature = [&](double x, double y, double z, int desc_bytes, double u, double v) {
      Blob desc(static_cast<std::size_t>(desc_bytes));
      for (std::size_t i = 0; i < desc.size(); ++i) desc[i] = static_cast<std::byte>(i * 7 + static_cast<std::size_t>(u));
      r.Run("INSERT INTO Feature(node_id, word_id, pos_x, pos_y, size, dir, response, octave, depth_x, "
            "depth_y, depth_z, descriptor_size, descriptor) VALUES(7, 1, ?, ?, 31, 0, 1, 0, ?, ?, ?, ?, ?)",
            u, v, x, y, z, std::int64_t{desc_bytes}, desc);
    };
    feature(1.0, 0.0, 0.5, 32, 10, 20);
    feature(2.0, 1.0, 0.0, 32, 30, 40);
    feature(NAN, NAN, NAN, 32, 50, 60);  // no depth: skipped
    feature(1.0, 1.0, 1.0, 64, 70, 80);  // not a 256-bit descriptor: skipped
  }
  auto rep = ImportRtabmap(in, out);
  REQUIRE_MESSAGE(rep.ok(), rep.status().ToString());
  CHECK(rep->rtabmap_version == "0.23.1");
  CHECK(rep->keyframes == 1);
  CHECK(rep->features == 2);
  CHECK(rep->features_skipped == 2);
  CHECK(rep->has_camera);
  CHECK(rep->camera.fx == 525);
  CHECK(rep->camera.cy == 239.5);
  CHECK(rep->camera.width == 640);
  CHECK_FALSE(std::filesystem::exists(out + ".tmp"));

  WithKeyframe(out, 7, [&](const MapDb& db, const KeyframeView& v) {
    CHECK(db.metadata().camera.fy == 526);
    auto kfs = db.Keyframes();
    REQUIRE(kfs.ok());
    CHECK((*kfs)[0].id == KeyframeId{7});
    CHECK((*kfs)[0].weight == 3);
    CHECK((*kfs)[0].pose.isApprox(pose, 1e-6));
    REQUIRE(v.feature_count == 2);
    const Eigen::Vector3d p0 = pose * Eigen::Vector3d(1.0, 0.0, 0.5);
    for (int i = 0; i < 3; ++i) CHECK(v.points[i] == doctest::Approx(p0(i)).epsilon(1e-5));
    CHECK(v.keypoints[2] == 30.0f);
    CHECK(v.keypoints[3] == 40.0f);
    CHECK(v.descriptor(1)[1] == static_cast<std::uint8_t>(7 + 30));
    const auto dense = v.dense;
    if (depth_kind == "rvl-only") {
      CHECK(v.dense_format == DenseFormat::kRvlDepth16);
      CHECK(std::equal(dense.begin(), dense.end(), depth_blob.begin(), depth_blob.end()));
      return;
    }
    REQUIRE(v.dense_format == DenseFormat::kPngDepthAndJpegColour);
    const cv::Mat png(1, static_cast<int>(v.dense_split), CV_8UC1, const_cast<std::byte*>(dense.data()));
    const cv::Mat got_depth = cv::imdecode(png, cv::IMREAD_UNCHANGED);
    REQUIRE(got_depth.type() == CV_16UC1);
    CHECK(cv::countNonZero(got_depth != depth) == 0);  // lossless, also after RVL -> PNG
    const auto colour_part = dense.subspan(v.dense_split);
    CHECK(std::equal(colour_part.begin(), colour_part.end(), jpeg.begin(), jpeg.end()));
  });
}

TEST_CASE("--features orb: ORB from the Data images in the calibration's pixels, points from depth, a vocabulary") {
  TempDir dir;
  const std::string in = dir.File("rtabmap.db"), out = dir.File("map.db");
  test::TumFolderSpec tex_spec;
  tex_spec.width = 160;  // half the calibration's 320x240: RTAB-Map's decimated images
  tex_spec.height = 120;
  const cv::Mat texture = test::TumTexture(tex_spec);
  cv::Mat depth(120, 160, CV_16UC1);
  for (int r = 0; r < depth.rows; ++r)
    for (int c = 0; c < depth.cols; ++c) depth.at<std::uint16_t>(r, c) = static_cast<std::uint16_t>(1500 + 4 * c);
  {
    RtabDb r(in, test::kRtabmapSchema023);
    for (std::int64_t id = 1; id <= 3; ++id) {
      r.AddNode(id, 1, test::PoseBlob(PoseFromXYYaw(0.5 * static_cast<double>(id), 0.0, 0.0)));
      if (id == 3) continue;  // no Data row: no features
      const cv::Mat colour = texture(cv::Rect(static_cast<int>(id) * 8, 0, 160, 120)).clone();
      const Blob depth_blob = id == 1 ? Encode(depth, ".png") : RvlOf(depth);
      r.Run("INSERT INTO Data(id, image, depth, calibration) VALUES(?, ?, ?, ?)", id,
            Encode(colour, ".jpg"), depth_blob, test::CalibrationBlob(250, 250, 160, 120, 320, 240));
    }
  }
  RtabmapImportOptions o;
  o.features = RtabmapFeatureSource::kOrb;
  o.vocabulary.vocabulary.branching = 4;
  o.vocabulary.vocabulary.depth = 3;
  auto rep = ImportRtabmap(in, out, o);
  REQUIRE_MESSAGE(rep.ok(), rep.status().ToString());
  CHECK(rep->keyframes == 3);
  CHECK(rep->orb_keyframes == 2);
  CHECK(rep->orb_nodes_without_images == 1);
  CHECK(rep->features >= 2 * 30);
  CHECK(rep->vocabulary_trained);
  CHECK(rep->vocabulary.training_keyframes == 3);
  CHECK(rep->camera.width == 320);

  auto m = InspectMap(out);
  REQUIRE_MESSAGE(m.ok(), m.status().ToString());
  REQUIRE(m->keyframes.size() == 3);
  for (int i = 0; i < 2; ++i) {
    CAPTURE(i);
    CHECK(m->keyframes[static_cast<std::size_t>(i)].features >= 30);
    CHECK(m->keyframes[static_cast<std::size_t>(i)].points3d == m->keyframes[static_cast<std::size_t>(i)].features);
    CHECK(m->keyframes[static_cast<std::size_t>(i)].has_colour);
  }
  CHECK(m->keyframes[2].features == 0);
  REQUIRE(m->vocabulary.has_value());
  CHECK(m->vocabulary->words == rep->vocabulary.words);

  WithKeyframe(out, 1, [&](const MapDb& db, const KeyframeView& v) {
    CHECK(db.metadata().camera.width == 320);
    REQUIRE(v.feature_count >= 30);
    CHECK(v.dense_format == DenseFormat::kJpegColourRvlDepth);
    CHECK(v.dense_width == 160);
    float max_u = 0.0f;
    for (std::uint32_t i = 0; i < v.feature_count; ++i) {
      max_u = std::max(max_u, v.keypoints[2 * i]);
      CHECK(v.keypoints[2 * i] < 320.0f);
      CHECK(v.keypoints[2 * i + 1] < 240.0f);
    }
    CHECK(max_u > 160.0f);  // in the calibration's pixels, not the image's
    // The depth at the keypoint, back-projected with the calibration: z is 1.5 m + 4 mm per
    // image column, the image column being u / 2.
    const float u = v.keypoints[0];
    const float z = v.points[2];
    CHECK(z == doctest::Approx(1.5 + 0.004 * static_cast<int>(u / 2.0f)).epsilon(0.01));
  });
}

TEST_CASE("hundreds of pose-only nodes: ids kept, links deduplicated, optimized poses used") {
  TempDir dir;
  const std::string in = dir.File("rtabmap.db"), out = dir.File("map.db");
  constexpr int kNodes = 300;
  const auto raw = [](int i) { return PoseFromXYYaw(0.5 * i, 0.0, 0.01 * i); };
  const auto opt = [](int i) { return PoseFromXYYaw(0.5 * i + 10.0, 1.0, 0.01 * i); };
  {
    RtabDb r(in, test::kRtabmapSchema019);
    std::vector<std::int32_t> ids;
    std::vector<Pose3> poses;
    for (int i = 1; i <= kNodes; ++i) {
      r.AddNode(i, i % 4, test::PoseBlob(raw(i)));
      ids.push_back(i);
      poses.push_back(opt(i));
    }
    r.AddNode(301, -9, test::PoseBlob(raw(301)));        // invalid: skipped
    r.AddNode(302, 0, Blob(48, std::byte{0}));            // null pose, not optimized: skipped
    r.Run("UPDATE Admin SET opt_ids=?, opt_poses=?", test::OptIdsBlob(ids), test::OptPosesBlob(poses));
    for (int i = 1; i < kNodes; ++i) {  // every neighbour edge stored twice, as RTAB-Map does
      const Pose3 t = raw(i).inverse() * raw(i + 1);
      r.AddLink(i, i + 1, 0, test::PoseBlob(t));
      r.AddLink(i + 1, i, 0, test::PoseBlob(t.inverse()));
    }
    r.AddLink(150, 1, 1, test::PoseBlob(raw(150).inverse() * raw(1)));  // stored once, from > to
    r.AddLink(5, 5, 7, test::PoseBlob(Pose3::Identity()));              // pose prior
    r.AddLink(10, -1, 8, test::PoseBlob(Pose3::Identity()));            // landmark
    r.AddLink(300, 301, 0, test::PoseBlob(Pose3::Identity()));          // to an invalid node
  }
  auto rep = ImportRtabmap(in, out);
  REQUIRE_MESSAGE(rep.ok(), rep.status().ToString());
  CHECK(rep->rtabmap_version == "0.19.3");
  CHECK(rep->nodes == 302);
  CHECK(rep->keyframes == kNodes);
  CHECK(rep->skipped_invalid == 1);
  CHECK(rep->skipped_null_pose == 1);
  CHECK(rep->optimized_poses == kNodes);
  CHECK(rep->links == kNodes);  // 299 neighbours + 1 loop closure
  CHECK(rep->links_duplicate == kNodes - 1);
  CHECK(rep->links_self == 1);
  CHECK(rep->links_landmark == 1);
  CHECK(rep->links_dangling == 1);
  CHECK_FALSE(rep->has_camera);

  auto db = MapDb::Open(out);
  REQUIRE(db.ok());
  CHECK((*db)->metadata().keyframe_count == kNodes);
  CHECK((*db)->metadata().source.find("rtabmap:") == 0);
  auto kfs = (*db)->Keyframes();
  REQUIRE(kfs.ok());
  CHECK(kfs->front().id == KeyframeId{1});
  CHECK(kfs->back().id == KeyframeId{kNodes});
  CHECK((*kfs)[16].pose.isApprox(opt(17), 1e-5));
  CHECK((*kfs)[16].payload_bytes == kPayloadHeaderBytes);  // pose-only: an empty payload
  auto links = (*db)->Links();
  REQUIRE(links.ok());
  REQUIRE(links->size() == kNodes);
  for (const auto& l : *links) CHECK(l.from < l.to);
  const auto loop = std::find_if(links->begin(), links->end(),
                                 [](const LinkRecord& l) { return l.type == LinkType::kGlobalClosure; });
  REQUIRE(loop != links->end());
  CHECK(loop->from == KeyframeId{1});
  CHECK(loop->to == KeyframeId{150});
  CHECK(loop->transform.isApprox(raw(1).inverse() * raw(150), 1e-5));  // inverted to from < to

  RtabmapImportOptions raw_poses;
  raw_poses.use_optimized_poses = false;
  raw_poses.overwrite = true;
  auto rep2 = ImportRtabmap(in, out, raw_poses);
  REQUIRE(rep2.ok());
  CHECK(rep2->optimized_poses == 0);
  CHECK(rep2->keyframes == kNodes);  // 302's null pose still skipped
}

// Builds a two-node map, lets `damage` break it (returning the error text to expect), and checks
// the import fails with that text, leaves an existing OUT byte-identical and no OUT.tmp behind.
void ExpectDamagedImportFails(const std::function<std::string(RtabDb&, const Blob&, const Blob&)>& damage) {
  TempDir dir;
  const std::string in = dir.File("rtabmap.db"), out = dir.File("map.db");
  std::string expect;
  {
    RtabDb r(in, test::kRtabmapSchema023);
    r.AddNode(1, 0, test::PoseBlob(PoseFromXYYaw(0, 0, 0)));
    r.AddNode(2, 0, test::PoseBlob(PoseFromXYYaw(1, 0, 0)));
    r.AddLink(1, 2, 0, test::PoseBlob(PoseFromXYYaw(1, 0, 0)));
    expect = damage(r, test::OptIdsBlob({1, 2}),
                    test::OptPosesBlob({PoseFromXYYaw(0, 0, 0), PoseFromXYYaw(1, 0, 0)}));
  }
  // An existing output survives a failed import byte for byte (the import writes OUT.tmp).
  test::BuildMap(out);
  const auto before = test::Snapshot(out);
  RtabmapImportOptions opts;
  opts.overwrite = true;
  auto rep = ImportRtabmap(in, out, opts);
  REQUIRE_FALSE(rep.ok());
  INFO(rep.status().ToString());
  CHECK(rep.status().message().find(expect) != std::string::npos);
  CHECK(test::Snapshot(out) == before);
  CHECK_FALSE(std::filesystem::exists(out + ".tmp"));
  std::filesystem::remove(out);
  CHECK_FALSE(ImportRtabmap(in, out).ok());
  CHECK_FALSE(std::filesystem::exists(out));
}

TEST_CASE("damaged optimized poses (zlib + trailer) give one clear error, no output") {
  const auto opt = [](const std::function<void(Blob&)>& edit, const std::string& expect) {
    return [=](RtabDb& r, const Blob& ids, const Blob& poses) {
      Blob bad = poses;
      edit(bad);
      r.Run("UPDATE Admin SET opt_ids=?, opt_poses=?", ids, bad);
      return expect;
    };
  };
  const auto set_cols = [](std::int32_t cols) {
    return [=](Blob& b) { std::memcpy(b.data() + b.size() - 8, &cols, 4); };
  };
  SUBCASE("bad zlib") {
    ExpectDamagedImportFails(opt([](Blob& b) { b[0] = b[1] = std::byte{0}; }, "Admin.opt_poses: zlib data"));
  }
  SUBCASE("trailer claims more than the data holds") {
    ExpectDamagedImportFails(opt(set_cols(48), "inflates to 96 bytes"));
  }
  SUBCASE("trailer claims less than the data holds") {
    ExpectDamagedImportFails(opt(set_cols(12), "inflates to more"));
  }
  SUBCASE("shorter than its trailer") {
    ExpectDamagedImportFails(opt([](Blob& b) { b.resize(5); }, "shorter than the 12-byte"));
  }
}

TEST_CASE("RTAB-Map matrices: the element size is OpenCV 4's, CV_16F (depth 7) two bytes") {
  // OpenCV's depth numbering: 8U 8S 16U 16S 32S 32F 64F 16F; type = depth + 8 * (channels - 1).
  CHECK(RtabmapElementBytes(CV_8UC1) == 1);
  CHECK(RtabmapElementBytes(CV_8UC3) == 3);
  CHECK(RtabmapElementBytes(CV_32SC1) == 4);
  CHECK(RtabmapElementBytes(CV_32FC1) == 4);
  CHECK(RtabmapElementBytes(CV_64FC1) == 8);
  CHECK(RtabmapElementBytes(CV_16FC1) == 2);
  CHECK(RtabmapElementBytes(CV_16FC2) == 4);
  // A 1 x 2 CV_16FC2 matrix (the fuzzer's input, fuzz/regressions/rtabmap_blob/cv16f_2ch.bin, is
  // one) decodes to its 8 bytes, and a compressed one round-trips.
  RtabmapMatrix m{1, 2, CV_16FC2, Blob(8)};
  for (std::size_t i = 0; i < m.data.size(); ++i) m.data[i] = std::byte(i + 1);
  const auto back = UncompressRtabmapData(CompressRtabmapData(m), "half floats");
  REQUIRE(back.ok());
  CHECK(back->type == CV_16FC2);
  CHECK(back->data == m.data);
  m.data.resize(6);  // too short for its claim: the compressed stream no longer matches
  const auto bad = UncompressRtabmapData(CompressRtabmapData(m), "half floats");
  REQUIRE_FALSE(bad.ok());
  CHECK(bad.status().message().find("half floats: trailer claims 1x2 of OpenCV type 15 = 8 bytes, but the data inflates to 6") !=
        std::string::npos);
}

TEST_CASE("damaged node, data and link blobs give one clear error naming them, no output") {
  const auto run = [](std::string sql, Blob blob, std::string expect) {
    return [=](RtabDb& r, const Blob&, const Blob&) {
      r.Run(sql, blob);
      return expect;
    };
  };
  SUBCASE("short pose blob") {
    ExpectDamagedImportFails(run("UPDATE Node SET pose=? WHERE id=2", Blob(20, std::byte{1}),
                                 "node 2: Node.pose is 20 bytes, expected 48"));
  }
  SUBCASE("corrupt JPEG") {
    ExpectDamagedImportFails(run("INSERT INTO Data(id, image) VALUES(1, ?)",
                                 {std::byte{0xFF}, std::byte{0xD8}, std::byte{0xFF}, std::byte{0}, std::byte{1}},
                                 "node 1: Data.image of 5 bytes"));
  }
  SUBCASE("truncated RVL depth") {
    Blob rvl = RvlOf(Depth());
    rvl.resize(rvl.size() / 2);
    ExpectDamagedImportFails(run("INSERT INTO Data(id, depth) VALUES(2, ?)", rvl, "node 2: Data.depth"));
  }
  SUBCASE("bad calibration") {
    ExpectDamagedImportFails(run("INSERT INTO Data(id, calibration) VALUES(1, ?)", Blob(50, std::byte{0x7f}),
                                 "node 1: Data.calibration"));
  }
  SUBCASE("bad information matrix") {
    ExpectDamagedImportFails(run("UPDATE Link SET information_matrix=? WHERE from_id=1", Blob(10, std::byte{0}),
                                 "link 1->2 (type 0): Link.information_matrix is 10 bytes"));
  }
}

TEST_CASE("the last working memory: Node.time_enter >= the last Info.time_enter, recorded") {
  // A mapping session started (Info row at 09:00, written while memory was empty), added nodes
  // 1..6, and ended: RTAB-Map wrote the closing Info row at 10:00:00 and re-stamped the WM it
  // ended with (4, 5, 6) at 10:00:00 or later. Node 7 is invalid (weight -9): not imported, so
  // not in the record either. Node 8 has no time_enter (NULL compares as not >=).
  TempDir dir;
  const std::string in = dir.File("rtabmap.db"), out = dir.File("map.db");
  {
    RtabDb r(in, test::kRtabmapSchema023);
    for (int i = 1; i <= 8; ++i) r.AddNode(i, i == 7 ? -9 : 0, test::PoseBlob(PoseFromXYYaw(i, 0, 0)));
    r.Exec("UPDATE Node SET time_enter='2024-05-01 09:10:00' WHERE id <= 3");
    r.Exec("UPDATE Node SET time_enter='2024-05-01 10:00:00' WHERE id IN (4, 5, 7)");
    r.Exec("UPDATE Node SET time_enter='2024-05-01 10:00:01' WHERE id = 6");
    r.Exec("INSERT INTO Info(STM_size, time_enter) VALUES(10, '2024-05-01 09:00:00')");
    r.Exec("INSERT INTO Info(STM_size, time_enter) VALUES(10, '2024-05-01 10:00:00')");
  }
  auto rep = ImportRtabmap(in, out);
  REQUIRE_MESSAGE(rep.ok(), rep.status().ToString());
  CHECK(rep->last_wm_recorded);
  CHECK(rep->last_wm_nodes == 3);
  CHECK(rep->last_info_time_enter == "2024-05-01 10:00:00");
  auto db = MapDb::Open(out);
  REQUIRE(db.ok());
  auto last = (*db)->LastWorkingMemory();
  REQUIRE_MESSAGE(last.ok(), last.status().ToString());
  CHECK_FALSE(last->every_node);
  std::vector<std::int64_t> ids;
  for (KeyframeId id : last->ids) ids.push_back(id.value);
  CHECK(ids == std::vector<std::int64_t>{4, 5, 6});
  CHECK(last->rule.find("2024-05-01 10:00:00") != std::string::npos);
}

TEST_CASE("the last working memory: nothing to go by means every node, said so") {
  TempDir dir;
  const std::string in = dir.File("rtabmap.db"), out = dir.File("map.db");
  {
    RtabDb r(in, test::kRtabmapSchema019);  // an Info table, but no row in it
    for (int i = 1; i <= 3; ++i) r.AddNode(i, 0, test::PoseBlob(PoseFromXYYaw(i, 0, 0)));
  }
  auto rep = ImportRtabmap(in, out);
  REQUIRE_MESSAGE(rep.ok(), rep.status().ToString());
  CHECK_FALSE(rep->last_wm_recorded);
  auto db = MapDb::Open(out);
  REQUIRE(db.ok());
  auto last = (*db)->LastWorkingMemory();
  REQUIRE_MESSAGE(last.ok(), last.status().ToString());
  CHECK(last->every_node);
  CHECK(last->rule.find("no Info row") != std::string::npos);
}

TEST_CASE("the last working memory of maps that predate the record") {
  TempDir dir;
  SUBCASE("a simulator map: every node") {
    const std::string path = dir.File("sim.db");
    test::BuildMap(path);
    auto db = MapDb::Open(path);
    REQUIRE(db.ok());
    auto last = (*db)->LastWorkingMemory();
    REQUIRE(last.ok());
    CHECK(last->every_node);
    CHECK(last->rule.empty());
  }
  SUBCASE("an RTAB-Map import without the record: refused, naming the fix") {
    const std::string in = dir.File("rtabmap.db"), out = dir.File("map.db");
    {
      RtabDb r(in, test::kRtabmapSchema023);
      r.AddNode(1, 0, test::PoseBlob(PoseFromXYYaw(1, 0, 0)));
    }
    REQUIRE(ImportRtabmap(in, out).ok());
    {  // what an import by an older zonemap looks like: no last_wm keys, no table
      sqlite3* raw = nullptr;
      REQUIRE(sqlite3_open(out.c_str(), &raw) == SQLITE_OK);
      REQUIRE(sqlite3_exec(raw, "DELETE FROM meta WHERE key LIKE 'last_wm%'; DROP TABLE last_wm;",
                           nullptr, nullptr, nullptr) == SQLITE_OK);
      sqlite3_close(raw);
    }
    auto db = MapDb::Open(out);
    REQUIRE_MESSAGE(db.ok(), db.status().ToString());  // still readable
    auto last = (*db)->LastWorkingMemory();
    REQUIRE_FALSE(last.ok());
    CHECK(last.status().code() == StatusCode::kFailedPrecondition);
    CHECK(last.status().message().find("import-rtabmap") != std::string::npos);
  }
}

TEST_CASE("the last working memory record: ids the map does not hold are clear errors") {
  TempDir dir;
  const std::string path = dir.File("map.db");
  test::BuildMap(path);
  {
    auto w = MapDbWriter::OpenExisting(path);
    REQUIRE(w.ok());
    const KeyframeId missing[] = {KeyframeId{1}, KeyframeId{999999}};
    const Status st = (*w)->SetLastWorkingMemory(missing, "test");
    CHECK(st.code() == StatusCode::kInvalidArgument);
    CHECK(st.message().find("keyframe 999999") != std::string::npos);
  }
  {
    auto db = MapDb::Open(path);
    REQUIRE(db.ok());
    auto last = (*db)->LastWorkingMemory();
    REQUIRE(last.ok());
    CHECK(last->every_node);  // the failed write left no record behind
  }
  {  // a record edited behind zonemap's back
    auto w = MapDbWriter::OpenExisting(path);
    REQUIRE(w.ok());
    const KeyframeId one[] = {KeyframeId{1}};
    REQUIRE((*w)->SetLastWorkingMemory(one, "test").ok());
  }
  sqlite3* raw = nullptr;
  REQUIRE(sqlite3_open(path.c_str(), &raw) == SQLITE_OK);
  REQUIRE(sqlite3_exec(raw, "INSERT INTO last_wm(keyframe_id) VALUES(424242)", nullptr, nullptr,
                       nullptr) == SQLITE_OK);
  sqlite3_close(raw);
  auto db = MapDb::Open(path);
  REQUIRE(db.ok());
  auto last = (*db)->LastWorkingMemory();
  REQUIRE_FALSE(last.ok());
  CHECK(last.status().code() == StatusCode::kCorrupt);
  CHECK(last.status().message().find("keyframe 424242") != std::string::npos);
}

TEST_CASE("inputs that are not RTAB-Map databases are refused") {
  TempDir dir;
  const std::string ours = dir.File("ours.db"), out = dir.File("out.db");
  test::BuildMap(ours);
  auto r = ImportRtabmap(ours, out);
  REQUIRE_FALSE(r.ok());
  CHECK(r.status().message().find("no table Node") != std::string::npos);
  auto missing = ImportRtabmap(dir.File("nope.db"), out);
  CHECK(missing.status().code() == StatusCode::kNotFound);
  auto exists = ImportRtabmap(ours, ours);
  CHECK(exists.status().message().find("same file") != std::string::npos);
  CHECK_FALSE(std::filesystem::exists(out));
}

}  // namespace
}  // namespace zm
