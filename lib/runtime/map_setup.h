// Start-up pieces shared by the tick loop (TickLoop::Create and Tick call them) and the public
// API's host path (include/zonemap/ZoneManager, which has no database, arena or frame source):
// the MapIndex the policies decide on and the policy's options for one budget. One
// implementation each (docs/style.md §14), so a host driving zonemap with its own keyframes gets
// exactly the policy zonemapd runs (and the same decide step: decide_step.h).
//
// Both allocate (start-up only).
#pragma once

#include <span>
#include <vector>

#include "common/status.h"
#include "geometry/pose.h"
#include "mapdb/map_db.h"
#include "memory/map_index.h"
#include "memory/policy.h"
#include "runtime/budget.h"
#include "runtime/tick_loop.h"
#include "zones/zone_set.h"

namespace zm {

// The policies' index over a map's metadata: keyframes, links, zone memberships, and the zone
// adjacency (zones touching, sharing a keyframe or joined by a link; the predictive policy
// prefetches along it). `zones` gives the zone count and geometry.
[[nodiscard]] Result<MapIndex> BuildPolicyIndex(std::span<const KeyframeMeta> keyframes,
                                                std::span<const LinkRecord> links,
                                                const ZoneSet& zones,
                                                std::span<const ZoneMember> members);

// Whether `policy` starts from the map's last working memory: basic with
// Mem/InitWMWithAllNodes=false and no working memory given. Only then does a caller with a map
// database read MapReader::LastWorkingMemory() for PolicyOptionsFor (an RTAB-Map import that
// predates the record is refused there, so nobody else may ask).
[[nodiscard]] bool StartsFromLastWorkingMemory(const PolicyOptions& policy);

// The policy's options for a map under `budget`: config.policy with K_max, the oracle's future,
// and for basic its MemoryThr (memory management is on when a count or byte limit is set, as
// RTAB-Map's MemoryThr > 0) and, when StartsFromLastWorkingMemory, its start-up working memory:
// the map's last one, `recorded` (what an imported RTAB-Map database recorded: Node.time_enter
// >= the last Info.time_enter), or every node when the map recorded none or says every node (a
// map built without memory management; basic-baseline.md §3.4). A caller without a map database
// (the public API's ZoneManager) passes none; TickLoop::Create passes the database's.
[[nodiscard]] PolicyOptions PolicyOptionsFor(const LoopConfig& config, const Budget& budget,
                                             std::span<const KeyframeMeta> keyframes,
                                             std::vector<ZoneId> oracle_future,
                                             RecordedWorkingMemory* recorded = nullptr);

}  // namespace zm
