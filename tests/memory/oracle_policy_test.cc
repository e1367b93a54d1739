// oracle = Belady's MIN over zones: the hand example where it beats LRU, and the property that
// with equal-size zones it makes no more zone loads than semantic or predictive.
#include "memory/oracle_policy.h"

#include <doctest/doctest.h>

#include <random>

#include "memory/memory_test_util.h"
#include "memory/predictive_policy.h"
#include "memory/semantic_policy.h"

namespace zm {
namespace {

using test::At;
using test::Harness;
using test::Zones;
using Zv = std::vector<std::int32_t>;

std::uint64_t Run(const test::MapSpec& s, std::uint32_t k_max, const std::vector<int>& walk,
                  const Harness::Factory& make) {
  Harness h(s, k_max, k_max, make);
  h.source.log_calls = false;
  h.verify_slots = false;
  h.Start(At(0, walk[0]));
  for (std::size_t i = 1; i < walk.size(); ++i) {
    auto t = h.Tick(At(i, walk[i]));
    REQUIRE(t.peak_resident_keyframes <= k_max);
  }
  return h.policy->zone_loads();
}

std::vector<ZoneId> Future(const std::vector<int>& walk) {
  std::vector<ZoneId> f;
  for (int z : walk) f.push_back(z < 0 ? kNoZone : ZoneId{z});
  return f;
}

TEST_CASE("oracle: evicts the zone needed farthest in the future") {
  const std::vector<int> walk{0, 1, 2, 0, 1, 2};
  Harness h(test::LineMap({3, 3, 3}), 6, 6, [&](const MapIndex& index) {
    return std::make_unique<OraclePolicy>(index, OracleOptions{6, Future(walk)});
  });
  h.Start(At(0, 0));
  h.Tick(At(1, 1));
  h.Tick(At(2, 2));  // A = {0, 1}: 0 is next needed at step 3, 1 at step 4 -> evict 1
  CHECK(Zones(h.before.zones_unloaded()) == Zv{1});
  h.Tick(At(3, 0));
  CHECK(h.before.empty());
  h.Tick(At(4, 1));  // evict 0 (never needed again)
  CHECK(Zones(h.before.zones_unloaded()) == Zv{0});
  h.Tick(At(5, 2));
  CHECK(h.policy->zone_loads() == 4);
  // LRU on the same walk loads a zone on every step.
  CHECK(Run(test::LineMap({3, 3, 3}), 6, walk, [](const MapIndex& index) {
          return std::make_unique<SemanticPolicy>(index, SemanticOptions{6});
        }) == 6);
}

TEST_CASE("oracle property: with equal-size zones no policy makes fewer zone loads") {
  std::mt19937 rng(19);
  for (int trial = 0; trial < 40; ++trial) {
    const int zones = 3 + static_cast<int>(rng() % 8);
    const int size = 1 + static_cast<int>(rng() % 5);
    test::MapSpec s = test::LineMap(std::vector<int>(static_cast<std::size_t>(zones), size));
    s.adjacency.resize(static_cast<std::size_t>(zones));
    for (int z = 0; z < zones; ++z) {
      s.adjacency[static_cast<std::size_t>(z)].push_back(ZoneId{(z + 1) % zones});
    }
    const auto k_max = static_cast<std::uint32_t>(size * (1 + static_cast<int>(rng() % static_cast<std::uint32_t>(zones))));
    std::vector<int> walk{0};
    for (int i = 0; i < 80; ++i) walk.push_back(static_cast<int>(rng() % static_cast<std::uint32_t>(zones + 1)) - 1);
    const auto oracle = Run(s, k_max, walk, [&](const MapIndex& index) {
      return std::make_unique<OraclePolicy>(index, OracleOptions{k_max, Future(walk)});
    });
    const auto semantic = Run(s, k_max, walk, [&](const MapIndex& index) {
      return std::make_unique<SemanticPolicy>(index, SemanticOptions{k_max});
    });
    const auto predictive = Run(s, k_max, walk, [&](const MapIndex& index) {
      PredictiveOptions o;
      o.k_max = k_max;
      return std::make_unique<PredictivePolicy>(index, o);
    });
    CHECK(oracle <= semantic);
    CHECK(oracle <= predictive);
  }
}

}  // namespace
}  // namespace zm
