// `zonemap bench`'s report writer (bench_report.h).
#include "bench_report.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <initializer_list>
#include <map>
#include <sstream>
#include <vector>

#include "harness/cotenant.h"
#include "harness/repeats.h"
#include "paper_tables.h"

namespace zm::app {
namespace {

namespace fs = std::filesystem;

std::string Quote(const std::string& s) { return "'" + s + "'"; }

std::string Fmt(double v, int decimals) {
  if (std::isnan(v)) return "–";
  char b[64];
  std::snprintf(b, sizeof b, "%.*f", decimals, v);
  return b;
}

std::string Label(const nlohmann::json& r) {
  return r.contains("policy_label") ? r["policy_label"].get<std::string>()
                                    : r["policy"].get<std::string>();
}

struct Table {
  std::vector<std::string> header;
  std::vector<std::vector<std::string>> rows;
  void Write(const std::string& base, const std::string& title) const {
    std::ofstream md(base + ".md");
    md << "### " << title << "\n\n|";
    for (const auto& h : header) md << ' ' << h << " |";
    md << "\n|";
    for (std::size_t i = 0; i < header.size(); ++i) md << "---|";
    md << '\n';
    for (const auto& r : rows) {
      md << '|';
      for (const auto& c : r) md << ' ' << c << " |";
      md << '\n';
    }
    std::ofstream csv(base + ".csv");
    for (std::size_t i = 0; i < header.size(); ++i) csv << (i ? "," : "") << header[i];
    csv << '\n';
    for (const auto& r : rows) {
      for (std::size_t i = 0; i < r.size(); ++i) csv << (i ? "," : "") << '"' << r[i] << '"';
      csv << '\n';
    }
  }
};


// A cell's statistic at a JSON pointer of its runs' summaries (null when no run had it).
const nlohmann::json& Stat(const nlohmann::json& cell, const std::string& pointer) {
  static const nlohmann::json kNone;
  const auto& st = cell["stats"];
  const auto it = st.find(pointer);
  return it == st.end() ? kNone : *it;
}

// The mean of a statistic, NaN when no run had it (for ratios of means).
double Mean(const nlohmann::json& cell, const std::string& pointer) {
  const nlohmann::json& s = Stat(cell, pointer);
  return s.is_object() && s.value("n", 0U) > 0 ? s.value("mean", std::nan("")) : std::nan("");
}

// A strings' tally over the repeats: "completed" when all agree, else "completed 2, killed 1".
// Several pointers are joined per run ("/cotenant/symbol", "/cotenant/outcome": "○ completed").
std::string Tally(const nlohmann::json& cell, std::initializer_list<const char*> pointers) {
  std::vector<std::pair<std::string, int>> seen;
  for (const auto& run : cell["runs"]) {
    std::string v;
    for (const char* p : pointers) {
      const nlohmann::json::json_pointer ptr(p);
      // Appended piece by piece: "" + std::string&& trips GCC 12's -O3 -Wrestrict false positive.
      if (!v.empty()) v += ' ';
      v += run.contains(ptr) && run[ptr].is_string() ? run[ptr].get<std::string>() : "–";
    }
    auto it = std::find_if(seen.begin(), seen.end(), [&](const auto& p) { return p.first == v; });
    if (it == seen.end()) {
      seen.emplace_back(v, 1);
    } else {
      ++it->second;
    }
  }
  if (seen.size() == 1) return seen[0].first;
  std::string out;
  for (const auto& [v, n] : seen) out += (out.empty() ? "" : ", ") + v + " " + std::to_string(n);
  return out;
}

}  // namespace

void WriteBenchReport(const nlohmann::json& results, const BenchReportOptions& o) {
  // Every numeric cell: mean ± 95 % CI over the repeats (FormatStat), "(1 run)" for one.
  const auto S = [&o](const nlohmann::json& cell, const std::string& ptr, int decimals,
                           double scale = 1.0) {
    return FormatStat(Stat(cell, ptr), decimals, scale, o.repeats);
  };
  constexpr double kMiB = 1.0 / 1048576.0;
  // Loop closures accepted (RTAB-Map's count) and frames localized. Summaries of version 1 have
  // one count, loop_closures, which was both.
  const auto closures = [&S](const nlohmann::json& cell, const char* pointer) {
    return S(cell, Stat(cell, pointer).is_null() ? "/loop_closures" : pointer, 0);
  };
  Table t1{{"scenario", "K_max", "policy", "co-tenant", "map process", "update rate (Hz)",
            "frames dropped", "frames arrived", "loop closures accepted", "frames localized",
            "avg TimeTotal (ms)", "incl. start-up tick (ms)", "without idle-time loads (ms)",
            "with idle-time loads (ms)", "p99 tick (ms)", "ATE RMSE (m)", "RPE trans RMSE (m)",
            "RPE rot RMSE (deg)"},
           {}};
  Table t2{{"scenario", "K_max", "model (stand-in)", "policy", "outcome", "requests completed",
            "of", "restarts", "TPS median", "TPS aggregate", "latency p50 (ms)",
            "latency mean (ms)", "latency p95 (ms)", "major faults"},
           {}};
  Table t6{{"scenario", "K_max", "policy", "co-tenant", "device", "limit (MiB)", "peak (MiB)",
            "swap peak (MiB)", "OOM kills", "map peak RSS (MiB)", "co-tenant peak RSS (MiB)",
            "map major faults", "map process", "co-tenant"},
           {}};
  Table t3{{"scenario", "K_max", "policy", "co-tenant", "peak resident kf", "peak resident MB",
            "over-budget ticks", "max excess kf", "OOM events", "kf loaded", "kf unloaded",
            "DB statements start-up / steady", "DB transactions start-up / steady",
            "DB blob reads start-up / steady", "DB MB read", "zone loads", "zone loads / oracle"},
           {}};
  std::map<std::string, double> oracle_loads;
  for (const auto& r : results) {
    if (r["policy"] == "oracle") {
      oracle_loads[r["scenario_name"].get<std::string>() + "/" +
                   std::to_string(r["k_max"].get<std::uint64_t>())] = Mean(r, "/zone_loads");
    }
  }
  for (const auto& r : results) {
    const std::string sc = r["scenario_name"], pol = Label(r), model = r["model"];
    const auto split = [&](const char* key) {
      return S(r, std::string("/startup/") + key, 0) + " / " +
             S(r, std::string("/steady_state/") + key, 0);
    };
    const std::string k = std::to_string(r["k_max"].get<std::uint64_t>());
    const std::string map_outcome = Tally(r, {"/map/outcome"});
    t1.rows.push_back(
        {sc, k, pol, model, map_outcome, S(r, "/update_rate_hz", 2), S(r, "/frames_dropped", 0),
         S(r, "/frames_arrived", 0), closures(r, "/closures_accepted"),
         closures(r, "/frames_localized"), S(r, "/time_total_ms/steady", 2),
         S(r, "/time_total_ms/with_startup", 2), S(r, "/time_total_ms/without_idle_loads", 2),
         S(r, "/time_total_ms/with_idle_loads", 2), S(r, "/tick_ms/p99", 2), S(r, "/ate_rmse_m", 3),
         S(r, "/rpe_trans_rmse_m", 3), S(r, "/rpe_rot_rmse_deg", 2)});
    if (model != "none") {
      t2.rows.push_back(
          {sc, k, model, pol, Tally(r, {"/cotenant/symbol", "/cotenant/outcome"}),
           S(r, "/cotenant/requests_completed", 1), S(r, "/cotenant/requests_planned", 0),
           S(r, "/cotenant/restarts", 1), S(r, "/cotenant/tokens_per_s", 2),
           S(r, "/cotenant/tokens_per_s_aggregate", 2), S(r, "/cotenant/latency_ms/p50", 0),
           S(r, "/cotenant/latency_ms/mean", 0), S(r, "/cotenant/latency_ms/p95", 0),
           S(r, "/cotenant/major_faults", 0)});
    }
    const nlohmann::json& dev0 = r["runs"][0].value("device", nlohmann::json::object());
    t6.rows.push_back({sc, k, pol, model,
                       dev0.value("kind", std::string("?")) +
                           (dev0.value("simulated", false) ? " (simulated)" : ""),
                       S(r, "/device/limit_bytes", 1, kMiB), S(r, "/device/peak_bytes", 1, kMiB),
                       S(r, "/device/swap/peak_bytes", 1, kMiB), S(r, "/device/oom_kills", 1),
                       S(r, "/device/map_peak_rss_bytes", 1, kMiB),
                       S(r, "/device/cotenant_peak_rss_bytes", 1, kMiB),
                       S(r, "/map/major_faults", 0), map_outcome,
                       model != "none" ? Tally(r, {"/cotenant/outcome"}) : std::string("–")});
    const auto ok = oracle_loads.find(sc + "/" + k);
    const double zl = Mean(r, "/zone_loads");
    t3.rows.push_back(
        {sc, k, pol, model, S(r, "/peak_resident_keyframes", 0),
         S(r, "/peak_resident_bytes", 1, 1e-6), S(r, "/over_budget_ticks", 0),
         S(r, "/max_over_budget_keyframes", 0), S(r, "/oom_events", 1),
         S(r, "/keyframes_loaded", 0), S(r, "/keyframes_unloaded", 0),
         // Database work in one unit for every policy (basic's searches included),
         // the start-up load apart from the rest of the run.
         split("db_queries"), split("db_transactions"), split("db_blob_reads"),
         S(r, "/db_bytes_read", 1, 1e-6), S(r, "/zone_loads", 0),
         ok != oracle_loads.end() && ok->second > 0 && zl > 0 ? Fmt(zl / ok->second, 2) : "–"});
  }
  // Ratios of the repeats' means, measured side by side in this run (same scenario, budget and
  // co-tenant).
  Table t4{{"scenario", "K_max", "co-tenant", "ratio (of means)", "avg TimeTotal", "kf loaded",
            "DB transactions", "DB bytes read", "ATE"},
           {}};
  auto find = [&](const std::string& sc, std::uint64_t k, const std::string& model,
                  const std::string& pol) {
    for (const auto& r : results) {
      if (r["scenario_name"] == sc && r["k_max"] == k && r["model"] == model && Label(r) == pol)
        return &r;
    }
    return static_cast<const nlohmann::json*>(nullptr);
  };
  auto ratio = [](double a, double b) {
    return b != 0 && !std::isnan(a) && !std::isnan(b) ? Fmt(a / b, 2) : std::string("–");
  };
  for (const auto& r : results) {
    if (Label(r) != "semantic") continue;
    const std::string sc = r["scenario_name"], model = r["model"];
    const std::uint64_t k = r["k_max"];
    for (auto [num, den] :
         {std::pair{"semantic", "basic"}, std::pair{"predictive", "semantic"}}) {
      const auto* a = find(sc, k, model, num);
      const auto* b = find(sc, k, model, den);
      if (a == nullptr || b == nullptr) continue;
      const auto rm = [&](const char* ptr) { return ratio(Mean(*a, ptr), Mean(*b, ptr)); };
      t4.rows.push_back({sc, std::to_string(k), model, std::string(num) + "/" + den,
                         rm("/time_total_ms/steady"), rm("/keyframes_loaded"),
                         rm("/db_transactions"), rm("/db_bytes_read"), rm("/ate_rmse_m")});
    }
  }
  // Tick latency per policy (issue 14): steady-state ticks (after the start-up tick), each
  // against unbounded's in the same scenario and co-tenant setting (no loads at all: the
  // floor; a ratio of means); the start-up load apart.
  Table t5{{"scenario", "K_max", "policy", "co-tenant", "ticks", "tick p50 (ms)", "tick p99 (ms)",
            "tick max (ms)", "p99 / unbounded", "max / unbounded", "start-up tick (ms)",
            "start-up kf", "start-up MB", "idle load (ms)", "late ticks", "loop closures accepted",
            "frames localized", "ATE RMSE (m)"},
           {}};
  for (const auto& r : results) {
    const std::string sc = r["scenario_name"], model = r["model"];
    const nlohmann::json* floor = nullptr;
    for (const auto& u : results) {
      if (u["scenario_name"] == sc && u["model"] == model && u["policy"] == "unbounded")
        floor = &u;
    }
    const auto vs = [&](const char* ptr) {
      return floor == nullptr ? std::string("–") : ratio(Mean(r, ptr), Mean(*floor, ptr));
    };
    t5.rows.push_back({sc, std::to_string(r["k_max"].get<std::uint64_t>()), Label(r), model,
                       S(r, "/tick_ms/count", 0), S(r, "/tick_ms/p50", 2), S(r, "/tick_ms/p99", 2),
                       S(r, "/tick_ms/max", 1), vs("/tick_ms/p99"), vs("/tick_ms/max"),
                       S(r, "/startup/tick_ms", 1), S(r, "/startup/keyframes_loaded", 0),
                       S(r, "/startup/bytes_read", 1, 1e-6), S(r, "/loads/idle_load_ms_total", 0),
                       S(r, "/loads/late_ticks", 0), closures(r, "/closures_accepted"),
                       closures(r, "/frames_localized"), S(r, "/ate_rmse_m", 4)});
  }
  // Every table states the device (and "simulated" for the ledger), its scale, the clock and
  // the repeats.
  std::string device_used = "cgroup";
  for (const auto& cell : results) {
    for (const auto& r : cell["runs"]) {
      const nlohmann::json d = r.value("device", nlohmann::json::object());
      if (!d.value("simulated", false)) continue;
      const std::string why = d.value("fallback_reason", std::string());
      device_used = "ledger, SIMULATED" + (why.empty() ? std::string() : ": " + why);
    }
  }
  const std::string stated =
      " (device " + device_used + ", device scale " + Fmt(o.device_scale, 3) +
      ", time compression " + Fmt(o.time_compression, 2) + "; " +
      (o.repeats == 1 ? std::string("1 run per cell)")
                    : std::to_string(o.repeats) +
                          " runs per cell, interleaved: mean ± 95 % CI, Student's t)");
  t1.Write(o.out + "/table1", "Table I analogue: SLAM with and without the co-tenant" + stated);
  t6.Write(o.out + "/device", "The device: memory, OOM kills, outcomes" + stated);
  t5.Write(o.out + "/latency", "Tick latency (steady state; start-up apart)" + stated);
  t2.Write(o.out + "/table2",
           "Table II analogue: the co-tenant beside SLAM (stand-in for VLM decoding)" + stated);
  t3.Write(o.out + "/memory", "Memory and churn" + stated);
  t4.Write(o.out + "/ratios", "Ratios measured side by side in this run" + stated);
  {
    nlohmann::json tables = {{"results", results}};
    std::ofstream(o.out + "/tables.json") << tables.dump(2) << '\n';
  }
  // The paper's Table I and Table II in the paper's form, the paper's numbers beside ours.
  const std::string paper = PaperTablesMarkdown(results);
  if (!paper.empty()) std::ofstream(o.out + "/paper_tables.md") << paper << '\n';
  for (const char* f : {"table1", "table2", "device", "memory", "ratios", "latency"}) {
    std::ifstream in(o.out + "/" + f + ".md");
    std::ostringstream text;
    text << in.rdbuf();
    std::printf("%s\n", text.str().c_str());
  }
  if (!paper.empty()) std::printf("%s\n\n", paper.c_str());
  std::printf("The co-tenant is a stand-in: %s.\n", std::string(kCotenantNote).c_str());
  if (o.plots) {
    const std::string plots = std::string(ZM_SOURCE_DIR_FOR_APP) + "/scripts/plots.py";
    // Debian's interpreter has python3-matplotlib; a python3 earlier on PATH may not.
    const std::string py = fs::exists("/usr/bin/python3") ? "/usr/bin/python3" : "python3";
    const std::string c = py + " " + Quote(plots) + " " + Quote(o.out);
    if (std::system(c.c_str()) != 0)
      std::fprintf(stderr, "bench: figures failed (%s)\n", c.c_str());
  }
  std::printf(
      "bench: wrote %s/{table1,table2,device,memory,ratios,latency}.{md,csv}, paper_tables.md, "
      "results.json, figures/\n",
      o.out.c_str());
}

}  // namespace zm::app
