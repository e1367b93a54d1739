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
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <initializer_list>
#include <map>
#include <sstream>

#include "commands.h"
#include "harness/cotenant.h"
#include "harness/device_run.h"
#include "harness/experiment_profile.h"
#include "harness/repeats.h"
#include "runtime/stop_signal.h"
#include "sim/scenario.h"

namespace zm::app {

namespace {

namespace fs = std::filesystem;

std::vector<std::string> Split(const std::string& s) {
  std::vector<std::string> out;
  std::stringstream ss(s);
  std::string item;
  while (std::getline(ss, item, ',')) {
    if (!item.empty()) out.push_back(item);
  }
  return out;
}

std::string SelfExe() {
  std::error_code ec;
  auto p = fs::read_symlink("/proc/self/exe", ec);
  return ec ? std::string("zonemap") : p.string();
}

std::string Quote(const std::string& s) { return "'" + s + "'"; }

// Generates a scenario with this very program (`zonemap sim ...`) unless it is already there.
Status EnsureScenario(const std::string& spec, const std::string& dir,
                      const std::string& floorplans, bool quick) {
  if (fs::exists(dir + "/scenario.json") && fs::exists(dir + "/map.db")) return Status::Ok();
  if (spec.rfind("dir:", 0) == 0) {  // an existing scenario directory: used as it is
    return NotFound("scenario directory '" + spec.substr(4) +
                    "' has no scenario.json and map.db (make one with `zonemap sim`)");
  }
  std::string cmd = Quote(SelfExe()) + " sim ";
  if (spec == "hospital") {
    cmd += "hospital --seed 1 --quiet --out " + Quote(dir);
    if (quick) cmd += " --area 2000 --tasks 12";
  } else if (spec.rfind("floorplan:", 0) == 0) {
    const std::string name = spec.substr(10);
    const std::string map = floorplans + "/" + name + "_map.png";
    const std::string gt = floorplans + "/" + name + "_gt.png";
    if (!fs::exists(map)) return NotFound("floor plan '" + map + "' does not exist");
    cmd +=
        "floorplan " + Quote(map) + " --gt " + Quote(gt) + " --seed 1 --quiet --out " + Quote(dir);
    if (quick) cmd += " --tasks 8";
  } else {
    return InvalidArgument("unknown scenario '" + spec + "' (hospital or floorplan:NAME)");
  }
  std::fprintf(stderr, "bench: generating %s\n", spec.c_str());
  if (std::system(cmd.c_str()) != 0) return Internal("scenario generation failed: " + cmd);
  return Status::Ok();
}

double Num(const nlohmann::json& j, const char* key) {
  return j.contains(key) && j[key].is_number() ? j[key].get<double>() : std::nan("");
}

std::string Fmt(double v, int decimals) {
  if (std::isnan(v)) return "–";
  char b[64];
  std::snprintf(b, sizeof b, "%.*f", decimals, v);
  return b;
}

// A policy entry of --policies: NAME, or NAME:unsliced (loads finish inside the tick that plans
// them, as before issue 14: [loads] sliced = false), measured side by side with the sliced one.
struct PolicyVariant {
  std::string policy;
  bool unsliced = false;
  std::string label;  // what the tables and figures call it
};

Result<PolicyVariant> ParsePolicyVariant(const std::string& entry) {
  PolicyVariant v;
  const auto colon = entry.find(':');
  v.policy = entry.substr(0, colon);
  v.label = entry;
  if (colon != std::string::npos) {
    if (entry.substr(colon + 1) != "unsliced") {
      return InvalidArgument("policy variant '" + entry + "': only NAME:unsliced is known");
    }
    v.unsliced = true;
  }
  return v;
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

// One cell of the matrix: a scenario, a budget, a co-tenant model and a policy variant, run
// --repeat times.
struct Cell {
  std::string scenario_name;
  std::string scenario_dir;
  std::string budget;  // as given ("1", "two-zones", "400kf")
  std::uint64_t k = 0;
  std::string model;
  PolicyVariant variant;
  std::string run_name;
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

void AddBenchCommand(CLI::App& app, CommandContext& ctx) {
  struct Opts {
    std::string out, profile = "orin-nano-8gb";
    std::string scenarios, policies, models, budgets;
    std::string floorplans = ZM_DEFAULT_FLOORPLANS_DIR;
    std::string device = "cgroup";
    double device_scale = 1.0;
    double time_compression = 1.0;
    std::uint32_t cotenant_requests = 30;
    int repeat = 0;
    std::uint32_t prompt_tokens = 0, answer_tokens = 0;
    bool quick = false, no_plots = false;
    std::string lock_arena;  // --lock-arena on|off: passed to every run ("" = the profile's)
    std::string zram_charge = "on";  // --zram-charge on|off: passed to every run
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
  auto* device_opt = cmd->add_option(
      "--device", o->device,
      "cgroup (default; the ledger, labelled simulated, where none can be made) or ledger");
  cmd->add_option(
      "--device-scale", o->device_scale,
      "0 < S <= 1: device memory, OS reserve, weights, KV cache and keyframe bytes x S");
  cmd->add_option("--time-compression", o->time_compression,
                  "every run's frames arrive at the profile's rate, X times faster than real time "
                  "(1 = real time; 0 = every frame as fast as possible, no drops)");
  cmd->add_option("--cotenant-requests", o->cotenant_requests,
                  "co-tenant requests per run, spread over the patrol (default 30)");
  cmd->add_option("--repeat", o->repeat,
                  "runs per cell, interleaved across cells (default 5; --quick: 3); tables show "
                  "mean ± 95 % CI");
  cmd->add_option("--prompt-tokens", o->prompt_tokens,
                  "co-tenant prompt length (default: the profile's)");
  cmd->add_option("--answer-tokens", o->answer_tokens,
                  "co-tenant answer length (default: the profile's)");
  cmd->add_option("--pace", o->time_compression, "old name of --time-compression");
  cmd->add_flag("--no-plots", o->no_plots, "skip the matplotlib figures");
  AddDeviceMemoryOptions(*cmd, &o->lock_arena, &o->zram_charge);  // passed to every run
  cmd->callback([o, &ctx, device_opt] {
    InstallStopSignals();
    auto device_kind = ParseDeviceKind(o->device);
    if (!device_kind.ok()) return ctx.Fail("bench", device_kind.status());
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
    fs::create_directories(o->out);

    // The cells: scenarios (generated first) x budgets x models x policies.
    std::vector<Cell> cells;
    for (const std::string& spec : scenarios) {
      std::string name = spec.substr(spec.find(':') == std::string::npos ? 0 : spec.find(':') + 1);
      std::string sdir = o->out + "/scenarios/" + name;
      if (spec.rfind("dir:", 0) == 0) {
        sdir = spec.substr(4);
        name = fs::path(sdir).lexically_normal().filename().string();
        if (name.empty())
          name = fs::path(sdir).lexically_normal().parent_path().filename().string();
      }
      if (Status s = EnsureScenario(spec, sdir, o->floorplans, q); !s.ok())
        return ctx.Fail("bench", s);
      auto info = sim::LoadScenario(sdir);
      if (!info.ok()) return ctx.Fail("bench", info.status());
      // Budget sweep from metadata: a fraction of the map, or the two largest zones.
      auto db = MapDb::Open(info->map_db);
      if (!db.ok()) return ctx.Fail("bench", db.status());
      auto sizes = db.value()->ZoneSizes();
      if (!sizes.ok()) return ctx.Fail("bench", sizes.status());
      std::vector<std::uint32_t> zs = sizes.value();
      std::sort(zs.rbegin(), zs.rend());
      const std::uint64_t n = db.value()->metadata().keyframe_count;
      db.value().reset();
      for (const std::string& b : budgets) {
        std::uint64_t k = 0;
        if (b == "two-zones") {
          k = zs.size() >= 2 ? zs[0] + zs[1] : n;
        } else if (b.size() > 2 && b.substr(b.size() - 2) == "kf") {  // "400kf": a count
          k = std::strtoull(b.c_str(), nullptr, 10);
        } else {
          k = static_cast<std::uint64_t>(
              std::llround(std::atof(b.c_str()) * static_cast<double>(n)));
        }
        k = std::clamp<std::uint64_t>(k, zs.empty() ? 1 : zs[0], n);
        for (const std::string& model : models) {
          for (const std::string& entry : policies) {
            auto variant = ParsePolicyVariant(entry);
            if (!variant.ok()) return ctx.Fail("bench", variant.status());
            if (model != "none" && variant->policy == "oracle")
              continue;  // a bound, not a contender
            Cell c{name, sdir, b, k, model, variant.value(), {}};
            c.run_name = variant->policy + (variant->unsliced ? "-unsliced" : "") + "-k" +
                         std::to_string(k) + "-" + model;
            cells.push_back(std::move(c));
          }
        }
      }
    }

    // The runs, interleaved: repeat r of every cell, then repeat r + 1.
    std::vector<std::vector<nlohmann::json>> summaries(cells.size(),
                                                       std::vector<nlohmann::json>(repeats));
    const std::vector<CellRepeat> order = InterleavedOrder(cells.size(), repeats);
    for (std::size_t i = 0; i < order.size(); ++i) {
      const Cell& c = cells[order[i].cell];
      const std::uint32_t rep = order[i].repeat;
      auto profile = LoadExperimentProfile(o->profile);
      if (!profile.ok()) return ctx.Fail("bench", profile.status());
      ProfileOverrides ov;
      ov.policy = c.variant.policy;
      ov.memory_thr = std::to_string(c.k);
      if (!o->lock_arena.empty()) ov.lock_arena = o->lock_arena;
      if (Status s = ApplyOverrides(ov, profile->core); !s.ok()) return ctx.Fail("bench", s);
      if (c.variant.unsliced) profile->core.loads.sliced = false;
      if (c.model != "none") {
        if (Status s = ApplyModelOverride(c.model, profile.value()); !s.ok()) {
          return ctx.Fail("bench", s);
        }
      }
      // The profile's request length (512 + 128 for the paper's device) unless asked otherwise.
      if (o->prompt_tokens != 0) profile->cotenant.prompt_tokens = o->prompt_tokens;
      if (o->answer_tokens != 0) profile->cotenant.answer_tokens = o->answer_tokens;
      DeviceRunRequest req;
      req.scenario_dir = c.scenario_dir;
      req.out_dir =
          o->out + "/runs/" + c.scenario_name + "/" + c.run_name + "/rep" + std::to_string(rep);
      req.profile = profile.value();
      req.with_cotenant = c.model != "none";
      req.device = *device_kind;
      req.device_explicit = device_opt->count() > 0;
      req.device_scale = o->device_scale;
      // Every run, alone and with the co-tenant, on the same frames' clock (issue 17 §4).
      req.time_compression = o->time_compression;
      req.cotenant_requests = o->cotenant_requests;
      req.charge_zram = o->zram_charge == "on";
      std::fprintf(stderr, "bench: %s %s repeat %u/%u (run %zu of %zu)\n", c.scenario_name.c_str(),
                   c.run_name.c_str(), rep + 1, repeats, i + 1, order.size());
      auto r = RunOnDevice(req, StopFlag());
      if (!r.ok()) return ctx.Fail("bench", r.status().Annotate(c.run_name));
      summaries[order[i].cell][rep] = std::move(r).value();
      if (StopFlag()->load()) return ctx.Fail("bench", "interrupted");
    }

    // Per cell: every repeat's summary, the statistics over them, the representative repeat.
    nlohmann::json all = nlohmann::json::array();
    for (std::size_t ci = 0; ci < cells.size(); ++ci) {
      const Cell& c = cells[ci];
      const std::vector<nlohmann::json>& runs = summaries[ci];
      std::vector<double> tick_means;
      nlohmann::json dirs = nlohmann::json::array();
      for (std::uint32_t r = 0; r < repeats; ++r) {
        tick_means.push_back(Num(runs[r]["tick_ms"], "mean"));
        dirs.push_back("runs/" + c.scenario_name + "/" + c.run_name + "/rep" + std::to_string(r));
      }
      const std::size_t rep = RepresentativeRepeat(tick_means);
      const nlohmann::json& first = runs[0];
      all.push_back({{"scenario_name", c.scenario_name},
                     {"cell", c.run_name},
                     {"policy", c.variant.policy},
                     {"policy_label", c.variant.label},
                     {"budget", c.budget},
                     {"model", c.model},
                     {"k_max", first.value("k_max", std::uint64_t{0})},
                     {"repeats", repeats},
                     {"order", "interleaved"},
                     // The run the figures show: mean tick time nearest the median of the repeats.
                     {"representative_repeat", rep},
                     {"representative_by", "/tick_ms/mean"},
                     {"run_dirs", dirs},
                     {"stats", StatsOfSummaries(runs)},
                     {"runs", runs}});
    }
    std::ofstream(o->out + "/results.json") << all.dump(2) << '\n';

    // Every numeric cell: mean ± 95 % CI over the repeats (FormatStat), "(1 run)" for one.
    const auto S = [repeats](const nlohmann::json& cell, const std::string& ptr, int decimals,
                             double scale = 1.0) {
      return FormatStat(Stat(cell, ptr), decimals, scale, repeats);
    };
    constexpr double kMiB = 1.0 / 1048576.0;
    Table t1{
        {"scenario", "K_max", "policy", "co-tenant", "map process", "update rate (Hz)",
         "frames dropped", "frames arrived", "loop closures", "avg TimeTotal (ms)",
         "incl. start-up tick (ms)", "without idle-time loads (ms)", "with idle-time loads (ms)",
         "p99 tick (ms)", "ATE RMSE (m)", "RPE trans RMSE (m)", "RPE rot RMSE (deg)"},
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
    for (const auto& r : all) {
      if (r["policy"] == "oracle") {
        oracle_loads[r["scenario_name"].get<std::string>() + "/" +
                     std::to_string(r["k_max"].get<std::uint64_t>())] = Mean(r, "/zone_loads");
      }
    }
    for (const auto& r : all) {
      const std::string sc = r["scenario_name"], pol = Label(r), model = r["model"];
      const auto split = [&](const char* key) {
        return S(r, std::string("/startup/") + key, 0) + " / " +
               S(r, std::string("/steady_state/") + key, 0);
      };
      const std::string k = std::to_string(r["k_max"].get<std::uint64_t>());
      const std::string map_outcome = Tally(r, {"/map/outcome"});
      t1.rows.push_back(
          {sc, k, pol, model, map_outcome, S(r, "/update_rate_hz", 2), S(r, "/frames_dropped", 0),
           S(r, "/frames_arrived", 0), S(r, "/loop_closures", 0), S(r, "/time_total_ms/steady", 2),
           S(r, "/time_total_ms/with_startup", 2), S(r, "/time_total_ms/without_idle_loads", 2),
           S(r, "/time_total_ms/with_idle_loads", 2), S(r, "/tick_ms/p99", 2),
           S(r, "/ate_rmse_m", 3), S(r, "/rpe_trans_rmse_m", 3), S(r, "/rpe_rot_rmse_deg", 2)});
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
      for (const auto& r : all) {
        if (r["scenario_name"] == sc && r["k_max"] == k && r["model"] == model && Label(r) == pol)
          return &r;
      }
      return static_cast<const nlohmann::json*>(nullptr);
    };
    auto ratio = [](double a, double b) {
      return b != 0 && !std::isnan(a) && !std::isnan(b) ? Fmt(a / b, 2) : std::string("–");
    };
    for (const auto& r : all) {
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
    Table t5{
        {"scenario", "K_max", "policy", "co-tenant", "ticks", "tick p50 (ms)", "tick p99 (ms)",
         "tick max (ms)", "p99 / unbounded", "max / unbounded", "start-up tick (ms)", "start-up kf",
         "start-up MB", "idle load (ms)", "late ticks", "loop closures", "ATE RMSE (m)"},
        {}};
    for (const auto& r : all) {
      const std::string sc = r["scenario_name"], model = r["model"];
      const nlohmann::json* floor = nullptr;
      for (const auto& u : all) {
        if (u["scenario_name"] == sc && u["model"] == model && u["policy"] == "unbounded")
          floor = &u;
      }
      const auto vs = [&](const char* ptr) {
        return floor == nullptr ? std::string("–") : ratio(Mean(r, ptr), Mean(*floor, ptr));
      };
      t5.rows.push_back({sc, std::to_string(r["k_max"].get<std::uint64_t>()), Label(r), model,
                         S(r, "/tick_ms/count", 0), S(r, "/tick_ms/p50", 2),
                         S(r, "/tick_ms/p99", 2), S(r, "/tick_ms/max", 1), vs("/tick_ms/p99"),
                         vs("/tick_ms/max"), S(r, "/startup/tick_ms", 1),
                         S(r, "/startup/keyframes_loaded", 0), S(r, "/startup/bytes_read", 1, 1e-6),
                         S(r, "/loads/idle_load_ms_total", 0), S(r, "/loads/late_ticks", 0),
                         S(r, "/loop_closures", 0), S(r, "/ate_rmse_m", 4)});
    }
    // Every table states the device (and "simulated" for the ledger), its scale, the clock and
    // the repeats.
    std::string device_used = "cgroup";
    for (const auto& cell : all) {
      for (const auto& r : cell["runs"]) {
        const nlohmann::json d = r.value("device", nlohmann::json::object());
        if (!d.value("simulated", false)) continue;
        const std::string why = d.value("fallback_reason", std::string());
        device_used = "ledger, SIMULATED" + (why.empty() ? std::string() : ": " + why);
      }
    }
    const std::string stated =
        " (device " + device_used + ", device scale " + Fmt(o->device_scale, 3) +
        ", time compression " + Fmt(o->time_compression, 2) + "; " +
        (repeats == 1 ? std::string("1 run per cell)")
                      : std::to_string(repeats) +
                            " runs per cell, interleaved: mean ± 95 % CI, Student's t)");
    t1.Write(o->out + "/table1", "Table I analogue: SLAM with and without the co-tenant" + stated);
    t6.Write(o->out + "/device", "The device: memory, OOM kills, outcomes" + stated);
    t5.Write(o->out + "/latency", "Tick latency (steady state; start-up apart)" + stated);
    t2.Write(o->out + "/table2",
             "Table II analogue: the co-tenant beside SLAM (stand-in for VLM decoding)" + stated);
    t3.Write(o->out + "/memory", "Memory and churn" + stated);
    t4.Write(o->out + "/ratios", "Ratios measured side by side in this run" + stated);
    {
      nlohmann::json tables = {{"results", all}};
      std::ofstream(o->out + "/tables.json") << tables.dump(2) << '\n';
    }
    for (const char* f : {"table1", "table2", "device", "memory", "ratios", "latency"}) {
      std::ifstream in(o->out + "/" + f + ".md");
      std::ostringstream text;
      text << in.rdbuf();
      std::printf("%s\n", text.str().c_str());
    }
    std::printf("The co-tenant is a stand-in: %s.\n", std::string(kCotenantNote).c_str());
    if (!o->no_plots) {
      const std::string plots = std::string(ZM_SOURCE_DIR_FOR_APP) + "/scripts/plots.py";
      // Debian's interpreter has python3-matplotlib; a python3 earlier on PATH may not.
      const std::string py = fs::exists("/usr/bin/python3") ? "/usr/bin/python3" : "python3";
      const std::string c = py + " " + Quote(plots) + " " + Quote(o->out);
      if (std::system(c.c_str()) != 0)
        std::fprintf(stderr, "bench: figures failed (%s)\n", c.c_str());
    }
    std::printf(
        "bench: wrote %s/{table1,table2,device,memory,ratios,latency}.{md,csv}, results.json, "
        "figures/\n",
        o->out.c_str());
  });
}

}  // namespace zm::app
