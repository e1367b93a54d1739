// MakePolicy: the one place that makes every policy by kind (policy_kind.h says what each is).
#include <string>

#include "memory/basic_policy.h"
#include "memory/oracle_policy.h"
#include "memory/policy.h"
#include "memory/predictive_policy.h"
#include "memory/radius_policy.h"
#include "memory/semantic_policy.h"
#include "memory/unbounded_policy.h"

namespace zm {

Result<std::unique_ptr<MemoryPolicy>> MakePolicy(const MapIndex& index,
                                                 const PolicyOptions& options,
                                                 LtmGraph* ltm_graph) {
  const PolicyTraits& traits = Traits(options.kind);
  if (traits.bounded && options.k_max == 0) {
    return InvalidArgument("policy " + std::string(traits.name) + " needs k_max > 0 (MemoryThr)");
  }
  switch (options.kind) {
    case PolicyKind::kSemantic: {
      SemanticOptions o = options.semantic;
      o.k_max = options.k_max;
      return std::unique_ptr<MemoryPolicy>(std::make_unique<SemanticPolicy>(index, o));
    }
    case PolicyKind::kOracle: {
      OracleOptions o = options.oracle;
      o.k_max = options.k_max;
      return std::unique_ptr<MemoryPolicy>(std::make_unique<OraclePolicy>(index, o));
    }
    case PolicyKind::kBasic: {
      BasicOptions o = options.basic;
      if (options.k_max != 0) o.memory_thr = options.k_max;
      return std::unique_ptr<MemoryPolicy>(
          std::make_unique<BasicPolicy>(index, std::move(o), ltm_graph));
    }
    case PolicyKind::kRadius: {
      RadiusOptions o = options.radius;
      o.k_max = options.k_max;
      if (!(o.tile_m > 0) || o.map_radius_m < 0 || o.update_distance_m < 0) {
        return InvalidArgument(
            "radius: tile_m must be > 0, map_radius_m and update_distance_m >= 0");
      }
      return std::unique_ptr<MemoryPolicy>(std::make_unique<RadiusPolicy>(index, o));
    }
    case PolicyKind::kPredictive: {
      PredictiveOptions o = options.predictive;
      o.k_max = options.k_max;
      return std::unique_ptr<MemoryPolicy>(std::make_unique<PredictivePolicy>(index, o));
    }
    case PolicyKind::kUnbounded:
      return std::unique_ptr<MemoryPolicy>(std::make_unique<UnboundedPolicy>(index));
  }
  return Internal("MakePolicy: policy kind " + std::to_string(static_cast<int>(options.kind)) +
                  " has no case");
}

}  // namespace zm
