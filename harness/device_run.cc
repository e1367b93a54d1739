#include "harness/device_run.h"

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <unistd.h>

#include "harness/cotenant.h"
#include "harness/device_ledger.h"

namespace zm {

Result<nlohmann::json> RunOnDevice(const DeviceRunRequest& request, const std::atomic<bool>* stop) {
  const Profile& p = request.profile.core;
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
    CotenantConfig cc = CotenantConfigFromProfile(request.profile);
    cc.device_scale = request.cotenant_scale;
    cc.requests = 0;  // serve until the loop ends
    if (ledger) cc.ledger_path = ledger_path;
    ZM_ASSIGN_OR_RETURN(CotenantProcess proc, CotenantProcess::Spawn(cc));
    cotenant.emplace(std::move(proc));
  }

  std::uint64_t map_oom_events = 0;
  RunRequest run;
  run.scenario_dir = request.scenario_dir;
  run.out_dir = request.out_dir;
  run.loop = p;
  run.telemetry = p.telemetry;
  run.verify_checksums = request.verify_checksums;
  run.profile_name = p.source;
  run.pace_speedup = request.pace_speedup;
  char extra[96];
  run.on_tick = [&](const TickLoop& loop) -> std::string_view {
    if (!map_tenant) return {};
    const std::uint64_t slots = loop.bounded() ? loop.arena().capacity()
                                               : loop.working_set().resident_count();
    const std::uint64_t charge = p.map.overhead_bytes + slots * loop.slot_bytes();
    if (charge != map_tenant->bytes() && !map_tenant->TryUpdate(charge)) ++map_oom_events;
    const int n = std::snprintf(extra, sizeof extra, "\"oom_events\":%llu",
                                static_cast<unsigned long long>(ledger->oom_events()));
    return n > 0 ? std::string_view(extra, static_cast<std::size_t>(n)) : std::string_view();
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
            {"device_scale", c.device_scale},
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
