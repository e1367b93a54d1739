// The TUM RGB-D folder reader (lib/tum/tum_folder.h) on folders written by the test: both
// listings, colour-depth association by nearest stamp within the tolerance, gaps and malformed
// lines counted and reported, and every bad image one error naming the file, never a crash.
#include <doctest/doctest.h>

#include <filesystem>
#include <fstream>

#include "mapdb/mapdb_test_util.h"
#include "support/test_util.h"
#include "support/tum_folder_writer.h"
#include "tum/tum_frame.h"

namespace zm {
namespace {

using test::Contains;

using test::TempDir;
using test::TumFolderSpec;
using test::WriteTumFolder;

TumFolderOptions OptionsFor(const TumFolderSpec& s) {
  TumFolderOptions o;
  o.camera = test::TumTestCamera(s);
  return o;
}

TEST_CASE("tum: rgb.txt and depth.txt are associated by the nearest stamp and every frame reads") {
  TempDir dir;
  TumFolderSpec spec;
  spec.frames = 5;
  WriteTumFolder(dir.File("seq"), spec);
  auto folder = ReadTumFolder(dir.File("seq"), OptionsFor(spec));
  REQUIRE_MESSAGE(folder.ok(), folder.status().ToString());
  CHECK(folder->listing == "rgb.txt + depth.txt");
  CHECK(folder->colour_entries == 5);
  CHECK(folder->depth_entries == 5);
  CHECK(folder->gaps == 0);
  REQUIRE(folder->frames.size() == 5);
  for (std::size_t i = 0; i < 5; ++i) {
    const TumFrameFiles& f = folder->frames[i];
    CHECK(f.depth_stamp_s - f.stamp_s == doctest::Approx(0.004).epsilon(1e-3));
    CHECK(Contains(f.rgb_path, "/rgb/"));
    CHECK(Contains(f.depth_path, "/depth/"));
    TumFrameImages images;
    REQUIRE(ReadTumFrame(f, OptionsFor(spec), &images).ok());
    CHECK(images.colour.type() == CV_8UC3);
    CHECK(images.depth16.type() == CV_16UC1);
    CHECK(images.colour.cols == 320);
    CHECK(images.depth16.at<std::uint16_t>(0, 0) == 10000);  // 2 m at 5,000 per metre
  }
}

TEST_CASE("tum: associations.txt is used when present, either pair first") {
  TempDir dir;
  TumFolderSpec spec;
  spec.frames = 4;
  spec.associations = true;
  WriteTumFolder(dir.File("seq"), spec);
  SUBCASE("colour first") {}
  SUBCASE("depth first") {
    // Rewrite the file with the depth pair first, as associate.py writes it with its arguments
    // swapped.
    std::ifstream in(dir.File("seq/associations.txt"));
    std::string a, b, c, d, text;
    while (in >> a >> b >> c >> d) text += c + " " + d + " " + a + " " + b + "\n";
    in.close();
    std::ofstream(dir.File("seq/associations.txt")) << text;
  }
  auto folder = ReadTumFolder(dir.File("seq"), OptionsFor(spec));
  REQUIRE(folder.ok());
  CHECK(folder->listing == "associations.txt");
  REQUIRE(folder->frames.size() == 4);
  CHECK(Contains(folder->frames[0].rgb_path, "/rgb/"));
  CHECK(folder->frames[0].depth_stamp_s > folder->frames[0].stamp_s);
  TumFrameImages images;
  CHECK(ReadTumFrame(folder->frames[3], OptionsFor(spec), &images).ok());
}

TEST_CASE("tum: gaps and malformed lines are counted and reported, not errors") {
  TempDir dir;
  TumFolderSpec spec;
  spec.frames = 8;
  spec.depth_gaps = {2, 5};
  WriteTumFolder(dir.File("seq"), spec);
  {
    std::ofstream add(dir.File("seq/rgb.txt"), std::ios::app);
    add << "not-a-stamp rgb/x.png\n"
        << "1305031200.0\n";
  }
  auto folder = ReadTumFolder(dir.File("seq"), OptionsFor(spec));
  REQUIRE(folder.ok());
  CHECK(folder->colour_entries == 8);
  CHECK(folder->gaps == 2);
  CHECK(folder->malformed_lines == 2);
  CHECK(folder->frames.size() == 6);
  REQUIRE(folder->problems.size() == 4);
  CHECK(Contains(folder->problems[0], "rgb.txt line 11: expected 'stamp path', skipped"));
  CHECK(Contains(folder->problems[2], "no depth within 0.02"));
  CHECK(Contains(folder->problems[2], "(gap)"));
}

TEST_CASE("tum: a tighter tolerance than the depth's offset makes every frame a gap") {
  TempDir dir;
  TumFolderSpec spec;
  spec.frames = 3;
  WriteTumFolder(dir.File("seq"), spec);
  TumFolderOptions o = OptionsFor(spec);
  o.max_stamp_difference_s = 0.001;
  auto folder = ReadTumFolder(dir.File("seq"), o);
  REQUIRE_FALSE(folder.ok());
  CHECK(folder.status().code() == StatusCode::kFailedPrecondition);
  CHECK(Contains(folder.status().message(), "no colour frame with depth"));
  CHECK(Contains(folder.status().message(), "3 gaps"));
}

TEST_CASE("tum: every bad image is one error naming the file") {
  TempDir dir;
  TumFolderSpec spec;
  spec.frames = 5;
  spec.missing_colour = {0};
  spec.unreadable_colour = {1};
  spec.truncated_depth = {2};
  spec.wrong_size_colour = {3};
  WriteTumFolder(dir.File("seq"), spec);
  auto folder = ReadTumFolder(dir.File("seq"), OptionsFor(spec));
  REQUIRE(folder.ok());
  REQUIRE(folder->frames.size() == 5);
  struct Case {
    int frame;
    StatusCode code;
    std::string text;
  };
  const Case cases[] = {
      {0, StatusCode::kNotFound, "colour image " + folder->frames[0].rgb_path + " is missing"},
      {1, StatusCode::kCorrupt,
       "colour image " + folder->frames[1].rgb_path + " (17 bytes) cannot be decoded"},
      {2, StatusCode::kCorrupt, "depth image " + folder->frames[2].depth_path},
      {3, StatusCode::kInvalidArgument, "is 160x120, the camera is 320x240"},
  };
  for (const Case& c : cases) {
    CAPTURE(c.frame);
    TumFrameImages images;
    const Status st =
        ReadTumFrame(folder->frames[static_cast<std::size_t>(c.frame)], OptionsFor(spec), &images);
    REQUIRE_FALSE(st.ok());
    INFO(st.message());
    CHECK(st.code() == c.code);
    CHECK(Contains(st.message(), c.text));
    CHECK(st.message().find('\n') == std::string::npos);
    CHECK(images.colour.empty());
    CHECK(images.depth16.empty());
  }
  TumFrameImages images;
  CHECK(ReadTumFrame(folder->frames[4], OptionsFor(spec), &images).ok());
}

TEST_CASE("tum: a folder without lists, and bad options, are refused") {
  TempDir dir;
  std::filesystem::create_directories(dir.File("empty"));
  auto none = ReadTumFolder(dir.File("empty"));
  REQUIRE_FALSE(none.ok());
  CHECK(Contains(none.status().message(),
                 "has neither associations.txt nor both rgb.txt and depth.txt"));
  auto missing = ReadTumFolder(dir.File("nope"));
  REQUIRE_FALSE(missing.ok());
  CHECK(missing.status().code() == StatusCode::kNotFound);
  TumFolderOptions o;
  o.depth_units_per_m = 0;
  CHECK(Contains(ValidateTumFolderOptions(o).message(), "depth units per metre"));
  o = TumFolderOptions{};
  CHECK(o.camera.fx == 517.3);
  CHECK(o.camera.cy == 255.3);
  CHECK(o.camera.width == 640);
}

}  // namespace
}  // namespace zm
