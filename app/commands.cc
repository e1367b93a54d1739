#include "commands.h"

#include <iostream>

#include "harness/device_run.h"

namespace zm::app {

void CommandContext::Fail(std::string_view command, const Status& status) {
  Fail(command, status.message());
}

void CommandContext::Fail(std::string_view command, std::string_view message) {
  std::cerr << "zonemap " << command << ": " << message << '\n';
  exit_code = 1;
}

void AddDeviceRunOptions(CLI::App& cmd, DeviceRunOptions* o) {
  o->device_option = cmd.add_option(
      "--device", o->device,
      "cgroup (default; falls back to the ledger, labelled simulated, where none can be made) or "
      "ledger");
  cmd.add_option("--device-scale", o->device_scale,
                 "0 < S <= 1: device memory, OS reserve, weights, KV cache and keyframe bytes x S");
  cmd.add_option("--time-compression", o->time_compression,
                 "frames arrive at the profile's rate, X times faster than real time (default 1: "
                 "the profile's real rate, [loop] rate_hz: a patrol takes as long as it did on the "
                 "robot; 0 = every frame as fast as the loop goes, no drops)");
  cmd.add_option("--pace", o->time_compression, "old name of --time-compression");
  cmd.add_option("--cotenant-requests", o->cotenant_requests,
                 "co-tenant requests spread over the patrol (default 30)");
  cmd.add_option("--lock-arena", o->lock_arena,
                 "on|off: mlock the bounded policies' arena (default: the profile's "
                 "map.lock_arena; basic's heap is never locked)")
      ->check(CLI::IsMember({"on", "off"}));
  cmd.add_option("--zram-charge", o->zram_charge,
                 "on (default): the device's limit gives up the DRAM zram's compressed pages "
                 "occupy, as on the Jetson | off: zram is free memory beside the device")
      ->check(CLI::IsMember({"on", "off"}));
}

Status SetDeviceRun(const DeviceRunOptions& o, DeviceRunRequest& req) {
  ZM_ASSIGN_OR_RETURN(req.device, ParseDeviceKind(o.device));
  req.device_explicit = o.device_option != nullptr && o.device_option->count() > 0;
  req.device_scale = o.device_scale;
  // Every run, alone and with the co-tenant, on the same frames' clock (issue 17 §4).
  req.time_compression = o.time_compression;
  req.cotenant_requests = o.cotenant_requests;
  req.charge_zram = o.zram_charge == "on";
  return Status::Ok();
}

CLI::App* GetOrAddSubcommand(CLI::App& app, const std::string& name,
                             const std::string& description) {
  for (CLI::App* sub : app.get_subcommands([](CLI::App*) { return true; })) {
    if (sub->get_name() == name) return sub;
  }
  CLI::App* sub = app.add_subcommand(name, description);
  sub->require_subcommand(1);
  return sub;
}

CLI::App* AddZonesSubcommand(CLI::App& app, const std::string& name,
                             const std::string& description) {
  return GetOrAddSubcommand(app, "zones", "Semantic zones: annotate a map, segment a grid")
      ->add_subcommand(name, description);
}

void AddAllCommands(CLI::App& app, CommandContext& ctx) {
  AddArenaCommand(app, ctx);
  AddBudgetCommand(app, ctx);
  AddImportCommand(app, ctx);
  AddEvalCommand(app, ctx);
  AddZonesSegmentCommand(app, ctx);
  AddZonesAnnotateCommand(app, ctx);
  AddSimCommand(app, ctx);
  AddRunCommand(app, ctx);
  AddBenchCommand(app, ctx);
  AddVocabCommand(app, ctx);
  AddInspectCommand(app, ctx);
  AddImportTumCommand(app, ctx);
}

}  // namespace zm::app
