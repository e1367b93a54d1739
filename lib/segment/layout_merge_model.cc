// The layout merge model (layout_merge.h): evaluation, parsing, the compiled-in model, and the
// record of the options its training pieces were cut with.
#include <algorithm>
#include <cmath>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "segment/layout_merge.h"

namespace zm {
namespace {

using segment_detail::Idx;

// A number as JSON writes it (shortest round trip), for messages.
std::string Number(double v) { return nlohmann::json(v).dump(); }

// One part of "trained_with": every field of `fields` present as a number, no other key.
template <class Options, std::size_t N>
Status ReadRecord(const nlohmann::json& j, const char* part,
                  const OptionField<Options> (&fields)[N], Options* out) {
  const std::string where = std::string("layout merge model: trained_with.") + part;
  if (!j.is_object()) return InvalidArgument(where + " is not an object");
  for (const auto& [key, value] : j.items()) {
    bool known = false;
    for (const OptionField<Options>& f : fields) known = known || key == f.name;
    if (!known) return InvalidArgument(where + ": unknown option '" + key + "'");
  }
  for (const OptionField<Options>& f : fields) {
    if (!j.contains(f.name) || !j.at(f.name).is_number()) {
      return InvalidArgument(where + ": '" + f.name + "' is missing or not a number");
    }
    out->*f.field = j.at(f.name).template get<double>();
  }
  return Status::Ok();
}

template <class Options, std::size_t N>
void WriteRecord(const OptionField<Options> (&fields)[N], const Options& o, nlohmann::json* out) {
  *out = nlohmann::json::object();
  for (const OptionField<Options>& f : fields) (*out)[f.name] = o.*f.field;
}

// The first field where `trained` and `used` differ, named, or OK.
template <class Options, std::size_t N>
Status Compare(const OptionField<Options> (&fields)[N], const Options& trained,
               const Options& used) {
  for (const OptionField<Options>& f : fields) {
    if (trained.*f.field != used.*f.field) {
      return InvalidArgument(
          std::string("the layout merge model was trained on pieces made with ") + f.name + "=" +
          Number(trained.*f.field) + ", these options have " + Number(used.*f.field) +
          ": keep the model's value, retrain the model with these options "
          "(scripts/train_layout_merge.py --param), or use the rule merges "
          "(layout_merge_threshold=0)");
    }
  }
  return Status::Ok();
}

}  // namespace

double LayoutMergeModel::Probability(const std::array<float, kLayoutFeatureCount>& x) const {
  double raw = init;
  for (const Tree& t : trees) {
    int n = 0;
    while (t.feature[Idx(n)] >= 0) {
      n = static_cast<double>(x[Idx(t.feature[Idx(n)])]) <= t.threshold[Idx(n)] ? t.left[Idx(n)]
                                                                                : t.right[Idx(n)];
    }
    raw += rate * static_cast<double>(t.value[Idx(n)]);
  }
  return 1.0 / (1.0 + std::exp(-raw));
}

bool LayoutMergeModel::Uses(int index) const {
  for (const Tree& t : trees) {
    if (std::find(t.feature.begin(), t.feature.end(), index) != t.feature.end()) return true;
  }
  return false;
}

Result<LayoutMergeModel> ParseLayoutMergeModel(const std::string& json_text) {
  LayoutMergeModel m;
  try {
    const nlohmann::json j = nlohmann::json::parse(json_text);
    const auto names = j.at("features").get<std::vector<std::string>>();
    // A model trained before later features were added lists a prefix of them and uses no
    // other (checked per node below).
    if (names.empty() || names.size() > kLayoutFeatureNames.size()) {
      return InvalidArgument("layout merge model: " + std::to_string(names.size()) +
                             " features, expected 1 to " + std::to_string(kLayoutFeatureCount));
    }
    const int known_features = static_cast<int>(names.size());
    for (std::size_t i = 0; i < names.size(); ++i) {
      if (names[i] != kLayoutFeatureNames[i]) {
        return InvalidArgument("layout merge model: feature " + std::to_string(i) + " is '" +
                               names[i] + "', expected '" + kLayoutFeatureNames[i] + "'");
      }
    }
    m.init = j.at("init").get<double>();
    m.rate = j.at("learning_rate").get<double>();
    for (const auto& jt : j.at("trees")) {
      LayoutMergeModel::Tree t;
      t.feature = jt.at("feature").get<std::vector<int>>();
      t.threshold = jt.at("threshold").get<std::vector<double>>();
      t.left = jt.at("left").get<std::vector<int>>();
      t.right = jt.at("right").get<std::vector<int>>();
      t.value = jt.at("value").get<std::vector<float>>();
      const std::size_t n = t.feature.size();
      if (n == 0 || t.threshold.size() != n || t.left.size() != n || t.right.size() != n ||
          t.value.size() != n) {
        return InvalidArgument("layout merge model: tree " + std::to_string(m.trees.size()) +
                               " has arrays of different lengths");
      }
      for (std::size_t i = 0; i < n; ++i) {
        if (t.feature[i] < 0) continue;
        // Children come after their parent: no cycles, every walk ends at a leaf.
        if (t.feature[i] >= known_features || t.left[i] <= static_cast<int>(i) ||
            t.right[i] <= static_cast<int>(i) || t.left[i] >= static_cast<int>(n) ||
            t.right[i] >= static_cast<int>(n)) {
          return InvalidArgument("layout merge model: tree " + std::to_string(m.trees.size()) +
                                 " node " + std::to_string(i) + " is malformed");
        }
      }
      m.trees.push_back(std::move(t));
    }
    if (!j.contains("trained_with")) {
      return InvalidArgument(
          "layout merge model: no \"trained_with\" (the cut and rule-merge options its "
          "training pieces were made with); retrain it with scripts/train_layout_merge.py");
    }
    const nlohmann::json& with = j.at("trained_with");
    if (!with.is_object() || with.size() != 2) {
      return InvalidArgument(
          "layout merge model: \"trained_with\" must hold exactly \"cut\" and "
          "\"rule_merge\"");
    }
    ZM_RETURN_IF_ERROR(ReadRecord(with.at("cut"), "cut", kCutOptionFields, &m.cut));
    ZM_RETURN_IF_ERROR(
        ReadRecord(with.at("rule_merge"), "rule_merge", kRuleMergeOptionFields, &m.rule_merge));
  } catch (const nlohmann::json::exception& e) {
    return InvalidArgument(std::string("layout merge model: ") + e.what());
  }
  return m;
}

Result<LayoutMergeModel> LoadLayoutMergeModel(const std::string& path) {
  std::ifstream in(path);
  if (!in) return IoError(path + ": cannot open the layout merge model");
  std::stringstream ss;
  ss << in.rdbuf();
  auto m = ParseLayoutMergeModel(ss.str());
  if (!m.ok()) return InvalidArgument(path + ": " + m.status().message());
  return m;
}

const LayoutMergeModel& DefaultLayoutMergeModel() {
  static const LayoutMergeModel model = [] {
    static constexpr const char* kJson =
#include "segment/layout_merge_model.inc"
        ;
    auto m = ParseLayoutMergeModel(kJson);
    // The compiled-in model is checked by a test; an empty model merges nothing.
    return m.ok() ? std::move(m).value() : LayoutMergeModel{};
  }();
  return model;
}

std::string LayoutMergeTrainedWithJson(const CutOptions& cut, const RuleMergeOptions& rules) {
  nlohmann::json j = nlohmann::json::object();
  WriteRecord(kCutOptionFields, cut, &j["cut"]);
  WriteRecord(kRuleMergeOptionFields, rules, &j["rule_merge"]);
  return j.dump();
}

Status CheckLayoutMergeModelOptions(const LayoutMergeModel& model, const CutOptions& cut,
                                    const RuleMergeOptions& rules) {
  ZM_RETURN_IF_ERROR(Compare(kCutOptionFields, model.cut, cut));
  return Compare(kRuleMergeOptionFields, model.rule_merge, rules);
}

}  // namespace zm
