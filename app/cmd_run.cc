// `zonemap run`: replays a scenario's localization run through the tick loop under a policy and
// a device profile, writing RUNDIR/ticks.jsonl, estimate.tum and summary.json.
#include <cstdio>
#include <memory>

#include "commands.h"
#include "harness/device_run.h"
#include "runtime/stop_signal.h"

namespace zm::app {

void AddRunCommand(CLI::App& app, CommandContext& ctx) {
  struct Opts {
    std::string scenario, out, profile = "host", policy, memory_thr, cotenant, process_cap;
    std::string device = "cgroup";
    std::string lock_arena, map_files = "cold", zram_charge = "on";
    double device_scale = 1.0, time_compression = 1.0;
    std::uint32_t cotenant_requests = 30;
    double cotenant_period = 0.0;
    std::uint64_t max_ticks = 0;
    bool verify = false, quiet = false;
  };
  auto o = std::make_shared<Opts>();
  auto* cmd = app.add_subcommand("run", "Replay a scenario through the tick loop under a policy");
  cmd->add_option("--scenario", o->scenario, "scenario directory (from `zonemap sim`)")->required();
  cmd->add_option("--out", o->out, "run directory to write")->required();
  cmd->add_option("--policy", o->policy, "basic|radius|semantic|predictive|oracle|unbounded");
  cmd->add_option("--profile", o->profile, "device profile name or TOML path (default host)");
  cmd->add_option("--memory-thr", o->memory_thr, "MemoryThr: N keyframes, BYTES (e.g. 512MiB), or N,BYTES");
  cmd->add_option("--cotenant", o->cotenant, "run the VLM stand-in beside the loop (model name)");
  auto* device_opt = cmd->add_option(
      "--device", o->device,
      "cgroup (default; falls back to the ledger, labelled simulated, where none can be made) or "
      "ledger");
  cmd->add_option("--device-scale", o->device_scale,
                  "0 < S <= 1: device memory, OS reserve, weights, KV cache and keyframe bytes x S");
  cmd->add_option("--time-compression", o->time_compression,
                  "frames arrive at the profile's rate, X times faster than real time (1 = real "
                  "time; 0 = every frame as fast as the loop goes, no drops)");
  cmd->add_option("--cotenant-requests", o->cotenant_requests,
                  "co-tenant requests spread over the patrol (default 30)");
  cmd->add_option("--cotenant-period-s", o->cotenant_period,
                  "wall seconds between co-tenant requests (default: the patrol / requests)");
  cmd->add_option("--process-cap", o->process_cap, "cap this process (setrlimit), e.g. 6GiB; 0 = none");
  cmd->add_option("--pace", o->time_compression, "old name of --time-compression");
  cmd->add_option("--max-ticks", o->max_ticks, "stop after this many ticks (0 = all)");
  cmd->add_option("--map-files", o->map_files,
                  "cold (default: the scenario's files dropped from the page cache first, so every "
                  "read is charged to the device) | warm (left as cached)")
      ->check(CLI::IsMember({"cold", "warm"}));
  AddDeviceMemoryOptions(*cmd, &o->lock_arena, &o->zram_charge);
  cmd->add_flag("--verify-checksums", o->verify, "CRC-check every payload as it lands in its slot");
  cmd->add_flag("--quiet", o->quiet, "print nothing on success");
  cmd->callback([o, &ctx, device_opt] {
    auto profile = LoadExperimentProfile(o->profile);
    if (!profile.ok()) return ctx.Fail("run", profile.status());
    ProfileOverrides ov;
    if (!o->policy.empty()) ov.policy = o->policy;
    if (!o->memory_thr.empty()) ov.memory_thr = o->memory_thr;
    if (!o->process_cap.empty()) ov.process_cap = o->process_cap;
    if (!o->lock_arena.empty()) ov.lock_arena = o->lock_arena;
    if (Status s = ApplyOverrides(ov, profile->core); !s.ok()) return ctx.Fail("run", s);
    if (!o->cotenant.empty()) {
      if (Status s = ApplyModelOverride(o->cotenant, profile.value()); !s.ok()) {
        return ctx.Fail("run", s);
      }
    }
    profile->core.loop.max_ticks = o->max_ticks;
    auto kind = ParseDeviceKind(o->device);
    if (!kind.ok()) return ctx.Fail("run", kind.status());
    InstallStopSignals();
    DeviceRunRequest req;
    req.scenario_dir = o->scenario;
    req.out_dir = o->out;
    req.profile = profile.value();
    req.with_cotenant = !o->cotenant.empty();
    req.device = *kind;
    req.device_explicit = device_opt->count() > 0;
    req.device_scale = o->device_scale;
    req.time_compression = o->time_compression;
    req.cotenant_requests = o->cotenant_requests;
    req.cotenant_period_s = o->cotenant_period;
    req.verify_checksums = o->verify;
    req.cold_files = o->map_files == "cold";
    req.charge_zram = o->zram_charge == "on";
    auto s = RunOnDevice(req, StopFlag());
    if (!s.ok()) return ctx.Fail("run", s.status());
    if (o->quiet) return;
    const auto& j = s.value();
    const auto& d = j["device"];
    std::printf("device: %s%s, limit %.1f MiB, peak %.1f MiB, OOM kills %llu (device scale %g)\n",
                d["description"].get<std::string>().c_str(),
                d["simulated"].get<bool>() ? " [simulated]" : "",
                d["limit_bytes"].get<double>() / 1048576.0, d["peak_bytes"].get<double>() / 1048576.0,
                static_cast<unsigned long long>(d["oom_kills"].get<std::uint64_t>()), o->device_scale);
    const auto& sw = d["swap"];
    std::printf("device swap: %s, limit %.1f MiB, peak %.1f MiB, zram memory peak %.1f MiB\n",
                sw["kind"].get<std::string>().c_str(), sw["limit_bytes"].get<double>() / 1048576.0,
                sw["peak_bytes"].get<double>() / 1048576.0,
                sw["zram_mem_used_peak_bytes"].get<double>() / 1048576.0);
    std::printf(
        "map process: %s, %llu major faults, arena %s; frames: %llu arrived, %llu dropped "
        "(time compression %g)\n",
        j["map"]["outcome"].get<std::string>().c_str(),
        static_cast<unsigned long long>(j["map"]["major_faults"].get<std::uint64_t>()),
        j["map"]["arena_locked"].get<bool>() ? "locked" : "not locked",
        static_cast<unsigned long long>(j["frames_arrived"].get<std::uint64_t>()),
        static_cast<unsigned long long>(j["frames_dropped"].get<std::uint64_t>()),
        o->time_compression);
    std::printf("%s: %llu ticks, K_max %u, peak resident %u, loop closures %llu, ATE %.3f m, "
                "tick p50 %.2f ms p99 %.2f ms, over-budget ticks %llu%s\n",
                j["policy"].get<std::string>().c_str(),
                static_cast<unsigned long long>(j["ticks"].get<std::uint64_t>()),
                j["k_max"].get<unsigned>(), j["peak_resident_keyframes"].get<unsigned>(),
                static_cast<unsigned long long>(j["loop_closures"].get<std::uint64_t>()),
                j["ate_rmse_m"].is_number() ? j["ate_rmse_m"].get<double>() : -1.0,
                j["tick_ms"]["p50"].get<double>(), j["tick_ms"]["p99"].get<double>(),
                static_cast<unsigned long long>(j["over_budget_ticks"].get<std::uint64_t>()),
                j["interrupted"].get<bool>() ? " (interrupted)" : "");
    if (j.contains("cotenant")) {
      const auto& c = j["cotenant"];
      const bool has_latency = c.contains("latency_ms") && c["latency_ms"].is_object() &&
                               c["latency_ms"].value("p50", nlohmann::json()).is_number();
      std::printf("co-tenant (stand-in) %s: %s, %u of %u requests, %u restarts, %.2f tokens/s, "
                  "latency p50 %.0f ms\n",
                  c.value("model", std::string()).c_str(),
                  c.value("outcome", std::string()).c_str(), c.value("requests_completed", 0U),
                  c.value("requests_planned", 0U), c.value("restarts", 0U),
                  c.contains("tokens_per_s") && c["tokens_per_s"].is_number()
                      ? c["tokens_per_s"].get<double>()
                      : 0.0,
                  has_latency ? c["latency_ms"]["p50"].get<double>() : 0.0);
    }
    std::printf("wrote %s/summary.json\n", o->out.c_str());
  });
}

}  // namespace zm::app
