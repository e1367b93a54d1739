#include "runtime/streaming_stats.h"

#include <algorithm>
#include <cmath>

namespace zm {
namespace {
const double kLogRatio = std::log(StreamingStats::kBucketRatio);
}  // namespace

int StreamingStats::BucketOf(double value) noexcept {
  if (!(value > kMinValue)) return 0;
  if (value >= kMaxValue) return kBuckets - 1;
  const int b = static_cast<int>(std::log(value / kMinValue) / kLogRatio);
  return std::clamp(b, 0, kBuckets - 1);
}

double StreamingStats::CentreOf(int bucket) noexcept {
  // Bucket b holds [kMin * r^b, kMin * r^(b+1)); its geometric centre is kMin * r^(b + 1/2).
  return kMinValue * std::exp((static_cast<double>(bucket) + 0.5) * kLogRatio);
}

void StreamingStats::Add(double value) noexcept {
  if (!(value >= 0.0)) {  // negative or NaN: a caller's bug, counted, never trusted
    value = 0.0;
    ++clamped_;
  }
  if (count_ == 0) {
    min_ = max_ = value;
  } else {
    min_ = std::min(min_, value);
    max_ = std::max(max_, value);
  }
  ++count_;
  sum_ += value;
  ++buckets_[static_cast<std::size_t>(BucketOf(value))];
}

double StreamingStats::Quantile(double q) const noexcept {
  if (count_ == 0) return 0.0;
  q = std::clamp(q, 0.0, 1.0);
  if (q <= 0.0) return min_;
  if (q >= 1.0) return max_;
  const auto rank = std::max<std::uint64_t>(
      1, static_cast<std::uint64_t>(std::ceil(q * static_cast<double>(count_))));
  std::uint64_t seen = 0;
  for (int b = 0; b < kBuckets; ++b) {
    seen += buckets_[static_cast<std::size_t>(b)];
    if (seen >= rank) return std::clamp(CentreOf(b), min_, max_);
  }
  return max_;
}

}  // namespace zm
