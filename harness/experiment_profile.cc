#include "harness/experiment_profile.h"

#include "harness/cotenant.h"

namespace zm {
namespace {

Result<ExperimentProfile> Read(ProfileDocument& doc) {
  ExperimentProfile p;
  ZM_ASSIGN_OR_RETURN(p.core, ReadProfile(doc));
  TableReader co = doc.root().Sub("cotenant");
  CotenantOptions& c = p.cotenant;
  co.U32("prompt_tokens", c.prompt_tokens);
  co.U32("answer_tokens", c.answer_tokens, 1);
  co.U32("prompt_batch_tokens", c.prompt_batch_tokens, 1);
  co.U32("context_tokens", c.context_tokens, 1);
  co.Double("request_period_s", c.request_period_s, 0.0, 1e6);
  co.Double("watchdog_s", c.watchdog_s, 0.0, 1e6);
  co.Double("restart_delay_s", c.restart_delay_s, 0.0, 1e6);
  co.Bytes("kv_bytes_per_token", c.kv_bytes_per_token);
  std::string kv_allocation(KvAllocationName(c.kv_allocation));
  co.String("kv_allocation", kv_allocation);
  if (kv_allocation == "per_request" || kv_allocation == "at_load") {
    c.kv_allocation = kv_allocation == "at_load" ? KvAllocation::kAtLoad : KvAllocation::kPerRequest;
  } else {
    co.FailKey("kv_allocation", "must be \"per_request\" or \"at_load\", not \"" + kv_allocation + "\"");
  }
  std::string weights(CotenantWeightsName(c.weights));
  co.String("weights", weights);
  if (!ParseCotenantWeights(weights, &c.weights)) {
    co.FailKey("weights", "must be \"pinned\", \"mmap\" or \"read\", not \"" + weights + "\"");
  }
  co.Bool("prefetch", c.prefetch);
  co.Bool("cold_start", c.cold_start);
  co.String("weights_dir", c.weights_dir);
  if (std::uint64_t{c.prompt_tokens} + c.answer_tokens > c.context_tokens) {
    co.FailKey("context_tokens", "must hold prompt_tokens + answer_tokens (" +
                                     std::to_string(std::uint64_t{c.prompt_tokens} + c.answer_tokens) +
                                     " tokens), not " + std::to_string(c.context_tokens));
  }
  co.Finish();
  ZM_RETURN_IF_ERROR(doc.Finish());
  return p;
}

}  // namespace

Result<ExperimentProfile> LoadExperimentProfile(const std::string& name_or_path) {
  ZM_ASSIGN_OR_RETURN(ProfileDocument doc, ProfileDocument::Load(name_or_path));
  return Read(doc);
}

Result<ExperimentProfile> ParseExperimentProfile(std::string_view toml_text,
                                                 const std::string& source) {
  ZM_ASSIGN_OR_RETURN(ProfileDocument doc, ProfileDocument::Parse(toml_text, source));
  return Read(doc);
}

Status ApplyModelOverride(std::string_view model_name, ExperimentProfile& profile,
                          ModelShare share) {
  ZM_ASSIGN_OR_RETURN(const CotenantModel model, FindCotenantModel(model_name));
  Profile& p = profile.core;
  if (share == ModelShare::kFrozen && p.map.map_share_bytes == 0) {
    ZM_ASSIGN_OR_RETURN(p.map.map_share_bytes, MapShareBytes(p));
  }
  p.model.name = std::string(model.name);
  p.model.weights_bytes = model.weights_bytes;
  return ValidateMemorySplit(p).Annotate("after --cotenant " + std::string(model_name));
}

}  // namespace zm
