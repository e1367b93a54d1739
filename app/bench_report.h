// `zonemap bench`'s report writer: from results.json's entries (bench_matrix.h), the bench's
// tables (table1, table2, device, memory, ratios, latency; markdown and CSV), tables.json, the
// tables on stdout and the figures (scripts/plots.py). Every numeric cell formats a statistic
// results.json holds (FormatStat: mean ± 95 % CI); nothing here computes one.
#pragma once

#include <cstdint>
#include <nlohmann/json.hpp>
#include <string>

namespace zm::app {

struct BenchReportOptions {
  std::string out;
  double device_scale = 1.0;
  double time_compression = 1.0;
  std::uint32_t repeats = 1;
  bool plots = true;
};

void WriteBenchReport(const nlohmann::json& results, const BenchReportOptions& options);

}  // namespace zm::app
