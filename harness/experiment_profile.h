// The evaluation's view of a profile: the core's Profile (runtime/profile.h) plus the sections
// only the harness reads ([cotenant]: how the VLM stand-in behaves, harness/cotenant_options.h). The same file serves both;
// zonemapd skips the harness's sections.
//
// Invariants: as runtime/profile.h (every key known, every value checked, the memory split adds
// up); the stand-in's weights and KV cache come from the core's [model], never from a copy.
#pragma once

#include <cstdint>
#include <string>
#include <string_view>

#include "common/status.h"
#include "harness/cotenant_options.h"
#include "runtime/profile.h"

namespace zm {

struct ExperimentProfile {
  Profile core;
  CotenantOptions cotenant;  // [cotenant]
};

[[nodiscard]] Result<ExperimentProfile> LoadExperimentProfile(const std::string& name_or_path);
[[nodiscard]] Result<ExperimentProfile> ParseExperimentProfile(std::string_view toml_text,
                                                               const std::string& source);

// What becomes of a derived map share when [model] changes.
enum class ModelShare {
  kFrozen,     // kept as derived for the profile's model (--cotenant: the paper's fixed MemoryThr)
  kRederived,  // derived anew for the new model (`zonemap budget --model`: a profile written for it)
};

// --cotenant MODEL: the paper's model by name (cotenant.h's table) becomes [model]. The map share
// was planned for the profile's model, and the paper keeps MemoryThr fixed while models change,
// so by default the derived share is frozen first.
[[nodiscard]] Status ApplyModelOverride(std::string_view model_name, ExperimentProfile& profile,
                                        ModelShare share = ModelShare::kFrozen);

}  // namespace zm
