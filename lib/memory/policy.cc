// MakePolicy: the one place that knows every policy by name.
#include <string>

#include "memory/basic_policy.h"
#include "memory/oracle_policy.h"
#include "memory/policy.h"
#include "memory/predictive_policy.h"
#include "memory/radius_policy.h"
#include "memory/semantic_policy.h"
#include "memory/unbounded_policy.h"

namespace zm {

Status ValidatePolicyName(std::string_view name) {
  for (std::string_view known : {"semantic", "basic", "radius", "predictive", "oracle", "unbounded"}) {
    if (name == known) return Status::Ok();
  }
  return InvalidArgument("unknown memory policy '" + std::string(name) +
                         "'; expected semantic, basic, radius, predictive, oracle or unbounded");
}

bool IsBoundedPolicy(std::string_view name) { return name != "basic" && name != "unbounded"; }

Result<std::unique_ptr<MemoryPolicy>> MakePolicy(const MapIndex& index,
                                                 const PolicyOptions& options,
                                                 LtmGraph* ltm_graph) {
  const std::string& p = options.policy;
  if (p != "unbounded" && options.k_max == 0 && p != "basic") {
    return InvalidArgument("policy " + p + " needs k_max > 0 (MemoryThr)");
  }
  if (p == "semantic") {
    SemanticOptions o = options.semantic;
    o.k_max = options.k_max;
    return std::unique_ptr<MemoryPolicy>(std::make_unique<SemanticPolicy>(index, o));
  }
  if (p == "oracle") {
    OracleOptions o = options.oracle;
    o.k_max = options.k_max;
    return std::unique_ptr<MemoryPolicy>(std::make_unique<OraclePolicy>(index, o));
  }
  if (p == "basic") {
    BasicOptions o = options.basic;
    if (options.k_max != 0) o.memory_thr = options.k_max;
    return std::unique_ptr<MemoryPolicy>(
        std::make_unique<BasicPolicy>(index, std::move(o), ltm_graph));
  }
  if (p == "radius") {
    RadiusOptions o = options.radius;
    o.k_max = options.k_max;
    if (!(o.tile_m > 0) || o.map_radius_m < 0 || o.update_distance_m < 0) {
      return InvalidArgument("radius: tile_m must be > 0, map_radius_m and update_distance_m >= 0");
    }
    return std::unique_ptr<MemoryPolicy>(std::make_unique<RadiusPolicy>(index, o));
  }
  if (p == "predictive") {
    PredictiveOptions o = options.predictive;
    o.k_max = options.k_max;
    return std::unique_ptr<MemoryPolicy>(std::make_unique<PredictivePolicy>(index, o));
  }
  if (p == "unbounded") {
    return std::unique_ptr<MemoryPolicy>(std::make_unique<UnboundedPolicy>(index));
  }
  return InvalidArgument("unknown memory policy '" + p +
                         "'; expected semantic, basic, radius, predictive, oracle or unbounded");
}

}  // namespace zm
