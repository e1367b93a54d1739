// Sample statistics for tick times (and any other per-tick quantity): a buffer reserved once at
// start, then allocation-free Add(), and exact order statistics for summary.json.
//
// Percentiles are exact over the stored samples, with linear interpolation between the two
// closest ranks (numpy's default, "linear"): p = q * (n - 1), value = x[floor(p)] +
// (p - floor(p)) * (x[floor(p) + 1] - x[floor(p)]) on the sorted samples.
//
// Invariants:
//   - After Reserve(capacity), Add() and Summarize() never allocate: Summarize() sorts into a
//     scratch buffer reserved alongside the samples.
//   - count/mean/min/max cover every Add(), even past capacity; samples past capacity are not
//     stored (counted in dropped()), so the percentiles are then over the first `capacity`
//     samples. Size the buffer from the number of frames so nothing drops.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include <nlohmann/json_fwd.hpp>

namespace zm {

struct SampleSummary {
  std::uint64_t count = 0;    // every Add()
  std::uint64_t stored = 0;   // samples the percentiles are over
  std::uint64_t dropped = 0;  // Add() calls beyond capacity
  double mean = 0.0;
  double min = 0.0;
  double max = 0.0;
  double p50 = 0.0;
  double p95 = 0.0;
  double p99 = 0.0;
};

class SampleStats {
 public:
  SampleStats() = default;
  explicit SampleStats(std::size_t capacity) { Reserve(capacity); }

  // Allocates room for `capacity` samples (and the sort scratch). Start-up only.
  void Reserve(std::size_t capacity);
  // Records one sample. Allocation-free. Returns false if it was not stored (buffer full);
  // count, mean, min and max still include it.
  bool Add(double value) noexcept;
  // Forgets every sample; keeps the capacity.
  void Clear() noexcept;

  [[nodiscard]] std::size_t capacity() const noexcept { return samples_.capacity(); }
  [[nodiscard]] std::uint64_t count() const noexcept { return count_; }
  [[nodiscard]] std::uint64_t dropped() const noexcept { return count_ - samples_.size(); }
  [[nodiscard]] std::span<const double> samples() const noexcept { return samples_; }

  // Exact statistics. Allocation-free; all zero when empty.
  [[nodiscard]] SampleSummary Summarize() const noexcept;

 private:
  std::vector<double> samples_;
  mutable std::vector<double> scratch_;
  std::uint64_t count_ = 0;
  double sum_ = 0.0;
  double min_ = 0.0;
  double max_ = 0.0;
};

// The q-quantile (0 <= q <= 1) of already sorted values, linear interpolation; 0 when empty.
[[nodiscard]] double PercentileOfSorted(std::span<const double> sorted, double q) noexcept;

// {"mean", "p50", "p99", "max"} (the keys of summary.json's tick_ms) plus "min", "p95",
// "count" and "dropped".
[[nodiscard]] nlohmann::json ToJson(const SampleSummary& summary);

}  // namespace zm
