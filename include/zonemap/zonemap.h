// zonemap: keeps a robot's keyframe map inside a hard memory budget by loading and unloading
// whole semantic zones (rooms, corridors), next to a large AI model on an 8 GB edge computer.
//
// The one include a user needs. Two ways in (docs/api.md):
//   zonemap::ZoneManager  bring your own keyframe store: register the host's keyframes and
//                         zones, call once per tick with the pose, carry out the answer
//                         (unload these ids, then load these) under the budget invariant;
//   zonemap::MapLoop      the complete path: zonemap's map database, arena, policy and
//                         localizer, as zonemapd runs them; frames in, corrected poses out.
//
// The public headers use the C++20 standard library only (no Eigen, OpenCV, SQLite, toml++ or
// nlohmann types; tests/api checks their include closure). Link zonemap::zonemap (CMake,
// find_package(zonemap)) or `pkg-config --static --libs zonemap`.
#pragma once

#include "zonemap/map_loop.h"
#include "zonemap/status.h"
#include "zonemap/types.h"
#include "zonemap/zone_manager.h"
