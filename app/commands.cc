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

void AddAllCommands(CLI::App& app, CommandContext& ctx) {
  AddArenaCommand(app, ctx);
}

}  // namespace zm::app
