// StreamingStats: count, mean, min, max and quantiles of a non-negative quantity (tick times in
// ms, tokens/s, latencies) in fixed memory, for as long as a process runs.
//
// This is zonemap's ONE percentile definition (docs/style.md §14): every p50/p99 in telemetry,
// summary.json and the evaluation's tables comes from StreamingStats::Quantile.
//
//   - Values are counted in logarithmic buckets 1 % wide from 1e-6 to 1e9 (in the caller's unit);
//     smaller values (and 0) share the lowest bucket, larger ones the highest.
//   - Quantile(q) is nearest-rank: the bucket holding the ceil(q * n)-th smallest value
//     (rank 1 for q = 0), reported as that bucket's geometric centre clamped to [min, max]. So a
//     quantile is within 0.5 % of the true nearest-rank sample (exact at the extremes), and
//     min, max, count and mean are exact.
//
// Invariants: no heap at all (the buckets are an array inside the object); Add() is O(1) and
// never allocates or throws; Quantile() is O(buckets) and never allocates. Negative and NaN
// values are clamped to 0 and counted in clamped().
#pragma once

#include <array>
#include <cstdint>

namespace zm {

class StreamingStats {
 public:
  static constexpr double kMinValue = 1e-6;
  static constexpr double kMaxValue = 1e9;
  static constexpr double kBucketRatio = 1.01;
  static constexpr int kBuckets = 3473;  // ceil(ln(kMaxValue / kMinValue) / ln(1.01)) + 1

  void Add(double value) noexcept;
  void Clear() noexcept { *this = StreamingStats(); }

  [[nodiscard]] std::uint64_t count() const noexcept { return count_; }
  [[nodiscard]] double mean() const noexcept {
    return count_ == 0 ? 0.0 : sum_ / static_cast<double>(count_);
  }
  [[nodiscard]] double sum() const noexcept { return sum_; }
  [[nodiscard]] double min() const noexcept { return count_ == 0 ? 0.0 : min_; }
  [[nodiscard]] double max() const noexcept { return count_ == 0 ? 0.0 : max_; }
  [[nodiscard]] std::uint64_t clamped() const noexcept { return clamped_; }
  // q in [0, 1]; 0 when empty. See the file comment for the definition.
  [[nodiscard]] double Quantile(double q) const noexcept;

 private:
  static int BucketOf(double value) noexcept;
  static double CentreOf(int bucket) noexcept;

  std::array<std::uint64_t, kBuckets> buckets_{};
  std::uint64_t count_ = 0;
  std::uint64_t clamped_ = 0;
  double sum_ = 0.0;
  double min_ = 0.0;
  double max_ = 0.0;
};

}  // namespace zm
