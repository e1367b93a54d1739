// Frames file: round trip, refill without allocation, and corrupt files rejected with errors.
#include "runtime/frames_file.h"

#include <doctest/doctest.h>

#include <cstdio>
#include <filesystem>
#include <fstream>

#include "support/counting_allocator.h"

namespace zm {
namespace {

std::string TempPath(const char* name) {
  return (std::filesystem::temp_directory_path() / name).string();
}

CameraIntrinsics TestCamera() { return {.fx = 320, .fy = 320, .cx = 320, .cy = 240, .width = 640, .height = 480}; }

Frame MakeFrame(std::uint64_t index, std::uint32_t n) {
  Frame f;
  f.index = index;
  f.stamp_s = 0.5 * static_cast<double>(index);
  f.odom = PoseFromXYYaw(1.0 + static_cast<double>(index), -2.0, 0.3, 1.0);
  for (std::uint32_t i = 0; i < n; ++i) {
    Descriptor256 d{};
    for (std::size_t b = 0; b < d.size(); ++b) d[b] = static_cast<std::uint8_t>(i * 7 + b + index);
    f.descriptors.push_back(d);
    f.keypoints.push_back(static_cast<float>(i));
    f.keypoints.push_back(static_cast<float>(index));
  }
  return f;
}

TEST_CASE("frames file round-trips frames and refills a reserved frame") {
  const std::string path = TempPath("zm_frames_roundtrip.bin");
  {
    auto w = FrameWriter::Create(path, TestCamera(), 2.0);
    REQUIRE(w.ok());
    for (std::uint64_t i = 0; i < 5; ++i) REQUIRE(w->Append(MakeFrame(i, static_cast<std::uint32_t>(10 * i))).ok());
    CHECK(w->Append(MakeFrame(7, 1)).code() == StatusCode::kInvalidArgument);
    REQUIRE(w->Finish().ok());
  }
  auto r = FrameReader::Open(path);
  REQUIRE(r.ok());
  CHECK(r->count() == 5);
  CHECK(r->max_features() == 40);
  CHECK(r->camera().width == 640);
  CHECK(r->rate_hz() == 2.0);
  Frame f;
  f.Reserve(r->max_features());
  for (std::uint64_t i = 0; i < 5; ++i) {
    const Frame expect = MakeFrame(i, static_cast<std::uint32_t>(10 * i));
    test::AllocationCounter counter;
    auto more = r->Next(&f);
    const auto allocations = counter.allocations();
    REQUIRE(more.ok());
    CHECK(*more);
    CHECK(allocations == 0);
    CHECK(f.index == i);
    CHECK(f.stamp_s == expect.stamp_s);
    CHECK(f.descriptors == expect.descriptors);
    CHECK(f.keypoints == expect.keypoints);
    CHECK((f.odom.matrix() - expect.odom.matrix()).norm() < 1e-12);
  }
  auto end = r->Next(&f);
  REQUIRE(end.ok());
  CHECK_FALSE(*end);
  REQUIRE(r->Rewind().ok());
  auto again = r->Next(&f);
  REQUIRE(again.ok());
  CHECK(*again);
  CHECK(f.index == 0);
  std::filesystem::remove(path);
}

TEST_CASE("frames file: a truncated or foreign file is a clear error") {
  const std::string path = TempPath("zm_frames_trunc.bin");
  {
    auto w = FrameWriter::Create(path, TestCamera(), 5.0);
    REQUIRE(w.ok());
    for (std::uint64_t i = 0; i < 3; ++i) REQUIRE(w->Append(MakeFrame(i, 8)).ok());
    REQUIRE(w->Finish().ok());
  }
  std::filesystem::resize_file(path, std::filesystem::file_size(path) - 10);
  auto r = FrameReader::Open(path);
  REQUIRE(r.ok());
  Frame f;
  f.Reserve(8);
  CHECK(*r->Next(&f));
  CHECK(*r->Next(&f));
  auto bad = r->Next(&f);
  REQUIRE_FALSE(bad.ok());
  CHECK(bad.status().code() == StatusCode::kCorrupt);
  CHECK(bad.status().message().find("frame 2") != std::string::npos);

  { std::ofstream(path, std::ios::binary) << "not a frames file at all, just text"; }
  auto foreign = FrameReader::Open(path);
  REQUIRE_FALSE(foreign.ok());
  CHECK(foreign.status().code() == StatusCode::kCorrupt);
  CHECK(FrameReader::Open(TempPath("zm_frames_missing.bin")).status().code() == StatusCode::kNotFound);
  std::filesystem::remove(path);
}

}  // namespace
}  // namespace zm

namespace zm {
namespace {

TEST_CASE("frames file v2: a frame's colour image round-trips, a damaged one is a clear error") {
  const std::string path = TempPath("zm_frames_images.bin");
  {
    auto w = FrameWriter::Create(path, TestCamera(), 10.0);
    REQUIRE(w.ok());
    for (std::uint64_t i = 0; i < 3; ++i) {
      Frame f = MakeFrame(i, 0);  // a camera's frame: no features, an image
      f.colour_codec = ImageCodec::kJpeg;
      f.colour.assign(100 + 50 * i, std::byte{static_cast<unsigned char>(i + 1)});
      REQUIRE(w->Append(f).ok());
    }
    Frame png = MakeFrame(3, 0);
    png.colour_codec = ImageCodec::kPng;
    png.colour.assign(10, std::byte{1});
    CHECK(w->Append(png).message().find("not JPEG") != std::string::npos);
    REQUIRE(w->Finish().ok());
  }
  auto r = FrameReader::Open(path);
  REQUIRE(r.ok());
  CHECK(r->max_colour_bytes() == 200);
  Frame f;
  f.Reserve(r->max_features(), r->max_colour_bytes());
  for (std::uint64_t i = 0; i < 3; ++i) {
    test::AllocationCounter counter;
    auto more = r->Next(&f);
    CHECK(counter.allocations() == 0);
    REQUIRE(more.ok());
    REQUIRE(*more);
    CHECK(f.has_image());
    CHECK(f.colour.size() == 100 + 50 * i);
    CHECK(f.colour.front() == std::byte{static_cast<unsigned char>(i + 1)});
    CHECK(f.feature_count() == 0);
  }
  // Cut inside the last image: the reader names the frame and the image.
  std::filesystem::resize_file(path, std::filesystem::file_size(path) - 20);
  auto cut = FrameReader::Open(path);
  REQUIRE(cut.ok());
  f.Reserve(0, cut->max_colour_bytes());
  REQUIRE(cut->Next(&f).ok());
  REQUIRE(cut->Next(&f).ok());
  auto last = cut->Next(&f);
  REQUIRE_FALSE(last.ok());
  CHECK(last.status().message().find("frame 2") != std::string::npos);
  CHECK(last.status().message().find("inside its colour image") != std::string::npos);
  std::filesystem::remove(path);
}

}  // namespace
}  // namespace zm
