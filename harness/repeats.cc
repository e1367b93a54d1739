// Repeats: the interleaved order and the statistics over a cell's repeats. See repeats.h.
#include "harness/repeats.h"

#include <array>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>

#include "runtime/streaming_stats.h"

namespace zm {
namespace {

// t_{0.975, dof} for dof 1..30 (scipy.stats.t.ppf(0.975, dof), 7 significant digits). Beyond 30
// the Cornish-Fisher expansion below is within 1e-5 of it.
constexpr std::array<double, 30> kT975 = {
    12.706205, 4.302653, 3.182446, 2.776445, 2.570582, 2.446912, 2.364624, 2.306004,
    2.262157,  2.228139, 2.200985, 2.178813, 2.160369, 2.144787, 2.131450, 2.119905,
    2.109816,  2.100922, 2.093024, 2.085963, 2.079614, 2.073873, 2.068658, 2.063899,
    2.059539,  2.055529, 2.051831, 2.048407, 2.045230, 2.042272};

void Collect(const nlohmann::json& j, const std::string& pointer,
             std::map<std::string, std::vector<double>>& out, std::size_t index,
             std::size_t count) {
  if (j.is_object()) {
    for (auto it = j.begin(); it != j.end(); ++it) {
      std::string key = it.key();
      // JSON pointer escaping (RFC 6901): "~" -> "~0", "/" -> "~1".
      std::string escaped;
      for (char c : key)
        escaped += c == '~' ? std::string("~0") : c == '/' ? "~1" : std::string(1, c);
      Collect(it.value(), pointer + "/" + escaped, out, index, count);
    }
  } else if (j.is_number() && !j.is_boolean()) {
    auto& v = out[pointer];
    if (v.empty()) v.assign(count, std::numeric_limits<double>::quiet_NaN());
    v[index] = j.get<double>();
  }
}

}  // namespace

std::vector<CellRepeat> InterleavedOrder(std::size_t cells, std::uint32_t repeats) {
  std::vector<CellRepeat> order;
  order.reserve(cells * repeats);
  for (std::uint32_t r = 0; r < repeats; ++r) {
    for (std::size_t c = 0; c < cells; ++c) order.push_back({c, r});
  }
  return order;
}

double StudentT975(std::uint32_t dof) {
  if (dof == 0) return std::numeric_limits<double>::quiet_NaN();
  if (dof <= kT975.size()) return kT975[dof - 1];
  // Cornish-Fisher expansion of t in the normal quantile z (Abramowitz & Stegun 26.7.5).
  const double z = 1.959963984540054;
  const double v = dof;
  const double z3 = z * z * z, z5 = z3 * z * z, z7 = z5 * z * z;
  return z + (z3 + z) / (4 * v) + (5 * z5 + 16 * z3 + 3 * z) / (96 * v * v) +
         (3 * z7 + 19 * z5 + 17 * z3 - 15 * z) / (384 * v * v * v);
}

RepeatStats SummarizeRepeats(std::span<const double> values) {
  RepeatStats s;
  StreamingStats median;
  double sum = 0.0;
  for (double v : values) {
    if (std::isnan(v)) continue;
    s.values.push_back(v);
    sum += v;
    median.Add(v);
    s.min = s.n == 0 ? v : std::min(s.min, v);
    s.max = s.n == 0 ? v : std::max(s.max, v);
    ++s.n;
  }
  if (s.n == 0) return s;
  s.mean = sum / s.n;
  s.median = median.Quantile(0.5);
  if (s.n >= 2) {
    double ss = 0.0;
    for (double v : s.values) ss += (v - s.mean) * (v - s.mean);
    s.sd = std::sqrt(ss / (s.n - 1));
    s.ci95 = StudentT975(s.n - 1) * s.sd / std::sqrt(static_cast<double>(s.n));
  }
  return s;
}

nlohmann::json ToJson(const RepeatStats& s) {
  return {{"n", s.n},   {"mean", s.mean}, {"ci95", s.ci95}, {"median", s.median},
          {"sd", s.sd}, {"min", s.min},   {"max", s.max},   {"values", s.values}};
}

nlohmann::json StatsOfSummaries(const std::vector<nlohmann::json>& summaries) {
  std::map<std::string, std::vector<double>> by_pointer;
  for (std::size_t i = 0; i < summaries.size(); ++i) {
    Collect(summaries[i], "", by_pointer, i, summaries.size());
  }
  nlohmann::json out = nlohmann::json::object();
  for (const auto& [pointer, values] : by_pointer) out[pointer] = ToJson(SummarizeRepeats(values));
  return out;
}

std::size_t RepresentativeRepeat(std::span<const double> key) {
  const RepeatStats s = SummarizeRepeats(key);
  std::size_t best = 0;
  double best_d = std::numeric_limits<double>::infinity();
  for (std::size_t i = 0; i < key.size(); ++i) {
    if (std::isnan(key[i])) continue;
    const double d = std::fabs(key[i] - s.median);
    if (d < best_d) {
      best_d = d;
      best = i;
    }
  }
  return best;
}

std::string FormatNumber(double v, int decimals, bool group_thousands) {
  if (std::isnan(v)) return "–";
  char b[96];
  std::snprintf(b, sizeof b, "%.*f", decimals, v);
  std::string s = b;
  if (!group_thousands || !std::isfinite(v)) return s;
  const std::size_t digits_from = s[0] == '-' ? 1 : 0;
  std::size_t int_end = s.find('.');
  if (int_end == std::string::npos) int_end = s.size();
  for (std::size_t i = int_end; i > digits_from + 3; i -= 3) s.insert(i - 3, 1, ',');
  return s;
}

std::string FormatStat(const nlohmann::json& stat, int decimals, double scale,
                       std::uint32_t expected_n, StatStyle style) {
  if (!stat.is_object() || !stat.contains("n") || !stat["n"].is_number()) return "–";
  const auto n = stat["n"].get<std::uint32_t>();
  if (n == 0) return "–";
  const bool g = style.group_thousands;
  std::string s = FormatNumber(stat.value("mean", 0.0) * scale, decimals, g);
  if (n == 1) {
    if (!(style.n_in_header && expected_n == 1)) s += " (1 run)";
  } else {
    s += " ± ";
    s += FormatNumber(stat.value("ci95", 0.0) * scale, decimals, g);
    if (expected_n > n) s += " (n = " + std::to_string(n) + ")";
  }
  return s;
}

}  // namespace zm
