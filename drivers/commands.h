#pragma once
// `visco driver`: the robot driver process.

namespace CLI {
class App;
}

namespace visco::drivers {

/// Registers `visco driver`. Not real-time safe.
void RegisterCommands(CLI::App& app);

/// Sends spdlog's default logger to stderr, so that a command's stdout carries its JSON summary alone. Not real-time
/// safe.
void LogToStderr();

}  // namespace visco::drivers
