// zonemap: the command line of the library (docs/design.md "The command line").
#include <CLI/CLI.hpp>
#include <opencv2/core/utility.hpp>

#include "commands.h"

int main(int argc, char** argv) {
  // Single-threaded by design; OpenCV's pool also spins forever under qemu-user.
  cv::setNumThreads(0);
  CLI::App app{"zonemap: semantic zone-based keyframe map management for memory-bounded robots"};
  app.set_version_flag("--version", "zonemap 0.1.0");
  app.require_subcommand(1);
  zm::app::CommandContext ctx;
  zm::app::AddAllCommands(app, ctx);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  }
  return ctx.exit_code;
}
