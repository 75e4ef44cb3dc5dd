// The `visco` program: one command with subcommands (CONTRACT.md). Each library registers its own subcommands;
// this file only wires them together and owns the user-facing error path and exit statuses.

#include <spdlog/spdlog.h>

#include <CLI/CLI.hpp>
#include <cstdio>
#include <exception>

#include "app/spy_command.h"
#include "common/error.h"
#include "control/commands.h"
#include "control/sim_commands.h"
#include "drivers/commands.h"
#include "planning/apo_command.h"
#include "planning/commands.h"
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
  visco::drivers::RegisterCommands(app);
  visco::planning::RegisterCommands(app);
  visco::vision::RegisterCommands(app);
  visco::control::RegisterCommands(app);
  visco::control::RegisterSimCommands(app);
  visco::planning::RegisterApoCommand(app);

  spdlog::set_pattern("%Y-%m-%dT%H:%M:%S.%e %^%l%$ %v");
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForAllHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForVersion& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    // Usage errors are bad input: exit 2 with one line naming what is wrong.
    std::fprintf(stderr, "visco: command line: %s\nRun 'visco --help' for usage.\n", e.what());
    return 2;
  } catch (const visco::InputError& e) {
    std::fprintf(stderr, "visco: %s\n", e.what());
    return 2;
  } catch (const visco::JobFailed& e) {
    std::fprintf(stderr, "visco: %s\n", e.what());
    return 1;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "visco: internal error: %s\n", e.what());
    return 1;
  }
  return 0;
}
