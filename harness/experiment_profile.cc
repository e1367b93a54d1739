#include "harness/experiment_profile.h"

#include "harness/cotenant.h"

namespace zm {
namespace {

Result<ExperimentProfile> Read(ProfileDocument& doc) {
  ExperimentProfile p;
  ZM_ASSIGN_OR_RETURN(p.core, ReadProfile(doc));
  TableReader co = doc.root().Sub("cotenant");
  co.U32("prompt_tokens", p.cotenant.prompt_tokens);
  co.U32("answer_tokens", p.cotenant.answer_tokens, 1);
  co.U32("prompt_batch_tokens", p.cotenant.prompt_batch_tokens, 1);
  co.Double("request_period_s", p.cotenant.request_period_s, 0.0, 1e6);
  co.Double("request_deadline_s", p.cotenant.request_deadline_s, 0.0, 1e6);
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

Status ApplyModelOverride(std::string_view model_name, ExperimentProfile& profile) {
  ZM_ASSIGN_OR_RETURN(const CotenantModel model, FindCotenantModel(model_name));
  Profile& p = profile.core;
  if (p.map.map_share_bytes == 0) {
    ZM_ASSIGN_OR_RETURN(p.map.map_share_bytes, MapShareBytes(p));
  }
  p.model.name = std::string(model.name);
  p.model.weights_bytes = model.weights_bytes;
  return ValidateMemorySplit(p).Annotate("after --cotenant " + std::string(model_name));
}

}  // namespace zm
