// The paper-form Table I and Table II (app/paper_tables.h) on a small results.json built as the
// bench builds it (every repeat's summary, StatsOfSummaries over them): the paper's columns in
// its order, ours beside the paper's numbers, the schema-1 counts read, outcomes with their
// symbols, mean ± 95 % CI with each column's n in its header, the configuration picked at the
// smallest K_max and never an unsliced variant; and `zonemap bench`'s report writer writes the
// same text to paper_tables.md.
#include "paper_tables.h"

#include <doctest/doctest.h>

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "bench_report.h"
#include "harness/repeats.h"

namespace zm::app {
namespace {

using nlohmann::json;

constexpr double kLimit = 838860800.0;  // 800 MiB

// A run's summary.json with the keys the tables read; basic writes schema version 1 (one count,
// loop_closures; TimeTotal as tick_ms.mean), semantic version 2.
json Summary(const std::string& policy, bool killed, double rate, int closures) {
  json s = {{"policy", policy},
            {"k_max", 1820},
            {"update_rate_hz", rate},
            {"ate_rmse_m", policy == "basic" ? 0.12 : 0.05},
            {"rpe_trans_rmse_m", 0.156},
            {"rpe_rot_rmse_deg", 0.4},
            {"frames_arrived", 60},
            {"frames_dropped", killed ? 12 : 1},
            {"time_compression", 10.0},
            {"device_scale", 0.125},
            {"device",
             {{"kind", "cgroup"},
              {"limit_bytes", kLimit},
              {"peak_bytes", killed ? kLimit : 7e8},
              {"oom_kills", killed ? 1 : 0}}},
            {"map", {{"outcome", killed ? "killed" : "completed"}, {"major_faults", 47}}}};
  if (policy == "basic") {
    s["loop_closures"] = closures;
    s["tick_ms"] = {{"mean", 25.0}};
  } else {
    s["schema_version"] = 2;
    s["closures_accepted"] = closures;
    s["frames_localized"] = closures;
    s["time_total_ms"] = {{"steady", 21.0}, {"with_startup", 22.5}};
  }
  return s;
}

json WithCotenant(json s, const std::string& outcome, double tps, double p50, double p95) {
  s["cotenant"] = {{"model", "qwen3-vl-2b"},   {"outcome", outcome},
                   {"requests_completed", 12}, {"restarts", 0},
                   {"tokens_per_s", tps},      {"latency_ms", {{"p50", p50}, {"p95", p95}}}};
  return s;
}

// One cell of results.json, as bench_matrix.cc writes it.
json Cell(const std::string& policy, const std::string& label, const std::string& model,
          std::uint64_t k, const std::vector<json>& runs) {
  const std::string name = label + "-k" + std::to_string(k) + "-" + model;
  return {{"scenario_name", "tiny"},
          {"cell", name},
          {"policy", policy},
          {"policy_label", label},
          {"model", model},
          {"k_max", k},
          {"repeats", runs.size()},
          {"representative_repeat", 0},
          {"stats", StatsOfSummaries(runs)},
          {"runs", runs}};
}

// The four configurations, one run each, plus cells that are none of them: an unsliced variant
// and a looser budget (each would win by its numbers if it were picked) and the oracle.
json OneRunEach() {
  json r = json::array();
  r.push_back(Cell("basic", "basic", "none", 1820, {Summary("basic", false, 0.95, 40)}));
  r.push_back(Cell("basic", "basic", "qwen3-vl-2b", 1820,
                   {WithCotenant(Summary("basic", true, 0.65, 14), "stalled", 1.5, 10600, 11400)}));
  r.push_back(Cell("semantic", "semantic", "none", 1820, {Summary("semantic", false, 0.95, 40)}));
  r.push_back(
      Cell("semantic", "semantic", "qwen3-vl-2b", 1820,
           {WithCotenant(Summary("semantic", false, 0.95, 40), "completed", 4.6, 2300, 2600)}));
  r.push_back(Cell("basic", "basic:unsliced", "none", 100, {Summary("basic", false, 0.11, 1)}));
  r.push_back(Cell("semantic", "semantic", "none", 3000, {Summary("semantic", false, 0.12, 2)}));
  r.push_back(Cell("oracle", "oracle", "none", 1820, {Summary("oracle", false, 0.13, 3)}));
  return r;
}

bool Has(const std::string& text, const std::string& line) {
  const bool found = text.find(line) != std::string::npos;
  if (!found) MESSAGE("missing: " << line << "\nin:\n" << text);
  return found;
}

TEST_CASE("paper tables: the paper's columns, ours beside the paper's numbers") {
  const std::string t = PaperTablesMarkdown(OneRunEach());
  CHECK(Has(t, "## tiny: the paper's tables\n"));
  CHECK(Has(t,
            "device: memory cgroup (the kernel's OOM killer), limit 0.78 GiB, device scale "
            "0.125, time compression 10x; MemoryThr (K_max) 1820. The co-tenant is a stand-in "
            "for VLM decoding. One run per configuration. Each cell: ours (the paper's, "
            "Jetson Orin Nano 8 GB).\n"));
  CHECK(Has(t, "### Table I analogue: SLAM with and without the co-tenant\n"));
  CHECK(Has(t,
            "| metric | Basic only (1 run) | Basic + VLM (1 run) | Semantic only (1 run) | "
            "Semantic + VLM (1 run) |\n|---|---|---|---|---|\n"));
  // One run under a header that says so: the bare value, then the paper's.
  CHECK(Has(t, "| update rate (Hz) ↑ | 0.95 (0.96) | 0.65 (0.65) | 0.95 (0.96) | 0.95 (0.95) |"));
  // Schema 1's loop_closures (basic) and 2's closures_accepted are the same row.
  CHECK(Has(t, "| loop closures ↑ | 40 (53) | 14 (31) | 40 (35) | 40 (33) |"));
  // TimeTotal: basic's from tick_ms.mean (before issue 27); the paper's thousands grouped.
  CHECK(Has(t,
            "| avg TimeTotal (ms) ↓ | 25.0 (779.41) | 25.0 (5,064.87) | 21.0 (566.06) | "
            "21.0 (784.81) |"));
  CHECK(Has(t, "| ATE RMSE (m) ↓ | 0.120 (0.140) | 0.120 (0.310) | 0.050 (0.180) |"));
  CHECK(Has(t, "| avg TimeTotal incl. the start-up tick (ms) | – | – | 22.5 | 22.5 |"));
  CHECK(Has(t, "| frames localized (a closure accepted on the frame) | 40 | 14 | 40 | 40 |"));
  CHECK(Has(t, "| frames dropped of arrived | 1 of 60 | 12 of 60 | 1 of 60 | 1 of 60 |"));
  CHECK(Has(t, "| device OOM kills | 0.0 | 1.0 | 0.0 | 0.0 |"));
  CHECK(Has(t, "| device peak | 0.70 GB | 0.84 GB | 0.70 GB | 0.70 GB |"));
  CHECK(Has(t, "| device DRAM peak: usage + zram's store (GB) | – | – | – | – |"));
  CHECK(Has(t, "| map process outcome | ○ completed | † killed | ○ completed | ○ completed |"));
  CHECK(Has(t, "| co-tenant outcome | – | △ stalled | – | ○ completed |"));
  CHECK(Has(t, "### Table II analogue: the co-tenant beside SLAM\n"));
  CHECK(Has(t,
            "| model (stand-in) | policy | runs | outcome | requests completed | TPS median | "
            "TPS aggregate | latency p50 (ms) | latency mean (ms) | latency p95 (ms) | major "
            "faults |\n|---|---|---|---|---|---|---|---|---|---|---|\n"));
  CHECK(Has(t,
            "| qwen3-vl-2b | Basic | 1 | △ stalled | 12.0 | 1.50 | – | 10,600 | – | 11,400 | – |"));
  CHECK(Has(t,
            "| qwen3-vl-2b | Semantic | 1 | ○ completed | 12.0 | 4.60 | – | 2,300 | – | 2,600 | "
            "– |"));
  CHECK(Has(t,
            "| qwen3-vl-2b: the paper | Basic | 1 | △ | | 32.43 | – | 9,642 | – | – | – |\n"
            "| qwen3-vl-2b: the paper | Semantic | 1 | ○ | | 33.36 | – | 10,260 | – | – | – |\n"));
  // Neither the unsliced variant (smaller K_max) nor the looser budget nor the oracle is a column.
  CHECK(t.find("0.11") == std::string::npos);
  CHECK(t.find("0.12 (") == std::string::npos);
  CHECK(t.find("0.13") == std::string::npos);
  CHECK(PaperTablesMarkdown(json::array()).empty());
}

TEST_CASE("paper tables: repeats show mean ± 95 % CI, n in the header and the outcomes' tally") {
  json r = OneRunEach();
  // Semantic + VLM run three times: update rate {0.90, 0.95, 1.00}, mean 0.95, half-width
  // t(0.975, 2) x 0.05 / sqrt(3) = 0.124; aggregate tokens/s in two runs only {3, 5}: mean 4,
  // half-width t(0.975, 1) x sqrt(2) / sqrt(2) = 12.71; major faults {11000, 11419, 11838}: mean
  // 11,419, half-width 4.302653 x 419 / sqrt(3) = 1,041; one run of the three killed, restarted.
  std::vector<json> runs;
  const double rates[] = {0.90, 0.95, 1.00};
  const double faults[] = {11000, 11419, 11838};
  for (int i = 0; i < 3; ++i) {
    json s = WithCotenant(Summary("semantic", false, rates[i], 40), i == 2 ? "killed" : "completed",
                          4.6, 2300, 2600);
    s["map"]["major_faults"] = faults[i];
    s["cotenant"]["weights"] = "pinned";
    s["cotenant"]["restarts"] = i == 2 ? 1 : 0;
    if (i < 2) s["cotenant"]["tokens_per_s_aggregate"] = i == 0 ? 3.0 : 5.0;
    runs.push_back(s);
  }
  r[3] = Cell("semantic", "semantic", "qwen3-vl-2b", 1820, runs);
  const std::string t = PaperTablesMarkdown(r);
  CHECK(Has(t,
            "| metric | Basic only (1 run) | Basic + VLM (1 run) | Semantic only (1 run) | "
            "Semantic + VLM (n = 3) |"));
  CHECK(Has(t,
            "| update rate (Hz) ↑ | 0.95 (0.96) | 0.65 (0.65) | 0.95 (0.96) | 0.95 ± 0.12 "
            "(0.95) |"));
  CHECK(Has(t, "(weights pinned). 1 or 3 runs per configuration, interleaved (ABAB...)"));
  CHECK(Has(t, "| map major faults | 47 | 47 | 47 | 11,419 ± 1,041 |"));
  CHECK(Has(t,
            "| co-tenant outcome | – | △ stalled | – | ○ completed 2, † killed 1, restarts "
            "0.3 ± 1.4 |"));
  CHECK(Has(t,
            "| qwen3-vl-2b | Semantic | 3 | ○ completed 2, † killed 1 | 12.0 ± 0.0 | "
            "4.60 ± 0.00 | 4.00 ± 12.71 (n = 2) | 2,300 ± 0 |"));
}

TEST_CASE("paper tables: zonemap bench's report writer writes them as paper_tables.md") {
  const std::filesystem::path dir =
      std::filesystem::path(ZM_BINARY_DIR) / "tests" / "app" / "paper_tables_writer";
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  const json results = OneRunEach();
  WriteBenchReport(results, {.out = dir.string(),
                             .device_scale = 0.125,
                             .time_compression = 10.0,
                             .repeats = 1,
                             .plots = false});
  std::ifstream in(dir / "paper_tables.md");
  REQUIRE(in.good());
  std::ostringstream text;
  text << in.rdbuf();
  CHECK(text.str() == PaperTablesMarkdown(results) + "\n");
  // Beside the bench's own tables, from the same cells.
  CHECK(std::filesystem::exists(dir / "table1.md"));
  CHECK(std::filesystem::exists(dir / "table2.csv"));
}

}  // namespace
}  // namespace zm::app
