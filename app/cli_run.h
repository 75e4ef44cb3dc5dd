#pragma once
// The user-facing error path shared by the programs (`visco`, `visco-rt`): parses the command line, runs the chosen
// subcommand and maps what it throws to the contract's exit statuses (0 success, 1 the job failed, 2 bad input or
// usage, with one line on stderr naming the file, the object and what is wrong).

namespace CLI {
class App;
}

namespace visco::app {

/// Parses `argv` into `app`, runs the subcommand callbacks, returns the exit status. `program` prefixes messages.
int RunCommandLine(CLI::App& app, const char* program, int argc, char** argv);

}  // namespace visco::app
