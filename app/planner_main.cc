// `visco`: the planner's commands (vcrays, backproject, critical, plan, camera, apo) and --version run in this
// program, which links neither vision nor the real-time parts, so that scripts calling the planner in a loop do not
// pay for loading OpenCV, ViSP and AprilTag (about 250 shared libraries). Every other command, and the help that
// lists them all, is handed to `visco-full` next to it: the same arguments in the same process (exec), so exit
// statuses, signals, stdin and stdout are the command's own.

#include <unistd.h>

#include <CLI/CLI.hpp>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <string>

#include "app/cli_run.h"
#include "app/paths.h"
#include "face_contact/cli/apo_command.h"
#include "planning/cli/commands.h"

#ifdef VISCO_MIMALLOC
#include <mimalloc.h>  // linked for its malloc; --version names it (and so the program really links it)
#endif

#ifndef VISCO_VERSION
#define VISCO_VERSION "unknown"
#endif

int main(int argc, char** argv) {
  CLI::App app{"visco: the planner's commands (the full program, visco-full, runs the others).", "visco"};
  std::string version = std::string("visco ") + VISCO_VERSION;
#ifdef VISCO_MIMALLOC
  version += " (allocator: mimalloc " + std::to_string(mi_version()) + ")";
#endif
  app.set_version_flag("--version", version);
  app.require_subcommand(1);
  app.fallthrough(false);
  visco::planning::RegisterCommands(app);
  visco::face_contact::RegisterApoCommand(app);

  bool here = argc >= 2 && std::strcmp(argv[1], "--version") == 0;
  if (argc >= 2) {
    for (const CLI::App* sub : app.get_subcommands([](CLI::App*) { return true; })) here |= sub->get_name() == argv[1];
  }
  if (here) return visco::app::RunCommandLine(app, "visco", argc, argv);

  const std::string full = (visco::app::ExecutableDir() / "visco-full").string();
  execv(full.c_str(), argv);
  std::fprintf(stderr, "visco: cannot run %s (the program for every command but the planner's): %s\n", full.c_str(),
               std::strerror(errno));
  return 1;
}
