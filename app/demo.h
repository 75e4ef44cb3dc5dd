#pragma once
// `visco demo`: plan the default scene and execute it in closed loop as separate processes (app/demo.cc).

namespace CLI {
class App;
}

namespace visco::app {

/// Registers `visco demo` on `app`.
void RegisterDemoCommand(CLI::App& app);

}  // namespace visco::app
