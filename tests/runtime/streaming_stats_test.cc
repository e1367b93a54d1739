// StreamingStats: the one percentile definition (nearest rank, within 0.5 %), fixed memory.
#include "runtime/streaming_stats.h"

#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

#include "support/counting_allocator.h"

namespace zm {
namespace {

// The exact nearest-rank quantile of a sample (the definition StreamingStats approximates).
double NearestRank(std::vector<double> v, double q) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  const auto rank = static_cast<std::size_t>(std::ceil(q * static_cast<double>(v.size())));
  return v.at(std::clamp<std::size_t>(rank, 1, v.size()) - 1);
}

TEST_CASE("quantiles are the nearest-rank sample within 0.5 %, count, mean, min, max exact") {
  std::mt19937_64 rng(3);
  std::lognormal_distribution<double> tick_ms(1.0, 0.8);
  for (std::size_t n : {1u, 2u, 7u, 100u, 10'000u}) {
    CAPTURE(n);
    StreamingStats s;
    std::vector<double> v;
    double sum = 0.0;
    for (std::size_t i = 0; i < n; ++i) {
      v.push_back(tick_ms(rng));
      s.Add(v.back());
      sum += v.back();
    }
    CHECK(s.count() == n);
    CHECK(s.mean() == doctest::Approx(sum / static_cast<double>(n)));
    CHECK(s.min() == *std::min_element(v.begin(), v.end()));
    CHECK(s.max() == *std::max_element(v.begin(), v.end()));
    for (double q : {0.0, 0.01, 0.5, 0.9, 0.99, 1.0}) {
      CAPTURE(q);
      const double exact = NearestRank(v, q);
      CHECK(std::abs(s.Quantile(q) - exact) <= 0.0051 * exact + 1e-12);
    }
  }
}

TEST_CASE("hand-worked: p50 of 1..4 is 2, p99 is 4 (nearest rank), empty is 0") {
  StreamingStats s;
  CHECK(s.Quantile(0.5) == 0.0);
  for (double x : {4.0, 1.0, 3.0, 2.0}) s.Add(x);
  CHECK(s.Quantile(0.5) == doctest::Approx(2.0).epsilon(0.005));
  CHECK(s.Quantile(0.99) == doctest::Approx(4.0).epsilon(0.005));
  CHECK(s.Quantile(0.25) == doctest::Approx(1.0).epsilon(0.005));
}

TEST_CASE("out-of-range values: zero, tiny, huge, negative and NaN") {
  StreamingStats s;
  s.Add(0.0);
  s.Add(1e-9);
  s.Add(5e12);
  s.Add(-3.0);
  s.Add(std::nan(""));
  CHECK(s.count() == 5);
  CHECK(s.clamped() == 2);
  CHECK(s.min() == 0.0);
  CHECK(s.max() == 5e12);
  CHECK(s.Quantile(1.0) == 5e12);
  CHECK(s.Quantile(0.5) <= StreamingStats::kMinValue * StreamingStats::kBucketRatio);
}

TEST_CASE("Add and Quantile never allocate, whatever the count") {
  StreamingStats s;
  test::AllocationCounter counter;
  for (int i = 0; i < 1'000'000; ++i) s.Add(static_cast<double>(i % 977) * 0.013);
  const double p99 = s.Quantile(0.99);
  CHECK(counter.allocations() == 0);
  CHECK(p99 > 0.0);
}

}  // namespace
}  // namespace zm
