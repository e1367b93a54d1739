// Glue between the public pose (include/zonemap/types.h: seven doubles, standard library only)
// and the core's Eigen isometry, and the profile both entry points start from. Private to the
// API library. Status, Result, the ids and LinkKind need no glue: the core uses the public types
// themselves (lib/common/).
#pragma once

#include <string>
#include <string_view>

#include "common/status.h"
#include "geometry/pose.h"
#include "runtime/profile.h"
#include "zonemap/types.h"

namespace zonemap::internal {

// A public pose as the input gate sees it: the isometry with its quaternion normalised, and
// |q| as sent (the gate's quaternion rule, runtime/input_gate.h, decides whether it is unit
// enough).
struct GatedPose {
  zm::Pose3 pose = zm::Pose3::Identity();
  double quaternion_norm = 1.0;
};

// The syntax check of a public pose: every number finite (`what` names the pose in the error).
// Sanity, the quaternion's norm included, is the gate's.
[[nodiscard]] zm::Result<GatedPose> ToPose3(const Pose& p, std::string_view what);
[[nodiscard]] Pose FromPose3(const zm::Pose3& p);

// The profile of MapLoopOptions::profile and ManagerOptions::profile, resolved the one way for
// both: a name (searched like zonemapd's) or a .toml path is loaded; empty (both options'
// default) is no profile: every module's defaults and no device memory, so the budget is a
// count (MemoryThr's, else the whole map); its source reads kNoProfileSource.
inline constexpr std::string_view kNoProfileSource = "(no profile)";
[[nodiscard]] zm::Result<zm::Profile> ProfileOrDefaults(const std::string& name_or_path);

}  // namespace zonemap::internal
