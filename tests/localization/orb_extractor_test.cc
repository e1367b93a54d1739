// The ORB adapter (lib/localization/orb_extractor.h): many features on a textured image, none on
// a flat one; strongest first; grey and BGR give the same features; depth (millimetres, TUM's
// 5000 per metre, float metres) gives 3-D points that Project() maps back onto the keypoints;
// features without depth keep their keypoint, flagged; bad inputs give one clear error; what a
// warm Extract allocates is what OpenCV's ORB allocates, nothing more.
#include "localization/orb_extractor.h"

#include <doctest/doctest.h>

#include <cmath>
#include <cstring>
#include <opencv2/imgproc.hpp>
#include <random>

#include "arena/sanitizers.h"
#include "localization/camera.h"
#include "localization/qvga_camera.h"
#include "support/counting_allocator.h"

namespace zm {
namespace {

using test::kCamera;
using test::kH;
using test::kW;

// Random grey 6x6 blocks, lightly blurred: corners everywhere, deterministic from the seed.
cv::Mat TexturedGrey(std::uint32_t seed) {
  std::mt19937 rng(seed);
  cv::Mat img(kH, kW, CV_8UC1);
  for (int y = 0; y < kH; y += 6) {
    for (int x = 0; x < kW; x += 6) {
      img(cv::Rect(x, y, std::min(6, kW - x), std::min(6, kH - y))) =
          cv::Scalar(static_cast<double>(rng() % 256));
    }
  }
  cv::GaussianBlur(img, img, cv::Size(3, 3), 0.8);
  return img;
}

OrbExtractor MakeExtractor(OrbOptions options = {}) {
  auto e = OrbExtractor::Create(options, kCamera);
  REQUIRE(e.ok());
  return std::move(e).value();
}

TEST_CASE("orb extractor: many features on texture, none on a flat image, strongest first") {
  OrbExtractor extractor = MakeExtractor();
  OrbFeatures out(1000);
  REQUIRE(extractor.Extract(TexturedGrey(1), {}, &out).ok());
  MESSAGE("features on a 320x240 textured image: " << out.count);
  CHECK(out.count >= 300);
  CHECK(out.count <= 1000);
  CHECK(out.word_count == std::min(out.count, 500u));
  CHECK(out.with_point == 0);  // no depth given
  for (std::uint32_t i = 1; i < out.count; ++i) CHECK(out.responses[i - 1] >= out.responses[i]);
  for (std::uint32_t i = 0; i < out.count; ++i) {
    CHECK(out.keypoints[2 * i] >= 0.0f);
    CHECK(out.keypoints[2 * i] < static_cast<float>(kW));
    CHECK(out.has_point[i] == 0);
  }

  const cv::Mat flat(kH, kW, CV_8UC1, cv::Scalar(128));
  REQUIRE(extractor.Extract(flat, {}, &out).ok());
  CHECK(out.count == 0);
  CHECK(out.word_count == 0);
}

TEST_CASE("orb extractor: grey and BGR inputs give the same features, run after run") {
  OrbExtractor extractor = MakeExtractor();
  const cv::Mat grey = TexturedGrey(2);
  cv::Mat bgr;
  cv::cvtColor(grey, bgr, cv::COLOR_GRAY2BGR);
  OrbFeatures a(1000);
  OrbFeatures b(1000);
  REQUIRE(extractor.Extract(grey, {}, &a).ok());
  REQUIRE(extractor.Extract(bgr, {}, &b).ok());
  REQUIRE(a.count == b.count);
  REQUIRE(a.count > 0);
  CHECK(std::memcmp(a.descriptors.data(), b.descriptors.data(), a.count * kDescriptorBytes) == 0);
  CHECK(std::memcmp(a.keypoints.data(), b.keypoints.data(), 2 * a.count * sizeof(float)) == 0);
  // The caller's grey image is read, never written (the extractor converts into its own).
  CHECK(cv::norm(grey, TexturedGrey(2), cv::NORM_INF) == 0.0);
}

TEST_CASE("orb extractor: depth gives camera-frame points on the pinhole rays") {
  OrbExtractor extractor = MakeExtractor();
  const cv::Mat grey = TexturedGrey(3);
  struct Case {
    const char* name;
    DepthImage depth;
  };
  const Case cases[] = {
      {"16-bit millimetres", {cv::Mat(kH, kW, CV_16UC1, cv::Scalar(2500)), 1000.0}},
      {"16-bit TUM 5000/m", {cv::Mat(kH, kW, CV_16UC1, cv::Scalar(12500)), 5000.0}},
      {"float metres", {cv::Mat(kH, kW, CV_32FC1, cv::Scalar(2.5)), 1.0}},
  };
  for (const Case& c : cases) {
    CAPTURE(c.name);
    OrbFeatures out(1000);
    REQUIRE(extractor.Extract(grey, c.depth, &out).ok());
    REQUIRE(out.count > 0);
    CHECK(out.with_point == out.count);
    for (std::uint32_t i = 0; i < out.count; ++i) {
      const float* p = &out.points[3 * i];
      CHECK(p[2] == doctest::Approx(2.5f));
      Eigen::Vector2d uv;
      REQUIRE(Project(kCamera, Eigen::Vector3d(p[0], p[1], p[2]), &uv));
      CHECK(uv.x() == doctest::Approx(out.keypoints[2 * i]).epsilon(1e-4));
      CHECK(uv.y() == doctest::Approx(out.keypoints[2 * i + 1]).epsilon(1e-4));
    }
  }

  // No depth on the left half (zeros) and a far wall beyond max_depth_m on the bottom rows:
  // those features keep their keypoints and descriptors but have no point.
  OrbOptions far_limit;
  far_limit.max_depth_m = 4.0;
  OrbExtractor limited = MakeExtractor(far_limit);
  cv::Mat depth(kH, kW, CV_16UC1, cv::Scalar(2000));
  depth(cv::Rect(0, 0, kW / 2, kH)) = cv::Scalar(0);
  depth(cv::Rect(kW / 2, kH - 40, kW / 2, 40)) = cv::Scalar(6000);
  OrbFeatures out(1000);
  REQUIRE(limited.Extract(grey, {depth, 1000.0}, &out).ok());
  std::uint32_t flagged = 0;
  for (std::uint32_t i = 0; i < out.count; ++i) {
    // Keypoints are in zonemap's convention: the pixel holding (u, v) is (floor u, floor v).
    const int x = static_cast<int>(std::floor(out.keypoints[2 * i]));
    const int y = static_cast<int>(std::floor(out.keypoints[2 * i + 1]));
    const bool expect_point = x >= kW / 2 && y < kH - 40;
    CHECK(out.has_point[i] == (expect_point ? 1 : 0));
    if (!expect_point) {
      ++flagged;
      CHECK(std::isnan(out.points[3 * i]));
    }
  }
  CHECK(flagged > 0);
  CHECK(out.with_point == out.count - flagged);
}

TEST_CASE("orb extractor: bad inputs give one clear error naming the thing and the limit") {
  OrbExtractor extractor = MakeExtractor();
  OrbFeatures out(1000);
  const cv::Mat grey = TexturedGrey(4);
  auto error = [&](const cv::Mat& colour, const DepthImage& depth, OrbFeatures* o) {
    const Status s = extractor.Extract(colour, depth, o);
    CHECK(s.code() == StatusCode::kInvalidArgument);
    CHECK(o->count == 0);
    return s.message();
  };
  CHECK(error(cv::Mat(), {}, &out) == "colour image is empty");
  CHECK(error(cv::Mat(kH, kW, CV_16UC1), {}, &out) ==
        "colour image type CV_16UC1 not supported (8UC1 grey, 8UC3 BGR or 8UC4 BGRA)");
  CHECK(error(cv::Mat(kH + 1, kW, CV_8UC1), {}, &out) == "colour image 320x241 != camera 320x240");
  CHECK(error(grey, {cv::Mat(kH / 2, kW / 2, CV_16UC1), 1000.0}, &out) ==
        "depth image 160x120 != colour 320x240");
  CHECK(error(grey, {cv::Mat(kH, kW, CV_8UC1), 1000.0}, &out).find("depth image type CV_8UC1") ==
        0);
  CHECK(error(grey, {cv::Mat(kH, kW, CV_16UC1), 0.0}, &out).find("units_per_m") !=
        std::string::npos);
  OrbFeatures small(10);
  CHECK(error(grey, {}, &small) == "feature buffer capacity 10 < max_features 1000");

  OrbOptions o;
  o.word_features = 2000;
  CHECK(OrbExtractor::Create(o, kCamera).status().message() ==
        "orb word_features 2000 outside [1, max_features 1000]");
  CameraIntrinsics bad = kCamera;
  bad.fx = 0.0;
  CHECK(OrbExtractor::Create({}, bad).status().code() == StatusCode::kInvalidArgument);
}

TEST_CASE(
    "orb extractor: a warm Extract makes no heap allocation, OpenCV's go to the frame scratch") {
  OrbExtractor extractor = MakeExtractor();
  const cv::Mat grey = TexturedGrey(5);
  cv::Mat bgr;
  cv::cvtColor(grey, bgr, cv::COLOR_GRAY2BGR);
  const DepthImage depth{cv::Mat(kH, kW, CV_16UC1, cv::Scalar(2000)), 1000.0};
  OrbFeatures out(1000);
  for (int i = 0; i < 2; ++i) REQUIRE(extractor.Extract(bgr, depth, &out).ok());  // warm-up

  // The bare detector with the same parameters and reused outputs, warmed the same way.
  const OrbOptions& o = extractor.options();
  cv::Ptr<cv::ORB> orb =
      cv::ORB::create(static_cast<int>(o.max_features), o.scale_factor, static_cast<int>(o.levels),
                      static_cast<int>(o.edge_threshold), 0, 2, cv::ORB::HARRIS_SCORE,
                      static_cast<int>(o.patch_size), static_cast<int>(o.fast_threshold));
  std::vector<cv::KeyPoint> keypoints;
  cv::Mat descriptors;
  for (int i = 0; i < 2; ++i) orb->detectAndCompute(grey, cv::noArray(), keypoints, descriptors);

  std::uint64_t orb_news = 0;
  std::uint64_t orb_mallocs = 0;
  {
    test::AllocationCounter news;
    test::MallocCounter mallocs;
    orb->detectAndCompute(grey, cv::noArray(), keypoints, descriptors);
    orb_news = news.allocations();
    orb_mallocs = mallocs.mallocs();
  }
  std::uint64_t ours_news = 0;
  std::uint64_t ours_mallocs = 0;
  {
    test::AllocationCounter news;
    test::MallocCounter mallocs;
    REQUIRE(extractor.Extract(bgr, depth, &out).ok());
    ours_news = news.allocations();
    ours_mallocs = mallocs.mallocs();
  }
  MESSAGE("warm 320x240 frame: cv::ORB::detectAndCompute "
          << orb_news << " operator new + " << orb_mallocs << " malloc; Extract " << ours_news
          << " + " << ours_mallocs);
  // The bare detector does allocate (else the scratch would prove nothing); the extractor, whose
  // OpenCV calls run inside its ScratchScope, does not: neither operator new nor malloc.
  CHECK(orb_news > 0);
  CHECK(orb_mallocs > 0);
  CHECK(ours_news == 0);
#if ZM_ASAN
  // AddressSanitizer owns malloc, so the scratch cannot take the C allocator's requests here:
  // what remains is FAST's row buffers (cv::utils::BufferArea -> cv::fastMalloc), one per
  // pyramid level. The build without a sanitizer (the aarch64 tests) interposes malloc and
  // proves zero.
  CHECK(ours_mallocs <= extractor.options().levels);
#else
  CHECK(ours_mallocs == 0);
#endif
  const FrameScratchStats st = extractor.scratch_stats();
  MESSAGE("frame scratch: " << st.high_water_bytes << " of " << st.capacity_bytes
                            << " bytes at the high water, " << st.allocations << " blocks in "
                            << st.scopes << " frames");
  CHECK(st.overflows == 0);
  CHECK(st.blocks_outliving_scope == 0);
  CHECK(st.high_water_bytes > 0);
  CHECK(st.high_water_bytes <= st.capacity_bytes);
}

TEST_CASE(
    "orb extractor: an undersized frame scratch overflows to the heap, counted, and the "
    "features are the same") {
  OrbOptions small = {};
  small.scratch_bytes = 4096;
  Result<OrbExtractor> tiny = OrbExtractor::Create(small, kCamera);
  REQUIRE(tiny.ok());
  OrbExtractor normal = MakeExtractor();
  const cv::Mat grey = TexturedGrey(7);
  OrbFeatures a(1000);
  OrbFeatures b(1000);
  REQUIRE(tiny->Extract(grey, {}, &a).ok());
  REQUIRE(normal.Extract(grey, {}, &b).ok());
  CHECK(tiny->scratch_stats().overflows > 0);
  CHECK(tiny->scratch_stats().blocks_outliving_scope == 0);
  REQUIRE(a.count == b.count);
  REQUIRE(a.count > 0);
  for (std::uint32_t i = 0; i < a.count; ++i) {
    CHECK(a.descriptors[i] == b.descriptors[i]);
    CHECK(a.keypoints[2 * i] == b.keypoints[2 * i]);
  }
}

}  // namespace
}  // namespace zm
