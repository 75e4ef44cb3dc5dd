#pragma once
// `visco spy`: launches lcm-spy with visco's message jar on the class path.

namespace CLI {
class App;
}

namespace visco::app {

/// Adds the `spy` subcommand to `app`. Not real-time safe (setup only).
void RegisterSpyCommand(CLI::App& app);

}  // namespace visco::app
