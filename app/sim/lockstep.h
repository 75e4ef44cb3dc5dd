#pragma once
// Lockstep simulation (`visco sim --lockstep`, `visco demo --lockstep`): the closed loop of `visco demo` -- the robot
// driver driving the simulated robot, the rendered camera, the vision pipeline and the controller's loop -- in one
// process, on one thread, on a simulated clock. Nothing reads the wall clock and nothing runs concurrently, so a run
// is a function of its inputs (scene, strategy, rays, camera files, options, seed): the same seed gives the same
// messages, bit for bit, timestamps included (docs/replay.md, "Lockstep runs").
//
// The parts are the live ones: drivers::Driver with drivers::SimulatedRobot behind the LCM driver transport, the LCM
// robot link, control::ControlLoop::RunCycle with control::Executor, control::ControllerBridge (vision in; faults,
// telemetry and heartbeats out), RenderedCamera, and vision::VisionPipeline fed as `visco replay` feeds it. They talk
// LCM on a private in-process bus (memq://) that this thread serves between the steps (drivers::LockstepBus), and
// every message on it goes into the event log, stamped with the simulated time it was published at; the controller's
// period records and its configuration go in as `visco run --log` writes them, so that `visco replay --check`
// replays the log through vision and the executor. Part of visco::sim. Not real-time code.

#include <atomic>
#include <cstdint>
#include <string>

#include "app/sim/camera.h"
#include "common/event_log.h"
#include "control/executor.h"
#include "control/types.h"
#include "drivers/driver.h"
#include "drivers/simulated_robot.h"

namespace visco::sim {

/// The simulated clock's epoch: 2026-01-01T00:00:00Z in microseconds (the run's first message's time).
inline constexpr std::int64_t kLockstepEpochUtime = 1'767'225'600'000'000;

/// The controller's configuration of `visco demo` (its `visco run` options on a 2-core machine): also the lockstep's.
control::ExecutorConfig DemoExecutorConfig();

struct LockstepOptions {
  std::string scene_path;     // required: the scene (goal, C-obstacles, start region)
  std::string strategy_path;  // required: `visco plan` output
  std::string rays_path;      // required: `visco vcrays` output
  bool have_start = false;
  control::Vec2 start;  // metres; default: the centroid of the scene's start region
  // The simulated robot (seed, adversary, rates); its world, cone and start come from the scene.
  drivers::SimulatedRobotConfig robot;
  drivers::DriverConfig driver;  // session_seed 0: derived from robot.seed (a run's nonces are part of its payloads)
  int node_id = 1;
  RenderedCameraConfig render;  // required (calibration, extrinsics, objects); its seed is derived from robot.seed
  double camera_hz = 15.0;
  double latency_s = 0.005;  // capture to publication of an image; vision's output follows at the same instant
  double truth_hz = 200.0;   // VISCO_SIM_TRUTH
  double rate_hz = 500.0;    // the controller's loop
  double telemetry_hz = 50.0;
  double heartbeat_timeout_s = 1.0;  // the robot link's
  control::ExecutorConfig executor = DemoExecutorConfig();
  double max_duration_s = 120.0;  // simulated seconds; then an e-stop, as `visco run --duration`
  std::int64_t start_utime = kLockstepEpochUtime;
  EventLogTap* log = nullptr;               // optional: every message, the period records, the configuration
  const std::atomic<bool>* stop = nullptr;  // optional: an e-stop request (SIGINT)
};

struct LockstepResult {
  control::Mode mode = control::Mode::kIdle;
  std::string reason;
  int steps_completed = 0;
  int num_steps = 0;
  std::int64_t cycles = 0;
  std::uint64_t commands_sent = 0;
  std::uint64_t statuses_received = 0;
  std::uint64_t faults_published = 0;  // by the controller
  std::int64_t images = 0;
  std::int64_t frames_processed = 0;  // by vision
  std::int64_t messages = 0;          // on the bus (all logged)
  std::int64_t records = 0;           // controller period records logged
  control::Vec2 position;             // the robot's true final position
  bool contact = false;
  double goal_error_m = 0.0;  // distance of the true final position to the goal region (0: inside)
  double simulated_s = 0.0;
  double wall_s = 0.0;
  std::string driver_state;
  drivers::DriverStats driver;
  /// The controller recognised the goal and the robot truly is in it.
  bool reached() const { return mode == control::Mode::kDone && goal_error_m == 0.0; }
  std::string ToJson() const;
};

/// Runs the loop to its end: the strategy done or stopped (then a few more periods, as `visco run` lingers), or
/// `max_duration_s` (an e-stop). @throws InputError for bad files or options, JobFailed if the bus cannot be opened.
LockstepResult RunLockstep(const LockstepOptions& options);

}  // namespace visco::sim
