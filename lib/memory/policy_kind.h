// The memory policies by kind, and what each one is (its traits), in one table.
//
// A policy's name is parsed once, where it enters (a profile's [policy] name, --policy, the
// public API's options): from there on the code holds a PolicyKind and asks its traits instead
// of comparing names. Adding a policy is one row here plus its case in MakePolicy (policy.cc).
//
//   kind         bounded  arena covers map  has a budget  may start from the last WM
//   semantic     yes      no                yes           no
//   basic        no       yes               yes           yes (Mem/InitWMWithAllNodes=false)
//   radius       yes      no                yes           no
//   predictive   yes      no                yes           no
//   oracle       yes      no                yes           no
//   unbounded    no       yes               no            no
#pragma once

#include <cstdint>
#include <span>
#include <string_view>

#include "common/status.h"

namespace zm {

enum class PolicyKind : std::uint8_t {
  kSemantic,    // the paper's Algorithm 1: zone-level LRU
  kBasic,       // RTAB-Map's retrieval and transfer (Rtabmap/MemoryThr)
  kRadius,      // Autoware-style distance tiles
  kPredictive,  // route prefetch, farthest-next-use eviction
  kOracle,      // Belady's bound over the known zone of every tick
  kUnbounded,   // everything resident
};

struct PolicyTraits {
  PolicyKind kind;
  std::string_view name;
  // Never holds more than K_max keyframes: its arena has exactly K_max slots, so exceeding the
  // budget is physically impossible (and such an arena may be locked).
  bool bounded;
  // Its arena holds the whole map: it models RTAB-Map's heap, which grows; the over-budget flag
  // measures by how much it exceeds MemoryThr. (Today exactly the policies that are not bounded.)
  bool arena_covers_map;
  // Has a MemoryThr at all: unbounded ignores every limit (K_max = the whole map, a run-time
  // budget change is ignored).
  bool has_budget;
  // May start from the working memory the map database last recorded (basic with
  // Mem/InitWMWithAllNodes=false and no working memory given: map_setup.h).
  bool may_start_from_last_wm;
};

// Every policy, in PolicyKind order.
[[nodiscard]] std::span<const PolicyTraits> AllPolicies();
[[nodiscard]] const PolicyTraits& Traits(PolicyKind kind);
[[nodiscard]] std::string_view PolicyName(PolicyKind kind);
// The kind named `name` ("semantic", "basic", ...); an unknown name is an error that lists them.
[[nodiscard]] Result<PolicyKind> ParsePolicyKind(std::string_view name);

}  // namespace zm
