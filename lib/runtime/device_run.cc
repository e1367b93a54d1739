#include "runtime/device_run.h"

#include <filesystem>
#include <fstream>
#include <unistd.h>

#include "runtime/cotenant.h"
#include "runtime/device_ledger.h"

namespace zm {

Result<LoopConfig> LoopConfigFromProfile(const Profile& p) {
  LoopConfig c;
  c.policy.policy = std::string(PolicyKindName(p.policy.kind));
  const BasicPolicyOptions& b = p.policy.basic;
  c.policy.basic.max_retrieved = b.max_retrieved;
  c.policy.basic.max_local_retrieved = b.max_local_retrieved;
  c.policy.basic.local_radius_m = b.local_radius_m;
  c.policy.basic.local_immunization_ratio = b.local_immunization_ratio;
  c.policy.basic.transfer_sorting_by_weight_id = b.transfer_sorting_by_weight_id;
  // A map built without memory management starts with every node in WM either way
  // (basic-baseline.md §3.4): the simulator's mapping run has no memory management.
  c.policy.basic.init_wm_with_all_nodes = true;
  c.policy.radius.tile_m = p.policy.radius.tile_m;
  c.policy.radius.map_radius_m = p.policy.radius.map_radius_m;
  c.policy.radius.update_distance_m = p.policy.radius.update_distance_m;
  c.policy.predictive.max_keyframes_per_tick = p.policy.predictive.max_keyframes_per_tick;
  c.policy.predictive.max_ms_per_tick = p.policy.predictive.max_ms_per_tick;
  c.zones.hysteresis_m = p.policy.hysteresis_m;

  const LocalizationOptions& l = p.localization;
  c.localizer.radius_m = l.radius_m;
  c.localizer.max_heading_diff_rad = l.max_heading_deg * M_PI / 180.0;
  c.localizer.min_inliers = l.min_inliers;
  c.localizer.ratio = static_cast<float>(l.ratio);
  c.localizer.max_hamming = l.max_hamming;
  c.localizer.ransac_reprojection_px = l.ransac_reproj_px;
  c.localizer.ransac_iterations = static_cast<int>(l.ransac_iterations);

  c.slot_bytes = p.map.slot_bytes;
  c.lock_arena = p.map.lock_arena;
  c.prefault_arena = p.map.prefault_arena;
  c.telemetry_flush_ticks = p.loop.telemetry_flush_ticks;
  if (p.policy.kind != PolicyKind::kUnbounded) {
    c.memory_thr_keyframes = p.map.memory_thr_keyframes;
    ZM_ASSIGN_OR_RETURN(const std::uint64_t share, MapShareBytes(p));
    if (share != 0) {
      if (p.map.overhead_bytes >= share) {
        return OutOfRange(p.source + ": map overhead leaves nothing of the map share");
      }
      c.memory_thr_bytes = share - p.map.overhead_bytes;
    }
  }
  return c;
}

Result<nlohmann::json> RunOnDevice(const DeviceRunRequest& request, const std::atomic<bool>* stop) {
  const Profile& p = request.profile;
  ZM_ASSIGN_OR_RETURN(LoopConfig loop_config, LoopConfigFromProfile(p));
  loop_config.max_ticks = request.max_ticks;
  loop_config.verify_checksums = request.verify_checksums;
  std::error_code ec;
  std::filesystem::create_directories(request.out_dir, ec);

  // One ledger per run, private to it (the co-tenant thread attaches to the same file).
  const std::string ledger_path =
      request.out_dir + "/.ledger-" + std::to_string(static_cast<long long>(::getpid()));
  (void)DeviceLedger::Remove(ledger_path);
  const std::uint64_t device_bytes = p.device.memory_bytes;
  std::optional<DeviceLedger> ledger;
  std::optional<LedgerTenant> os_tenant, map_tenant;
  if (device_bytes != 0) {
    ZM_ASSIGN_OR_RETURN(DeviceLedger opened, DeviceLedger::Open(ledger_path, device_bytes));
    ledger.emplace(std::move(opened));
    ZM_ASSIGN_OR_RETURN(LedgerTenant os, ledger->Register("os", p.device.os_reserve_bytes));
    os_tenant.emplace(std::move(os));
    ZM_ASSIGN_OR_RETURN(LedgerTenant map, ledger->Register("map", p.map.overhead_bytes));
    map_tenant.emplace(std::move(map));
  }

  // The co-tenant is its own process, as the VLM server is on the robot: its memory must not
  // count against the map process's cap, and it competes for cores and memory bandwidth.
  std::optional<CotenantProcess> cotenant;
  if (request.with_cotenant) {
    CotenantConfig cc = CotenantConfigFromProfile(p);
    cc.scale = request.cotenant_scale;
    cc.requests = 0;  // serve until the loop ends
    if (ledger) cc.ledger_path = ledger_path;
    ZM_ASSIGN_OR_RETURN(CotenantProcess proc, CotenantProcess::Spawn(cc));
    cotenant.emplace(std::move(proc));
  }

  std::uint64_t map_oom_events = 0;
  RunRequest run;
  run.scenario_dir = request.scenario_dir;
  run.out_dir = request.out_dir;
  run.loop = loop_config;
  run.profile_name = p.source;
  run.pace_speedup = request.pace_speedup;
  run.on_tick = [&](const TickLoop& loop) {
    if (!map_tenant) return;
    const std::uint64_t slots = loop.bounded() ? loop.arena().capacity()
                                               : loop.working_set().resident_count();
    const std::uint64_t charge = p.map.overhead_bytes + slots * loop.slot_bytes();
    if (charge != map_tenant->bytes() && !map_tenant->TryUpdate(charge)) ++map_oom_events;
  };
  auto summary = RunScenario(run, stop);

  nlohmann::json ct = nullptr;
  if (cotenant) {
    cotenant->RequestStop();
    auto r = cotenant->Wait();
    if (r.ok()) {
      const CotenantResult& c = r.value();
      ct = {{"model", c.model},
            {"weights_bytes", c.weights_bytes},
            {"scale", c.scale},
            {"tokens_per_s", c.tokens_per_s},
            {"latency_ms", c.latency_ms_p50},
            {"latency_ms_p95", c.latency_ms_p95},
            {"requests", c.requests},
            {"outcome", std::string(CotenantOutcomeName(c.outcome))},
            {"symbol", std::string(CotenantOutcomeSymbol(c.outcome))},
            {"reason", c.reason},
            {"note", c.note}};
      std::ofstream(request.out_dir + "/cotenant.json") << ToJson(c).dump(2) << '\n';
    } else {
      ct = {{"outcome", "failed"}, {"reason", r.status().message()}, {"note", std::string(kCotenantNote)}};
    }
  }
  if (!summary.ok()) {
    (void)DeviceLedger::Remove(ledger_path);
    return summary.status();
  }
  nlohmann::json s = std::move(summary).value();
  if (!ct.is_null()) s["cotenant"] = ct;
  if (ledger) {
    s["device"] = {{"name", p.device.name},
                   {"memory_bytes", device_bytes},
                   {"os_reserve_bytes", p.device.os_reserve_bytes},
                   {"peak_sum_bytes", ledger->peak_sum_bytes()},
                   {"oom_events", ledger->oom_events()},
                   {"map_oom_events", map_oom_events}};
    s["oom_events"] = ledger->oom_events();
  }
  std::ofstream(request.out_dir + "/summary.json") << s.dump(2) << '\n';
  map_tenant.reset();
  os_tenant.reset();
  ledger.reset();
  (void)DeviceLedger::Remove(ledger_path);
  return s;
}

}  // namespace zm
