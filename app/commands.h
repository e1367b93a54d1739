// The subcommands of `zonemap`. Each Add*Command() attaches one CLI11 subcommand whose callback
// sets the process exit code through CommandContext; errors are printed as one line naming the
// thing and the limit, never as an exception trace.
#pragma once

#include <CLI/CLI.hpp>
#include <cstdint>
#include <string>
#include <string_view>

#include "common/status.h"

namespace zm {
struct DeviceRunRequest;  // harness/device_run.h
}  // namespace zm

namespace zm::app {

struct CommandContext {
  int exit_code = 0;
  // Prints "zonemap <command>: <message>" to stderr and sets a non-zero exit code.
  void Fail(std::string_view command, const Status& status);
  void Fail(std::string_view command, std::string_view message);
};

// Returns the subcommand `name` of `app`, creating it if needed, so that groups such as
// `zonemap zones annotate|segment` can be filled from several files in any order.
CLI::App* GetOrAddSubcommand(CLI::App& app, const std::string& name, const std::string& description);
// `zonemap zones NAME`: one of the zones group's subcommands (the group described once, here).
CLI::App* AddZonesSubcommand(CLI::App& app, const std::string& name,
                             const std::string& description);

// How a run goes on the device, as the command line says it: the options `run` and `bench` share
// (bench passes them to every run of its matrix), declared once by AddDeviceRunOptions.
struct DeviceRunOptions {
  std::string device = "cgroup";  // --device cgroup|ledger
  double device_scale = 1.0;      // --device-scale S
  double time_compression = 1.0;  // --time-compression X (old name --pace)
  std::uint32_t cotenant_requests = 30;
  std::string lock_arena;                // --lock-arena on|off ("" = the profile's map.lock_arena)
  std::string zram_charge = "on";        // --zram-charge on|off
  CLI::Option* device_option = nullptr;  // --device itself: whether it was given
};
void AddDeviceRunOptions(CLI::App& cmd, DeviceRunOptions* options);
// Fills the device side of a run's request (device, whether explicit, scale, time compression,
// co-tenant requests, zram charge); fails on an unknown --device. --lock-arena is a profile
// override, the caller's (ProfileOverrides).
[[nodiscard]] Status SetDeviceRun(const DeviceRunOptions& options, DeviceRunRequest& request);

// Attaches every subcommand (commands.cc holds the list).
void AddAllCommands(CLI::App& app, CommandContext& ctx);

void AddArenaCommand(CLI::App& app, CommandContext& ctx);
void AddBudgetCommand(CLI::App& app, CommandContext& ctx);
void AddImportCommand(CLI::App& app, CommandContext& ctx);
void AddEvalCommand(CLI::App& app, CommandContext& ctx);
void AddZonesSegmentCommand(CLI::App& app, CommandContext& ctx);
void AddZonesAnnotateCommand(CLI::App& app, CommandContext& ctx);
void AddSimCommand(CLI::App& app, CommandContext& ctx);
void AddRunCommand(CLI::App& app, CommandContext& ctx);
void AddBenchCommand(CLI::App& app, CommandContext& ctx);
void AddVocabCommand(CLI::App& app, CommandContext& ctx);
void AddInspectCommand(CLI::App& app, CommandContext& ctx);
void AddImportTumCommand(CLI::App& app, CommandContext& ctx);

}  // namespace zm::app
