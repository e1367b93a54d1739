// Shared start-up pieces: see map_setup.h. The tick loop and the public API both call them.
#include "runtime/map_setup.h"

#include <utility>

#include "zones/adjacency.h"

namespace zm {

Result<MapIndex> BuildPolicyIndex(std::span<const KeyframeMeta> keyframes,
                                  std::span<const LinkRecord> links, const ZoneSet& zones,
                                  std::span<const ZoneMember> members) {
  const ZoneGraph graph = BuildAdjacency(zones, members, links);
  std::vector<std::vector<ZoneId>> adjacency(zones.size());
  for (std::size_t z = 0; z < zones.size(); ++z) {
    const auto nb = graph.Neighbours(ZoneId{static_cast<std::int32_t>(z)});
    adjacency[z].assign(nb.begin(), nb.end());
  }
  MapIndexInput input;
  input.keyframes = keyframes;
  input.links = links;
  input.members = members;
  input.zone_count = static_cast<std::int32_t>(zones.size());
  input.zone_adjacency = adjacency;
  return MapIndex::Build(input);
}

bool StartsFromLastWorkingMemory(const PolicyOptions& policy) {
  return Traits(policy.kind).may_start_from_last_wm && !policy.basic.init_wm_with_all_nodes &&
         policy.basic.initial_wm.empty();
}

PolicyOptions PolicyOptionsFor(const LoopConfig& config, const Budget& budget,
                               std::span<const KeyframeMeta> keyframes,
                               std::vector<ZoneId> oracle_future, RecordedWorkingMemory* recorded) {
  PolicyOptions popt = config.policy;
  popt.k_max = budget.k_max;
  popt.oracle.future = std::move(oracle_future);
  if (popt.kind == PolicyKind::kBasic) {
    // Memory management is on when MemoryThr is set (RTAB-Map: MemoryThr > 0).
    const bool any_limit = config.map.memory_thr_keyframes != 0 || budget.map_share_bytes != 0;
    popt.basic.memory_thr = any_limit ? budget.k_max : 0;
    popt.k_max = popt.basic.memory_thr;
    if (StartsFromLastWorkingMemory(config.policy)) {
      if (recorded != nullptr && !recorded->every_node) {
        popt.basic.initial_wm = std::move(recorded->ids);
      } else {
        popt.basic.initial_wm.reserve(keyframes.size());
        for (const KeyframeMeta& k : keyframes) popt.basic.initial_wm.push_back(k.id);
      }
    }
  }
  return popt;
}

}  // namespace zm
