// The `visco` program: one command with subcommands (docs/formats.md). Each library registers its own subcommands;
// this file only wires them together and owns the user-facing error path and exit statuses.

#include <CLI/CLI.hpp>

#include "app/cli_run.h"
#include "app/demo.h"
#include "app/sim/commands.h"
#include "app/spy_command.h"
#include "control/commands.h"
#include "drivers/commands.h"
#include "face_contact/cli/apo_command.h"
#include "planning/cli/commands.h"
#include "replay/commands.h"
#include "replay/log_tap.h"
#include "vision/calibration_commands.h"
#include "vision/commands.h"

#ifndef VISCO_VERSION
#define VISCO_VERSION "unknown"
#endif

int main(int argc, char** argv) {
  CLI::App app{
      "visco: plans uncertainty-tolerant robot motions with visual constraints (Fox & Hutchinson) and executes them "
      "in real time over LCM and SocketCAN.",
      "visco"};
  app.set_version_flag("--version", std::string("visco ") + VISCO_VERSION);
  app.require_subcommand(1);
  app.fallthrough(false);

  visco::app::RegisterSpyCommand(app);
  visco::app::RegisterDemoCommand(app);
  visco::drivers::RegisterCommands(app);
  visco::planning::RegisterCommands(app);
  visco::vision::RegisterCommands(app);
  visco::vision::RegisterCalibrationCommands(app);
  visco::control::RegisterCommands(app);
  visco::sim::RegisterCommands(app);
  visco::face_contact::RegisterApoCommand(app);
  visco::replay::RegisterCommands(app);
  visco::replay::InstallEventLog();  // --log of run, sim, track and driver (common/event_log.h)

  return visco::app::RunCommandLine(app, "visco", argc, argv);
}
