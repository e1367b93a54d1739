// The paper's Table I and Table II in the paper's form, with the paper's own numbers beside ours
// (../shared/docs/evaluation.md), from results.json's cells (bench_matrix.h). `zonemap bench`
// writes it as paper_tables.md beside its other tables (bench_report.h): one producer of every
// table, in C++ (issue 25 §2; scripts/paper_tables.py did this until then).
//
// Per scenario: the device (memory cgroup, or the ledger: "SIMULATED"), its limit and scale, the
// time compression and MemoryThr; then
//   Table I: one row per metric, one column per configuration in the paper's order (Basic only,
//     Basic + VLM, Semantic only, Semantic + VLM); each cell "ours (the paper's)", then the rows
//     the paper leaves implicit (TimeTotal the other ways, frames, the device, outcomes);
//   Table II: one row per model and policy: outcome (○ completed, △ stalled, × failed to start,
//     † killed), requests completed, median and aggregate tokens/s, latency p50 / mean / p95,
//     major faults; the paper's row beside ours.
// Every number of ours is mean ± 95 % CI over the cell's runs as results.json holds it
// (FormatStat, harness/repeats.h: thousands grouped, each column's n in its header); nothing here
// computes a statistic. Where several budgets ran, a configuration is its cell with the smallest
// K_max (the tightest: the paper's); a NAME:unsliced variant is never one of them.
#pragma once

#include <nlohmann/json.hpp>
#include <string>

namespace zm::app {

// The markdown of every scenario's paper-form tables (results.json's array); "" when `results`
// holds no cell.
[[nodiscard]] std::string PaperTablesMarkdown(const nlohmann::json& results);

}  // namespace zm::app
