// Anchor translation unit of zm_runtime; sources are listed in infra_sources.cmake and
// loop_sources.cmake.
#include "common/status.h"
