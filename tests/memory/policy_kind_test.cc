// The policy table (lib/memory/policy_kind.h): every name parses to its kind and back, an unknown
// name is one clear error listing them, and the traits the runtime decides by are the ones
// documented (docs/memory.md).
#include "memory/policy_kind.h"

#include <doctest/doctest.h>

#include <string>

namespace zm {
namespace {

TEST_CASE("policy kind: every name parses to its kind and back") {
  REQUIRE(AllPolicies().size() == 6);
  for (const PolicyTraits& t : AllPolicies()) {
    CAPTURE(std::string(t.name));
    auto kind = ParsePolicyKind(t.name);
    REQUIRE(kind.ok());
    CHECK(*kind == t.kind);
    CHECK(PolicyName(t.kind) == t.name);
    CHECK(&Traits(t.kind) == &t);
  }
  CHECK(*ParsePolicyKind("semantic") == PolicyKind::kSemantic);
  CHECK(*ParsePolicyKind("unbounded") == PolicyKind::kUnbounded);
}

TEST_CASE("policy kind: an unknown name lists the known ones") {
  for (const char* bad : {"lru", "", "Semantic", "semantic "}) {
    auto kind = ParsePolicyKind(bad);
    REQUIRE_FALSE(kind.ok());
    CHECK(kind.status().code() == StatusCode::kInvalidArgument);
    CHECK(kind.status().message() ==
          "unknown memory policy '" + std::string(bad) +
              "'; expected semantic, basic, radius, predictive, oracle or unbounded");
  }
}

TEST_CASE("policy kind: the traits table") {
  // Bounded: an arena of exactly K_max slots; the others model RTAB-Map's growing heap.
  for (PolicyKind k : {PolicyKind::kSemantic, PolicyKind::kRadius, PolicyKind::kPredictive,
                       PolicyKind::kOracle}) {
    CAPTURE(std::string(PolicyName(k)));
    CHECK(Traits(k).bounded);
    CHECK_FALSE(Traits(k).arena_covers_map);
    CHECK(Traits(k).has_budget);
    CHECK_FALSE(Traits(k).may_start_from_last_wm);
  }
  CHECK_FALSE(Traits(PolicyKind::kBasic).bounded);
  CHECK(Traits(PolicyKind::kBasic).arena_covers_map);
  CHECK(Traits(PolicyKind::kBasic).has_budget);
  CHECK(Traits(PolicyKind::kBasic).may_start_from_last_wm);
  CHECK_FALSE(Traits(PolicyKind::kUnbounded).bounded);
  CHECK(Traits(PolicyKind::kUnbounded).arena_covers_map);
  CHECK_FALSE(Traits(PolicyKind::kUnbounded).has_budget);
  CHECK_FALSE(Traits(PolicyKind::kUnbounded).may_start_from_last_wm);
}

}  // namespace
}  // namespace zm
