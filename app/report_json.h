// JSON pieces the commands' reports share, so that a field reads the same in every report
// (import-rtabmap, import-tum, inspect).
#pragma once

#include <nlohmann/json.hpp>

#include "mapdb/map_db.h"

namespace zm::app {

// A camera's intrinsics: {"fx", "fy", "cx", "cy", "width", "height"}.
inline nlohmann::json CameraJson(const CameraIntrinsics& c) {
  return {{"fx", c.fx}, {"fy", c.fy},       {"cx", c.cx},
          {"cy", c.cy}, {"width", c.width}, {"height", c.height}};
}

}  // namespace zm::app
