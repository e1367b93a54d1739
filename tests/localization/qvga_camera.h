// The 320 x 240 pinhole camera the ORB extractor and front-end tests draw their images for.
#pragma once

#include "localization/camera.h"

namespace zm::test {

inline constexpr int kW = 320;
inline constexpr int kH = 240;
inline const CameraIntrinsics kCamera{300.0, 300.0, 160.0, 120.0, kW, kH};

}  // namespace zm::test
