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
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>

#include "commands.h"
#include "runtime/stop_signal.h"
#include "harness/cotenant.h"
#include "harness/device_run.h"
#include "harness/experiment_profile.h"
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
Status EnsureScenario(const std::string& spec, const std::string& dir, const std::string& floorplans,
                      bool quick) {
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
    cmd += "floorplan " + Quote(map) + " --gt " + Quote(gt) + " --seed 1 --quiet --out " + Quote(dir);
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

double Median(std::vector<double> v) {
  if (v.empty()) return std::nan("");
  std::sort(v.begin(), v.end());
  const std::size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
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
    int repeat = 1;
    std::uint32_t prompt_tokens = 0, answer_tokens = 0;
    bool quick = false, no_plots = false;
    std::string lock_arena;  // --lock-arena on|off: passed to every run ("" = the profile's)
  };
  auto o = std::make_shared<Opts>();
  auto* cmd = app.add_subcommand("bench", "Run the evaluation matrix and write the paper's tables and figures");
  cmd->add_option("--out", o->out, "output directory")->required();
  cmd->add_flag("--quick", o->quick, "the short default of `make demo`");
  cmd->add_option("--profile", o->profile, "device profile (default orin-nano-8gb)");
  cmd->add_option("--scenarios", o->scenarios, "comma list: hospital, floorplan:NAME, dir:PATH (an existing scenario)");
  cmd->add_option("--policies", o->policies, "comma list of policies; NAME:unsliced = loads inside the tick (as before issue 14)");
  cmd->add_option("--models", o->models, "comma list of co-tenant models ('none' = without)");
  cmd->add_option("--budgets", o->budgets, "comma list of MemoryThr as fractions of the map (e.g. 1,0.5,0.25), 'two-zones' or a count 'Nkf'");
  cmd->add_option("--floorplans", o->floorplans, "folder with <name>_map.png and <name>_gt.png");
  auto* device_opt = cmd->add_option("--device", o->device,
                  "cgroup (default; the ledger, labelled simulated, where none can be made) or ledger");
  cmd->add_option("--device-scale", o->device_scale,
                  "0 < S <= 1: device memory, OS reserve, weights, KV cache and keyframe bytes x S");
  cmd->add_option("--time-compression", o->time_compression,
                  "every run's frames arrive at the profile's rate, X times faster than real time "
                  "(1 = real time; 0 = every frame as fast as possible, no drops)");
  cmd->add_option("--cotenant-requests", o->cotenant_requests,
                  "co-tenant requests per run, spread over the patrol (default 30)");
  cmd->add_option("--repeat", o->repeat, "runs per cell; timings are medians over them");
  cmd->add_option("--prompt-tokens", o->prompt_tokens, "co-tenant prompt length (default: profile; --quick: 128)");
  cmd->add_option("--answer-tokens", o->answer_tokens, "co-tenant answer length (default: profile; --quick: 32)");
  cmd->add_option("--pace", o->time_compression, "old name of --time-compression");
  cmd->add_flag("--no-plots", o->no_plots, "skip the matplotlib figures");
  cmd->add_option("--lock-arena", o->lock_arena,
                  "on|off: mlock the bounded policies' arena in every run (default: the profile's "
                  "map.lock_arena; basic's heap is never locked)")
      ->check(CLI::IsMember({"on", "off"}));
  cmd->callback([o, &ctx, device_opt] {
    InstallStopSignals();
    auto device_kind = ParseDeviceKind(o->device);
    if (!device_kind.ok()) return ctx.Fail("bench", device_kind.status());
    const bool q = o->quick;
    const auto scenarios = Split(!o->scenarios.empty() ? o->scenarios
                                 : q ? "hospital"
                                     : "hospital,floorplan:freiburg_building52,floorplan:map15");
    const auto policies = Split(!o->policies.empty() ? o->policies
                                : q ? "unbounded,basic,semantic,predictive,oracle"
                                    : "unbounded,basic,radius,semantic,predictive,oracle");
    const auto models = Split(!o->models.empty() ? o->models
                              : q ? "none,qwen3-vl-2b"
                                  : "none,qwen3-vl-2b,qwen3-vl-4b,qwen3.5-0.8b,qwen3.5-2b,gemma3-4b");
    const auto budgets = Split(!o->budgets.empty() ? o->budgets : q ? "0.3" : "1,0.5,0.3,two-zones");
    fs::create_directories(o->out);
    nlohmann::json all = nlohmann::json::array();

    for (const std::string& spec : scenarios) {
      std::string name = spec.substr(spec.find(':') == std::string::npos ? 0 : spec.find(':') + 1);
      std::string sdir = o->out + "/scenarios/" + name;
      if (spec.rfind("dir:", 0) == 0) {
        sdir = spec.substr(4);
        name = fs::path(sdir).lexically_normal().filename().string();
        if (name.empty()) name = fs::path(sdir).lexically_normal().parent_path().filename().string();
      }
      if (Status s = EnsureScenario(spec, sdir, o->floorplans, q); !s.ok()) return ctx.Fail("bench", s);
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
          k = static_cast<std::uint64_t>(std::llround(std::atof(b.c_str()) * static_cast<double>(n)));
        }
        k = std::clamp<std::uint64_t>(k, zs.empty() ? 1 : zs[0], n);
        for (const std::string& model : models) {
          for (const std::string& entry : policies) {
            auto variant = ParsePolicyVariant(entry);
            if (!variant.ok()) return ctx.Fail("bench", variant.status());
            const std::string& policy = variant->policy;
            if (model != "none" && policy == "oracle") continue;  // a bound, not a contender
            const std::string run_name = policy + (variant->unsliced ? "-unsliced" : "") + "-k" +
                                         std::to_string(k) + "-" + model;
            std::vector<double> tick_means;
            nlohmann::json last;
            for (int rep = 0; rep < std::max(1, o->repeat); ++rep) {
              auto profile = LoadExperimentProfile(o->profile);
              if (!profile.ok()) return ctx.Fail("bench", profile.status());
              ProfileOverrides ov;
              ov.policy = policy;
              ov.memory_thr = std::to_string(k);
              if (!o->lock_arena.empty()) ov.lock_arena = o->lock_arena;
              if (Status s = ApplyOverrides(ov, profile->core); !s.ok()) return ctx.Fail("bench", s);
              if (variant->unsliced) profile->core.loads.sliced = false;
              if (model != "none") {
                if (Status s = ApplyModelOverride(model, profile.value()); !s.ok()) {
                  return ctx.Fail("bench", s);
                }
              }
              // Shorter requests in --quick so that several complete within one replay; the
              // decode rate (tokens/s) does not depend on the request length.
              if (o->prompt_tokens != 0 || q) profile->cotenant.prompt_tokens = o->prompt_tokens ? o->prompt_tokens : 128;
              if (o->answer_tokens != 0 || q) profile->cotenant.answer_tokens = o->answer_tokens ? o->answer_tokens : 32;
              DeviceRunRequest req;
              req.scenario_dir = sdir;
              req.out_dir = o->out + "/runs/" + name + "/" + run_name;
              req.profile = profile.value();
              req.with_cotenant = model != "none";
              req.device = *device_kind;
              req.device_explicit = device_opt->count() > 0;
              req.device_scale = o->device_scale;
              // Every run, alone and with the co-tenant, on the same frames' clock (issue 17 §4).
              req.time_compression = o->time_compression;
              req.cotenant_requests = o->cotenant_requests;
              std::fprintf(stderr, "bench: %s %s (%d/%d)\n", name.c_str(), run_name.c_str(), rep + 1,
                           std::max(1, o->repeat));
              auto r = RunOnDevice(req, StopFlag());
              if (!r.ok()) return ctx.Fail("bench", r.status().Annotate(run_name));
              last = r.value();
              tick_means.push_back(last["tick_ms"]["mean"].get<double>());
              if (StopFlag()->load()) return ctx.Fail("bench", "interrupted");
            }
            last["scenario_name"] = name;
            last["policy_label"] = variant->label;
            last["budget"] = b;
            last["model"] = model;
            last["tick_ms_mean_median_of_repeats"] = Median(tick_means);
            last["repeats"] = std::max(1, o->repeat);
            all.push_back(last);
          }
        }
      }
    }
    std::ofstream(o->out + "/results.json") << all.dump(2) << '\n';

    // Table I analogue, Table II analogue, memory and churn.
    Table t1{{"scenario", "K_max", "policy", "co-tenant", "map process", "update rate (Hz)",
              "frames dropped / arrived", "loop closures", "avg tick (ms)", "p99 tick (ms)",
              "ATE RMSE (m)", "RPE trans RMSE (m)", "RPE rot RMSE (deg)"}, {}};
    Table t2{{"scenario", "K_max", "model (stand-in)", "policy", "outcome", "requests", "restarts",
              "TPS", "latency p50 (ms)"}, {}};
    Table t6{{"scenario", "K_max", "policy", "co-tenant", "device", "limit (MiB)", "peak (MiB)",
              "OOM kills", "map peak RSS (MiB)", "co-tenant peak RSS (MiB)", "map process",
              "co-tenant"}, {}};
    Table t3{{"scenario", "K_max", "policy", "co-tenant", "peak resident kf", "peak resident MB",
              "over-budget ticks", "max excess kf", "OOM events", "kf loaded", "kf unloaded",
              "DB statements start-up / steady", "DB transactions start-up / steady",
              "DB blob reads start-up / steady", "DB MB read", "zone loads", "zone loads / oracle"}, {}};
    std::map<std::string, double> oracle_loads;
    for (const auto& r : all) {
      if (r["policy"] == "oracle") {
        oracle_loads[r["scenario_name"].get<std::string>() + "/" + std::to_string(r["k_max"].get<int>())] =
            r["zone_loads"].get<double>();
      }
    }
    for (const auto& r : all) {
      const std::string sc = r["scenario_name"], pol = Label(r), model = r["model"];
      const auto split = [&r](const char* key) {
        return std::to_string(r["startup"].value(key, std::uint64_t{0})) + " / " +
               std::to_string(r["steady_state"].value(key, std::uint64_t{0}));
      };
      const std::string k = std::to_string(r["k_max"].get<int>());
      const nlohmann::json dev = r.value("device", nlohmann::json::object());
      const nlohmann::json mp = r.value("map", nlohmann::json::object());
      const std::string map_outcome = mp.value("outcome", std::string("?"));
      t1.rows.push_back({sc, k, pol, model, map_outcome, Fmt(Num(r, "update_rate_hz"), 2),
                         std::to_string(r.value("frames_dropped", std::uint64_t{0})) + " / " +
                             std::to_string(r.value("frames_arrived", std::uint64_t{0})),
                         std::to_string(r["loop_closures"].get<std::uint64_t>()),
                         Fmt(r["tick_ms_mean_median_of_repeats"].get<double>(), 2),
                         Fmt(r["tick_ms"]["p99"].get<double>(), 2), Fmt(Num(r, "ate_rmse_m"), 3),
                         Fmt(Num(r, "rpe_trans_rmse_m"), 3), Fmt(Num(r, "rpe_rot_rmse_deg"), 2)});
      if (r.contains("cotenant")) {
        const auto& c = r["cotenant"];
        const double tps = c.contains("tokens_per_s") && c["tokens_per_s"].is_number()
                               ? c["tokens_per_s"].get<double>() : std::nan("");
        const double lat = c.contains("latency_ms") && c["latency_ms"].is_object()
                               ? Num(c["latency_ms"], "p50") : std::nan("");
        t2.rows.push_back({sc, k, c.value("model", model), pol,
                           c.value("symbol", std::string("?")) + " " + c.value("outcome", std::string()),
                           std::to_string(c.value("requests_completed", 0U)) + " / " +
                               std::to_string(c.value("requests_planned", 0U)),
                           std::to_string(c.value("restarts", 0U)), Fmt(tps, 2), Fmt(lat, 0)});
      }
      const auto mib = [&dev](const char* key) { return Fmt(Num(dev, key) / 1048576.0, 1); };
      t6.rows.push_back({sc, k, pol, model,
                         dev.value("kind", std::string("?")) +
                             (dev.value("simulated", false) ? " (simulated)" : ""),
                         mib("limit_bytes"), mib("peak_bytes"),
                         std::to_string(dev.value("oom_kills", std::uint64_t{0})),
                         mib("map_peak_rss_bytes"), mib("cotenant_peak_rss_bytes"), map_outcome,
                         r.contains("cotenant") ? r["cotenant"].value("outcome", std::string("?"))
                                                : std::string("–")});
      const auto ok = oracle_loads.find(sc + "/" + k);
      const double zl = r["zone_loads"].get<double>();
      t3.rows.push_back({sc, k, pol, model,
                         std::to_string(r["peak_resident_keyframes"].get<std::uint64_t>()),
                         Fmt(r["peak_resident_bytes"].get<double>() / 1e6, 1),
                         std::to_string(r["over_budget_ticks"].get<std::uint64_t>()),
                         std::to_string(r["max_over_budget_keyframes"].get<std::uint64_t>()),
                         std::to_string(r.value("oom_events", std::uint64_t{0})),
                         std::to_string(r["keyframes_loaded"].get<std::uint64_t>()),
                         std::to_string(r["keyframes_unloaded"].get<std::uint64_t>()),
                         // Database work in one unit for every policy (basic's searches included),
                         // the start-up load apart from the rest of the run.
                         split("db_queries"), split("db_transactions"), split("db_blob_reads"),
                         Fmt(r["db_bytes_read"].get<double>() / 1e6, 1), Fmt(zl, 0),
                         ok != oracle_loads.end() && ok->second > 0 && zl > 0 ? Fmt(zl / ok->second, 2) : "–"});
    }
    // Ratios measured side by side in this run (same scenario, budget and co-tenant).
    Table t4{{"scenario", "K_max", "co-tenant", "ratio", "avg tick", "kf loaded", "DB transactions",
              "DB bytes read", "ATE"}, {}};
    auto find = [&](const std::string& sc, int k, const std::string& model, const std::string& pol) {
      for (const auto& r : all) {
        if (r["scenario_name"] == sc && r["k_max"] == k && r["model"] == model && Label(r) == pol) return &r;
      }
      return static_cast<const nlohmann::json*>(nullptr);
    };
    auto ratio = [](double a, double b) { return b != 0 ? Fmt(a / b, 2) : std::string("–"); };
    for (const auto& r : all) {
      if (Label(r) != "semantic") continue;
      const std::string sc = r["scenario_name"], model = r["model"];
      const int k = r["k_max"];
      for (auto [num, den] : {std::pair{"semantic", "basic"}, std::pair{"predictive", "semantic"}}) {
        const auto* a = find(sc, k, model, num);
        const auto* b = find(sc, k, model, den);
        if (a == nullptr || b == nullptr) continue;
        t4.rows.push_back({sc, std::to_string(k), model, std::string(num) + "/" + den,
                           ratio((*a)["tick_ms_mean_median_of_repeats"], (*b)["tick_ms_mean_median_of_repeats"]),
                           ratio((*a)["keyframes_loaded"], (*b)["keyframes_loaded"]),
                           ratio((*a)["db_transactions"], (*b)["db_transactions"]),
                           ratio((*a)["db_bytes_read"], (*b)["db_bytes_read"]),
                           ratio(Num(*a, "ate_rmse_m"), Num(*b, "ate_rmse_m"))});
      }
    }
    // Tick latency per policy (issue 14): steady-state ticks (after the start-up tick), each
    // against unbounded's in the same scenario and co-tenant setting (no loads at all: the
    // floor); the start-up load apart.
    Table t5{{"scenario", "K_max", "policy", "co-tenant", "ticks", "tick p50 (ms)", "tick p99 (ms)",
              "tick max (ms)", "p99 / unbounded", "max / unbounded", "start-up tick (ms)",
              "start-up kf", "start-up MB", "idle load (ms)", "late ticks", "loop closures", "ATE RMSE (m)"}, {}};
    for (const auto& r : all) {
      const std::string sc = r["scenario_name"], model = r["model"];
      const auto& tm = r["tick_ms"];
      const nlohmann::json* floor = nullptr;
      for (const auto& u : all) {
        if (u["scenario_name"] == sc && u["model"] == model && u["policy"] == "unbounded") floor = &u;
      }
      const auto vs = [&](const char* key) {
        if (floor == nullptr) return std::string("–");
        const double d = (*floor)["tick_ms"][key].get<double>();
        return d > 0 ? Fmt(tm[key].get<double>() / d, 2) : std::string("–");
      };
      const nlohmann::json st = r.value("startup", nlohmann::json::object());
      const nlohmann::json ld = r.value("loads", nlohmann::json::object());
      t5.rows.push_back({sc, std::to_string(r["k_max"].get<int>()), Label(r), model,
                         std::to_string(tm.value("count", std::uint64_t{0})),
                         Fmt(tm["p50"].get<double>(), 2), Fmt(tm["p99"].get<double>(), 2),
                         Fmt(tm["max"].get<double>(), 1), vs("p99"), vs("max"),
                         Fmt(st.value("tick_ms", std::nan("")), 1),
                         std::to_string(st.value("keyframes_loaded", std::uint64_t{0})),
                         Fmt(st.value("bytes_read", 0.0) / 1e6, 1),
                         Fmt(ld.value("idle_load_ms_total", 0.0), 0),
                         std::to_string(ld.value("late_ticks", std::uint64_t{0})),
                         std::to_string(r["loop_closures"].get<std::uint64_t>()),
                         Fmt(Num(r, "ate_rmse_m"), 4)});
    }
    // Every table states the device (and "simulated" for the ledger), its scale and the clock.
    std::string device_used = "cgroup";
    for (const auto& r : all) {
      const nlohmann::json d = r.value("device", nlohmann::json::object());
      if (!d.value("simulated", false)) continue;
      const std::string why = d.value("fallback_reason", std::string());
      device_used = "ledger, SIMULATED" + (why.empty() ? std::string() : ": " + why);
    }
    const std::string stated = " (device " + device_used + ", device scale " +
                               Fmt(o->device_scale, 3) + ", time compression " +
                               Fmt(o->time_compression, 2) + ")";
    t1.Write(o->out + "/table1", "Table I analogue: SLAM with and without the co-tenant" + stated);
    t6.Write(o->out + "/device", "The device: memory, OOM kills, outcomes" + stated);
    t5.Write(o->out + "/latency", "Tick latency (steady state; start-up apart)" + stated);
    t2.Write(o->out + "/table2", "Table II analogue: the co-tenant beside SLAM (stand-in for VLM decoding)" + stated);
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
      if (std::system(c.c_str()) != 0) std::fprintf(stderr, "bench: figures failed (%s)\n", c.c_str());
    }
    std::printf("bench: wrote %s/{table1,table2,device,memory,ratios,latency}.{md,csv}, results.json, figures/\n",
                o->out.c_str());
  });
}

}  // namespace zm::app
