// --device-scale: the range check, the one rounding rule, every byte of the memory split scaled
// together so K_max is the same at 1/8 as at full size, and the cgroup's limit.
#include "harness/device_scale.h"

#include <doctest/doctest.h>

#include <cmath>
#include <limits>

#include "runtime/profile.h"

namespace zm {
namespace {

TEST_CASE("the scale must be above 0 and at most 1") {
  CHECK(ValidateDeviceScale(1.0).ok());
  CHECK(ValidateDeviceScale(0.125).ok());
  for (double bad : {0.0, -0.5, 1.5, std::nan(""), std::numeric_limits<double>::infinity()}) {
    CAPTURE(bad);
    const Status s = ValidateDeviceScale(bad);
    REQUIRE_FALSE(s.ok());
    CHECK(s.message().find("--device-scale") != std::string::npos);
    CHECK(s.message().find("<= 1") != std::string::npos);
  }
}

TEST_CASE("bytes round to the nearest, zero stays zero and a size never vanishes or grows") {
  CHECK(ScaleBytes(0, 0.125) == 0);
  CHECK(ScaleBytes(8, 0.125) == 1);
  CHECK(ScaleBytes(3, 0.125) == 1);   // 0.375 would round to 0: "some" stays "some"
  CHECK(ScaleBytes(12, 0.125) == 2);  // 1.5 rounds away from zero
  CHECK(ScaleBytes(1000, 1.0) == 1000);
  CHECK(ScaleBytes(std::numeric_limits<std::uint64_t>::max(), 1.0) ==
        std::numeric_limits<std::uint64_t>::max());
  CHECK(ScaleBytes(8ULL << 30, 0.125) == 1ULL << 30);
}

TEST_CASE("the whole split scales but counts and the process cap do not") {
  auto p = LoadProfile("orin-nano-8gb");
  REQUIRE_MESSAGE(p.ok(), p.status().ToString());
  DeviceOptions d = p->device;
  ModelOptions m = p->model;
  MapOptions map = p->map;
  map.memory_thr_keyframes = 500;
  map.slot_bytes = 2200000;
  REQUIRE(ApplyDeviceScale(0.125, d, m, map).ok());
  CHECK(d.memory_bytes == ScaleBytes(p->device.memory_bytes, 0.125));
  CHECK(d.memory_bytes == 1ULL << 30);
  CHECK(d.os_reserve_bytes == ScaleBytes(p->device.os_reserve_bytes, 0.125));
  CHECK(m.weights_bytes == ScaleBytes(p->model.weights_bytes, 0.125));
  CHECK(m.kv_cache_bytes == ScaleBytes(p->model.kv_cache_bytes, 0.125));
  CHECK(map.headroom_bytes == ScaleBytes(p->map.headroom_bytes, 0.125));
  CHECK(map.overhead_bytes == ScaleBytes(p->map.overhead_bytes, 0.125));
  CHECK(map.slot_bytes == 275000);
  CHECK(map.memory_thr_keyframes == 500);
  CHECK(map.process_cap_bytes == p->map.process_cap_bytes);
  DeviceOptions same = p->device;
  ModelOptions same_m = p->model;
  MapOptions same_map = p->map;
  REQUIRE(ApplyDeviceScale(1.0, same, same_m, same_map).ok());
  CHECK(same.memory_bytes == p->device.memory_bytes);
  CHECK(same_m.weights_bytes == p->model.weights_bytes);
  CHECK_FALSE(ApplyDeviceScale(2.0, same, same_m, same_map).ok());
  CHECK(same.memory_bytes == p->device.memory_bytes);  // untouched on error
}

TEST_CASE("K_max is the same at 1/8 as at full size") {
  auto p = LoadProfile("orin-nano-8gb");
  REQUIRE(p.ok());
  const std::uint64_t keyframe = 2200000;  // RTAB-Map's ~2.2 MB per node
  auto k_max = [&](double scale) {
    BudgetInputs in;
    in.device = p->device;
    in.model = p->model;
    in.map = p->map;
    REQUIRE(ApplyDeviceScale(scale, in.device, in.model, in.map).ok());
    in.largest_keyframe_bytes = ScaleBytes(keyframe, scale);
    in.keyframe_count = 10000;
    auto b = DeriveBudget(in);
    REQUIRE_MESSAGE(b.ok(), b.status().ToString());
    return b->k_max;
  };
  const std::uint32_t full = k_max(1.0);
  MESSAGE("orin-nano-8gb, 2.2 MB keyframes: K_max " << full << " at 1, " << k_max(0.125)
                                                    << " at 1/8, " << k_max(0.25) << " at 1/4");
  CHECK(full > 100);
  // The share and the slot are rounded separately: at most one slot apart.
  CHECK(std::abs(static_cast<int>(k_max(0.125)) - static_cast<int>(full)) <= 1);
  CHECK(std::abs(static_cast<int>(k_max(0.25)) - static_cast<int>(full)) <= 1);
}

TEST_CASE("the cgroup's limit is device memory less the OS reserve") {
  DeviceOptions d;
  d.name = "test";
  d.memory_bytes = 8ULL << 30;
  d.os_reserve_bytes = 7ULL << 28;  // 1.75 GiB
  auto limit = DeviceLimitBytes(d);
  REQUIRE(limit.ok());
  CHECK(*limit == (8ULL << 30) - (7ULL << 28));
  d.os_reserve_bytes = d.memory_bytes;
  CHECK(DeviceLimitBytes(d).status().message().find("leaves nothing") != std::string::npos);
  d.memory_bytes = 0;
  CHECK(DeviceLimitBytes(d).status().message().find("memory_bytes is 0") != std::string::npos);
}

}  // namespace
}  // namespace zm
