// The subcommands of `zonemap`. Each Add*Command() attaches one CLI11 subcommand whose callback
// sets the process exit code through CommandContext; errors are printed as one line naming the
// thing and the limit, never as an exception trace.
#pragma once

#include <CLI/CLI.hpp>
#include <string>
#include <string_view>

#include "common/status.h"

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

// The device's memory options every run takes, declared once for `run` and `bench`:
// --lock-arena on|off (empty = the profile's map.lock_arena) and --zram-charge on|off.
void AddDeviceMemoryOptions(CLI::App& cmd, std::string* lock_arena, std::string* zram_charge);

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
