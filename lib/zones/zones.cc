// Anchor translation unit of zm_zones; the module's sources are listed in sources.cmake and
// segment_sources.cmake.
#include "common/ids.h"
