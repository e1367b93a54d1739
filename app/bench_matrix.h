// `zonemap bench`'s matrix runner: the cells (scenarios x budgets x co-tenant models x policy
// variants) and their runs, --repeat times each, interleaved (harness/repeats.h), every run one
// RunOnDevice. Its output is results.json's entries, one per cell: every repeat's summary and the
// statistics over them (StatsOfSummaries). The tables are bench_report.h's.
#pragma once

#include <atomic>
#include <cstdint>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "common/status.h"
#include "harness/device_run.h"

namespace zm::app {

// A policy entry of --policies: NAME, or NAME:unsliced (loads finish inside the tick that plans
// them, as before issue 14: [loads] sliced = false), measured side by side with the sliced one.
struct PolicyVariant {
  std::string policy;
  bool unsliced = false;
  std::string label;  // what the tables and figures call it
};
[[nodiscard]] Result<PolicyVariant> ParsePolicyVariant(const std::string& entry);

// One cell of the matrix: a scenario, a budget, a co-tenant model and a policy variant, run
// --repeat times.
struct BenchCell {
  std::string scenario_name;
  std::string scenario_dir;
  std::string budget;  // as given ("1", "two-zones", "400kf")
  std::uint64_t k = 0;
  std::string model;
  PolicyVariant variant;
  std::string run_name;
};

// What the matrix is made of and how every run of it runs (the command line's, defaults applied).
struct BenchMatrixOptions {
  std::string out;
  std::string profile;
  std::string floorplans;
  std::vector<std::string> scenarios, policies, models, budgets;
  bool quick = false;  // smaller generated scenarios
  std::uint32_t repeats = 1;
  // Every run's request but its scenario, directory, profile and co-tenant: the device, its
  // scale, the time compression, the co-tenant requests, the zram charge (SetDeviceRun).
  DeviceRunRequest run;
  std::uint32_t prompt_tokens = 0, answer_tokens = 0;  // 0 = the profile's
  std::string lock_arena;                              // "" = the profile's
};

// The cells, scenarios generated first (with this very program, `zonemap sim`) where missing.
[[nodiscard]] Result<std::vector<BenchCell>> PlanBenchCells(const BenchMatrixOptions& options);

// Runs every cell options.repeats times, interleaved, each run in
// OUT/runs/<scenario>/<cell>/rep<r>; returns results.json's array (and writes OUT/results.json).
[[nodiscard]] Result<nlohmann::json> RunBenchMatrix(const BenchMatrixOptions& options,
                                                    const std::vector<BenchCell>& cells,
                                                    const std::atomic<bool>* stop);

}  // namespace zm::app
