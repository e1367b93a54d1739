// The memory-policy seam: a policy is a pure decision over the MapIndex (metadata) and its own
// small state; it writes a Plan, which the WorkingSet carries out. Policies never touch the
// database, the arena or payload bytes, so their tests need neither.
//
// One tick, in this order (the runtime's loop):
//   plan.Clear(); policy.PlanBeforeLocalize(ctx, &plan); working_set.Apply(plan, &tel);
//   ... localizer matches against working_set.resident(), fills ctx.highest_hypothesis and
//       ctx.localized_on ...
//   plan.Clear(); policy.PlanAfterLocalize(ctx, &plan); working_set.Apply(plan, &tel);
// Start(ctx, &plan) is called once before the first tick (start-up load).
//
// Two hooks because Algorithm 1 (semantic, and radius/predictive/oracle) runs before
// localization, while RTAB-Map's retrieval and transfer (basic) run after its likelihood and
// loop-closure step, so basic's retrieved nodes become candidates from the next tick.
#pragma once

#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "common/ids.h"
#include "common/status.h"
#include "geometry/pose.h"
#include "memory/map_index.h"
#include "memory/plan.h"
#include "memory/policy_kind.h"

namespace zm {

struct TickContext {
  std::uint64_t tick = 0;
  double now_s = 0.0;                 // monotonic seconds (basic truncates ages to whole seconds)
  Pose3 pose = Pose3::Identity();     // current pose estimate, map frame
  ZoneId zone = kNoZone;              // GetZone(pose) after hysteresis; kNoZone = outside all
  bool small_displacement = false;    // < 0.1 m and < 0.1 rad since the last kept frame
  KeyframeId highest_hypothesis{0};   // best-ranked resident keyframe for this frame; 0 = none
  KeyframeId localized_on{0};         // keyframe the frame was localized on; 0 = not localized
  std::span<const ZoneId> route;      // planned zone sequence (predictive); may be empty
};

class MemoryPolicy {
 public:
  virtual ~MemoryPolicy() = default;
  [[nodiscard]] virtual std::string_view name() const = 0;
  // Start-up load (called once, before the first tick).
  virtual void Start(const TickContext& ctx, Plan* plan) = 0;
  virtual void PlanBeforeLocalize(const TickContext& ctx, Plan* plan) = 0;
  virtual void PlanAfterLocalize(const TickContext& ctx, Plan* plan) = 0;
  // Zone batches this policy has started so far (0 for the keyframe-level policies).
  [[nodiscard]] virtual std::uint64_t zone_loads() const { return 0; }
  // MemoryThr changes to k_max at run time (zonemapd's `budget` line), between ticks; ctx is the
  // last tick's. A bounded policy that holds more than k_max writes releases only (no acquire of
  // a keyframe not yet resident) until it fits, so residency never exceeds the new budget at any
  // instant; basic changes its MemoryThr and lets its transfer shed nodes over the next ticks
  // (RTAB-Map's behaviour); unbounded ignores it. k_max never exceeds the arena's capacity (the
  // loop clamps). No allocation.
  virtual void ChangeBudget(std::uint32_t k_max, const TickContext& ctx, Plan* plan) = 0;
  // ctx.route was replaced (zonemapd's `route` line). Only predictive follows a route.
  virtual void RouteChanged(const TickContext& /*ctx*/) {}
};

// Options of every policy, plain structs (read once from a profile).
struct SemanticOptions {
  std::uint32_t k_max = 0;  // MemoryThr in keyframes
};

struct BasicOptions {
  std::uint32_t memory_thr = 0;            // Rtabmap/MemoryThr; 0 = memory management off
  std::uint32_t max_retrieved = 2;         // Rtabmap/MaxRetrieved
  std::uint32_t max_local_retrieved = 2;   // RGBD/MaxLocalRetrieved
  double local_radius_m = 10.0;            // RGBD/LocalRadius
  double local_immunization_ratio = 0.25;  // RGBD/LocalImmunizationRatio
  std::uint32_t prediction_lc_size = 18;   // |Bayes/PredictionLC|: margins 0..size-2
  bool transfer_sorting_by_weight_id = false;  // Mem/TransferSortingByWeightId
  bool init_wm_with_all_nodes = false;     // Mem/InitWMWithAllNodes
  std::vector<KeyframeId> initial_wm;      // the last session's WM when !init_wm_with_all_nodes
};

// Autoware's dynamic map loading (pointcloud_divider tiles, ndt_scan_matcher's
// dynamic_map_loading), scaled indoors: Autoware's outdoor defaults are a 20 m grid, a 150 m map
// radius and a 20 m update distance; a 150 m radius holds a whole hospital floor, so the indoor
// default radius is 30 m (about three rooms and a corridor either way).
struct RadiusOptions {
  std::uint32_t k_max = 0;
  double tile_m = 20.0;             // pointcloud_divider grid
  double map_radius_m = 30.0;       // dynamic_map_loading.map_radius (Autoware: 150 m outdoors)
  double update_distance_m = 20.0;  // dynamic_map_loading.update_distance
};

// Time slicing is not a policy option: the WorkingSet slices every policy's loads
// (LoadSliceOptions, working_set.h).
struct PredictiveOptions {
  std::uint32_t k_max = 0;
  bool prefetch = true;
};

struct OracleOptions {
  std::uint32_t k_max = 0;
  std::vector<ZoneId> future;  // the zone of every tick (kNoZone allowed), from tick 0
};

struct PolicyOptions {
  PolicyKind kind = PolicyKind::kSemantic;  // parsed once (policy_kind.h)
  std::uint32_t k_max = 0;          // copied into every policy's budget
  SemanticOptions semantic;
  BasicOptions basic;
  RadiusOptions radius;
  PredictiveOptions predictive;
  OracleOptions oracle;
};

class LtmGraph;

// Makes the policy of options.kind over `index` (which must outlive it). Allocates everything
// it will ever need here. Errors name the bad option. `ltm_graph` is where basic reads the
// long-term-memory nodes its graph searches admit (the run-time passes the map's SourceLtmGraph,
// which must outlive the policy); null = the MapIndex stands in (tests and the decision
// benchmark). The other policies ignore it.
[[nodiscard]] Result<std::unique_ptr<MemoryPolicy>> MakePolicy(const MapIndex& index,
                                                               const PolicyOptions& options,
                                                               LtmGraph* ltm_graph = nullptr);

}  // namespace zm
