// A replay on a simulated device: the profile's memory split, a device ledger shared with the
// co-tenant stand-in, and the map process's own charge updated every tick. What `zonemap run`
// and `zonemap bench` call; summary.json gains `cotenant` and `device` sections.
//
// Ledger tenants: "os" (the profile's OS/JetPack reserve), "map" (arena reservation for the
// bounded policies, whose budget is reserved up front; resident slots for basic/unbounded, whose
// memory grows like RTAB-Map's heap; plus the process overhead) and the co-tenant. A map update
// the device cannot hold is refused and counted as an out-of-memory event.
#pragma once

#include <atomic>
#include <string>

#include <nlohmann/json.hpp>

#include "common/status.h"
#include "harness/experiment_profile.h"
#include "harness/run.h"

namespace zm {

struct DeviceRunRequest {
  std::string scenario_dir;
  std::string out_dir;
  ExperimentProfile profile;
  bool with_cotenant = false;
  double cotenant_scale = 1.0;    // weights multiplier (tests, CI); the report states it
  bool verify_checksums = false;
  double pace_speedup = 0.0;  // see RunRequest
};

[[nodiscard]] Result<nlohmann::json> RunOnDevice(const DeviceRunRequest& request,
                                                 const std::atomic<bool>* stop = nullptr);

}  // namespace zm
