#include "drivers/commands.h"

#include <signal.h>
#include <spdlog/spdlog.h>

#include <CLI/CLI.hpp>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <memory>
#include <thread>
#include <vector>

#include "common/error.h"
#include "common/event_log.h"
#include "drivers/driver.h"
#include "drivers/driver_transport.h"
#include "drivers/simulated_robot.h"

namespace visco::drivers {
namespace {

std::atomic<bool> g_stop{false};
std::atomic<Driver*> g_driver{nullptr};
void OnSignal(int) { g_stop.store(true); }
// SIGUSR1: the operator's e-stop release (drivers/README.md): an action at the driver, never a bus message.
void OnRelease(int) {
  if (Driver* driver = g_driver.load()) driver->RequestOperatorRelease();
}

struct DriverOptions {
  std::string can_interface;
  std::string lcm_url;
  int node = 1;
  double watchdog_ms = 100.0;
  int period_us = 1000;
  double status_period_ms = 10.0;
  double heartbeat_ms = 100.0;
  double max_speed = 1.0;
  double max_acceleration = 2.0;
  double quick_stop_deceleration = 50.0;
  std::vector<double> start = {0.0, 0.0};
  std::vector<double> bounds;
  std::vector<double> workspace;
  double duration_s = 0.0;
  std::string log;
};

std::int64_t Micros(double ms, const char* option) {
  if (!std::isfinite(ms) || ms <= 0.0) throw InputError("command line", option, "must be a positive number");
  return static_cast<std::int64_t>(std::llround(ms * 1000.0));
}

void RunDriver(const DriverOptions& o) {
  DriverConfig config;
  config.watchdog_us = Micros(o.watchdog_ms, "--watchdog-ms");
  config.period_us = o.period_us;
  config.status_period_us = Micros(o.status_period_ms, "--status-period-ms");
  config.heartbeat_period_us = Micros(o.heartbeat_ms, "--heartbeat-ms");
  config.max_speed = o.max_speed;

  SimulatedRobotConfig robot_config;
  robot_config.start[0] = o.start[0];
  robot_config.start[1] = o.start[1];
  robot_config.max_acceleration = o.max_acceleration;
  robot_config.quick_stop_deceleration = o.quick_stop_deceleration;
  if (!o.bounds.empty()) {
    robot_config.walls = true;
    robot_config.bounds_min[0] = o.bounds[0];
    robot_config.bounds_min[1] = o.bounds[1];
    robot_config.bounds_max[0] = o.bounds[2];
    robot_config.bounds_max[1] = o.bounds[3];
  }
  if (!o.workspace.empty()) {
    robot_config.workspace = true;
    robot_config.workspace_min[0] = o.workspace[0];
    robot_config.workspace_min[1] = o.workspace[1];
    robot_config.workspace_max[0] = o.workspace[2];
    robot_config.workspace_max[1] = o.workspace[3];
  }
  SimulatedRobot robot(robot_config);
  std::unique_ptr<EventLogTap> log = OpenEventLog(o.log, o.lcm_url);

  DriverTransportConfig transport_config;
  transport_config.node_id = o.node;
  transport_config.can_interface = o.can_interface;
  transport_config.lcm_url = o.lcm_url;
  std::unique_ptr<DriverTransport> transport = o.can_interface.empty() ? MakeLcmDriverTransport(transport_config)
                                                                       : MakeSocketCanDriverTransport(transport_config);
  Driver driver(config, *transport, robot);

  struct sigaction action {};
  action.sa_handler = OnSignal;
  sigaction(SIGINT, &action, nullptr);
  sigaction(SIGTERM, &action, nullptr);
  g_driver.store(&driver);
  struct sigaction release {};
  release.sa_handler = OnRelease;
  release.sa_flags = SA_RESTART;
  sigaction(SIGUSR1, &release, nullptr);
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
  spdlog::info("driver: node {} on {}, watchdog {} ms, simulated robot at ({}, {})", o.node,
               o.can_interface.empty() ? "LCM " + (o.lcm_url.empty() ? std::string("(default)") : o.lcm_url)
                                       : "CAN " + o.can_interface,
               o.watchdog_ms, o.start[0], o.start[1]);
  driver.Run(g_stop);
  signal(SIGUSR1, SIG_IGN);
  g_driver.store(nullptr);
  if (timer.joinable()) timer.join();
  if (log) spdlog::info("driver: {}", log->Close());
  const DriverStats& s = driver.stats();
  std::printf(
      "{\"commands_applied\": %llu, \"bad_commands\": %llu, \"out_of_sequence\": %llu, \"wrong_session\": %llu, "
      "\"sessions\": %llu, \"refused_resets\": %llu, \"nmt_starts\": %llu, \"nmt_resets\": %llu, "
      "\"operator_releases\": %llu, \"quick_stops\": %llu, \"watchdog_stops\": %llu, "
      "\"bounds_stops\": %llu, \"estops\": %llu, \"resets\": %llu, \"bus_offs\": %llu, \"statuses_sent\": %llu, "
      "\"faults_sent\": %llu, "
      "\"send_failures\": %llu, \"state\": \"%s\"}\n",
      static_cast<unsigned long long>(s.commands_applied), static_cast<unsigned long long>(s.bad_commands),
      static_cast<unsigned long long>(s.out_of_sequence), static_cast<unsigned long long>(s.wrong_session),
      static_cast<unsigned long long>(s.sessions), static_cast<unsigned long long>(s.refused_resets),
      static_cast<unsigned long long>(s.nmt_starts), static_cast<unsigned long long>(s.nmt_resets),
      static_cast<unsigned long long>(s.operator_releases), static_cast<unsigned long long>(s.quick_stops),
      static_cast<unsigned long long>(s.watchdog_stops), static_cast<unsigned long long>(s.bounds_stops),
      static_cast<unsigned long long>(s.estops), static_cast<unsigned long long>(s.resets),
      static_cast<unsigned long long>(s.bus_offs), static_cast<unsigned long long>(s.statuses_sent),
      static_cast<unsigned long long>(s.faults_sent), static_cast<unsigned long long>(s.send_failures),
      ToString(driver.state()));
  std::fflush(stdout);
}

}  // namespace

void RegisterCommands(CLI::App& app) {
  auto options = std::make_shared<DriverOptions>();
  CLI::App* cmd = app.add_subcommand(
      "driver",
      "Robot driver process: receives velocity commands over SocketCAN (--can IFACE) or LCM (default), drives the "
      "simulated robot, answers every command with a status, sends heartbeats and EMCY/fault messages, and stops "
      "the robot when no valid command arrives within the watchdog period (protocol: drivers/README.md). It boots "
      "disabled in a fresh session and accepts only commands of its current session. A latched e-stop is released "
      "only by the operator: send the driver SIGUSR1 (kill -USR1 PID); it is then disabled until a controller's "
      "reset. Runs until SIGINT/SIGTERM or --duration; prints a JSON summary on exit.");
  cmd->add_option("--can", options->can_interface, "SocketCAN interface (e.g. vcan0); without it, LCM is used");
  cmd->add_option("--lcm-url", options->lcm_url, "LCM provider URL (LCM's default when empty)");
  cmd->add_option("--log", options->log,
                  "write an LCM event log (lcm-logger format) of the bus: every channel it publishes and receives "
                  "(needs a udpm:// bus; docs/replay.md)");
  cmd->add_option("--node", options->node, "CAN node id of the robot, 1..127")->check(CLI::Range(1, 127));
  cmd->add_option("--watchdog-ms", options->watchdog_ms, "command watchdog period, ms")->capture_default_str();
  cmd->add_option("--period-us", options->period_us, "robot update period, microseconds")
      ->check(CLI::Range(50, 1'000'000))
      ->capture_default_str();
  cmd->add_option("--status-period-ms", options->status_period_ms, "status period when no command arrives, ms")
      ->capture_default_str();
  cmd->add_option("--heartbeat-ms", options->heartbeat_ms, "heartbeat period, ms")->capture_default_str();
  cmd->add_option("--max-speed", options->max_speed, "speed limit, m/s (faster commands are clamped and reported)")
      ->capture_default_str();
  cmd->add_option("--max-acceleration", options->max_acceleration, "simulated robot's acceleration limit, m/s^2")
      ->capture_default_str();
  cmd->add_option("--quick-stop-deceleration", options->quick_stop_deceleration,
                  "simulated robot's deceleration on a safety stop, m/s^2")
      ->capture_default_str();
  cmd->add_option("--start", options->start, "initial position of the simulated robot, metres")->expected(2);
  cmd->add_option("--bounds", options->bounds, "walls of the simulated robot: XMIN YMIN XMAX YMAX, metres")
      ->expected(4);
  cmd->add_option("--workspace", options->workspace,
                  "workspace of the simulated robot: XMIN YMIN XMAX YMAX, metres; leaving it stops the robot with "
                  "the bounds fault (EMCY 0x8612)")
      ->expected(4);
  cmd->add_option("--duration", options->duration_s, "stop after this many seconds (0: run until a signal)")
      ->check(CLI::NonNegativeNumber);
  cmd->callback([options] { RunDriver(*options); });
}

}  // namespace visco::drivers
