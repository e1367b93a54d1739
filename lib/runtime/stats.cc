// Sample statistics: running count/sum/min/max on every Add(), exact percentiles by sorting a
// preallocated copy at Summarize().
#include "runtime/stats.h"

#include <algorithm>
#include <cmath>
#include <nlohmann/json.hpp>

namespace zm {

void SampleStats::Reserve(std::size_t capacity) {
  samples_.reserve(capacity);
  scratch_.reserve(capacity);
}

bool SampleStats::Add(double value) noexcept {
  if (count_ == 0) {
    min_ = max_ = value;
  } else {
    min_ = std::min(min_, value);
    max_ = std::max(max_, value);
  }
  ++count_;
  sum_ += value;
  if (samples_.size() == samples_.capacity()) return false;
  samples_.push_back(value);  // within capacity: never reallocates
  return true;
}

void SampleStats::Clear() noexcept {
  samples_.clear();
  count_ = 0;
  sum_ = min_ = max_ = 0.0;
}

double PercentileOfSorted(std::span<const double> sorted, double q) noexcept {
  if (sorted.empty()) return 0.0;
  q = std::clamp(q, 0.0, 1.0);
  const double pos = q * static_cast<double>(sorted.size() - 1);
  const auto lo = static_cast<std::size_t>(std::floor(pos));
  const std::size_t hi = std::min(lo + 1, sorted.size() - 1);
  const double frac = pos - static_cast<double>(lo);
  return sorted[lo] + frac * (sorted[hi] - sorted[lo]);
}

SampleSummary SampleStats::Summarize() const noexcept {
  SampleSummary s;
  s.count = count_;
  s.stored = samples_.size();
  s.dropped = dropped();
  if (count_ == 0) return s;
  s.mean = sum_ / static_cast<double>(count_);
  s.min = min_;
  s.max = max_;
  // scratch_ has the same capacity as samples_, so assign() does not allocate.
  scratch_.assign(samples_.begin(), samples_.end());
  std::sort(scratch_.begin(), scratch_.end());
  s.p50 = PercentileOfSorted(scratch_, 0.50);
  s.p95 = PercentileOfSorted(scratch_, 0.95);
  s.p99 = PercentileOfSorted(scratch_, 0.99);
  return s;
}

nlohmann::json ToJson(const SampleSummary& s) {
  return nlohmann::json{{"mean", s.mean}, {"p50", s.p50},         {"p95", s.p95},
                        {"p99", s.p99},   {"max", s.max},         {"min", s.min},
                        {"count", s.count}, {"dropped", s.dropped}};
}

}  // namespace zm
