// `zonemap run`: replays a scenario's localization run through the tick loop under a policy and
// a device profile, writing RUNDIR/ticks.jsonl, estimate.tum and summary.json.
#include <unistd.h>

#include <cstdio>
#include <memory>

#include "commands.h"
#include "param_options.h"
#include "harness/device_run.h"
#include "runtime/stop_signal.h"

namespace zm::app {

void AddRunCommand(CLI::App& app, CommandContext& ctx) {
  struct Opts {
    std::string scenario, out, profile = "host", policy, memory_thr, cotenant, process_cap;
    std::string map_files = "cold";
    DeviceRunOptions device;
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
  AddParamOption(*cmd, kMemoryThrParam, &o->memory_thr);
  cmd->add_option("--cotenant", o->cotenant, "run the VLM stand-in beside the loop (model name)");
  AddDeviceRunOptions(*cmd, &o->device);
  cmd->add_option("--cotenant-period-s", o->cotenant_period,
                  "wall seconds between co-tenant requests (default: the patrol / requests)");
  cmd->add_option("--process-cap", o->process_cap,
                  "cap this process (setrlimit), e.g. 6GiB; 0 = none");
  cmd->add_option("--max-ticks", o->max_ticks, "stop after this many ticks (0 = all)");
  cmd->add_option("--map-files", o->map_files,
                  "cold (default: the scenario's files dropped from the page cache first, so every "
                  "read is charged to the device) | warm (left as cached)")
      ->check(CLI::IsMember({"cold", "warm"}));
  cmd->add_flag("--verify-checksums", o->verify, "CRC-check every payload as it lands in its slot");
  cmd->add_flag("--quiet", o->quiet,
                "print nothing on success (else, on a terminal, a progress line shows frames, rate "
                "and ETA)");
  cmd->callback([o, &ctx] {
    auto profile = LoadExperimentProfile(o->profile);
    if (!profile.ok()) return ctx.Fail("run", profile.status());
    ProfileOverrides ov;
    if (!o->policy.empty()) ov.policy = o->policy;
    if (!o->memory_thr.empty()) ov.memory_thr = o->memory_thr;
    if (!o->process_cap.empty()) ov.process_cap = o->process_cap;
    if (!o->device.lock_arena.empty()) ov.lock_arena = o->device.lock_arena;
    if (Status s = ApplyOverrides(ov, profile->core); !s.ok()) return ctx.Fail("run", s);
    if (!o->cotenant.empty()) {
      if (Status s = ApplyModelOverride(o->cotenant, profile.value()); !s.ok()) {
        return ctx.Fail("run", s);
      }
    }
    profile->core.loop.max_ticks = o->max_ticks;
    DeviceRunRequest req;
    if (Status s = SetDeviceRun(o->device, req); !s.ok()) return ctx.Fail("run", s);
    InstallStopSignals();
    req.scenario_dir = o->scenario;
    req.out_dir = o->out;
    req.profile = profile.value();
    req.with_cotenant = !o->cotenant.empty();
    req.cotenant_period_s = o->cotenant_period;
    req.verify_checksums = o->verify;
    req.cold_files = o->map_files == "cold";
    // Progress only where someone watches: quiet when stderr is a file or a pipe.
    req.progress = !o->quiet && isatty(STDERR_FILENO) == 1;
    auto s = RunOnDevice(req, StopFlag());
    if (!s.ok()) return ctx.Fail("run", s.status());
    if (o->quiet) return;
    const DeviceRunSummary& r = s.value();
    const RunSummary& j = r.run;
    const DeviceSummary& d = r.device;
    std::printf("device: %s%s, limit %.1f MiB, peak %.1f MiB, OOM kills %llu (device scale %g)\n",
                d.description.c_str(), d.simulated ? " [simulated]" : "",
                static_cast<double>(d.limit_bytes) / 1048576.0,
                static_cast<double>(d.peak_bytes) / 1048576.0,
                static_cast<unsigned long long>(d.oom_kills), o->device.device_scale);
    const DeviceSwapSummary& sw = d.swap;
    std::printf("device swap: %s, limit %.1f MiB, peak %.1f MiB, zram memory peak %.1f MiB\n",
                sw.kind.c_str(), static_cast<double>(sw.limit_bytes) / 1048576.0,
                static_cast<double>(sw.peak_bytes) / 1048576.0,
                static_cast<double>(sw.zram_mem_used_peak_bytes) / 1048576.0);
    const ReplaySummary replay = j.replay.value_or(ReplaySummary{});
    std::printf(
        "map process: %s, %llu major faults, arena %s; frames: %llu arrived, %llu dropped "
        "(time compression %g)\n",
        r.map.outcome.c_str(), static_cast<unsigned long long>(r.map.major_faults),
        r.map.arena_locked ? "locked" : "not locked",
        static_cast<unsigned long long>(replay.frames_arrived),
        static_cast<unsigned long long>(replay.frames_dropped), o->device.time_compression);
    std::printf(
        "%s: %llu ticks, K_max %llu, peak resident %llu, loop closures accepted %llu "
        "(frames localized %llu), ATE %.3f m, tick p50 %.2f ms p99 %.2f ms, over-budget "
        "ticks %llu%s\n",
        j.policy.c_str(), static_cast<unsigned long long>(j.ticks),
        static_cast<unsigned long long>(j.k_max),
        static_cast<unsigned long long>(j.peak_resident_keyframes),
        static_cast<unsigned long long>(j.closures_accepted),
        static_cast<unsigned long long>(j.frames_localized),
        replay.trajectory.ate_rmse_m.value_or(-1.0), j.tick_ms.p50, j.tick_ms.p99,
        static_cast<unsigned long long>(j.over_budget_ticks),
        j.interrupted ? " (interrupted)" : "");
    std::printf("stages p50 / p99 ms:");
    for (std::size_t i = 0; i < j.stages.size(); ++i) {
      std::printf(" %s %.2f / %.2f", LoopStageName(static_cast<LoopStage>(i)), j.stages[i].p50_ms,
                  j.stages[i].p99_ms);
    }
    std::printf("\n");
    if (j.first_image_error) {
      std::printf("images refused: %llu, the first: %s\n",
                  static_cast<unsigned long long>(j.images_refused), j.first_image_error->c_str());
    }
    if (!r.cotenant.is_null()) {
      const nlohmann::json& c = r.cotenant;
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
