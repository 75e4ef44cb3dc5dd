#pragma once
// The planner's subcommands of the `visco` program: `vcrays`, `backproject` (docs/formats.md).

namespace CLI {
class App;
}

namespace visco::planning {

/// Registers the planner's subcommands (`visco vcrays`, `visco backproject`) on `app`.
void RegisterCommands(CLI::App& app);

}  // namespace visco::planning
