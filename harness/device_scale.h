// --device-scale S: the device under test at a fraction of its size, so that tests run the
// experiment at 1/8 and `make demo` at full size. Device memory, OS reserve, model weights, KV
// cache and keyframe footprint shrink together, so every ratio the experiment depends on (and
// K_max itself) stays what it is at full size.
//
// Invariants: 0 < S <= 1 (anything else is an error naming S); S = 1 changes nothing; a byte
// count of 0 ("unknown"/"none") stays 0 and a positive one stays positive.
#pragma once

#include <cstdint>

#include "common/status.h"
#include "runtime/budget.h"

namespace zm {

// OK when 0 < scale <= 1; otherwise an error naming the value and the range.
[[nodiscard]] Status ValidateDeviceScale(double scale);

// bytes * scale, rounded to the nearest byte; 0 stays 0, a positive count stays >= 1. The one
// rounding rule for every byte quantity the experiment scales.
[[nodiscard]] std::uint64_t ScaleBytes(std::uint64_t bytes, double scale) noexcept;

// Scales every byte quantity of the memory split by `scale`: device memory, OS reserve and swap;
// the model's weights and KV cache; the map's explicit share, headroom, overhead and slot size. Not
// scaled: keyframe counts (MemoryThr), and map.process_cap_bytes (an RLIMIT_AS cap counts code,
// libraries and sanitizer shadow that do not shrink with the device). The keyframes the map
// database holds are the scenario's: generate them with the same S as
// sim::DenseOptions::footprint_scale (lib/sim/rgbd.h; it scales the image resolution, so the
// footprint follows S approximately, not to the byte).
[[nodiscard]] Status ApplyDeviceScale(double scale, DeviceOptions& device, ModelOptions& model,
                                      MapOptions& map);

// The memory cgroup's limit for a device: memory - OS reserve (what the map and the model
// share). Errors when the device memory is unknown (0) or the reserve leaves nothing.
[[nodiscard]] Result<std::uint64_t> DeviceLimitBytes(const DeviceOptions& device);

}  // namespace zm
