// A small simulated hospital and the scenario options the harness and simulator tests start
// from (the tests run under ASan and qemu, so everything is small): a 300 m2 floor at 0.1 m, a
// 320x240 camera of 90 degrees seeing 6 m, 80 features a frame, a keyframe every 1.5 m or 60
// degrees, two writer threads. Each test sets what it is about on top: the image size, the
// number of patrol tasks, the frame rate.
#pragma once

#include <cstdint>

#include "sim/building.h"
#include "sim/scenario.h"

namespace zm::test {

inline sim::HospitalOptions SmallHospital(std::uint64_t seed) {
  sim::HospitalOptions h;
  h.seed = seed;
  h.area_m2 = 300.0;
  h.resolution_m = 0.1;
  return h;
}

inline sim::ScenarioOptions SmallScenario(std::uint64_t seed) {
  sim::ScenarioOptions o;
  o.seed = seed;
  o.camera.intrinsics = sim::MakeIntrinsics(320, 240, 90.0);
  o.noise.max_features = 80;
  o.camera.range_m = 6.0;
  o.keyframe_distance_m = 1.5;
  o.keyframe_angle_deg = 60.0;
  o.threads = 2;
  return o;
}

// The harness tests' replays: 160x120 images with a cloud at every pixel, frames at 1 Hz.
inline sim::ScenarioOptions SmallReplayScenario(std::uint64_t seed, int tasks) {
  sim::ScenarioOptions o = SmallScenario(seed);
  o.dense.width = 160;
  o.dense.height = 120;
  o.dense.cloud_step = 1;
  o.tasks = tasks;
  o.rate_hz = 1.0;
  return o;
}

}  // namespace zm::test
