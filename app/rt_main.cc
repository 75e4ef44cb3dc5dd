// `visco-rt`: the real-time programs alone -- `driver` (the robot driver) and `run` (the strategy executor) -- the
// very subcommands of `visco`, in an executable that links only drivers, control, lcmtypes and common: no planner,
// no vision, no OpenCV, ViSP or CGAL (docs/development.md: the real-time executable does not link the planner). It is a
// fraction of `visco`'s size and starts at once where `visco` takes seconds (the HIL VM's emulated CPU: 10-30 s).

#include <CLI/CLI.hpp>

#include "app/cli_run.h"
#include "control/commands.h"
#include "drivers/commands.h"

#ifndef VISCO_VERSION
#define VISCO_VERSION "unknown"
#endif

int main(int argc, char** argv) {
  CLI::App app{
      "visco-rt: the real-time part of visco alone (`visco driver`, `visco run`), without the planner and vision.",
      "visco-rt"};
  app.set_version_flag("--version", std::string("visco-rt ") + VISCO_VERSION);
  app.require_subcommand(1);
  app.fallthrough(false);
  visco::drivers::RegisterCommands(app);
  visco::control::RegisterCommands(app);
  return visco::app::RunCommandLine(app, "visco-rt", argc, argv);
}
