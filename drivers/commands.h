#pragma once
// `visco driver`: the robot driver process.

namespace CLI {
class App;
}

namespace visco::drivers {

struct DriverConfig;

/// The driver's options as flags (milliseconds), declared once for every command that runs a driver (`visco
/// driver`, `visco sim`).
struct DriverOptions {
  int node = 1;
  double watchdog_ms = 100.0;
  int period_us = 1000;
  double status_period_ms = 10.0;
  double heartbeat_ms = 100.0;
  double max_speed = 1.0;
};

/// Registers --node, --watchdog-ms, --period-us, --status-period-ms, --heartbeat-ms and --max-speed on `cmd`.
void AddDriverOptions(CLI::App& cmd, DriverOptions& options);

/// @throws visco::InputError for a period that is not a positive number of milliseconds.
DriverConfig ToDriverConfig(const DriverOptions& options);

/// Registers `visco driver`. Not real-time safe.
void RegisterCommands(CLI::App& app);

/// Sends spdlog's default logger to stderr, so that a command's stdout carries its JSON summary alone. Not real-time
/// safe.
void LogToStderr();

}  // namespace visco::drivers
