// The loop's visual front-end (lib/localization/front_end.h): a frame's JPEG or PNG colour image
// in, the extractor's features out (the same as extracting from the decoded image), without a
// heap allocation once warm; every kind of bad image is one error naming the frame, and leaves
// the frame without features.
#include "localization/front_end.h"

#include <doctest/doctest.h>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <random>
#include <vector>

#include "arena/sanitizers.h"
#include "localization/qvga_camera.h"
#include "mapdb/dense_codec.h"
#include "support/counting_allocator.h"

namespace zm {
namespace {

using test::kCamera;
using test::kH;
using test::kW;

cv::Mat TexturedRgb(std::uint32_t seed) {
  std::mt19937 rng(seed);
  cv::Mat img(kH, kW, CV_8UC3);
  for (int y = 0; y < kH; y += 6) {
    for (int x = 0; x < kW; x += 6) {
      img(cv::Rect(x, y, std::min(6, kW - x), std::min(6, kH - y))) =
          cv::Scalar(static_cast<double>(rng() % 256), static_cast<double>(rng() % 256),
                     static_cast<double>(rng() % 256));
    }
  }
  cv::GaussianBlur(img, img, cv::Size(3, 3), 0.8);
  return img;
}

Frame JpegFrame(const cv::Mat& rgb, std::uint64_t index = 1) {
  const std::span<const std::uint8_t> px(rgb.data, rgb.total() * 3);
  auto jpeg = EncodeJpegRgb(px, kW, kH, 95);
  REQUIRE(jpeg.ok());
  Frame f;
  f.index = index;
  f.Reserve(1000, jpeg->size());
  f.colour_codec = ImageCodec::kJpeg;
  f.colour.assign(jpeg->begin(), jpeg->end());
  return f;
}

Frame PngFrame(const cv::Mat& rgb, std::uint64_t index = 2) {
  cv::Mat bgr;
  cv::cvtColor(rgb, bgr, cv::COLOR_RGB2BGR);
  std::vector<std::uint8_t> png;
  REQUIRE(cv::imencode(".png", bgr, png));
  Frame f;
  f.index = index;
  f.Reserve(1000, png.size());
  f.colour_codec = ImageCodec::kPng;
  for (std::uint8_t b : png) f.colour.push_back(std::byte{b});
  return f;
}

std::unique_ptr<FrontEnd> Make() {
  auto fe = FrontEnd::Create(OrbOptions{}, kCamera);
  REQUIRE(fe.ok());
  return std::move(fe).value();
}

TEST_CASE("front-end: JPEG and PNG frames give the extractor's features, strongest first") {
  auto fe = Make();
  const cv::Mat rgb = TexturedRgb(3);
  Frame jf = JpegFrame(rgb);
  FrontEndTimes t;
  REQUIRE(fe->Process(&jf, &t).ok());
  CHECK(jf.feature_count() > 200);
  CHECK(jf.keypoints.size() == 2 * std::size_t{jf.feature_count()});
  CHECK(t.extract_ms > 0.0);

  // PNG is lossless: its features are exactly those of the image itself.
  Frame pf = PngFrame(rgb);
  REQUIRE(fe->Process(&pf, &t).ok());
  auto direct = OrbExtractor::Create(OrbOptions{}, kCamera);
  REQUIRE(direct.ok());
  cv::Mat grey;
  cv::cvtColor(rgb, grey, cv::COLOR_RGB2GRAY);
  OrbFeatures expect(1000);
  REQUIRE(direct->Extract(grey, {}, &expect).ok());
  REQUIRE(pf.feature_count() == expect.count);
  for (std::uint32_t i = 0; i < expect.count; ++i) {
    CHECK(pf.descriptors[i] == expect.descriptors[i]);
    CHECK(pf.keypoints[2 * i] == expect.keypoints[2 * i]);
  }
}

TEST_CASE("front-end: a warm frame allocates nothing from the heap") {
  auto fe = Make();
  Frame a = JpegFrame(TexturedRgb(4));
  Frame b = JpegFrame(TexturedRgb(5));
  Frame p = PngFrame(TexturedRgb(6));
  FrontEndTimes t;
  REQUIRE(fe->Process(&a, &t).ok());  // warm-up
  REQUIRE(fe->Process(&p, &t).ok());
  test::AllocationCounter news;
  test::MallocCounter mallocs;
  REQUIRE(fe->Process(&b, &t).ok());  // a JPEG frame
  REQUIRE(fe->Process(&p, &t).ok());  // and a PNG one
  CHECK(news.allocations() == 0);
#if ZM_ASAN
  CHECK(mallocs.mallocs() <= 2 * OrbOptions{}.levels);  // FAST's BufferArea: orb_extractor_test
#else
  CHECK(mallocs.mallocs() == 0);
#endif
}

TEST_CASE("front-end: bad images are one error naming the frame, and no features") {
  auto fe = Make();
  FrontEndTimes t;
  const auto fails = [&](Frame f) {
    const Status s = fe->Process(&f, &t);
    CHECK(f.feature_count() == 0);
    return s.ok() ? std::string("ok") : s.message();
  };
  Frame good = JpegFrame(TexturedRgb(6), 7);
  Frame empty = good;
  empty.colour.clear();
  CHECK(fails(empty) == "frame 7: colour image is empty");
  Frame cut = good;
  cut.colour.resize(cut.colour.size() / 2);
  CHECK(fails(cut).find("frame 7: colour image") == 0);
  Frame noise = good;
  for (std::byte& b : noise.colour) b = std::byte{0x5A};
  CHECK(fails(noise).find("frame 7: colour image") == 0);
  Frame rvl = good;
  rvl.colour_codec = ImageCodec::kRvl;
  CHECK(fails(rvl) == "frame 7: colour image: codec not readable (JPEG or PNG)");
  // A PNG of another size.
  std::vector<std::uint8_t> png;
  REQUIRE(cv::imencode(".png", cv::Mat(10, 10, CV_8UC3, cv::Scalar(1, 2, 3)), png));
  Frame small = good;
  small.colour_codec = ImageCodec::kPng;
  small.colour.clear();
  for (std::uint8_t b : png) small.colour.push_back(std::byte{b});
  CHECK(fails(small) == "frame 7: colour image: PNG of " + std::to_string(png.size()) +
                            " bytes is 10x10, expected 320x240");
  // And the front-end still works afterwards.
  REQUIRE(fe->Process(&good, &t).ok());
  CHECK(good.feature_count() > 0);
}

}  // namespace
}  // namespace zm
