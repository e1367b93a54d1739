// The policy table (see policy_kind.h).
#include "memory/policy_kind.h"

#include <array>
#include <cassert>
#include <string>

namespace zm {
namespace {

constexpr std::array<PolicyTraits, 6> kPolicies{{
    // kind                    name          bounded covers has_budget last_wm
    {PolicyKind::kSemantic,   "semantic",   true,   false, true,      false},
    {PolicyKind::kBasic,      "basic",      false,  true,  true,      true},
    {PolicyKind::kRadius,     "radius",     true,   false, true,      false},
    {PolicyKind::kPredictive, "predictive", true,   false, true,      false},
    {PolicyKind::kOracle,     "oracle",     true,   false, true,      false},
    {PolicyKind::kUnbounded,  "unbounded",  false,  true,  false,     false},
}};

constexpr bool InKindOrder() {
  for (std::size_t i = 0; i < kPolicies.size(); ++i) {
    if (static_cast<std::size_t>(kPolicies[i].kind) != i) return false;
  }
  return true;
}
static_assert(InKindOrder(), "kPolicies must list the kinds in PolicyKind order");

}  // namespace

std::span<const PolicyTraits> AllPolicies() { return kPolicies; }

const PolicyTraits& Traits(PolicyKind kind) {
  const auto i = static_cast<std::size_t>(kind);
  assert(i < kPolicies.size());
  return kPolicies[i];
}

std::string_view PolicyName(PolicyKind kind) { return Traits(kind).name; }

Result<PolicyKind> ParsePolicyKind(std::string_view name) {
  for (const PolicyTraits& t : kPolicies) {
    if (t.name == name) return t.kind;
  }
  std::string known;
  for (std::size_t i = 0; i < kPolicies.size(); ++i) {
    if (i > 0) known += i + 1 == kPolicies.size() ? " or " : ", ";
    known += kPolicies[i].name;
  }
  return InvalidArgument("unknown memory policy '" + std::string(name) + "'; expected " + known);
}

}  // namespace zm
