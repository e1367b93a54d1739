// Dense keyframes, per keyframe: the generator's cost (render, JPEG encode, RVL encode, the whole
// keyframe) and the load path's decode (JPEG, RVL, and DecodeInSlot: colour, depth, points,
// cloud), on default keyframes (640x480) of a simulated hospital (docs/sim.md, "Dense
// keyframes"). A program that prints figures; it asserts nothing.
//
//   build/host-release/bench/zm_dense_bench --benchmark_repetitions=5
//       --benchmark_report_aggregates_only=true      (one line)
#include <benchmark/benchmark.h>

#include <cstring>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <vector>

#include "mapdb/dense_codec.h"
#include "mapdb/keyframe_payload.h"
#include "mapdb/rvl.h"
#include "sim/building.h"
#include "sim/observe.h"
#include "sim/rgbd.h"

namespace {

using namespace zm;        // NOLINT: a benchmark file
using namespace zm::sim;   // NOLINT

struct Fixture {
  Building building;
  LandmarkMap landmarks;
  CameraModel camera{MakeIntrinsics(640, 480, 90.0), 8.0, 1.0};
  std::vector<Pose3> poses;
  std::vector<RenderedKeyframe> keyframes;
  std::vector<RgbdImage> images;

  Fixture() {
    HospitalOptions h;
    h.area_m2 = 1200.0;
    building = std::move(GenerateHospital(h)).value();
    landmarks = LandmarkMap::Generate(building, LandmarkOptions{}, 1);
    for (std::size_t z = 0; z < building.zones.size() && poses.size() < 16; ++z) {
      const Eigen::Vector2d p = building.zones[z].viewpoint;
      poses.push_back(PoseFromXYYaw(p.x(), p.y(), 0.7 * static_cast<double>(z), camera.height_m));
    }
    const DenseOptions dense;
    for (std::size_t i = 0; i < poses.size(); ++i) {
      Rng rng(1, i);
      RenderedKeyframe kf;
      if (!RenderKeyframe(building, landmarks, 0, poses[i], camera, NoiseOptions{}, dense, dense.width,
                          dense.height, KeyframeId(static_cast<std::int64_t>(i + 1)), rng, &kf)
               .ok()) {
        std::abort();
      }
      keyframes.push_back(std::move(kf));
      std::vector<VisibleLandmark> visible;
      landmarks.Visible(building, 0, poses[i], camera, &visible);
      RgbdImage img;
      RenderRgbd(building, 0, poses[i], camera, landmarks, visible, dense.width, dense.height, dense, 7, &img);
      images.push_back(std::move(img));
    }
  }
};

Fixture& F() {
  static Fixture f;
  return f;
}

void BM_RenderRgbd(benchmark::State& state) {
  Fixture& f = F();
  const DenseOptions dense;
  RgbdImage img;
  std::vector<VisibleLandmark> visible;
  std::size_t i = 0;
  for (auto _ : state) {
    const std::size_t k = i++ % f.poses.size();
    f.landmarks.Visible(f.building, 0, f.poses[k], f.camera, &visible);
    RenderRgbd(f.building, 0, f.poses[k], f.camera, f.landmarks, visible, dense.width, dense.height, dense, k, &img);
    benchmark::DoNotOptimize(img.rgb.data());
  }
}
BENCHMARK(BM_RenderRgbd)->Unit(benchmark::kMillisecond);

void BM_EncodeJpeg(benchmark::State& state) {
  Fixture& f = F();
  std::size_t i = 0, bytes = 0;
  for (auto _ : state) {
    const RgbdImage& img = f.images[i++ % f.images.size()];
    auto jpeg = EncodeJpegRgb(img.rgb, img.width, img.height, DenseOptions{}.jpeg_quality);
    bytes += jpeg->size();
    benchmark::DoNotOptimize(jpeg->data());
  }
  state.counters["bytes"] = static_cast<double>(bytes) / static_cast<double>(state.iterations());
}
BENCHMARK(BM_EncodeJpeg)->Unit(benchmark::kMillisecond);

// The alternative that was not taken: the same colour images as PNG (zlib level 1, the fastest).
void BM_EncodePngColour(benchmark::State& state) {
  Fixture& f = F();
  std::size_t i = 0, bytes = 0;
  std::vector<std::uint8_t> png;
  for (auto _ : state) {
    const RgbdImage& img = f.images[i++ % f.images.size()];
    const cv::Mat rgb(static_cast<int>(img.height), static_cast<int>(img.width), CV_8UC3,
                      const_cast<std::uint8_t*>(img.rgb.data()));
    cv::imencode(".png", rgb, png, {cv::IMWRITE_PNG_COMPRESSION, 1});
    bytes += png.size();
    benchmark::DoNotOptimize(png.data());
  }
  state.counters["bytes"] = static_cast<double>(bytes) / static_cast<double>(state.iterations());
}
BENCHMARK(BM_EncodePngColour)->Unit(benchmark::kMillisecond);

void BM_EncodeRvl(benchmark::State& state) {
  Fixture& f = F();
  std::size_t i = 0, bytes = 0;
  for (auto _ : state) {
    const std::vector<std::byte> rvl = EncodeRvlDepth(f.images[i++ % f.images.size()].depth);
    bytes += rvl.size();
    benchmark::DoNotOptimize(rvl.data());
  }
  state.counters["bytes"] = static_cast<double>(bytes) / static_cast<double>(state.iterations());
}
BENCHMARK(BM_EncodeRvl)->Unit(benchmark::kMillisecond);

// The generator's whole per-keyframe cost: features, render, JPEG, RVL, payload.
void BM_RenderKeyframe(benchmark::State& state) {
  Fixture& f = F();
  const DenseOptions dense;
  std::size_t i = 0;
  for (auto _ : state) {
    const std::size_t k = i++ % f.poses.size();
    Rng rng(2, k);
    RenderedKeyframe kf;
    if (!RenderKeyframe(f.building, f.landmarks, 0, f.poses[k], f.camera, NoiseOptions{}, dense, dense.width,
                        dense.height, KeyframeId(1), rng, &kf)
             .ok()) {
      state.SkipWithError("render failed");
    }
    benchmark::DoNotOptimize(kf.payload.data());
  }
}
BENCHMARK(BM_RenderKeyframe)->Unit(benchmark::kMillisecond);

void BM_DecodeJpeg(benchmark::State& state) {
  Fixture& f = F();
  auto decoder = DenseDecoder::Create(f.camera.intrinsics);
  std::vector<std::uint8_t> out(640 * 480 * 3);
  std::size_t i = 0;
  for (auto _ : state) {
    const KeyframeView v = *DecodePayload(f.keyframes[i++ % f.keyframes.size()].payload);
    if (!(*decoder)->DecodeJpegRgb(v.dense.first(v.dense_split), v.dense_width, v.dense_height, out).ok()) {
      state.SkipWithError("decode failed");
    }
  }
}
BENCHMARK(BM_DecodeJpeg)->Unit(benchmark::kMillisecond);

void BM_DecodeRvl(benchmark::State& state) {
  Fixture& f = F();
  std::vector<std::uint16_t> out(640 * 480);
  std::size_t i = 0;
  for (auto _ : state) {
    const KeyframeView v = *DecodePayload(f.keyframes[i++ % f.keyframes.size()].payload);
    if (!DecodeRvlDepthInto(v.dense.subspan(v.dense_split), v.dense_width, v.dense_height, out).ok()) {
      state.SkipWithError("decode failed");
    }
  }
}
BENCHMARK(BM_DecodeRvl)->Unit(benchmark::kMillisecond);

// What the load path adds per keyframe once the blob sits validated in its slot.
void BM_DecodeInSlot(benchmark::State& state) {
  Fixture& f = F();
  auto decoder = DenseDecoder::Create(f.camera.intrinsics);
  std::uint32_t largest = 0;
  for (const auto& kf : f.keyframes) largest = std::max(largest, kf.resident_bytes);
  std::vector<std::byte> slot(largest + 64);
  std::span<std::byte> aligned(slot.data() + (64 - reinterpret_cast<std::uintptr_t>(slot.data()) % 64) % 64, largest);
  std::size_t i = 0;
  for (auto _ : state) {
    const RenderedKeyframe& kf = f.keyframes[i++ % f.keyframes.size()];
    state.PauseTiming();
    std::memcpy(aligned.data(), kf.payload.data(), kf.payload.size());  // the blob read lands here
    state.ResumeTiming();
    auto landed = (*decoder)->DecodeInSlot(aligned, kf.payload.size());
    if (!landed.ok()) state.SkipWithError("decode failed");
  }
}
BENCHMARK(BM_DecodeInSlot)->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
