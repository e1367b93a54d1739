// Glue between the public types (include/zonemap/, standard library only) and the core's (Eigen
// poses, strong ids, zm::Status). Private to the API library.
#pragma once

#include <string_view>

#include "common/status.h"
#include "geometry/pose.h"
#include "zonemap/status.h"
#include "zonemap/types.h"

namespace zonemap::internal {

[[nodiscard]] Status ToPublic(const zm::Status& s);

// A public pose as an isometry: finite numbers and a quaternion of norm in [0.5, 1.5]
// (normalised), the line protocol's rule. `what` names the pose in the error.
[[nodiscard]] zm::Result<zm::Pose3> ToPose3(const Pose& p, std::string_view what);
[[nodiscard]] Pose FromPose3(const zm::Pose3& p);

}  // namespace zonemap::internal
