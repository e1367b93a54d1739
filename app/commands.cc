#include "commands.h"

#include <iostream>

namespace zm::app {

void CommandContext::Fail(std::string_view command, const Status& status) {
  Fail(command, status.message());
}

void CommandContext::Fail(std::string_view command, std::string_view message) {
  std::cerr << "zonemap " << command << ": " << message << '\n';
  exit_code = 1;
}

void AddDeviceMemoryOptions(CLI::App& cmd, std::string* lock_arena, std::string* zram_charge) {
  cmd.add_option("--lock-arena", *lock_arena,
                 "on|off: mlock the bounded policies' arena (default: the profile's "
                 "map.lock_arena; basic's heap is never locked)")
      ->check(CLI::IsMember({"on", "off"}));
  cmd.add_option("--zram-charge", *zram_charge,
                 "on (default): the device's limit gives up the DRAM zram's compressed pages "
                 "occupy, as on the Jetson | off: zram is free memory beside the device")
      ->check(CLI::IsMember({"on", "off"}));
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
