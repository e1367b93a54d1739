// Anchor translation unit of zm_geometry (the module is mostly headers until the trajectory
// code lands).
#include "geometry/pose.h"
