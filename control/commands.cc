#include "control/commands.h"

#include <CLI/CLI.hpp>
#include <atomic>
#include <cstdio>
#include <memory>

#include "common/error.h"
#include "common/event_log.h"
#include "common/stop_signals.h"
#include "control/run.h"
#include "control/servo_camera.h"

namespace visco::control {
namespace {

std::atomic<bool> g_stop{false};  // SIGINT, SIGTERM

struct CliOptions {
  RunOptions run;
  double max_vision_age_ms = 100;
  double status_timeout_ms = 100;
  double heartbeat_timeout_ms = 250;
  bool no_realtime = false;
  std::string log;
  std::string camera, extrinsics, objects;  // the calibrated camera of the servo law (all three or none)
  bool focal_given = false;
};

void Run(CliOptions& cli) {
  LogToStderr();  // stdout carries only the JSON summary
  RunOptions& o = cli.run;
  o.executor.max_vision_age_s = cli.max_vision_age_ms / 1000.0;
  o.executor.heartbeat_timeout_s = cli.status_timeout_ms / 1000.0;
  o.heartbeat_timeout_s = cli.heartbeat_timeout_ms / 1000.0;
  o.realtime = !cli.no_realtime;
  const int camera_files = !cli.camera.empty() + !cli.extrinsics.empty() + !cli.objects.empty();
  if (camera_files != 0 && camera_files != 3) {
    throw InputError("command line",
                     cli.camera.empty() ? "--camera" : (cli.extrinsics.empty() ? "--extrinsics" : "--objects"),
                     "the servo's calibrated camera needs all three of --camera, --extrinsics and --objects");
  }
  if (camera_files == 3) {
    if (cli.focal_given) {
      throw InputError("command line", "--focal-px",
                       "is the planar model's focal length: with --camera the calibration gives the interaction");
    }
    o.executor.servo.camera = LoadServoCamera(cli.camera, cli.extrinsics, cli.objects);
  }
  // The event log records the bus from before the strategy is loaded (a strategy on VISCO_STRATEGY is in it).
  std::unique_ptr<EventLogTap> log = OpenEventLog(cli.log, o.lcm_url);
  o.log = log.get();
  const Task task = LoadTask(o);
  StopOnSignals(g_stop);
  const RunResult result = RunTask(task, o, g_stop);
  std::printf("%s\n", result.ToJson().c_str());
  std::fflush(stdout);
  if (log) std::fprintf(stderr, "run: %s\n", log->Close().c_str());
  if (result.mode != Mode::kDone) throw JobFailed("run stopped: " + result.reason);
}

}  // namespace

void RegisterCommands(CLI::App& app) {
  auto cli = std::make_shared<CliOptions>();
  RunOptions& o = cli->run;
  CLI::App* cmd = app.add_subcommand(
      "run",
      "Execute a motion strategy in real time: a fixed-rate loop (default 500 Hz) reads the driver's status and "
      "vision's visual events / robot estimate, runs the strategy's steps (visual guarded, visual compliant, contact "
      "and goal-terminated motions, with time-outs), applies the safety limits and sends velocity commands to the "
      "robot over LCM or SocketCAN. Any stop (e-stop, driver silent or faulted, vision lost too long, limit, "
      "time-out) is announced on VISCO_FAULT and VISCO_TELEMETRY and in the log. Prints a JSON summary; exit 0 when "
      "the goal is recognised, 1 when the run stopped, 2 for bad input.");
  cmd->add_option("strategy", o.strategy_path,
                  "strategy JSON (`visco plan` output; optional extensions: top-level \"speed\" m/s, per-step "
                  "\"timeout_s\"); without it, the strategy is taken from the first VISCO_STRATEGY message")
      ->check(CLI::ExistingFile);
  cmd->add_option("--scene", o.scene_path, "scene file: goal (kernel), bounds, position uncertainty, robot polygon")
      ->check(CLI::ExistingFile);
  cmd->add_option("--rays", o.rays_path, "`visco vcrays` output: CVC ray geometry (needed for compliant motion)")
      ->check(CLI::ExistingFile);
  cmd->add_option("--strategy-wait", o.strategy_wait_s, "seconds to wait for VISCO_STRATEGY")->capture_default_str();
  cmd->add_option("--lcm-url", o.lcm_url, "LCM provider URL (LCM's default when empty)");
  cmd->add_option("--log", cli->log,
                  "write an LCM event log (lcm-logger format) of the bus: every channel it publishes and receives "
                  "(needs a udpm:// bus; docs/replay.md)");
  cmd->add_option("--can", o.can_interface, "SocketCAN interface of the robot (e.g. vcan0); default: LCM");
  cmd->add_option("--node", o.node_id, "robot node id, 1..127")->capture_default_str();
  cmd->add_option("--rate", o.rate_hz, "control rate, Hz (10..2000)")->capture_default_str();
  cmd->add_option("--speed", o.executor.default_speed, "commanded speed when the strategy gives none, m/s")
      ->capture_default_str();
  cmd->add_option("--max-speed", o.executor.limits.max_speed, "speed limit, m/s")->capture_default_str();
  cmd->add_option("--max-accel", o.executor.limits.max_accel, "acceleration limit, m/s^2")->capture_default_str();
  cmd->add_option("--bounds-margin", o.executor.limits.bounds_margin,
                  "the robot comes to rest this far inside a workspace bound (towards a bound the speed follows the "
                  "braking curve of --max-accel), m")
      ->capture_default_str();
  cmd->add_option("--gain", o.executor.servo.gain, "visual compliance gain lambda, 1/s")->capture_default_str();
  cmd->add_option("--camera", cli->camera,
                  "the camera's calibration (ViSP XML or OpenCV JSON), with --extrinsics and --objects (the files "
                  "`visco track` reads): the servo law's exact interaction for the tilted camera (docs/control.md)")
      ->check(CLI::ExistingFile);
  cmd->add_option("--extrinsics", cli->extrinsics, "the camera's pose in the world (JSON wMc), with --camera")
      ->check(CLI::ExistingFile);
  cmd->add_option("--objects", cli->objects,
                  "the object models (JSON; the robot's height: vision tracks the top of its edges), with --camera")
      ->check(CLI::ExistingFile);
  CLI::Option* focal =
      cmd->add_option("--focal-px", o.executor.servo.focal_px,
                      "without --camera only: the focal length of the planar camera model (the synthetic events of "
                      "`visco sim --rays`, which uses the same --focal-px), px")
          ->capture_default_str();
  cmd->add_option("--max-normal-speed", o.executor.servo.max_normal_speed,
                  "saturation of the servo's correction towards the line, m/s")
      ->capture_default_str();
  cmd->add_option("--max-vision-age-ms", cli->max_vision_age_ms,
                  "older visual events / estimates are stale: the command goes to zero and the step holds")
      ->capture_default_str();
  cmd->add_option("--max-hold", o.executor.max_hold_s, "a hold on stale vision longer than this stops, s")
      ->capture_default_str();
  cmd->add_option("--status-timeout-ms", cli->status_timeout_ms, "no driver status for this long stops the robot")
      ->capture_default_str();
  cmd->add_option("--heartbeat-timeout-ms", cli->heartbeat_timeout_ms, "no driver heartbeat for this long stops")
      ->capture_default_str();
  cmd->add_option("--startup-timeout", o.executor.startup_timeout_s,
                  "the driver must be ready (and vision must have spoken, if the first step needs it) within this, s")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  cmd->add_option("--step-timeout", o.executor.default_step_timeout_s, "time-out of steps that give none, s")
      ->capture_default_str();
  cmd->add_option("--stuck-s", o.executor.stuck_s,
                  "a goal- or ray-terminated step whose robot stays in contact without moving for this long, away "
                  "from the goal, fails then (stuck for good) instead of at its time-out, s (0: wait for the time-out)")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  cmd->add_flag("--goal-from-odometry", o.executor.goal_from_odometry,
                "recognise the goal from the driver's odometry instead of vision's robot estimate");
  cmd->add_flag("--no-realtime", cli->no_realtime, "do not try SCHED_FIFO and mlockall");
  cmd->add_option("--priority", o.priority, "SCHED_FIFO priority of the loop thread")->capture_default_str();
  cmd->add_option("--telemetry-hz", o.telemetry_hz, "VISCO_TELEMETRY rate, Hz")->capture_default_str();
  cmd->add_option("--duration", o.max_duration_s, "e-stop after this many seconds (0: no limit)")
      ->check(CLI::NonNegativeNumber);
  cmd->callback([cli, focal] {
    cli->focal_given = focal->count() > 0;
    Run(*cli);
  });
}

}  // namespace visco::control
