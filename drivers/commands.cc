#include "drivers/commands.h"

#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/spdlog.h>

#include <CLI/CLI.hpp>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <lcm/lcm-cpp.hpp>
#include <memory>
#include <thread>
#include <vector>

#include "common/error.h"
#include "common/event_log.h"
#include "common/stop_signals.h"
#include "drivers/driver.h"
#include "drivers/driver_transport.h"
#include "drivers/robot_backend.h"
#include "drivers/robot_link.h"
#include "drivers/simulated_robot.h"
#include "drivers/simulated_robot_options.h"
#include "lcmtypes/channels.h"
#include "visco/sim_truth_t.hpp"

namespace visco::drivers {
namespace {

std::atomic<bool> g_stop{false};  // SIGINT, SIGTERM, --duration

struct DriverCommand {
  std::string can_interface;
  std::string lcm_url;
  DriverOptions driver;
  SimulatedRobotOptions robot;
  RobotBackendOptions backend;
  double duration_s = 0.0;
  double truth_hz = 0.0;
  std::string log;
};

// Publishes the simulated robot's true state on VISCO_SIM_TRUTH at `hz` for a simulated camera in another process
// (off the driver's thread: it only takes the latest value the robot published).
std::thread StartTruthPublisher(SimulatedRobot& robot, double hz, const std::string& lcm_url, int node) {
  auto lcm = std::make_shared<lcm::LCM>(lcm_url);
  if (!lcm->good()) throw JobFailed("LCM: cannot initialise provider '" + lcm_url + "' for --truth-hz");
  return std::thread([&robot, hz, lcm, node] {
    const auto period =
        std::chrono::duration_cast<std::chrono::steady_clock::duration>(std::chrono::duration<double>(1.0 / hz));
    auto next = std::chrono::steady_clock::now();
    RobotTruth truth;
    while (!g_stop.load()) {
      next += period;
      std::this_thread::sleep_until(next);
      if (!robot.truth().TryTake(truth)) continue;
      sim_truth_t m;
      m.utime = WallMicros() - (MonotonicMicros() - truth.time_ns / 1000);  // the step's time on the wall clock
      m.node_id = node;
      for (int i = 0; i < 2; ++i) {
        m.position[i] = truth.position[i];
        m.velocity[i] = truth.velocity[i];
      }
      m.contact = truth.contact;
      m.mode = static_cast<std::int8_t>(truth.mode);
      lcm->publish(channels::kSimTruth, &m);
    }
  });
}

std::int64_t Micros(double ms, const char* option) {
  if (!std::isfinite(ms) || ms <= 0.0) throw InputError("command line", option, "must be a positive number");
  return static_cast<std::int64_t>(std::llround(ms * 1000.0));
}

void RunDriver(const DriverCommand& o) {
  LogToStderr();  // stdout carries only the JSON summary
  const DriverConfig config = ToDriverConfig(o.driver);

  RobotBackendOptions backend = o.backend;
  backend.max_speed = o.driver.max_speed;
  backend.driver_node = o.driver.node;
  backend.driver_interface = o.can_interface;
  backend.heartbeat_ms = o.driver.heartbeat_ms;
  SimulatedRobot* simulated = nullptr;
  std::unique_ptr<RobotInterface> robot_owner = MakeRobot(backend, o.robot, &simulated);
  RobotInterface& robot = *robot_owner;
  if (o.truth_hz > 0.0 && simulated == nullptr) {
    throw InputError("command line", "--truth-hz",
                     "publishes the simulated robot's truth: only with --robot simulated");
  }
  std::unique_ptr<EventLogTap> log = OpenEventLog(o.log, o.lcm_url);

  DriverTransportConfig transport_config;
  transport_config.node_id = o.driver.node;
  transport_config.can_interface = o.can_interface;
  transport_config.lcm_url = o.lcm_url;
  std::unique_ptr<DriverTransport> transport = o.can_interface.empty() ? MakeLcmDriverTransport(transport_config)
                                                                       : MakeSocketCanDriverTransport(transport_config);
  Driver driver(config, *transport, robot);
  // The robot's lifecycle (drivers/robot_interface.h): never a half-started robot.
  try {
    robot.Configure();
    robot.Activate();
  } catch (...) {
    robot.Deactivate();
    throw;
  }

  StopOnSignals(g_stop);
  // SIGUSR1: the operator's e-stop release (drivers/README.md).
  ReleaseOnSignal([](void* d) { static_cast<Driver*>(d)->RequestOperatorRelease(); }, &driver);
  if (!(o.truth_hz >= 0.0 && o.truth_hz <= 1000.0))
    throw InputError("command line", "--truth-hz", "must be in [0, 1000]");
  std::thread truth =
      o.truth_hz > 0.0 ? StartTruthPublisher(*simulated, o.truth_hz, o.lcm_url, o.driver.node) : std::thread();
  std::thread timer;
  if (o.duration_s > 0.0) {
    timer = std::thread([d = o.duration_s] {
      const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(d);
      while (!g_stop.load() && std::chrono::steady_clock::now() < end) {
        std::this_thread::sleep_for(std::chrono::milliseconds(5));
      }
      g_stop.store(true);
    });
  }
  const RobotFeedback at = robot.Read();
  spdlog::info("driver: node {} on {}, watchdog {} ms, {} robot at ({}, {}){}", o.driver.node,
               o.can_interface.empty() ? "LCM " + (o.lcm_url.empty() ? std::string("(default)") : o.lcm_url)
                                       : "CAN " + o.can_interface,
               o.driver.watchdog_ms, backend.kind, at.position[0], at.position[1],
               simulated != nullptr
                   ? " among " + std::to_string(simulated->model().world().obstacles.size()) + " C-obstacle(s)"
                   : std::string());
  driver.Run(g_stop);
  robot.Deactivate();
  IgnoreReleaseSignal();
  g_stop.store(true);
  if (timer.joinable()) timer.join();
  if (truth.joinable()) truth.join();
  if (log) spdlog::info("driver: {}", log->Close());
  const DriverStats& s = driver.stats();
  std::printf(
      "{\"commands_applied\": %llu, \"bad_commands\": %llu, \"out_of_sequence\": %llu, \"wrong_session\": %llu, "
      "\"sessions\": %llu, \"refused_resets\": %llu, \"nmt_starts\": %llu, \"nmt_resets\": %llu, "
      "\"operator_releases\": %llu, \"quick_stops\": %llu, \"watchdog_stops\": %llu, "
      "\"bounds_stops\": %llu, \"robot_faults\": %llu, \"estops\": %llu, \"resets\": %llu, \"bus_offs\": %llu, "
      "\"frames_dropped\": %llu, "
      "\"statuses_sent\": %llu, "
      "\"faults_sent\": %llu, "
      "\"send_failures\": %llu, \"state\": \"%s\", \"position\": [%.9g, %.9g], \"contact\": %s}\n",
      static_cast<unsigned long long>(s.commands_applied), static_cast<unsigned long long>(s.bad_commands),
      static_cast<unsigned long long>(s.out_of_sequence), static_cast<unsigned long long>(s.wrong_session),
      static_cast<unsigned long long>(s.sessions), static_cast<unsigned long long>(s.refused_resets),
      static_cast<unsigned long long>(s.nmt_starts), static_cast<unsigned long long>(s.nmt_resets),
      static_cast<unsigned long long>(s.operator_releases), static_cast<unsigned long long>(s.quick_stops),
      static_cast<unsigned long long>(s.watchdog_stops), static_cast<unsigned long long>(s.bounds_stops),
      static_cast<unsigned long long>(s.robot_faults), static_cast<unsigned long long>(s.estops),
      static_cast<unsigned long long>(s.resets), static_cast<unsigned long long>(s.bus_offs),
      static_cast<unsigned long long>(s.frames_dropped), static_cast<unsigned long long>(s.statuses_sent),
      static_cast<unsigned long long>(s.faults_sent), static_cast<unsigned long long>(s.send_failures),
      ToString(driver.state()), robot.Read().position[0], robot.Read().position[1],
      robot.Read().contact ? "true" : "false");
  std::fflush(stdout);
}

}  // namespace

void AddDriverOptions(CLI::App& cmd, DriverOptions& o) {
  const std::string group = "Driver";
  cmd.add_option("--node", o.node, "CAN node id of the robot, 1..127")
      ->check(CLI::Range(1, 127))
      ->capture_default_str()
      ->group(group);
  cmd.add_option("--watchdog-ms", o.watchdog_ms, "command watchdog period, ms")->capture_default_str()->group(group);
  cmd.add_option("--period-us", o.period_us, "robot update period, microseconds")
      ->check(CLI::Range(50, 1'000'000))
      ->capture_default_str()
      ->group(group);
  cmd.add_option("--status-period-ms", o.status_period_ms, "status period when no command arrives, ms")
      ->capture_default_str()
      ->group(group);
  cmd.add_option("--heartbeat-ms", o.heartbeat_ms, "heartbeat period, ms")->capture_default_str()->group(group);
  cmd.add_option("--max-speed", o.max_speed, "speed limit, m/s (faster commands are clamped and reported)")
      ->capture_default_str()
      ->group(group);
}

DriverConfig ToDriverConfig(const DriverOptions& o) {
  DriverConfig config;
  config.watchdog_us = Micros(o.watchdog_ms, "--watchdog-ms");
  config.period_us = o.period_us;
  config.status_period_us = Micros(o.status_period_ms, "--status-period-ms");
  config.heartbeat_period_us = Micros(o.heartbeat_ms, "--heartbeat-ms");
  if (!(o.max_speed > 0.0) || !std::isfinite(o.max_speed)) {
    throw InputError("command line", "--max-speed", "must be a positive number");
  }
  config.max_speed = o.max_speed;
  return config;
}

void LogToStderr() {
  auto logger = spdlog::get("visco");
  if (!logger) logger = spdlog::stderr_color_mt("visco");
  spdlog::set_default_logger(logger);
  spdlog::set_pattern("%Y-%m-%dT%H:%M:%S.%e %^%l%$ %v");
}

void RegisterCommands(CLI::App& app) {
  auto options = std::make_shared<DriverCommand>();
  CLI::App* cmd = app.add_subcommand(
      "driver",
      "Robot driver process: receives velocity commands over SocketCAN (--can IFACE) or LCM (default), drives the "
      "robot (the simulated one by default; CiA 402 drives or a plugin: --robot), answers every command with a status, "
      "sends heartbeats and EMCY/fault messages, and stops "
      "the robot when no valid command arrives within the watchdog period (protocol: drivers/README.md). It boots "
      "disabled in a fresh session and accepts only commands of its current session. A latched e-stop is released "
      "only by the operator: send the driver SIGUSR1 (kill -USR1 PID); it is then disabled until a controller's "
      "reset. Runs until SIGINT/SIGTERM or --duration; prints a JSON summary on exit.");
  cmd->add_option("--can", options->can_interface, "SocketCAN interface (e.g. vcan0); without it, LCM is used");
  cmd->add_option("--lcm-url", options->lcm_url, "LCM provider URL (LCM's default when empty)");
  cmd->add_option("--log", options->log,
                  "write an LCM event log (lcm-logger format) of the bus: every channel it publishes and receives "
                  "(needs a udpm:// bus; docs/replay.md)");
  AddDriverOptions(*cmd, options->driver);
  const std::string robot_group = "Robot backend (docs/your_own_robot.md)";
  cmd->add_option("--robot", options->backend.kind,
                  "what the driver drives: simulated (the simulated robot, its options below), cia402 (CiA 402 drives "
                  "over CAN, configured by --robot-config) or plugin (a shared library, --robot-plugin)")
      ->capture_default_str()
      ->group(robot_group);
  cmd->add_option("--robot-config", options->backend.config_path,
                  "the robot's configuration, a JSON file: the drives (cia402) or the plugin's own (passed to it as "
                  "text)")
      ->group(robot_group);
  cmd->add_option("--robot-plugin", options->backend.plugin_path,
                  "--robot plugin: the shared library (exports visco_robot_plugin_create, drivers/robot_plugin.h)")
      ->group(robot_group);
  AddSimulatedRobotOptions(*cmd, options->robot, /*with_world=*/true);
  cmd->add_option("--truth-hz", options->truth_hz,
                  "simulation: publish the robot's true state on VISCO_SIM_TRUTH (LCM) at this rate, for a simulated "
                  "camera in another process (`visco sim --no-driver`); 0: off")
      ->capture_default_str();
  cmd->add_option("--duration", options->duration_s, "stop after this many seconds (0: run until a signal)")
      ->check(CLI::NonNegativeNumber);
  cmd->callback([options] { RunDriver(*options); });
}

}  // namespace visco::drivers
