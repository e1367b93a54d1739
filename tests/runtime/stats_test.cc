// Sample statistics: exact percentiles (numpy "linear"), allocation-free Add() and Summarize()
// once reserved, and honest accounting of samples beyond capacity.
#include "runtime/stats.h"

#include <doctest/doctest.h>

#include <nlohmann/json.hpp>

#include "support/counting_allocator.h"

namespace zm {
namespace {

TEST_CASE("percentiles of 1..100 match numpy's linear interpolation") {
  SampleStats s(100);
  for (int i = 100; i >= 1; --i) s.Add(i);  // order must not matter
  const SampleSummary sum = s.Summarize();
  CHECK(sum.count == 100);
  CHECK(sum.mean == doctest::Approx(50.5));
  CHECK(sum.p50 == doctest::Approx(50.5));
  CHECK(sum.p95 == doctest::Approx(95.05));
  CHECK(sum.p99 == doctest::Approx(99.01));
  CHECK(sum.min == 1.0);
  CHECK(sum.max == 100.0);
}

TEST_CASE("single sample and empty buffer") {
  SampleStats s(4);
  CHECK(s.Summarize().count == 0);
  CHECK(s.Summarize().p99 == 0.0);
  s.Add(7.5);
  const SampleSummary sum = s.Summarize();
  CHECK(sum.p50 == 7.5);
  CHECK(sum.p99 == 7.5);
  CHECK(sum.max == 7.5);
}

TEST_CASE("Add and Summarize allocate nothing once reserved") {
  SampleStats s;
  s.Reserve(10000);
  test::AllocationCounter counter;
  for (int i = 0; i < 10000; ++i) s.Add(static_cast<double>((i * 7919) % 1000) * 0.01);
  const SampleSummary sum = s.Summarize();
  s.Clear();
  s.Add(1.0);
  CHECK(counter.allocations() == 0);
  CHECK(sum.count == 10000);
  CHECK(sum.max == doctest::Approx(9.99));
}

TEST_CASE("samples beyond capacity are counted, not stored, and never allocate") {
  SampleStats s(3);
  test::AllocationCounter counter;
  CHECK(s.Add(1.0));
  CHECK(s.Add(2.0));
  CHECK(s.Add(3.0));
  CHECK_FALSE(s.Add(100.0));
  CHECK(counter.allocations() == 0);
  const SampleSummary sum = s.Summarize();
  CHECK(sum.count == 4);
  CHECK(sum.stored == 3);
  CHECK(sum.dropped == 1);
  CHECK(sum.max == 100.0);                // running statistics see every sample
  CHECK(sum.mean == doctest::Approx(26.5));
  CHECK(sum.p50 == 2.0);                  // percentiles: over the stored ones
}

TEST_CASE("JSON has the summary.json tick_ms keys") {
  SampleStats s(2);
  s.Add(1.0);
  s.Add(3.0);
  const nlohmann::json j = ToJson(s.Summarize());
  for (const char* key : {"mean", "p50", "p99", "max"}) CHECK(j.contains(key));
  CHECK(j["mean"].get<double>() == 2.0);
}

}  // namespace
}  // namespace zm
