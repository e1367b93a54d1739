// Device scaling arithmetic. See device_scale.h.
#include "harness/device_scale.h"

#include <cmath>
#include <cstdio>

namespace zm {

Status ValidateDeviceScale(double scale) {
  if (!std::isfinite(scale) || scale <= 0.0 || scale > 1.0) {
    char buf[64];
    std::snprintf(buf, sizeof buf, "%g", scale);
    return InvalidArgument(std::string("--device-scale ") + buf +
                           " is out of range: it must be > 0 and <= 1");
  }
  return Status::Ok();
}

std::uint64_t ScaleBytes(std::uint64_t bytes, double scale) noexcept {
  if (bytes == 0) return 0;
  const long double scaled = std::round(static_cast<long double>(bytes) * scale);
  if (scaled < 1.0L) return 1;
  if (scaled >= static_cast<long double>(bytes)) return bytes;  // scale <= 1 never grows
  return static_cast<std::uint64_t>(scaled);
}

Status ApplyDeviceScale(double scale, DeviceOptions& device, ModelOptions& model, MapOptions& map) {
  ZM_RETURN_IF_ERROR(ValidateDeviceScale(scale));
  for (std::uint64_t* bytes : {&device.memory_bytes, &device.os_reserve_bytes, &device.swap_bytes,
                               &model.weights_bytes, &model.kv_cache_bytes, &map.map_share_bytes,
                               &map.headroom_bytes, &map.overhead_bytes, &map.slot_bytes}) {
    *bytes = ScaleBytes(*bytes, scale);
  }
  return Status::Ok();
}

Result<std::uint64_t> DeviceLimitBytes(const DeviceOptions& device) {
  if (device.memory_bytes == 0) {
    return InvalidArgument("device '" + device.name +
                           "': device.memory_bytes is 0 (unknown), so there is no device limit");
  }
  if (device.os_reserve_bytes >= device.memory_bytes) {
    return OutOfRange("device '" + device.name + "': the OS reserve " +
                      FormatBytes(device.os_reserve_bytes) + " leaves nothing of its memory " +
                      FormatBytes(device.memory_bytes));
  }
  return device.memory_bytes - device.os_reserve_bytes;
}

}  // namespace zm
