// `zonemap bench`: the evaluation matrix of docs/evaluation.md. Scenarios (the generated
// hospital and real floor plans) x policies x a MemoryThr sweep x co-tenant models, each a replay
// through the same tick loop on the same profile, then the paper's tables (markdown, CSV, JSON),
// ratios measured side by side in this one run, and figures (scripts/plots.py, matplotlib).
//
//   zonemap bench --quick --out out/demo      # hospital, semantic vs basic (+ predictive), one
//                                             # budget, with and without qwen3-vl-2b (stand-in)
//   zonemap bench --out out/full              # the full matrix
//   zonemap bench --scenarios dir:DENSE --budgets 400kf --models none
//                 --policies unbounded,basic,semantic,predictive,semantic:unsliced
//                 --out out/latency           # tick latency per policy on an existing scenario
//                                             # (issue 14: time-sliced loads vs loads in the tick)
//
// Every run also lands in the tick-latency table (latency.md: tick p50/p99/max after start-up,
// the start-up load apart, each against unbounded's of the same scenario) and figure
// (figures/latency_<scenario>.png: the CDF of tick time per policy).
//
// Repeats (issue 27 §4): --repeat N runs every cell N times (default 5; 3 with --quick),
// interleaved (repeat r of every cell before repeat r + 1 of any: harness/repeats.h), each run in
// runs/<scenario>/<cell>/rep<r>. results.json keeps every repeat's summary per cell and the
// statistics over them (StatsOfSummaries: the one place they are computed); every table cell is
// mean ± 95 % confidence interval (or "(1 run)").
//
// Every table, the paper's Table I and Table II in the paper's form beside the paper's numbers
// included (paper_tables.md), is written here, in C++: the one producer of the tables.
// --report-only writes them again from an existing OUT/results.json without running anything
// (an output of an earlier build, or after the tables changed).
//
// The command line only: the matrix runner (bench_matrix.h: the cells and their runs, results.json)
// and the report writer (bench_report.h: the tables and figures) do the work.
#include <algorithm>
#include <fstream>
#include <memory>
#include <sstream>

#include "bench_matrix.h"
#include "bench_report.h"
#include "commands.h"
#include "harness/cotenant.h"
#include "runtime/stop_signal.h"

namespace zm::app {

namespace {

std::vector<std::string> Split(const std::string& s) {
  std::vector<std::string> out;
  std::stringstream ss(s);
  std::string item;
  while (std::getline(ss, item, ',')) {
    if (!item.empty()) out.push_back(item);
  }
  return out;
}

// --report-only: the tables of an existing OUT/results.json. What every table states (the
// repeats, the device's scale, the time compression) is read from its runs' summaries.
template <typename Opts>
void WriteReportAgain(const Opts& o, CommandContext& ctx) {
  const std::string path = o.out + "/results.json";
  std::ifstream in(path);
  if (!in) return ctx.Fail("bench", NotFound("--report-only: no " + path));
  nlohmann::json results = nlohmann::json::parse(in, nullptr, /*allow_exceptions=*/false);
  if (!results.is_array() || results.empty()) {
    return ctx.Fail("bench", InvalidArgument("--report-only: " + path +
                                             " is not results.json's array of cells"));
  }
  std::uint32_t repeats = 1;
  for (const auto& cell : results) {
    if (cell.contains("runs") && cell["runs"].is_array())
      repeats = std::max(repeats, static_cast<std::uint32_t>(cell["runs"].size()));
  }
  nlohmann::json run = nlohmann::json::object();  // the first run's summary
  const nlohmann::json& first = results[0];
  if (first.is_object() && first.contains("runs") && first["runs"].is_array() &&
      !first["runs"].empty()) {
    run = first["runs"][0];
  }
  const auto num = [&run](const char* key, double fallback) {
    return run.contains(key) && run[key].is_number() ? run[key].get<double>() : fallback;
  };
  WriteBenchReport(results, {.out = o.out,
                             .device_scale = num("device_scale", 1.0),
                             .time_compression = num("time_compression", 1.0),
                             .repeats = repeats,
                             .plots = !o.no_plots});
}

}  // namespace

void AddBenchCommand(CLI::App& app, CommandContext& ctx) {
  struct Opts {
    std::string out, profile = "orin-nano-8gb";
    std::string scenarios, policies, models, budgets;
    std::string floorplans = ZM_DEFAULT_FLOORPLANS_DIR;
    DeviceRunOptions device;  // passed to every run
    int repeat = 0;
    std::uint32_t prompt_tokens = 0, answer_tokens = 0;
    bool quick = false, no_plots = false, report_only = false;
  };
  auto o = std::make_shared<Opts>();
  auto* cmd = app.add_subcommand(
      "bench", "Run the evaluation matrix and write the paper's tables and figures");
  cmd->add_option("--out", o->out, "output directory")->required();
  cmd->add_flag("--quick", o->quick, "the short default of `make demo`");
  cmd->add_option("--profile", o->profile, "device profile (default orin-nano-8gb)");
  cmd->add_option("--scenarios", o->scenarios,
                  "comma list: hospital, floorplan:NAME, dir:PATH (an existing scenario)");
  cmd->add_option(
      "--policies", o->policies,
      "comma list of policies; NAME:unsliced = loads inside the tick (as before issue 14)");
  cmd->add_option("--models", o->models, "comma list of co-tenant models ('none' = without)");
  cmd->add_option("--budgets", o->budgets,
                  "comma list of MemoryThr as fractions of the map (e.g. 1,0.5,0.25), 'two-zones' "
                  "or a count 'Nkf'");
  cmd->add_option("--floorplans", o->floorplans, "folder with <name>_map.png and <name>_gt.png");
  AddDeviceRunOptions(*cmd, &o->device);
  cmd->add_option("--repeat", o->repeat,
                  "runs per cell, interleaved across cells (default 5; --quick: 3); tables show "
                  "mean ± 95 % CI");
  cmd->add_option("--prompt-tokens", o->prompt_tokens,
                  "co-tenant prompt length (default: the profile's)");
  cmd->add_option("--answer-tokens", o->answer_tokens,
                  "co-tenant answer length (default: the profile's)");
  cmd->add_flag("--no-plots", o->no_plots, "skip the matplotlib figures");
  cmd->add_flag("--report-only", o->report_only,
                "run nothing: write the tables (and figures) again from OUT/results.json");
  cmd->callback([o, &ctx] {
    if (o->report_only) return WriteReportAgain(*o, ctx);
    InstallStopSignals();
    BenchMatrixOptions m;
    if (Status s = SetDeviceRun(o->device, m.run); !s.ok()) return ctx.Fail("bench", s);
    constexpr int kMaxRepeat = 1000;
    if (o->repeat < 0 || o->repeat > kMaxRepeat) {
      return ctx.Fail("bench", InvalidArgument("--repeat " + std::to_string(o->repeat) +
                                               ": must be 1 to " + std::to_string(kMaxRepeat) +
                                               " (0 = the default: 5, or 3 with --quick)"));
    }
    const bool q = o->quick;
    const auto repeats = static_cast<std::uint32_t>(o->repeat > 0 ? o->repeat : q ? 3 : 5);
    const auto scenarios = Split(!o->scenarios.empty() ? o->scenarios
                                 : q                   ? "hospital"
                                     : "hospital,floorplan:freiburg_building52,floorplan:map15");
    const auto policies = Split(!o->policies.empty() ? o->policies
                                : q                  ? "unbounded,basic,semantic,predictive,oracle"
                                    : "unbounded,basic,radius,semantic,predictive,oracle");
    const auto models =
        Split(!o->models.empty() ? o->models
              : q                ? "none,qwen3-vl-2b"
                  : "none,qwen3-vl-2b,qwen3-vl-4b,qwen3.5-0.8b,qwen3.5-2b,gemma3-4b");
    const auto budgets = Split(!o->budgets.empty() ? o->budgets
                               : q                 ? "0.3"
                                                   : "1,0.5,0.3,two-zones");
    m.out = o->out;
    m.profile = o->profile;
    m.floorplans = o->floorplans;
    m.scenarios = scenarios;
    m.policies = policies;
    m.models = models;
    m.budgets = budgets;
    m.quick = q;
    m.repeats = repeats;
    m.prompt_tokens = o->prompt_tokens;
    m.answer_tokens = o->answer_tokens;
    m.lock_arena = o->device.lock_arena;
    auto cells = PlanBenchCells(m);
    if (!cells.ok()) return ctx.Fail("bench", cells.status());
    auto results = RunBenchMatrix(m, *cells, StopFlag());
    if (!results.ok()) return ctx.Fail("bench", results.status());
    WriteBenchReport(*results, {.out = o->out,
                                .device_scale = o->device.device_scale,
                                .time_compression = o->device.time_compression,
                                .repeats = repeats,
                                .plots = !o->no_plots});
  });
}

}  // namespace zm::app
