// `zonemap run`: replays a scenario's localization run through the tick loop under a policy and
// a device profile, writing RUNDIR/ticks.jsonl, estimate.tum and summary.json.
#include <cstdio>
#include <memory>

#include "commands.h"
#include "harness/device_run.h"
#include "runtime/memory_cap.h"
#include "runtime/stop_signal.h"

namespace zm::app {

void AddRunCommand(CLI::App& app, CommandContext& ctx) {
  struct Opts {
    std::string scenario, out, profile = "host", policy, memory_thr, cotenant, process_cap;
    double cotenant_scale = 1.0, pace = 0.0;
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
  cmd->add_option("--cotenant-scale", o->cotenant_scale, "scale the stand-in's weights (tests)");
  cmd->add_option("--process-cap", o->process_cap, "cap this process (setrlimit), e.g. 6GiB; 0 = none");
  cmd->add_option("--pace", o->pace, "pace ticks at this multiple of the frames' clock (1 = real time; 0 = as fast as possible)");
  cmd->add_option("--max-ticks", o->max_ticks, "stop after this many ticks (0 = all)");
  cmd->add_flag("--verify-checksums", o->verify, "CRC-check every payload as it lands in its slot");
  cmd->add_flag("--quiet", o->quiet, "print nothing on success");
  cmd->callback([o, &ctx] {
    auto profile = LoadExperimentProfile(o->profile);
    if (!profile.ok()) return ctx.Fail("run", profile.status());
    ProfileOverrides ov;
    if (!o->policy.empty()) ov.policy = o->policy;
    if (!o->memory_thr.empty()) ov.memory_thr = o->memory_thr;
    if (!o->process_cap.empty()) ov.process_cap = o->process_cap;
    if (Status s = ApplyOverrides(ov, profile->core); !s.ok()) return ctx.Fail("run", s);
    if (!o->cotenant.empty()) {
      if (Status s = ApplyModelOverride(o->cotenant, profile.value()); !s.ok()) {
        return ctx.Fail("run", s);
      }
    }
    profile->core.loop.max_ticks = o->max_ticks;
    if (profile->core.map.process_cap_bytes != 0) {
      auto cap = ApplyProcessCap(profile->core.map.process_cap_bytes);
      if (!cap.ok()) return ctx.Fail("run", cap.status());
    }
    InstallStopSignals();
    DeviceRunRequest req;
    req.scenario_dir = o->scenario;
    req.out_dir = o->out;
    req.profile = profile.value();
    req.with_cotenant = !o->cotenant.empty();
    req.cotenant_scale = o->cotenant_scale;
    req.pace_speedup = o->pace;
    req.verify_checksums = o->verify;
    auto s = RunOnDevice(req, StopFlag());
    if (!s.ok()) return ctx.Fail("run", s.status());
    if (o->quiet) return;
    const auto& j = s.value();
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
      std::printf("co-tenant (stand-in) %s: %s, %.2f tokens/s, latency %.0f ms\n",
                  c.value("model", std::string()).c_str(),
                  c.value("outcome", std::string()).c_str(), c.value("tokens_per_s", 0.0),
                  c.value("latency_ms", 0.0));
    }
    std::printf("wrote %s/summary.json\n", o->out.c_str());
  });
}

}  // namespace zm::app
