// `zonemap bench`'s report writer, the one producer of its tables: from results.json's entries
// (bench_matrix.h), the bench's tables (table1, table2, device, memory, ratios, latency; markdown
// and CSV), the paper's Table I and Table II in the paper's form beside the paper's numbers
// (paper_tables.md: paper_tables.h), tables.json, the tables on stdout and the figures
// (scripts/plots.py: figures are not tables). Every numeric cell formats a statistic results.json
// holds (FormatStat: mean ± 95 % CI); nothing here computes one.
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

// Writes OUT/{table1,...}.{md,csv}, OUT/paper_tables.md and OUT/tables.json, prints them, then
// runs scripts/plots.py when options.plots.

void WriteBenchReport(const nlohmann::json& results, const BenchReportOptions& options);

}  // namespace zm::app
