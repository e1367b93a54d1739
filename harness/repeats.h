// Repeated runs of the evaluation (issue 27 §4): the order `zonemap bench --repeat N` runs its
// cells in, and the statistics over a cell's repeats that every table shows.
//
// Order: interleaved. Repeat r of every cell runs before repeat r + 1 of any cell (ABAB..., not
// AAA...BBB), so a slow drift of the shared machine (another build starting, the page cache
// filling, thermal state) spreads over every cell instead of landing on one.
//
// Statistics: this is the ONE place they are computed (docs/harness.md, "Repeats"). The bench
// writes them per cell into results.json ({n, mean, ci95, median, sd, min, max, values} for every
// numeric key of the runs' summary.json); its tables (app/bench_report.cc, app/paper_tables.cc)
// only format them, with FormatStat. mean = arithmetic mean; ci95 = the half-width of the 95 %
// confidence interval of the mean, Student's t with n - 1 degrees of freedom times the sample
// standard deviation over sqrt(n) (0 for n = 1: one run has no interval, and says so); median =
// StreamingStats's nearest-rank quantile (zonemap's one percentile definition).
#pragma once

#include <cstddef>
#include <cstdint>
#include <nlohmann/json.hpp>
#include <span>
#include <string>
#include <vector>

namespace zm {

// One run of the matrix: which cell (its index in the caller's list) and which repeat.
struct CellRepeat {
  std::size_t cell = 0;
  std::uint32_t repeat = 0;
  bool operator==(const CellRepeat&) const = default;
};

// Every (cell, repeat) of `cells` cells x `repeats` repeats, interleaved: repeat 0 of cells
// 0..cells-1, then repeat 1 of each, ... Empty when either is 0.
[[nodiscard]] std::vector<CellRepeat> InterleavedOrder(std::size_t cells, std::uint32_t repeats);

// The two-sided 95 % quantile of Student's t with `dof` degrees of freedom (t_{0.975, dof});
// dof 0 has none: NaN.
[[nodiscard]] double StudentT975(std::uint32_t dof);

struct RepeatStats {
  std::uint32_t n = 0;
  double mean = 0.0;
  double ci95 = 0.0;  // half-width; 0 when n < 2
  double median = 0.0;
  double sd = 0.0;  // sample standard deviation (n - 1); 0 when n < 2
  double min = 0.0;
  double max = 0.0;
  std::vector<double> values;  // in repeat order
};

// The statistics of `values` (NaN values are left out; n counts the rest).
[[nodiscard]] RepeatStats SummarizeRepeats(std::span<const double> values);

// {"n", "mean", "ci95", "median", "sd", "min", "max", "values"}.
[[nodiscard]] nlohmann::json ToJson(const RepeatStats& stats);

// For every numeric leaf of the summaries (a JSON pointer such as "/tick_ms/mean" or
// "/cotenant/tokens_per_s_aggregate"; arrays are not descended), the statistics over the
// summaries that have it: {pointer: ToJson(stats)}. A key missing or null in some repeats counts
// only where it is a number.
[[nodiscard]] nlohmann::json StatsOfSummaries(const std::vector<nlohmann::json>& summaries);

// The repeat to show where one run stands for the cell (figures, outcome columns): the one whose
// `key` value is nearest the median of `key` over the repeats (the first of equals); 0 when none
// has it.
[[nodiscard]] std::size_t RepresentativeRepeat(std::span<const double> key);

// How FormatStat writes a cell. The defaults are the bench's own tables (CSV-friendly numbers);
// the paper-form tables group thousands ("4,255 ± 323", as the paper prints its numbers) and
// state each column's n in its header, so a column of single runs shows bare values.
struct StatStyle {
  bool group_thousands = false;  // "11,419 ± 1,332"
  bool n_in_header = false;      // a one-run cell under a header that says "1 run": no "(1 run)"
};

// A statistic as a table cell: "12.35 ± 0.41" (n >= 2), "12.35 (1 run)" (n = 1), "–" (none or
// not a statistic). `scale` multiplies every number first (units: bytes to MiB...). When fewer
// runs had the value than `expected_n`, "(n = k)" follows (n >= 2) or "(1 run)" stays (n = 1).
// With style.n_in_header and n = expected_n = 1 the cell is the bare value.
[[nodiscard]] std::string FormatStat(const nlohmann::json& stat, int decimals, double scale = 1.0,
                                     std::uint32_t expected_n = 0, StatStyle style = {});

// A number as the tables print it: fixed `decimals`, thousands grouped with ',' when asked
// ("5,064.87"); NaN is "–".
[[nodiscard]] std::string FormatNumber(double v, int decimals, bool group_thousands);

}  // namespace zm
